#include "cpvs/eval/image.h"

#include <OpenEXR/ImfRgbaFile.h>
#include <png.h>

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
