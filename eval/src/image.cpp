#include "cpvs/eval/image.h"

#include <OpenEXR/ImfRgbaFile.h>
#include <png.h>
#include <zlib.h>

#include <fstream>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>

#include "cpvs/base/vec3.h"
#include "cpvs/base/hash.h"
#include "cpvs/base/error.h"

namespace cpvs {

float linearToSrgb(float v) {
  v = std::clamp(v, 0.0f, 1.0f);
  return v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
}

float srgbToLinear(float v) {
  v = std::clamp(v, 0.0f, 1.0f);
  return v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f);
}

void writeExr(const std::string& path, const Image& image) {
  if (image.width <= 0 || image.height <= 0) throw InputError(path + ": cannot write an empty image");
  std::vector<Imf::Rgba> rows(image.pixels.size());
  for (size_t i = 0; i < rows.size(); ++i) {
    const Rgb& p = image.pixels[i];
    rows[i] = Imf::Rgba(p.r, p.g, p.b, 1.0f);
  }
  try {
    Imf::RgbaOutputFile file(path.c_str(), image.width, image.height, Imf::WRITE_RGB);
    file.setFrameBuffer(rows.data(), 1, size_t(image.width));
    file.writePixels(image.height);
  } catch (const std::exception& e) {
    throw InputError(path + ": cannot write EXR: " + e.what());
  }
}

namespace {

struct FileCloser {
  void operator()(FILE* f) const { std::fclose(f); }
};

}  // namespace

void writePng(const std::string& path, const Image& image) {
  if (image.width <= 0 || image.height <= 0) throw InputError(path + ": cannot write an empty image");
  std::unique_ptr<FILE, FileCloser> f(std::fopen(path.c_str(), "wb"));
  if (!f) throw InputError(path + ": cannot open for writing");
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  if (!info) {
    png_destroy_write_struct(&png, nullptr);
    throw InputError(path + ": out of memory for PNG");
  }
  std::vector<uint8_t> row(size_t(image.width) * 3);
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    throw InputError(path + ": cannot write PNG");
  }
  png_init_io(png, f.get());
  png_set_IHDR(png, info, png_uint_32(image.width), png_uint_32(image.height), 8, PNG_COLOR_TYPE_RGB,
               PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_set_sRGB(png, info, PNG_sRGB_INTENT_PERCEPTUAL);
  png_write_info(png, info);
  auto encode = [](float v) { return uint8_t(std::lround(linearToSrgb(v) * 255.0f)); };
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) {
      const Rgb& p = image.at(x, y);
      row[3 * size_t(x)] = encode(p.r);
      row[3 * size_t(x) + 1] = encode(p.g);
      row[3 * size_t(x) + 2] = encode(p.b);
    }
    png_write_row(png, row.data());
  }
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  if (std::fflush(f.get()) != 0) throw InputError(path + ": cannot write PNG (disk full?)");
}

namespace {

void putBigEndian(std::string& out, uint32_t v, int bytes) {
  for (int i = bytes - 1; i >= 0; --i) out.push_back(char((v >> (8 * i)) & 0xFF));
}

// One PNG chunk: length, type, data, CRC of type and data.
void chunk(std::ofstream& out, const char* type, const std::string& data) {
  std::string head;
  putBigEndian(head, uint32_t(data.size()), 4);
  out.write(head.data(), 4);
  std::string body = std::string(type, 4) + data;
  out.write(body.data(), std::streamsize(body.size()));
  std::string crc;
  putBigEndian(crc, uint32_t(crc32(0, reinterpret_cast<const Bytef*>(body.data()), uInt(body.size()))), 4);
  out.write(crc.data(), 4);
}

// A frame's scanlines (filter 0, 8-bit sRGB), deflated.
std::string deflatedRows(const Image& image) {
  std::string raw;
  raw.reserve(size_t(image.height) * (size_t(image.width) * 3 + 1));
  for (int y = 0; y < image.height; ++y) {
    raw.push_back(0);
    for (int x = 0; x < image.width; ++x) {
      const Rgb& p = image.at(x, y);
      for (float v : {p.r, p.g, p.b}) raw.push_back(char(uint8_t(std::lround(linearToSrgb(v) * 255.0f))));
    }
  }
  uLongf size = compressBound(uLong(raw.size()));
  std::string packed(size, '\0');
  if (compress2(reinterpret_cast<Bytef*>(packed.data()), &size, reinterpret_cast<const Bytef*>(raw.data()), uLong(raw.size()),
                6) != Z_OK)
    throw InputError("cannot compress an animation frame");
  packed.resize(size);
  return packed;
}

}  // namespace

void writeAnimatedPng(const std::string& path, const std::vector<Image>& frames, int delayMs) {
  if (frames.empty()) throw InputError(path + ": an animation needs at least one frame");
  const int w = frames[0].width, h = frames[0].height;
  for (const Image& f : frames)
    if (f.width != w || f.height != h || w <= 0 || h <= 0) throw InputError(path + ": animation frames differ in size");
  std::ofstream out(path, std::ios::binary);
  if (!out) throw InputError(path + ": cannot open for writing");
  out.write("\x89PNG\r\n\x1a\n", 8);
  std::string ihdr;
  putBigEndian(ihdr, uint32_t(w), 4);
  putBigEndian(ihdr, uint32_t(h), 4);
  ihdr += std::string("\x08\x02\x00\x00\x00", 5);  // 8 bits, RGB, deflate, filter 0, no interlace
  chunk(out, "IHDR", ihdr);
  chunk(out, "sRGB", std::string(1, '\0'));
  std::string actl;
  putBigEndian(actl, uint32_t(frames.size()), 4);
  putBigEndian(actl, 0, 4);  // loop forever
  chunk(out, "acTL", actl);
  uint32_t sequence = 0;
  for (size_t i = 0; i < frames.size(); ++i) {
    std::string fctl;
    putBigEndian(fctl, sequence++, 4);
    putBigEndian(fctl, uint32_t(w), 4);
    putBigEndian(fctl, uint32_t(h), 4);
    putBigEndian(fctl, 0, 4);
    putBigEndian(fctl, 0, 4);
    putBigEndian(fctl, uint32_t(std::clamp(delayMs, 1, 65535)), 2);
    putBigEndian(fctl, 1000, 2);
    fctl += std::string("\x00\x00", 2);  // dispose none, blend source
    chunk(out, "fcTL", fctl);
    const std::string data = deflatedRows(frames[i]);
    if (i == 0) {
      chunk(out, "IDAT", data);  // the first frame is the image a plain PNG reader shows
    } else {
      std::string fdat;
      putBigEndian(fdat, sequence++, 4);
      chunk(out, "fdAT", fdat + data);
    }
  }
  chunk(out, "IEND", "");
  if (!out.flush()) throw InputError(path + ": cannot write PNG (disk full?)");
}

Image readPng(const std::string& path) {
  png_image img{};
  img.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&img, path.c_str()))
    throw InputError(path + ": cannot read PNG: " + img.message);
  img.format = PNG_FORMAT_RGB;
  std::vector<uint8_t> buf(PNG_IMAGE_SIZE(img));
  if (!png_image_finish_read(&img, nullptr, buf.data(), 0, nullptr)) {
    png_image_free(&img);
    throw InputError(path + ": cannot read PNG: " + img.message);
  }
  Image out(int(img.width), int(img.height));
  for (size_t i = 0; i < out.pixels.size(); ++i)
    out.pixels[i] = {srgbToLinear(buf[3 * i] / 255.0f), srgbToLinear(buf[3 * i + 1] / 255.0f),
                     srgbToLinear(buf[3 * i + 2] / 255.0f)};
  return out;
}

}  // namespace cpvs
