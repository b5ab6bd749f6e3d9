// A linear RGB float image and its two file forms: EXR (linear, half float) for tools,
// PNG (sRGB, 8 bit) for a quick look.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace cpvs {

struct Rgb {
  float r = 0, g = 0, b = 0;
};

/// Row-major, top row first, linear (not gamma-encoded) values.
struct Image {
  int width = 0, height = 0;
  std::vector<Rgb> pixels;

  Image() = default;
  Image(int w, int h) : width(w), height(h), pixels(size_t(w) * size_t(h)) {}
  Rgb& at(int x, int y) { return pixels[size_t(y) * size_t(width) + size_t(x)]; }
  const Rgb& at(int x, int y) const { return pixels[size_t(y) * size_t(width) + size_t(x)]; }
};

/// Writes an RGB half-float OpenEXR file. Throws InputError when it cannot be written.
void writeExr(const std::string& path, const Image& image);
/// Writes an 8-bit sRGB PNG (values clamped to [0, 1] and gamma-encoded).
void writePng(const std::string& path, const Image& image);
/// Writes an animated PNG (APNG): every frame the same size, shown `delayMs` each, looping.
/// Viewers without APNG show the first frame. InputError for no frames or mixed sizes.
void writeAnimatedPng(const std::string& path, const std::vector<Image>& frames, int delayMs);
/// Reads a PNG written by writePng back to linear values (for tests and comparisons).
Image readPng(const std::string& path);

/// The sRGB transfer function and its inverse, on [0, 1].
float linearToSrgb(float v);
float srgbToLinear(float v);

}  // namespace cpvs
