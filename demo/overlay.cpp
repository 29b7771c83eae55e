// The demo's text overlay and contact sheet, on the CPU over read-back frames, so both back
// ends draw exactly the same pixels (the golden tests compare them against one image).
// stb_easy_font turns text into axis-aligned quads (segments of 7-segment-like glyphs); each
// quad is filled into the image, scaled by a whole number of pixels so the text stays crisp.
#include <algorithm>
#include <cmath>
#include <vector>

#include "renderer.h"

#ifdef GF_DEMO_HAS_STB
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wsign-conversion"
#pragma GCC diagnostic ignored "-Wconversion"
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
#include <stb/stb_easy_font.h>
#pragma GCC diagnostic pop
#endif

namespace gf::demo {
namespace {

/// Blends `colour` with weight `alpha` over the pixels of [x0, x1) x [y0, y1), clipped.
void fillRect(Image& im, int x0, int y0, int x1, int y1, const uint8_t colour[3], int alpha) {
  x0 = std::clamp(x0, 0, im.width);
  x1 = std::clamp(x1, 0, im.width);
  y0 = std::clamp(y0, 0, im.height);
  y1 = std::clamp(y1, 0, im.height);
  for (int y = y0; y < y1; ++y)
    for (int x = x0; x < x1; ++x) {
      uint8_t* p = &im.rgba[4 * (size_t(y) * size_t(im.width) + size_t(x))];
      for (int c = 0; c < 3; ++c) p[c] = uint8_t((p[c] * (255 - alpha) + colour[c] * alpha) / 255);
    }
}

}  // namespace

bool overlayAvailable() {
#ifdef GF_DEMO_HAS_STB
  return true;
#else
  return false;
#endif
}

void drawOverlay(Image& image, std::span<const std::string> lines) {
#ifdef GF_DEMO_HAS_STB
  if (lines.empty() || image.width <= 0 || image.height <= 0) return;
  const int scale = image.width >= 480 ? 2 : 1;
  const int lineHeight = 12 * scale, margin = 4 * scale;
  int width = 0;
  for (const std::string& l : lines)
    width = std::max(width, stb_easy_font_width(const_cast<char*>(l.c_str())) * scale);
  const uint8_t panel[3] = {10, 12, 16}, white[3] = {245, 245, 245};
  fillRect(image, margin, margin, margin + width + 2 * margin,
           margin + int(lines.size()) * lineHeight + margin, panel, 150);
  // stb_easy_font averages ~270 bytes per character; twice that leaves room for wide ones.
  std::vector<char> quads;
  for (size_t i = 0; i < lines.size(); ++i) {
    quads.resize(540 * (lines[i].size() + 1));
    const int n = stb_easy_font_print(0, 0, const_cast<char*>(lines[i].c_str()), nullptr,
                                      quads.data(), int(quads.size()));
    const int ox = 2 * margin, oy = 2 * margin + int(i) * lineHeight;
    // Each quad is 4 vertices of 16 bytes (x, y, z as floats, then a colour).
    for (int q = 0; q < n; ++q) {
      const float* v = reinterpret_cast<const float*>(quads.data() + 64 * q);
      const int x0 = ox + int(std::lround(v[0] * float(scale)));
      const int y0 = oy + int(std::lround(v[1] * float(scale)));
      const int x1 = ox + int(std::lround(v[8] * float(scale)));
      const int y1 = oy + int(std::lround(v[9] * float(scale)));
      fillRect(image, std::min(x0, x1), std::min(y0, y1), std::max(x0, x1), std::max(y0, y1), white,
               255);
    }
  }
#else
  (void)image;
  (void)lines;
#endif
}

Result<Image> contactSheet(std::span<const Image> frames, int columns, int cellWidth) {
  if (frames.empty()) return fail("contact sheet: no frames");
  if (columns < 1 || cellWidth < 1) return fail("contact sheet: columns and width must be >= 1");
  const int w = frames[0].width, h = frames[0].height;
  for (const Image& f : frames)
    if (f.width != w || f.height != h || f.rgba.size() != size_t(w) * size_t(h) * 4)
      return fail("contact sheet: frames differ in size");
  const int cellHeight = std::max(1, int(std::lround(double(cellWidth) * h / w)));
  const int rows = (int(frames.size()) + columns - 1) / columns, gap = 2;
  Image sheet;
  sheet.width = columns * cellWidth + (columns + 1) * gap;
  sheet.height = rows * cellHeight + (rows + 1) * gap;
  sheet.rgba.assign(size_t(sheet.width) * size_t(sheet.height) * 4, 0);
  for (size_t p = 0; p < sheet.rgba.size(); p += 4) {
    sheet.rgba[p] = sheet.rgba[p + 1] = sheet.rgba[p + 2] = 24;
    sheet.rgba[p + 3] = 255;
  }
  for (size_t i = 0; i < frames.size(); ++i) {
    const int cx = gap + int(i) % columns * (cellWidth + gap);
    const int cy = gap + int(i) / columns * (cellHeight + gap);
    // Box filter: each cell pixel averages the source pixels its footprint covers.
    for (int y = 0; y < cellHeight; ++y) {
      const int sy0 = y * h / cellHeight, sy1 = std::max(sy0 + 1, (y + 1) * h / cellHeight);
      for (int x = 0; x < cellWidth; ++x) {
        const int sx0 = x * w / cellWidth, sx1 = std::max(sx0 + 1, (x + 1) * w / cellWidth);
        int sum[3] = {0, 0, 0};
        for (int sy = sy0; sy < sy1; ++sy)
          for (int sx = sx0; sx < sx1; ++sx)
            for (int c = 0; c < 3; ++c)
              sum[c] += frames[i].rgba[4 * (size_t(sy) * size_t(w) + size_t(sx)) + size_t(c)];
        const int n = (sy1 - sy0) * (sx1 - sx0);
        uint8_t* d = &sheet.rgba[4 * (size_t(cy + y) * size_t(sheet.width) + size_t(cx + x))];
        for (int c = 0; c < 3; ++c) d[c] = uint8_t((sum[c] + n / 2) / n);
      }
    }
  }
  return sheet;
}

}  // namespace gf::demo
