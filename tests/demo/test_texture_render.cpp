// Textured meshes in both back ends against an independent CPU reference: a quad carrying a 2x2
// texture is ray-cast per pixel on the CPU (the texture coordinate where the pixel's ray meets
// it, bilinear filtering with repeat wrapping of the sRGB-decoded texels, the shading model of
// render_checks.h) and compared with the rendered pixels; a crack face keeps its crack colour.
// Also the texture's mip chain (averages in linear light) and the image loader's errors.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <glm/ext/matrix_clip_space.hpp>
#include <glm/ext/matrix_transform.hpp>
#include <glm/geometric.hpp>
#include <string>
#include <vector>

#include "demo/render_checks.h"
#include "renderer.h"

namespace gf::demo {
namespace {

double srgbToLinear(uint8_t c) {
  const double x = c / 255.0;
  return x <= 0.04045 ? x / 12.92 : std::pow((x + 0.055) / 1.055, 2.4);
}

// A 2x2 texture whose four texels differ in every channel and are not 0 or 255, so that
// sampling the wrong texel, the wrong row order or skipping the sRGB decode all show.
Image checker2x2() {
  Image im;
  im.width = im.height = 2;
  // Rows top to bottom: top-left, top-right, bottom-left, bottom-right.
  im.rgba = {230, 40, 60, 255, 50, 210, 90, 255, 70, 80, 220, 255, 200, 190, 120, 255};
  return im;
}

// The texture lookup of the shaders on the CPU: bilinear, repeat, in linear light; v up from
// the bottom row.
glm::dvec3 sampleBilinear(const Image& im, double u, double v) {
  const double x = u * im.width - 0.5, y = (1.0 - v) * im.height - 0.5;
  const double fx = std::floor(x), fy = std::floor(y);
  const double ax = x - fx, ay = y - fy;
  auto texel = [&](int i, int j) {
    i = ((i % im.width) + im.width) % im.width;
    j = ((j % im.height) + im.height) % im.height;
    const uint8_t* p = &im.rgba[4 * (size_t(j) * size_t(im.width) + size_t(i))];
    return glm::dvec3(srgbToLinear(p[0]), srgbToLinear(p[1]), srgbToLinear(p[2]));
  };
  const int i = int(fx), j = int(fy);
  return (1 - ax) * (1 - ay) * texel(i, j) + ax * (1 - ay) * texel(i + 1, j) +
         (1 - ax) * ay * texel(i, j + 1) + ax * ay * texel(i + 1, j + 1);
}

std::unique_ptr<Renderer> makeRenderer(RendererKind kind, int w, int h, std::string& skip) {
  RendererOptions o;
  o.kind = kind;
  o.width = w;
  o.height = h;
  o.samples = 1;
  Result<std::unique_ptr<Renderer>> r = createRenderer(o);
  if (r) return std::move(r.value());
  skip = r.error().message;  // no device or context here, or not built
  return nullptr;
}

class TextureRender : public testing::TestWithParam<RendererKind> {};

// The quad [-1, 1]^2 in the x-y plane, facing +z, UVs (0, 0) at (-1, -1) to (1, 1) at (1, 1);
// triangles (0, 1, 2) below the diagonal y = x and (0, 2, 3) above it.
struct Quad {
  std::vector<float> positions = {-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0};
  std::vector<float> normals = {0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1};
  std::vector<float> uvs = {0, 0, 1, 0, 1, 1, 0, 1};
  std::vector<uint32_t> indices = {0, 1, 2, 0, 2, 3};
  // The camera the quad is seen through, slightly off its axis.
  static Camera camera() {
    Camera cam;
    cam.eye = {0.15f, 0.1f, 2.6f};
    cam.target = {0, 0, 0};
    cam.fovYDegrees = 50;
    return cam;
  }
};

// Pixel rays of the CPU reference come from the inverse of the camera's view-projection.
glm::mat4 inverseViewProjection(const Camera& cam, int w, int h) {
  return glm::inverse(glm::perspective(glm::radians(cam.fovYDegrees), float(w) / float(h),
                                       cam.nearPlane, cam.farPlane) *
                      glm::lookAt(cam.eye, cam.target, cam.up));
}

// The quad's pixels against a CPU ray cast.
TEST_P(TextureRender, PixelsShowTheTextureAndCrackFacesTheirColour) {
  const int w = 72, h = 72;
  std::string skip;
  auto renderer = makeRenderer(GetParam(), w, h, skip);
  if (!renderer) GTEST_SKIP() << skip;
  const Quad quad;
  const std::vector<float>&positions = quad.positions, &normals = quad.normals, &uvs = quad.uvs;
  const std::vector<uint32_t>& indices = quad.indices;
  const std::vector<uint8_t> cracks = {0, 1};
  Result<std::shared_ptr<const Texture>> texture = makeTexture(checker2x2());
  ASSERT_TRUE(texture) << texture.error().message;
  ASSERT_EQ(texture.value()->levels.size(), 2u);

  MeshFrame frame;
  frame.positions = positions;
  frame.normals = normals;
  frame.indices = indices;
  frame.uvs = uvs;
  frame.texture = texture.value();
  frame.topologyVersion = 1;
  frame.dirtyEnd = 4;
  frame.colour = {0.9f, 0.8f, 1.0f};  // tints the texture
  frame.crackColour = {0.3f, 0.6f, 0.35f};
  const Camera cam = Quad::camera();
  const glm::mat4 inv = inverseViewProjection(cam, w, h);

  for (const bool withCracks : {false, true}) {
    frame.crackMask = withCracks ? std::span<const uint8_t>(cracks) : std::span<const uint8_t>();
    frame.topologyVersion = withCracks ? 2 : 1;
    Image im;
    Result<FrameStats> r = renderer->render({&frame, 1}, cam, im);
    ASSERT_TRUE(r) << r.error().message;
    int checked = 0, quadrants[4] = {0, 0, 0, 0};
    for (int py = 2; py < h; py += 3)
      for (int px = 2; px < w; px += 3) {
        const float nx = 2.0f * (px + 0.5f) / w - 1.0f, ny = 1.0f - 2.0f * (py + 0.5f) / h;
        const glm::vec4 a = inv * glm::vec4(nx, ny, -1, 1), b = inv * glm::vec4(nx, ny, 1, 1);
        const glm::vec3 o = glm::vec3(a) / a.w, d = glm::vec3(b) / b.w - o;
        const glm::vec3 p = o - (o.z / d.z) * d;
        // Inside, off the quad's edges and its diagonal (where a pixel could take either
        // triangle).
        if (std::abs(p.x) > 0.92f || std::abs(p.y) > 0.92f || std::abs(p.x - p.y) < 0.08f) continue;
        const bool crack = withCracks && p.y > p.x;
        const glm::dvec3 base =
            crack ? glm::dvec3(frame.crackColour)
                  : glm::dvec3(frame.colour) * sampleBilinear(texture.value()->levels[0],
                                                              0.5 * (p.x + 1), 0.5 * (p.y + 1));
        const glm::dvec3 expected = test::shade(base, {0, 0, 1}, glm::dvec3(p), cam.eye);
        const uint8_t* got = &im.rgba[4 * (size_t(py) * w + px)];
        for (int c = 0; c < 3; ++c)
          ASSERT_NEAR(double(got[c]), expected[c], 2.5)
              << renderer->description() << (withCracks ? ", crack mask" : "") << ": pixel " << px
              << "," << py << " (quad " << p.x << ", " << p.y << ") channel " << c;
        ++checked;
        ++quadrants[(p.x > 0 ? 1 : 0) + (p.y > 0 ? 2 : 0)];
      }
    EXPECT_GT(checked, 200);
    for (int q = 0; q < 4; ++q) EXPECT_GT(quadrants[q], 20) << "quadrant " << q;
  }

  // The same quad untextured is drawn in its plain colour, as before textures existed.
  frame.texture = nullptr;
  frame.uvs = {};
  frame.crackMask = {};
  frame.topologyVersion = 3;
  Image plain;
  ASSERT_TRUE(renderer->render({&frame, 1}, cam, plain));
  const int px = w / 2 + 10, py = h / 2 + 10;
  const uint8_t* got = &plain.rgba[4 * (size_t(py) * w + px)];
  const glm::vec4 a = inv *
                      glm::vec4(2.0f * (px + 0.5f) / w - 1, 1 - 2.0f * (py + 0.5f) / h, -1, 1),
                  b = inv * glm::vec4(2.0f * (px + 0.5f) / w - 1, 1 - 2.0f * (py + 0.5f) / h, 1, 1);
  const glm::vec3 o = glm::vec3(a) / a.w, d = glm::vec3(b) / b.w - o;
  const glm::dvec3 expected =
      test::shade(glm::dvec3(frame.colour), {0, 0, 1}, glm::dvec3(o - (o.z / d.z) * d), cam.eye);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(double(got[c]), expected[c], 1.5) << "channel " << c;
}

// A mesh drawn in ranges (MeshFrame::ranges, a render mesh's materials): the quad's lower
// triangle in a plain red range, its upper one in a textured green range, against the CPU
// reference; crack flags go with the triangles of whichever range draws them (each range's
// gl_PrimitiveID starts at 0), and a range outside the triangles is an error.
TEST_P(TextureRender, RangesDrawTheirOwnColourAndTextureAndKeepCrackFlags) {
  const int w = 72, h = 72;
  std::string skip;
  auto renderer = makeRenderer(GetParam(), w, h, skip);
  if (!renderer) GTEST_SKIP() << skip;
  const Quad quad;
  const std::vector<float>&positions = quad.positions, &normals = quad.normals, &uvs = quad.uvs;
  const std::vector<uint32_t>& indices = quad.indices;
  const std::shared_ptr<const Texture> texture = makeTexture(checker2x2()).value();
  std::vector<DrawRange> ranges(2);
  ranges[0] = {0, 1, {0.8f, 0.1f, 0.1f}, nullptr};
  ranges[1] = {1, 1, {0.3f, 0.9f, 0.4f}, texture};
  MeshFrame frame;
  frame.positions = positions;
  frame.normals = normals;
  frame.indices = indices;
  frame.uvs = uvs;
  frame.ranges = ranges;
  frame.dirtyEnd = 4;
  frame.colour = {0.1f, 0.1f, 0.9f};  // not used: the ranges give the colours
  frame.crackColour = {0.95f, 0.85f, 0.2f};
  const Camera cam = Quad::camera();
  const glm::mat4 inv = inverseViewProjection(cam, w, h);
  const std::vector<uint8_t> masks[3] = {{}, {0, 1}, {1, 0}};
  for (int c = 0; c < 3; ++c) {
    frame.crackMask = masks[c];
    frame.topologyVersion = uint64_t(10 + c);
    Image im;
    Result<FrameStats> r = renderer->render({&frame, 1}, cam, im);
    ASSERT_TRUE(r) << r.error().message;
    int checked[2] = {0, 0};
    for (int py = 2; py < h; py += 3)
      for (int px = 2; px < w; px += 3) {
        const float nx = 2.0f * (px + 0.5f) / w - 1.0f, ny = 1.0f - 2.0f * (py + 0.5f) / h;
        const glm::vec4 a = inv * glm::vec4(nx, ny, -1, 1), b = inv * glm::vec4(nx, ny, 1, 1);
        const glm::vec3 o = glm::vec3(a) / a.w, d = glm::vec3(b) / b.w - o;
        const glm::vec3 p = o - (o.z / d.z) * d;
        if (std::abs(p.x) > 0.92f || std::abs(p.y) > 0.92f || std::abs(p.x - p.y) < 0.08f) continue;
        const int tri = p.y > p.x ? 1 : 0;
        const bool crack = !masks[c].empty() && masks[c][size_t(tri)] != 0;
        glm::dvec3 base = glm::dvec3(ranges[size_t(tri)].colour);
        if (tri == 1) base *= sampleBilinear(texture->levels[0], 0.5 * (p.x + 1), 0.5 * (p.y + 1));
        if (crack) base = glm::dvec3(frame.crackColour);
        const glm::dvec3 expected = test::shade(base, {0, 0, 1}, glm::dvec3(p), cam.eye);
        const uint8_t* got = &im.rgba[4 * (size_t(py) * w + px)];
        for (int k = 0; k < 3; ++k)
          ASSERT_NEAR(double(got[k]), expected[k], 2.5)
              << renderer->description() << ", mask " << c << ": pixel " << px << "," << py
              << " (triangle " << tri << ") channel " << k;
        ++checked[tri];
      }
    EXPECT_GT(checked[0], 100);
    EXPECT_GT(checked[1], 100);
  }
  ranges[1].triangleCount = 2;
  frame.topologyVersion = 20;
  Image im;
  Result<FrameStats> bad = renderer->render({&frame, 1}, cam, im);
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().message.find("range of triangles [1, 3) is outside 0..2"),
            std::string::npos)
      << bad.error().message;
}

// A textured mesh without its UVs is an error naming them, not a read past the end.
TEST_P(TextureRender, TextureWithoutUvsIsAnError) {
  std::string skip;
  auto renderer = makeRenderer(GetParam(), 16, 16, skip);
  if (!renderer) GTEST_SKIP() << skip;
  const std::vector<float> positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  const std::vector<float> normals = {0, 0, 1, 0, 0, 1, 0, 0, 1};
  const std::vector<uint32_t> indices = {0, 1, 2};
  MeshFrame frame;
  frame.positions = positions;
  frame.normals = normals;
  frame.indices = indices;
  frame.topologyVersion = 1;
  frame.dirtyEnd = 3;
  frame.texture = makeTexture(checker2x2()).value();
  Image im;
  Result<FrameStats> r = renderer->render({&frame, 1}, Camera{}, im);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("uvs has 0 values for 3 vertices (2 each, needed with a "
                                   "texture)"),
            std::string::npos)
      << r.error().message;
}

// Textured and untextured meshes in one frame, a texture shared by two meshes, a slot switching
// between them: the Vulkan validation layers report nothing.
TEST(TextureRenderVulkan, ValidationLayersStaySilent) {
  if (!std::filesystem::exists(
          "/usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json") &&
      !std::filesystem::exists("/etc/vulkan/explicit_layer.d/VkLayer_khronos_validation.json"))
    GTEST_SKIP() << "VK_LAYER_KHRONOS_validation is not installed";
  RendererOptions o;
  o.kind = RendererKind::Vulkan;
  o.width = 48;
  o.height = 32;
  o.validation = true;
  Result<std::unique_ptr<Renderer>> r = createRenderer(o);
  if (!r) GTEST_SKIP() << r.error().message;
  const Quad quad;
  const std::vector<float>&positions = quad.positions, &normals = quad.normals, &uvs = quad.uvs;
  const std::vector<uint32_t>& indices = quad.indices;
  const std::shared_ptr<const Texture> texture = makeTexture(checker2x2()).value();
  Camera cam;
  cam.eye = {0, 0, 3};
  cam.target = {0, 0, 0};
  for (int f = 0; f < 4; ++f) {
    std::vector<MeshFrame> frames(3);
    for (size_t i = 0; i < frames.size(); ++i) {
      MeshFrame& m = frames[i];
      m.positions = positions;
      m.normals = normals;
      m.indices = indices;
      m.topologyVersion = 1 + uint64_t(f / 2);
      m.dirtyEnd = 4;
      m.model = glm::translate(glm::mat4(1.0f), glm::vec3(float(i) - 1.0f, 0, 0));
      if (i != 1 && (f != 3 || i != 2)) {
        m.uvs = uvs;
        m.texture = texture;
      }
    }
    Image im;
    Result<FrameStats> s = r.value()->render(frames, cam, im);
    ASSERT_TRUE(s) << s.error().message;
  }
  const std::vector<std::string> messages = r.value()->validationMessages();
  EXPECT_TRUE(messages.empty()) << messages.size() << " messages, first: " << messages.front();
}

INSTANTIATE_TEST_SUITE_P(Backends, TextureRender,
                         testing::Values(RendererKind::Vulkan, RendererKind::Gl),
                         [](const testing::TestParamInfo<RendererKind>& i) {
                           return i.param == RendererKind::Vulkan ? "Vulkan" : "Gl";
                         });

// Each mip level halves the size down to 1x1, and its texels are means in linear light: the
// 1x1 level of the checker is the sRGB encoding of the mean of its four decoded texels.
TEST(Texture, MipLevelsAverageInLinearLight) {
  const Image im = checker2x2();
  Result<std::shared_ptr<const Texture>> t = makeTexture(im);
  ASSERT_TRUE(t);
  ASSERT_EQ(t.value()->levels.size(), 2u);
  const Image& top = t.value()->levels[1];
  ASSERT_EQ(top.width, 1);
  ASSERT_EQ(top.height, 1);
  for (int c = 0; c < 3; ++c) {
    double mean = 0;
    for (int k = 0; k < 4; ++k) mean += srgbToLinear(im.rgba[4 * k + c]) / 4;
    const double encoded =
        255 * (mean <= 0.0031308 ? 12.92 * mean : 1.055 * std::pow(mean, 1 / 2.4) - 0.055);
    EXPECT_NEAR(top.rgba[c], encoded, 0.5 + 1e-9) << "channel " << c;
  }
  // Odd and unequal sizes: 5x3 -> 2x1 -> 1x1.
  Image odd;
  odd.width = 5;
  odd.height = 3;
  odd.rgba.assign(5 * 3 * 4, 128);
  t = makeTexture(odd);
  ASSERT_TRUE(t);
  ASSERT_EQ(t.value()->levels.size(), 3u);
  EXPECT_EQ(t.value()->levels[1].width, 2);
  EXPECT_EQ(t.value()->levels[1].height, 1);
  EXPECT_EQ(t.value()->levels[2].width, 1);
  EXPECT_EQ(t.value()->levels[1].rgba[0], 128);  // a flat image stays flat
  EXPECT_FALSE(makeTexture(Image{}));
}

// PNG, and TGA and JPEG where Debian's assimp-testmodels provides them, decode to their size;
// the shipped duckCM.png is the package's duckCM.tga converted losslessly, texel for texel; a
// file that is no image is an error naming it.
TEST(Texture, LoadsPngTgaAndJpeg) {
  Result<std::shared_ptr<const Texture>> png =
      loadTexture(GF_SOURCE_DIR "/scenes/meshes/duckCM.png");
  if (!png && png.error().message.find("reads no images") != std::string::npos)
    GTEST_SKIP() << png.error().message;
  ASSERT_TRUE(png) << png.error().message;
  EXPECT_EQ(png.value()->levels[0].width, 512);
  EXPECT_EQ(png.value()->levels[0].height, 512);
  EXPECT_EQ(png.value()->levels.size(), 10u);
  const char* tgaPath = "/usr/share/assimp/models/Collada/duckCM.tga";
  if (std::filesystem::exists(tgaPath)) {
    Result<std::shared_ptr<const Texture>> tga = loadTexture(tgaPath);
    ASSERT_TRUE(tga) << tga.error().message;
    EXPECT_EQ(tga.value()->levels[0].rgba, png.value()->levels[0].rgba);
  }
  const char* jpg = "/usr/share/assimp/models/Collada/duck_sample.jpg";
  if (std::filesystem::exists(jpg)) {
    Result<std::shared_ptr<const Texture>> j = loadTexture(jpg);
    ASSERT_TRUE(j) << j.error().message;
    EXPECT_GT(j.value()->levels[0].width, 0);
  }
  const std::string bad = GF_SOURCE_DIR "/tests/data/scenes/images/not_a_png.png";
  Result<std::shared_ptr<const Texture>> no = loadTexture(bad);
  ASSERT_FALSE(no);
  EXPECT_EQ(no.error().message, bad + ": cannot decode the image: unknown image type");
}

}  // namespace
}  // namespace gf::demo
