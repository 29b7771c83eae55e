// The OpenGL (EGL) back end against independent references: a cube's silhouette against the
// analytic area of its projected outline; single pixels against the shading model evaluated on
// the CPU (front, back, crack and colour-map faces); the golden bunny against the reference image
// the Vulkan back end checks in; exact streaming byte counts; the automatic fallback to GL when
// no Vulkan driver exists. Skips only when no EGL context can be made (or GL was not built).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <glm/ext/matrix_clip_space.hpp>
#include <glm/ext/matrix_transform.hpp>
#include <glm/geometric.hpp>
#include <glm/mat4x4.hpp>
#include <optional>
#include <string>
#include <vector>

#include "demo/golden_scene.h"
#include "demo/render_checks.h"
#include "renderer.h"

namespace gf::demo {
namespace {

// The reference image of tests/demo/golden_scene.h, written by the Vulkan back end's test
// (test_vulkan_render.cpp says how to regenerate it); GL must match the same file.
const char* kGoldenPath = GF_SOURCE_DIR "/tests/demo/golden/bunny_160x120.png";

// A GL renderer; nullptr with `skip` set when this machine has no EGL (or GL was not built),
// nullptr after a test failure for any other error.
std::unique_ptr<Renderer> makeGl(int width, int height, int samples, std::string& skip) {
  RendererOptions o;
  o.kind = RendererKind::Gl;
  o.width = width;
  o.height = height;
  o.samples = samples;
  Result<std::unique_ptr<Renderer>> r = createRenderer(o);
  if (r) return std::move(r.value());
  const std::string& m = r.error().message;
  if (m.find("no EGL context") != std::string::npos || m.find("not built") != std::string::npos)
    skip = m;
  else
    ADD_FAILURE() << m;
  return nullptr;
}

#define MAKE_GL_OR_SKIP(var, w, h, samples)                    \
  std::string skip_##var;                                      \
  auto var = makeGl(w, h, samples, skip_##var);                \
  if (!var && !skip_##var.empty()) GTEST_SKIP() << skip_##var; \
  ASSERT_TRUE(var)

struct Mesh {
  std::vector<float> positions, normals, scalar;
  std::vector<uint32_t> indices;
  std::vector<uint8_t> crackMask;
  MeshFrame frame(uint64_t topology = 1) const {
    MeshFrame f;
    f.positions = positions;
    f.normals = normals;
    f.indices = indices;
    f.crackMask = crackMask;
    f.scalar = scalar;
    f.topologyVersion = topology;
    f.dirtyEnd = uint32_t(positions.size() / 3);
    return f;
  }
  void quad(const glm::vec3 corners[4], const glm::vec3& n) {
    const uint32_t base = uint32_t(positions.size() / 3);
    for (int k = 0; k < 4; ++k)
      for (int c = 0; c < 3; ++c) {
        positions.push_back(corners[k][c]);
        normals.push_back(n[c]);
      }
    for (uint32_t i : {0u, 1u, 2u, 0u, 2u, 3u}) indices.push_back(base + i);
  }
};

// Unit cube centred at the origin, flat normals (4 vertices per face), counter-clockwise from
// outside.
Mesh unitCube() {
  Mesh m;
  for (int axis = 0; axis < 3; ++axis)
    for (float sign : {-1.0f, 1.0f}) {
      glm::vec3 n(0.0f);
      n[axis] = sign;
      const glm::vec3 u = glm::vec3(n.y, n.z, n.x), v = glm::cross(n, u);
      const glm::vec3 c = 0.5f * n;
      const glm::vec3 corners[4] = {c - 0.5f * u - 0.5f * v, c + 0.5f * u - 0.5f * v,
                                    c + 0.5f * u + 0.5f * v, c - 0.5f * u + 0.5f * v};
      m.quad(corners, n);
    }
  return m;
}

glm::mat4 viewProj(const Camera& c, int w, int h) {
  return glm::perspective(glm::radians(c.fovYDegrees), float(w) / float(h), c.nearPlane,
                          c.farPlane) *
         glm::lookAt(c.eye, c.target, c.up);
}

bool isBackground(const Image& im, size_t pixel) {
  const int bg[3] = {158, 179, 204};  // 255 * (0.62, 0.70, 0.80)
  for (int c = 0; c < 3; ++c)
    if (std::abs(int(im.rgba[4 * pixel + c]) - bg[c]) > 2) return false;
  return true;
}

size_t foregroundPixels(const Image& im) {
  size_t n = 0;
  for (size_t p = 0; p < size_t(im.width) * size_t(im.height); ++p) n += !isBackground(im, p);
  return n;
}

TEST(GlRender, DescriptionNamesTheContext) {
  MAKE_GL_OR_SKIP(gl, 8, 8, 1);
  const std::string& d = gl->description();
  EXPECT_EQ(d.rfind("OpenGL ", 0), 0u) << d;
  EXPECT_NE(d.find(", EGL "), std::string::npos) << d;
  std::printf("[ GL ] %s\n", d.c_str());
}

// Each way to an EGL display (GF_EGL_PLATFORM forces one) that this machine offers draws the
// same image as the automatic choice; the ones it does not offer fail with a reason.
TEST(GlRender, EveryEglPlatformDrawsTheSame) {
  MAKE_GL_OR_SKIP(automatic, 64, 48, 4);
  const Mesh cube = unitCube();
  const MeshFrame frame = cube.frame();
  const Camera cam;
  Image reference;
  ASSERT_TRUE(automatic->render({&frame, 1}, cam, reference).ok());
  automatic.reset();
  std::optional<std::string> old;
  if (const char* v = std::getenv("GF_EGL_PLATFORM")) old = v;
  int working = 0;
  for (const char* platform : {"surfaceless", "device", "default", "bogus"}) {
    setenv("GF_EGL_PLATFORM", platform, 1);
    RendererOptions o;
    o.kind = RendererKind::Gl;
    o.width = 64;
    o.height = 48;
    Result<std::unique_ptr<Renderer>> r = createRenderer(o);
    if (!r) {
      std::printf("[ GL ] %s: %s\n", platform, r.error().message.c_str());
      EXPECT_NE(r.error().message.find(platform), std::string::npos) << r.error().message;
      continue;
    }
    EXPECT_NE(std::string(platform), "bogus");
    std::printf("[ GL ] %s: %s\n", platform, r.value()->description().c_str());
    Image im;
    ASSERT_TRUE(r.value()->render({&frame, 1}, cam, im).ok());
    EXPECT_EQ(im.rgba, reference.rgba) << platform;
    ++working;
  }
  if (old)
    setenv("GF_EGL_PLATFORM", old->c_str(), 1);
  else
    unsetenv("GF_EGL_PLATFORM");
  EXPECT_GE(working, 1);
}

// One sample per pixel: a pixel is covered when its centre is inside, so the count estimates
// the outline's area with an error of a fraction of a pixel per boundary pixel row.
TEST(GlRender, CubeSilhouetteMatchesProjectedHullArea) {
  const int w = 320, h = 240;
  MAKE_GL_OR_SKIP(gl, w, h, 1);
  const Mesh cube = unitCube();
  Camera cam;
  cam.eye = {1.9f, 1.4f, 2.6f};
  cam.target = {0.0f, 0.0f, 0.0f};
  cam.fovYDegrees = 45;
  MeshFrame frame = cube.frame();
  frame.colour = {0.9f, 0.3f, 0.05f};
  Image im;
  ASSERT_TRUE(gl->render({&frame, 1}, cam, im).ok());
  ASSERT_EQ(im.width, w);
  ASSERT_EQ(im.height, h);

  const glm::mat4 vp = viewProj(cam, w, h);
  std::vector<glm::dvec2> corners;
  for (int i = 0; i < 8; ++i) {
    const glm::vec4 clip =
        vp * glm::vec4(i & 1 ? 0.5f : -0.5f, i & 2 ? 0.5f : -0.5f, i & 4 ? 0.5f : -0.5f, 1.0f);
    corners.push_back({(clip.x / clip.w * 0.5 + 0.5) * w, (clip.y / clip.w * 0.5 + 0.5) * h});
  }
  const double area = test::convexHullArea(corners);
  const double counted = double(foregroundPixels(im));
  std::printf("[ GL ] cube outline: %.1f pixels analytic, %.0f rendered (%.3f %%)\n", area, counted,
              100.0 * (counted - area) / area);
  EXPECT_GT(area, 0.1 * w * h);  // the cube fills a good part of the frame, all inside it
  EXPECT_NEAR(counted, area, 0.01 * area);

  // Above the outline's top (image row 0 is the top) there is only sky: rows are not flipped.
  double top = 0;
  for (const auto& c : corners) top = std::max(top, c.y);
  for (int y = 0; y < int(h - top) - 2; ++y)
    for (int x = 0; x < w; ++x) ASSERT_TRUE(isBackground(im, size_t(y) * w + x)) << x << "," << y;
}

glm::vec3 colourMap(float s) {
  const glm::vec3 stops[5] = {{0.1f, 0.2f, 0.9f},
                              {0.1f, 0.8f, 0.9f},
                              {0.2f, 0.85f, 0.2f},
                              {0.95f, 0.9f, 0.1f},
                              {0.9f, 0.15f, 0.1f}};
  const float x = 4.0f * std::clamp(s, 0.0f, 1.0f);
  const int i = std::min(int(x), 3);
  return glm::mix(stops[i], stops[i + 1], x - float(i));
}

// The shading model on the CPU (render_checks.h), for a world normal n facing the eye.
glm::vec3 shade(const glm::vec3& base, glm::vec3 n, const glm::vec3& p, const glm::vec3& eye) {
  return glm::vec3(
      test::shade(glm::dvec3(base), glm::normalize(glm::dvec3(n)), glm::dvec3(p), glm::dvec3(eye)));
}

// A tilted quad (two triangles, the second a crack face) filling most of a 64x64 frame: pixels
// well inside each triangle match the CPU shading at the point the pixel centre's ray hits, from
// the front and from behind (two-sided), with and without the colour map.
TEST(GlRender, PixelsMatchTheShadingModel) {
  const int w = 64, hgt = 64;
  MAKE_GL_OR_SKIP(gl, w, hgt, 1);
  Mesh quad;
  const glm::vec3 corners[4] = {{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}};
  quad.quad(corners, {0, 0, 1});
  quad.crackMask = {0, 1};
  MeshFrame frame = quad.frame();
  // Rotated so the world normal is not an axis: checks n = mat3(model) * normal.
  frame.model = glm::rotate(glm::translate(glm::mat4(1.0f), glm::vec3(0.1f, 0.0f, 0.0f)),
                            glm::radians(-35.0f), glm::normalize(glm::vec3(1.0f, 0.3f, 0.0f)));
  frame.colour = {0.3f, 0.6f, 0.9f};
  frame.crackColour = {0.95f, 0.55f, 0.3f};
  const glm::vec3 worldNormal = glm::normalize(glm::mat3(frame.model) * glm::vec3(0, 0, 1));
  const glm::vec3 planePoint = glm::vec3(frame.model * glm::vec4(0, 0, 0, 1));
  const glm::mat4 toModel = glm::inverse(frame.model);

  const std::vector<float> scalar(4, 0.6f);
  int checked = 0;
  // Front, back, front with the colour map, front without a crack mask.
  for (int view = 0; view < 4; ++view) {
    Camera cam;
    cam.target = planePoint;
    cam.eye = planePoint + (view == 1 ? -2.6f : 2.6f) * worldNormal + glm::vec3(0.2f, 0.3f, 0.1f);
    cam.fovYDegrees = 50;
    frame.scalar = view == 2 ? std::span<const float>(scalar) : std::span<const float>();
    if (view == 3) frame.crackMask = {};
    Image im;
    ASSERT_TRUE(gl->render({&frame, 1}, cam, im).ok());
    const glm::mat4 inv = glm::inverse(viewProj(cam, w, hgt));
    for (int py = 4; py < hgt; py += 6)
      for (int px = 4; px < w; px += 6) {
        const float nx = 2.0f * (px + 0.5f) / w - 1.0f, ny = 1.0f - 2.0f * (py + 0.5f) / hgt;
        glm::vec4 a = inv * glm::vec4(nx, ny, -1, 1), b = inv * glm::vec4(nx, ny, 1, 1);
        const glm::vec3 o = glm::vec3(a) / a.w, d = glm::vec3(b) / b.w - o;
        const float t = glm::dot(planePoint - o, worldNormal) / glm::dot(d, worldNormal);
        const glm::vec3 p = o + t * d;
        const glm::vec3 q = glm::vec3(toModel * glm::vec4(p, 1.0f));  // quad coordinates
        // Away from the edges and the diagonal y = x (where MSAA-free coverage is ambiguous).
        if (std::abs(q.x) > 0.9f || std::abs(q.y) > 0.9f || std::abs(q.x - q.y) < 0.1f) continue;
        const bool crack = view < 3 && q.y > q.x;  // triangle (0, 2, 3) is the second one
        const glm::vec3 base =
            crack ? frame.crackColour : (view == 2 ? colourMap(0.6f) : frame.colour);
        const glm::vec3 n = view == 1 ? -worldNormal : worldNormal;
        const glm::vec3 expected = shade(base, n, p, cam.eye);
        const uint8_t* got = &im.rgba[4 * (size_t(py) * w + px)];
        for (int c = 0; c < 3; ++c)
          ASSERT_NEAR(double(got[c]), double(expected[c]), 1.5)
              << "view " << view << " pixel " << px << "," << py << " channel " << c;
        ++checked;
      }
  }
  EXPECT_GT(checked, 100);
}

TEST(GlRender, GoldenBunnyMatchesReference) {
  const test::GoldenScene scene = test::goldenScene();
  ASSERT_FALSE(scene.positions.empty());
  MAKE_GL_OR_SKIP(gl, 160, 120, 4);
  const MeshFrame frame = scene.frame();
  Image im;
  Result<FrameStats> stats = gl->render({&frame, 1}, scene.camera, im);
  ASSERT_TRUE(stats.ok()) << stats.error().message;
  if (const char* dir = std::getenv("GF_GL_WRITE_DIR")) {  // for looking at it
    ASSERT_TRUE(writePng(std::string(dir) + "/bunny_gl.png", im).ok());
  }
  // Not a blank frame: the bunny covers a good share of it.
  EXPECT_GT(foregroundPixels(im), size_t(0.15 * 160 * 120));
  Result<Image> golden = readPng(kGoldenPath);
  ASSERT_TRUE(golden.ok()) << golden.error().message;
  Result<ImageDiff> diff = compareImages(im, golden.value(), 24);
  ASSERT_TRUE(diff.ok()) << diff.error().message;
  std::printf("[ GL ] vs %s: mean abs %.3f, max %d, %.3f %% of pixels over 24\n", kGoldenPath,
              diff.value().meanAbs, diff.value().maxAbs, 100.0 * diff.value().fractionOver);
  // Tight enough that losing MSAA fails (1 sample instead of 4: mean 0.525, 0.65 % over 24),
  // loose enough for another GPU's sample pattern (GL on an H100: mean 0.073, 0.005 % over 24).
  EXPECT_LT(diff.value().meanAbs, 0.25);
  EXPECT_LT(diff.value().fractionOver, 0.002);
}

// The stage golden image (test_vulkan_render.cpp): the GL shadow map, grid and glass crack faces
// mirror the Vulkan back end's.
TEST(GlRender, GoldenStageMatchesReference) {
  const test::GoldenScene scene = test::goldenScene();
  ASSERT_FALSE(scene.positions.empty());
  MAKE_GL_OR_SKIP(gl, 160, 120, 4);
  FrameOptions shadows;
  shadows.shadows = true;
  Image im;
  ASSERT_TRUE(gl->render(scene.stage(), scene.camera, shadows, im).ok());
  if (const char* dir = std::getenv("GF_GL_WRITE_DIR")) {
    ASSERT_TRUE(writePng(std::string(dir) + "/stage_gl.png", im).ok());
  }
  Result<Image> golden = readPng(GF_SOURCE_DIR "/tests/demo/golden/bunny_stage_160x120.png");
  ASSERT_TRUE(golden.ok()) << golden.error().message;
  Result<ImageDiff> diff = compareImages(im, golden.value(), 24);
  ASSERT_TRUE(diff.ok()) << diff.error().message;
  std::printf("[ GL ] stage: mean abs %.3f, max %d, %.3f %% of pixels over 24\n",
              diff.value().meanAbs, diff.value().maxAbs, 100.0 * diff.value().fractionOver);
  EXPECT_LT(diff.value().meanAbs, 0.25);
  EXPECT_LT(diff.value().fractionOver, 0.002);
}

// Bytes per vertex: positions and normals (3 floats each) plus the scalar when present; a
// topology change re-sends vertices, indices (3 uint32) and, with a mask, crack flags (1 byte)
// per triangle.
TEST(GlRender, StreamingUploadsExactlyTheDirtyRange) {
  const test::GoldenScene scene = test::goldenScene();
  ASSERT_FALSE(scene.positions.empty());
  MAKE_GL_OR_SKIP(gl, 96, 72, 4);
  const uint64_t nv = scene.positions.size() / 3, nt = scene.indices.size() / 3;
  const uint64_t full = nv * 24 + nt * 13;
  MeshFrame frame = scene.frame();
  Image first;
  Result<FrameStats> s = gl->render({&frame, 1}, scene.camera, first);
  ASSERT_TRUE(s.ok()) << s.error().message;
  EXPECT_EQ(s.value().uploadedBytes, full);
  EXPECT_EQ(s.value().surfaceBytes, full);

  // Move k vertices; only they are sent, and the image equals a fresh full upload's.
  std::vector<float> moved = scene.positions;
  const uint32_t begin = uint32_t(nv / 3), k = 57;
  for (uint32_t v = begin; v < begin + k; ++v) moved[3 * v + 1] += 0.05f;
  frame.positions = moved;
  frame.dirtyBegin = begin;
  frame.dirtyEnd = begin + k;
  Image streamed;
  s = gl->render({&frame, 1}, scene.camera, streamed);
  ASSERT_TRUE(s.ok()) << s.error().message;
  EXPECT_EQ(s.value().uploadedBytes, uint64_t(k) * 24);
  EXPECT_EQ(s.value().surfaceBytes, full);
  MAKE_GL_OR_SKIP(fresh, 96, 72, 4);
  Image reference;
  ASSERT_TRUE(fresh->render({&frame, 1}, scene.camera, reference).ok());
  EXPECT_EQ(streamed.rgba, reference.rgba);
  EXPECT_NE(streamed.rgba, first.rgba);

  // Nothing dirty: nothing sent.
  frame.dirtyBegin = frame.dirtyEnd = 0;
  s = gl->render({&frame, 1}, scene.camera, streamed);
  ASSERT_TRUE(s.ok());
  EXPECT_EQ(s.value().uploadedBytes, 0u);

  // With a scalar stream a vertex costs one float more; adding it is a size change (full).
  const std::vector<float> scalar(nv, 0.3f);
  frame.scalar = scalar;
  s = gl->render({&frame, 1}, scene.camera, streamed);
  ASSERT_TRUE(s.ok());
  EXPECT_EQ(s.value().uploadedBytes, full + nv * 4);
  frame.dirtyBegin = 5;
  frame.dirtyEnd = 5 + k;
  s = gl->render({&frame, 1}, scene.camera, streamed);
  ASSERT_TRUE(s.ok());
  EXPECT_EQ(s.value().uploadedBytes, uint64_t(k) * 28);

  // A new topology version re-sends everything, whatever the dirty range says.
  frame.topologyVersion = 2;
  s = gl->render({&frame, 1}, scene.camera, streamed);
  ASSERT_TRUE(s.ok());
  EXPECT_EQ(s.value().uploadedBytes, full + nv * 4);
  EXPECT_EQ(s.value().surfaceBytes, full + nv * 4);

  // Without a crack mask no flags are sent (a size change, so a full upload less the flags).
  MeshFrame plain = frame;
  plain.crackMask = {};
  s = gl->render({&plain, 1}, scene.camera, streamed);
  ASSERT_TRUE(s.ok());
  EXPECT_EQ(s.value().uploadedBytes, full + nv * 4 - nt);
  EXPECT_EQ(s.value().surfaceBytes, full + nv * 4 - nt);

  // Bad input is an error naming the field, not a crash, and the next good frame works.
  MeshFrame bad = frame;
  bad.crackMask = std::span<const uint8_t>(scene.crackMask.data(), nt - 1);
  s = gl->render({&bad, 1}, scene.camera, streamed);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("crackMask"), std::string::npos) << s.error().message;
  s = gl->render({&frame, 1}, scene.camera, streamed);
  EXPECT_TRUE(s.ok());
}

// With no Vulkan driver the automatic choice is GL. The Vulkan loader reads VK_DRIVER_FILES /
// VK_ICD_FILENAMES at every vkCreateInstance (Debian 12's loader does, even after a driver was
// loaded earlier in the process); should one cache them, the test skips rather than lie.
TEST(GlRender, AutoFallsBackToGlWithoutVulkan) {
  struct Env {
    const char* name;
    std::optional<std::string> old;
  } env[] = {{"VK_DRIVER_FILES", {}}, {"VK_ICD_FILENAMES", {}}};
  for (Env& e : env) {
    if (const char* v = std::getenv(e.name)) e.old = v;
    setenv(e.name, "/nonexistent/gf_no_vulkan_icd.json", 1);
  }
  RendererOptions o;
  o.width = 32;
  o.height = 24;
  o.kind = RendererKind::Vulkan;
  const bool vulkanWorks = createRenderer(o).ok();
  o.kind = RendererKind::Auto;
  Result<std::unique_ptr<Renderer>> r = createRenderer(o);
  for (Env& e : env)
    if (e.old)
      setenv(e.name, e.old->c_str(), 1);
    else
      unsetenv(e.name);
  if (vulkanWorks) GTEST_SKIP() << "a Vulkan driver was loaded earlier in this process";
  if (!r && (r.error().message.find("no EGL context") != std::string::npos ||
             r.error().message.find("GL renderer: not built") != std::string::npos))
    GTEST_SKIP() << r.error().message;
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_EQ(r.value()->description().rfind("OpenGL ", 0), 0u) << r.value()->description();
}

}  // namespace
}  // namespace gf::demo
