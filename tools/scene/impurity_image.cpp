#include "scene/impurity_image.h"

#include <png.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>
#include <stdexcept>

namespace gf::scene {

GreyImage readPngGrey(const std::string& file) {
  // Check the signature ourselves so "not a PNG" is told apart from a corrupt PNG.
  std::unique_ptr<FILE, int (*)(FILE*)> f(std::fopen(file.c_str(), "rb"), &std::fclose);
  if (!f) throw std::runtime_error("cannot open '" + file + "': " + std::strerror(errno));
  unsigned char sig[8] = {};
  if (std::fread(sig, 1, 8, f.get()) != 8 || png_sig_cmp(sig, 0, 8) != 0)
    throw std::runtime_error("'" + file + "' is not a PNG image (bad signature)");
  f.reset();
  png_image img;
  std::memset(&img, 0, sizeof img);
  img.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&img, file.c_str()))
    throw std::runtime_error("'" + file + "': " + img.message);
  img.format = PNG_FORMAT_GRAY;
  GreyImage out;
  out.width = int(img.width);
  out.height = int(img.height);
  out.pixels.resize(PNG_IMAGE_SIZE(img));
  // Transparent pixels composite over white: a stroke is what is drawn, not the background.
  png_color white{255, 255, 255};
  if (!png_image_finish_read(&img, &white, out.pixels.data(), 0, nullptr)) {
    const std::string msg = img.message;
    png_image_free(&img);
    throw std::runtime_error("'" + file + "': " + msg);
  }
  return out;
}

std::vector<glm::dvec2> imageSegments(const GreyImage& image, double threshold) {
  const int W = image.width, H = image.height;
  auto dark = [&](int x, int y) {
    return x >= 0 && y >= 0 && x < W && y < H &&
           double(image.pixels[size_t(y) * size_t(W) + size_t(x)]) < threshold * 255.0;
  };
  auto uv = [&](int x, int y) { return glm::dvec2((x + 0.5) / W - 0.5, (0.5 * H - y - 0.5) / W); };
  static constexpr int kNext[4][2] = {{1, 0}, {0, 1}, {1, 1}, {-1, 1}};
  std::vector<glm::dvec2> seg;
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      if (!dark(x, y)) continue;
      for (const auto& d : kNext)
        if (dark(x + d[0], y + d[1])) {
          seg.push_back(uv(x, y));
          seg.push_back(uv(x + d[0], y + d[1]));
        }
    }
  return seg;
}

}  // namespace gf::scene
