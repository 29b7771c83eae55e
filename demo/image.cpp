// PNG files and image comparison for the demo's frames and the golden-image tests.
#include <png.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include "renderer.h"

namespace gf::demo {

Result<void> writePng(const std::string& path, const Image& image) {
  if (image.width <= 0 || image.height <= 0 ||
      image.rgba.size() != size_t(image.width) * size_t(image.height) * 4)
    return fail(path, ": image is ", std::to_string(image.width), "x", std::to_string(image.height),
                " with ", std::to_string(image.rgba.size()), " bytes, not 4 bytes per pixel");
  png_image png;
  std::memset(&png, 0, sizeof png);
  png.version = PNG_IMAGE_VERSION;
  png.width = png_uint_32(image.width);
  png.height = png_uint_32(image.height);
  png.format = PNG_FORMAT_RGBA;
  if (!png_image_write_to_file(&png, path.c_str(), 0, image.rgba.data(), 0, nullptr))
    return fail(path, ": cannot write PNG: ", png.message);
  return {};
}

Result<Image> readPng(const std::string& path) {
  png_image png;
  std::memset(&png, 0, sizeof png);
  png.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&png, path.c_str()))
    return fail(path, ": cannot read PNG: ", png.message);
  png.format = PNG_FORMAT_RGBA;
  Image image;
  image.width = int(png.width);
  image.height = int(png.height);
  image.rgba.resize(PNG_IMAGE_SIZE(png));
  if (!png_image_finish_read(&png, nullptr, image.rgba.data(), 0, nullptr))
    return fail(path, ": cannot decode PNG: ", png.message);
  return image;
}

Result<ImageDiff> compareImages(const Image& a, const Image& b, int threshold) {
  if (a.width != b.width || a.height != b.height || a.rgba.size() != b.rgba.size())
    return fail("compareImages: sizes differ: ", std::to_string(a.width), "x",
                std::to_string(a.height), " and ", std::to_string(b.width), "x",
                std::to_string(b.height));
  ImageDiff d;
  const size_t pixels = size_t(a.width) * size_t(a.height);
  if (pixels == 0) return d;
  double sum = 0;
  size_t over = 0;
  for (size_t p = 0; p < pixels; ++p) {
    int worst = 0;
    for (int c = 0; c < 3; ++c) {
      const int diff = std::abs(int(a.rgba[4 * p + c]) - int(b.rgba[4 * p + c]));
      sum += diff;
      worst = std::max(worst, diff);
    }
    d.maxAbs = std::max(d.maxAbs, worst);
    if (worst > threshold) ++over;
  }
  d.meanAbs = sum / double(3 * pixels);
  d.fractionOver = double(over) / double(pixels);
  return d;
}

}  // namespace gf::demo
