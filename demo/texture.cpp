// Textures for the renderers: image files decoded with stb_image (Debian's libstb-dev) and their
// mip levels, built here once so that both back ends sample the same texels.
#include <algorithm>
#include <cmath>
#include <memory>

#include "renderer.h"
#ifdef GF_DEMO_HAS_STB_IMAGE
#include <stb/stb_image.h>
#endif

namespace gf::demo {
namespace {

// The sRGB transfer function (IEC 61966-2-1), both ways, so that mip levels average light.
float toLinear(uint8_t c) {
  const float x = float(c) / 255.0f;
  return x <= 0.04045f ? x / 12.92f : std::pow((x + 0.055f) / 1.055f, 2.4f);
}
uint8_t toSrgb(float x) {
  const float y = x <= 0.0031308f ? 12.92f * x : 1.055f * std::pow(x, 1.0f / 2.4f) - 0.055f;
  return uint8_t(std::lround(std::clamp(y, 0.0f, 1.0f) * 255.0f));
}

// Half the size (at least 1): each texel the mean of the up to 2x2 it covers, colour in linear
// light, alpha as is.
Image halve(const Image& a) {
  Image b;
  b.width = std::max(1, a.width / 2);
  b.height = std::max(1, a.height / 2);
  b.rgba.resize(size_t(b.width) * size_t(b.height) * 4);
  for (int y = 0; y < b.height; ++y)
    for (int x = 0; x < b.width; ++x) {
      float sum[4] = {0, 0, 0, 0};
      int n = 0;
      for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx) {
          const int sx = std::min(2 * x + dx, a.width - 1), sy = std::min(2 * y + dy, a.height - 1);
          const uint8_t* p = &a.rgba[(size_t(sy) * size_t(a.width) + size_t(sx)) * 4];
          for (int c = 0; c < 3; ++c) sum[c] += toLinear(p[c]);
          sum[3] += float(p[3]);
          ++n;
        }
      uint8_t* q = &b.rgba[(size_t(y) * size_t(b.width) + size_t(x)) * 4];
      for (int c = 0; c < 3; ++c) q[c] = toSrgb(sum[c] / float(n));
      q[3] = uint8_t(std::lround(sum[3] / float(n)));
    }
  return b;
}

}  // namespace

Result<std::shared_ptr<const Texture>> makeTexture(Image image) {
  if (image.width <= 0 || image.height <= 0 || image.width > 16384 || image.height > 16384 ||
      image.rgba.size() != size_t(image.width) * size_t(image.height) * 4)
    return fail("texture image is ", std::to_string(image.width), "x", std::to_string(image.height),
                " with ", std::to_string(image.rgba.size()),
                " bytes: not 1..16384 pixels a side at 4 bytes per pixel");
  auto t = std::make_shared<Texture>();
  t->levels.push_back(std::move(image));
  while (t->levels.back().width > 1 || t->levels.back().height > 1)
    t->levels.push_back(halve(t->levels.back()));
  return std::shared_ptr<const Texture>(std::move(t));
}

Result<std::shared_ptr<const Texture>> loadTexture(const std::string& path) {
#ifdef GF_DEMO_HAS_STB_IMAGE
  int w = 0, h = 0, channels = 0;
  std::unique_ptr<stbi_uc, void (*)(void*)> pixels(stbi_load(path.c_str(), &w, &h, &channels, 4),
                                                   &stbi_image_free);
  if (!pixels) return fail(path, ": cannot decode the image: ", stbi_failure_reason());
  Image image;
  image.width = w;
  image.height = h;
  image.rgba.assign(pixels.get(), pixels.get() + size_t(w) * size_t(h) * 4);
  Result<std::shared_ptr<const Texture>> t = makeTexture(std::move(image));
  if (!t) return fail(path, ": ", t.error().message);
  return t;
#else
  return fail(path, ": this build reads no images (stb_image from libstb-dev was not found)");
#endif
}

}  // namespace gf::demo
