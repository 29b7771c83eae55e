// Impurity maps from black-and-white images (thesis sec 5.4): decodes a PNG with libpng (the
// runtime never links it) and turns its strokes into the 2D segments ImpurityMap::segments
// holds, in image units (the image is 1 wide, centred on 0, v up).
#pragma once

#include <glm/vec2.hpp>
#include <string>
#include <vector>

namespace gf::scene {

/// A decoded grey image, row-major from the top row, 0 = black.
struct GreyImage {
  int width = 0, height = 0;
  std::vector<uint8_t> pixels;
};

/// Reads any PNG as 8-bit grey. Throws std::runtime_error with the reason (cannot open, not a
/// PNG, corrupt data).
GreyImage readPngGrey(const std::string& file);

/// A segment between the centres of every pair of 8-neighbouring dark pixels (grey below
/// threshold * 255): a stroke becomes a chain (thin) or a lattice (thick) of segments, so
/// every mesh edge whose projection crosses the stroke crosses one of them. Isolated dark
/// pixels give none.
std::vector<glm::dvec2> imageSegments(const GreyImage& image, double threshold);

}  // namespace gf::scene
