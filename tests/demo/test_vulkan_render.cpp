// The Vulkan back end checked against independent truths: the silhouette area and the shading
// of a cube computed on the CPU, a golden image, exact byte counts of the streaming uploads, and
// a silent validation layer. Skipped only where no Vulkan device exists.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <glm/glm.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <string>
#include <vector>

#include "demo/golden_scene.h"
#include "demo/render_checks.h"
#include "renderer.h"
#include "vulkan_renderer.h"

namespace gf::demo {
namespace {

// The renderer, or a skip when this machine has no Vulkan device (or the back end is not built).
std::unique_ptr<Renderer> makeRenderer(int width, int height, int samples, bool validation,
                                       std::string* skip) {
  RendererOptions options;
  options.kind = RendererKind::Vulkan;
  options.width = width;
  options.height = height;
  options.samples = samples;
  options.validation = validation;
  Result<std::unique_ptr<Renderer>> r = createVulkanRenderer(options);
  if (r) return std::move(r.value());
  const std::string& m = r.error().message;
  for (const char* reason : {"not built", "VK_ERROR_INCOMPATIBLE_DRIVER", "no physical device",
                             "no suitable device", "is not installed"})
    if (m.find(reason) != std::string::npos) {
      *skip = m;
      return nullptr;
    }
  ADD_FAILURE() << m;
  return nullptr;
}

#define GF_MAKE_RENDERER(var, w, h, samples, validation)                               \
  std::string var##Skip;                                                               \
  std::unique_ptr<Renderer> var = makeRenderer(w, h, samples, validation, &var##Skip); \
  if (!var##Skip.empty()) GTEST_SKIP() << var##Skip;                                   \
  ASSERT_TRUE(var)

// A cube of side 1 centred at the origin: 4 vertices per face so normals are flat, triangles
// counter-clockwise seen from outside.
struct Cube {
  std::vector<float> positions, normals;
  std::vector<uint32_t> indices;
  Cube() {
    for (int axis = 0; axis < 3; ++axis)
      for (int sign : {-1, 1}) {
        glm::vec3 n(0), u(0), v(0);
        n[axis] = float(sign);
        u[(axis + 1) % 3] = 1;
        v[(axis + 2) % 3] = 1;
        if (sign < 0) std::swap(u, v);  // keeps u x v = n
        const uint32_t base = uint32_t(positions.size() / 3);
        for (glm::vec2 c :
             {glm::vec2(-1, -1), glm::vec2(1, -1), glm::vec2(1, 1), glm::vec2(-1, 1)}) {
          const glm::vec3 p = 0.5f * (n + c.x * u + c.y * v);
          positions.insert(positions.end(), {p.x, p.y, p.z});
          normals.insert(normals.end(), {n.x, n.y, n.z});
        }
        indices.insert(indices.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
      }
  }
  MeshFrame frame() const {
    MeshFrame f;
    f.positions = positions;
    f.normals = normals;
    f.indices = indices;
    f.topologyVersion = 1;
    f.dirtyEnd = uint32_t(positions.size() / 3);
    f.colour = {0.55f, 0.75f, 0.85f};
    return f;
  }
};

bool isBackground(const Image& im, int x, int y) {
  const uint8_t* p = &im.rgba[4 * (size_t(y) * size_t(im.width) + size_t(x))];
  // Clear colour (0.62, 0.70, 0.80) in UNORM8.
  return std::abs(p[0] - 158) <= 1 && std::abs(p[1] - 179) <= 1 && std::abs(p[2] - 204) <= 1;
}

TEST(VulkanRender, CubeSilhouetteAndShadingMatchTheCpu) {
  const int w = 320, h = 240;
  // One sample: a pixel is covered exactly when its centre is, so the count estimates the area.
  GF_MAKE_RENDERER(renderer, w, h, 1, false);
  const Cube cube;
  const MeshFrame frame = cube.frame();
  Camera cam;
  cam.eye = {1.8f, 1.5f, 2.6f};
  cam.target = {0.05f, -0.05f, 0.0f};
  cam.fovYDegrees = 40;
  Image im;
  Result<FrameStats> stats = renderer->render({&frame, 1}, cam, im);
  ASSERT_TRUE(stats) << stats.error().message;
  ASSERT_EQ(im.width, w);
  ASSERT_EQ(im.height, h);

  int covered = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) covered += isBackground(im, x, y) ? 0 : 1;

  // GL-convention matrices; the image has row 0 at the top.
  const glm::dmat4 proj = glm::perspective(glm::radians(double(cam.fovYDegrees)), double(w) / h,
                                           double(cam.nearPlane), double(cam.farPlane));
  const glm::dmat4 view =
      glm::lookAt(glm::dvec3(cam.eye), glm::dvec3(cam.target), glm::dvec3(cam.up));
  const glm::dmat4 viewProj = proj * view;
  auto toPixel = [&](glm::dvec3 p) {
    const glm::dvec4 c = viewProj * glm::dvec4(p, 1.0);
    return glm::dvec2((c.x / c.w + 1) / 2 * w, (1 - c.y / c.w) / 2 * h);
  };
  std::vector<glm::dvec2> corners;
  for (int i = 0; i < 8; ++i)
    corners.push_back(toPixel({i & 1 ? 0.5 : -0.5, i & 2 ? 0.5 : -0.5, i & 4 ? 0.5 : -0.5}));
  const double area = test::convexHullArea(corners);
  EXPECT_GT(area, 0.1 * w * h);  // the cube fills a good part of the frame
  EXPECT_NEAR(covered, area, 0.01 * area);
  std::printf("cube silhouette: %d px covered, projected hull %.1f px (%+.3f %%)\n", covered, area,
              100 * (covered - area) / area);

  // The colour at the pixel under the centre of three visible faces, against the model evaluated
  // at the point that pixel's centre sees (ray through the pixel centre, onto the face plane).
  const glm::dmat4 inv = glm::inverse(viewProj);
  double worst = 0;
  for (int axis = 0; axis < 3; ++axis) {
    glm::dvec3 n(0);
    n[axis] = 1;  // +x, +y and +z face the camera
    const glm::dvec2 px = glm::floor(toPixel(0.5 * n));
    const glm::dvec2 ndc((px.x + 0.5) / w * 2 - 1, 1 - (px.y + 0.5) / h * 2);
    const glm::dvec4 a = inv * glm::dvec4(ndc, -1, 1), b = inv * glm::dvec4(ndc, 1, 1);
    const glm::dvec3 p0 = glm::dvec3(a) / a.w, p1 = glm::dvec3(b) / b.w;
    const double t = (0.5 - p0[axis]) / (p1[axis] - p0[axis]);
    const glm::dvec3 expected =
        test::shade(glm::dvec3(frame.colour), n, p0 + t * (p1 - p0), glm::dvec3(cam.eye));
    const uint8_t* got = &im.rgba[4 * (size_t(px.y) * w + size_t(px.x))];
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(got[c], expected[c], 1.5) << "face " << axis << " channel " << c;
      worst = std::max(worst, std::abs(got[c] - expected[c]));
    }
    EXPECT_EQ(got[3], 255);
  }
  std::printf("cube face colours: worst channel error %.2f / 255\n", worst);
}

std::string goldenPath() { return GF_SOURCE_DIR "/tests/demo/golden/bunny_160x120.png"; }

// The reference image is tests/demo/golden/bunny_160x120.png, shared with the GL back end's test.
// Regenerate it (after a deliberate change of the shading model or the scene) with
//   GF_UPDATE_GOLDEN=1 gf_demo_tests --gtest_filter=VulkanRender.GoldenBunny
// and look at it before committing.
TEST(VulkanRender, GoldenBunny) {
  const test::GoldenScene scene = test::goldenScene();
  ASSERT_FALSE(scene.positions.empty());
  GF_MAKE_RENDERER(renderer, 160, 120, 4, false);
  const MeshFrame frame = scene.frame();
  Image im;
  Result<FrameStats> stats = renderer->render({&frame, 1}, scene.camera, im);
  ASSERT_TRUE(stats) << stats.error().message;

  // Not blank: the bunny covers part of the frame, with both crack and surface colours (crack
  // orange has red > blue, the surface blue > red).
  int object = 0, crack = 0, surface = 0;
  for (int y = 0; y < im.height; ++y)
    for (int x = 0; x < im.width; ++x) {
      if (isBackground(im, x, y)) continue;
      ++object;
      const uint8_t* p = &im.rgba[4 * (size_t(y) * size_t(im.width) + size_t(x))];
      crack += p[0] > p[2] + 40 ? 1 : 0;
      surface += p[2] > p[0] + 30 ? 1 : 0;
    }
  EXPECT_GT(object, im.width * im.height / 10);
  EXPECT_GT(crack, object / 10);
  EXPECT_GT(surface, object / 10);

  // Same input, same bits.
  Image again;
  ASSERT_TRUE(renderer->render({&frame, 1}, scene.camera, again));
  EXPECT_EQ(im.rgba, again.rgba);

  if (const char* update = std::getenv("GF_UPDATE_GOLDEN"); update && std::string(update) == "1") {
    Result<void> written = writePng(goldenPath(), im);
    ASSERT_TRUE(written) << written.error().message;
  }
  Result<Image> golden = readPng(goldenPath());
  ASSERT_TRUE(golden) << golden.error().message;
  Result<ImageDiff> diff = compareImages(im, golden.value(), 24);
  ASSERT_TRUE(diff) << diff.error().message;
  // Tight enough that losing MSAA fails (1 sample instead of 4: mean 0.525, 0.65 % over 24),
  // loose enough for another GPU's sample pattern (GL on an H100: mean 0.073, 0.005 % over 24).
  EXPECT_LT(diff.value().meanAbs, 0.25);
  EXPECT_LT(diff.value().fractionOver, 0.002);
  std::printf("golden diff: mean %.4f, max %d, over 24: %.4f%%\n", diff.value().meanAbs,
              diff.value().maxAbs, 100 * diff.value().fractionOver);
}

std::string stagePath() { return GF_SOURCE_DIR "/tests/demo/golden/bunny_stage_160x120.png"; }

// The demo's look (tests/demo/golden/bunny_stage_160x120.png, shared with GL): the golden bunny
// with glass crack faces (flat facets, sharp highlight) standing on a gridded floor, with the
// key light's shadow map. Regenerated with GoldenBunny (GF_UPDATE_GOLDEN=1, filter
// VulkanRender.Golden*). The shadow must be there: the same frame without it differs.
TEST(VulkanRender, GoldenStageWithShadowGridAndGlass) {
  const test::GoldenScene scene = test::goldenScene();
  ASSERT_FALSE(scene.positions.empty());
  GF_MAKE_RENDERER(renderer, 160, 120, 4, false);
  const std::vector<MeshFrame> frames = scene.stage();
  FrameOptions shadows;
  shadows.shadows = true;
  Image im, flat;
  ASSERT_TRUE(renderer->render(frames, scene.camera, shadows, im));
  ASSERT_TRUE(renderer->render(frames, scene.camera, FrameOptions{}, flat));
  Result<ImageDiff> shadowDiff = compareImages(im, flat, 24);
  ASSERT_TRUE(shadowDiff);
  EXPECT_GT(shadowDiff.value().fractionOver, 0.01);  // a visible shadow on the floor (2.3 %)
  if (const char* update = std::getenv("GF_UPDATE_GOLDEN"); update && std::string(update) == "1") {
    Result<void> written = writePng(stagePath(), im);
    ASSERT_TRUE(written) << written.error().message;
  }
  Result<Image> golden = readPng(stagePath());
  ASSERT_TRUE(golden) << golden.error().message;
  Result<ImageDiff> diff = compareImages(im, golden.value(), 24);
  ASSERT_TRUE(diff) << diff.error().message;
  EXPECT_LT(diff.value().meanAbs, 0.25);
  EXPECT_LT(diff.value().fractionOver, 0.002);
  std::printf("stage golden diff: mean %.4f, max %d, over 24: %.4f%%; shadow pass changes %.2f%%\n",
              diff.value().meanAbs, diff.value().maxAbs, 100 * diff.value().fractionOver,
              100 * shadowDiff.value().fractionOver);
}

TEST(VulkanRender, UploadsOnlyTheDirtyRange) {
  const test::GoldenScene scene = test::goldenScene();
  ASSERT_FALSE(scene.positions.empty());
  GF_MAKE_RENDERER(renderer, 160, 120, 4, false);
  const uint64_t v = scene.positions.size() / 3, t = scene.indices.size() / 3;
  std::vector<float> positions = scene.positions;
  MeshFrame frame = scene.frame();
  frame.positions = positions;
  Image im;

  // First frame: everything, 24 bytes per vertex (two float3), 12 per triangle (indices) and 4
  // per triangle (crack flag).
  Result<FrameStats> s = renderer->render({&frame, 1}, scene.camera, im);
  ASSERT_TRUE(s) << s.error().message;
  EXPECT_EQ(s.value().surfaceBytes, v * 24 + t * 16);
  EXPECT_EQ(s.value().uploadedBytes, s.value().surfaceBytes);

  // Move k vertices, same topology: only they are copied, and the image is the one a fresh
  // renderer draws from a full upload of the moved mesh.
  const uint32_t begin = 100, k = 57;
  ASSERT_LT(begin + k, v);
  for (uint32_t i = begin; i < begin + k; ++i) positions[3 * i + 1] += 0.02f;
  frame.dirtyBegin = begin;
  frame.dirtyEnd = begin + k;
  s = renderer->render({&frame, 1}, scene.camera, im);
  ASSERT_TRUE(s) << s.error().message;
  EXPECT_EQ(s.value().uploadedBytes, k * 24);
  EXPECT_EQ(s.value().surfaceBytes, v * 24 + t * 16);
  {
    GF_MAKE_RENDERER(fresh, 160, 120, 4, false);
    MeshFrame full = frame;
    full.dirtyBegin = 0;
    full.dirtyEnd = uint32_t(v);
    Image reference;
    ASSERT_TRUE(fresh->render({&full, 1}, scene.camera, reference));
    EXPECT_EQ(im.rgba, reference.rgba);
  }

  // Nothing dirty: nothing copied.
  frame.dirtyBegin = frame.dirtyEnd = 0;
  s = renderer->render({&frame, 1}, scene.camera, im);
  ASSERT_TRUE(s);
  EXPECT_EQ(s.value().uploadedBytes, 0u);

  // A scalar stream adds 4 bytes per vertex; switching it on is a full upload, then dirty ranges
  // cost 28 bytes per vertex.
  std::vector<float> scalar(v);
  for (size_t i = 0; i < v; ++i) scalar[i] = float(i % 97) / 96.0f;
  frame.scalar = scalar;
  s = renderer->render({&frame, 1}, scene.camera, im);
  ASSERT_TRUE(s);
  EXPECT_EQ(s.value().uploadedBytes, v * 28 + t * 16);
  EXPECT_EQ(s.value().uploadedBytes, s.value().surfaceBytes);
  frame.dirtyBegin = 5;
  frame.dirtyEnd = 5 + k;
  s = renderer->render({&frame, 1}, scene.camera, im);
  ASSERT_TRUE(s);
  EXPECT_EQ(s.value().uploadedBytes, k * 28);

  // A new topology version: everything again.
  frame.topologyVersion = 2;
  s = renderer->render({&frame, 1}, scene.camera, im);
  ASSERT_TRUE(s);
  EXPECT_EQ(s.value().uploadedBytes, s.value().surfaceBytes);

  // Bad input is an error naming the field, and the renderer stays usable.
  std::vector<uint32_t> badIndices = scene.indices;
  badIndices[7] = uint32_t(v);
  MeshFrame bad = frame;
  bad.indices = badIndices;
  bad.topologyVersion = 3;
  Result<FrameStats> e = renderer->render({&bad, 1}, scene.camera, im);
  ASSERT_FALSE(e);
  EXPECT_NE(e.error().message.find("index"), std::string::npos) << e.error().message;
  bad = frame;
  bad.dirtyEnd = uint32_t(v + 1);
  e = renderer->render({&bad, 1}, scene.camera, im);
  ASSERT_FALSE(e);
  EXPECT_NE(e.error().message.find("dirty range"), std::string::npos) << e.error().message;
  s = renderer->render({&frame, 1}, scene.camera, im);
  ASSERT_TRUE(s) << s.error().message;
}

TEST(VulkanRender, NoDriverIsAnErrorNotACrash) {
  // Point the loader at a driver manifest that does not exist (both the new and the old name).
  struct Env {
    const char* name;
    std::string old;
    bool had;
  };
  std::array<Env, 2> env{{{"VK_DRIVER_FILES", "", false}, {"VK_ICD_FILENAMES", "", false}}};
  for (Env& e : env) {
    if (const char* v = std::getenv(e.name)) e.old = v, e.had = true;
    setenv(e.name, "/nonexistent/graphfrac_no_icd.json", 1);
  }
  RendererOptions options;
  options.kind = RendererKind::Vulkan;
  options.width = 32;
  options.height = 32;
  Result<std::unique_ptr<Renderer>> r = createVulkanRenderer(options);
  for (Env& e : env) e.had ? setenv(e.name, e.old.c_str(), 1) : unsetenv(e.name);
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().message.rfind("Vulkan", 0), 0u) << r.error().message;
}

TEST(VulkanRender, ValidationLayersStaySilent) {
  if (!std::filesystem::exists(
          "/usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json") &&
      !std::filesystem::exists("/etc/vulkan/explicit_layer.d/VkLayer_khronos_validation.json"))
    GTEST_SKIP() << "VK_LAYER_KHRONOS_validation is not installed";
#ifdef GF_DEMO_HAS_VULKAN
  const size_t before = detail::vulkanValidationLog().size();
#endif
  {
    GF_MAKE_RENDERER(renderer, 96, 64, 4, true);
    EXPECT_NE(renderer->description().find("Vulkan, "), std::string::npos);
    const Cube cube;
    const test::GoldenScene scene = test::goldenScene();
    ASSERT_FALSE(scene.positions.empty());
    std::vector<float> positions = scene.positions;
    std::vector<float> scalar(positions.size() / 3, 0.5f);
    Image im;
    // Frames that exercise every path: first upload, dirty updates, a scalar stream switched on,
    // topology changes, a slot outgrowing its buffer, meshes added and dropped.
    for (int f = 0; f < 6; ++f) {
      std::vector<MeshFrame> frames;
      MeshFrame bunny = scene.frame();
      bunny.positions = positions;
      bunny.topologyVersion = f < 3 ? 1 : 2;
      bunny.dirtyBegin = 10;
      bunny.dirtyEnd = 40;
      if (f >= 2) bunny.scalar = scalar;
      MeshFrame box = cube.frame();
      box.model = glm::translate(glm::mat4(1.0f), glm::vec3(0.1f * f, 0, 0));
      // Slot 0 holds the cube first, then the (larger) bunny: it must grow.
      if (f == 0) {
        frames = {box};
      } else {
        frames = {bunny};
        if (f % 2 == 1) frames.push_back(box);
      }
      for (size_t i = 10; i < 40; ++i) positions[3 * i] += 0.001f;
      Result<FrameStats> s = renderer->render(frames, scene.camera, im);
      ASSERT_TRUE(s) << s.error().message;
      if (f == 3) {
        // A rejected frame (index out of range) on the way must not upset the layers either.
        std::vector<uint32_t> bad = scene.indices;
        bad.back() = uint32_t(positions.size() / 3);
        MeshFrame broken = bunny;
        broken.indices = bad;
        broken.topologyVersion = 99;
        ASSERT_FALSE(renderer->render({&broken, 1}, scene.camera, im));
      }
    }
    const std::vector<std::string> messages = renderer->validationMessages();
    EXPECT_TRUE(messages.empty()) << messages.size() << " messages, first: " << messages.front();
  }
#ifdef GF_DEMO_HAS_VULKAN
  // Destruction included.
  const std::vector<std::string> log = detail::vulkanValidationLog();
  EXPECT_EQ(log.size(), before) << "first new: " << (log.size() > before ? log[before] : "");
#endif
}

}  // namespace
}  // namespace gf::demo
