// graphfrac-viewer (demo/viewer_app.h): the script parser and the camera geometry in process,
// then the executable itself under Xvfb with scripted input, compared with a run without it.
// The window tests skip, and say why, where xvfb-run is missing or no window can be opened.
#if defined(GF_HAS_VIEWER)

#include <fcntl.h>
#include <gtest/gtest.h>
#include <spawn.h>
#include <sys/wait.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <glm/geometric.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "common/temp_dir.h"
#include "renderer.h"
#include "viewer_app.h"

extern char** environ;

namespace gf::demo {
namespace {

TEST(ViewerScript, ParsesEveryCommandAndSortsByFrame) {
  Result<std::vector<ScriptCommand>> r = parseScript(
      "# a comment\n"
      "frame 9 quit\n"
      "frame 2 drag 10 20 30 40 5   # held 5 frames\n"
      "\n"
      "frame 3 cut 1.5 2 3 4\n"
      "frame 3 key space\n"
      "frame 4 screenshot out/a.png\n",
      "s.txt");
  ASSERT_TRUE(r) << r.error().message;
  const std::vector<ScriptCommand>& c = r.value();
  ASSERT_EQ(c.size(), 5u);
  EXPECT_EQ(c[0].kind, ScriptCommand::Kind::Drag);
  EXPECT_EQ(c[0].frame, 2);
  EXPECT_EQ(c[0].frames, 5);
  EXPECT_EQ(c[0].y2, 40);
  EXPECT_EQ(c[1].kind, ScriptCommand::Kind::Cut);  // frame 3, in file order
  EXPECT_EQ(c[1].x1, 1.5);
  EXPECT_EQ(c[2].kind, ScriptCommand::Kind::Key);
  EXPECT_EQ(c[2].key, scriptKey("space"));
  EXPECT_EQ(c[3].path, "out/a.png");
  EXPECT_EQ(c[4].kind, ScriptCommand::Kind::Quit);
}

TEST(ViewerScript, ErrorsNameTheLine) {
  for (const char* bad : {"frame 0 quit", "frame 2 drag 1 2 3", "frame 2 key F1", "frame 2 jump",
                          "frame 2 quit now", "quit", "frame 2 drag 1 2 3 4 0"}) {
    Result<std::vector<ScriptCommand>> r = parseScript(std::string("\n") + bad + "\n", "s.txt");
    ASSERT_FALSE(r) << bad;
    EXPECT_NE(r.error().message.find("s.txt:2: "), std::string::npos) << r.error().message;
  }
  EXPECT_EQ(scriptKey("S"), scriptKey("s"));
  EXPECT_NE(scriptKey("1"), 0);
  EXPECT_EQ(scriptKey("F1"), 0);
}

TEST(ViewerGeometry, RayThroughThePictureCentreHitsTheTarget) {
  Camera c;
  c.eye = {1, 2, 3};
  c.target = {0, 0.5f, 0};
  const Ray r = cameraRay(c, 640, 360, 320, 180);
  const glm::dvec3 toTarget = glm::normalize(glm::dvec3(c.target) - glm::dvec3(c.eye));
  EXPECT_NEAR(glm::dot(r.direction, toTarget), 1.0, 1e-12);
  // The top edge of the picture is half the vertical field of view above the line of sight.
  const Ray top = cameraRay(c, 640, 360, 320, 0);
  EXPECT_NEAR(std::acos(glm::dot(top.direction, toTarget)) * 180 / 3.14159265358979, 22.5, 1e-6);
  EXPECT_GT(top.direction.y, r.direction.y);
}

TEST(ViewerGeometry, StrokeBladeHoldsBothRays) {
  Camera c;
  const StrokeBlade b = strokeBlade(c, 320, 180, 100, 20, 140, 170);
  ASSERT_EQ(b.vertices.size(), 4u);
  ASSERT_EQ(b.triangles.size(), 6u);
  const glm::dvec3 n = glm::normalize(glm::cross(glm::dvec3(b.vertices[1] - b.vertices[0]),
                                                 glm::dvec3(b.vertices[3] - b.vertices[0])));
  for (const Ray& r : {cameraRay(c, 320, 180, 100, 20), cameraRay(c, 320, 180, 140, 170)}) {
    EXPECT_NEAR(glm::dot(r.direction, n), 0.0, 1e-5);
    EXPECT_NEAR(glm::dot(r.origin - glm::dvec3(b.vertices[0]), n), 0.0, 1e-5);
  }
}

// ---- the executable under Xvfb ----

constexpr const char* kScene = GF_SOURCE_DIR "/tests/data/scenes/viewer/bar.json";
constexpr int kWidth = 320, kHeight = 180;

struct ViewerRun {
  int status = -1;
  std::string output;
};

/// Runs `xvfb-run -a graphfrac-viewer SCENE --size 320x180 --script SCRIPT args...`, its
/// stdout and stderr to a file.
ViewerRun runViewer(const test::TempDir& dir, const std::string& name, const std::string& script,
                    const std::vector<std::string>& extra = {}) {
  const std::string scriptPath = (dir.path / (name + ".txt")).string();
  std::ofstream(scriptPath) << script;
  const std::string log = (dir.path / (name + ".log")).string();
  std::vector<std::string> args = {
      "xvfb-run", "-a",      GF_VIEWER_EXE,
      kScene,     "--size",  std::to_string(kWidth) + "x" + std::to_string(kHeight),
      "--script", scriptPath};
  args.insert(args.end(), extra.begin(), extra.end());
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, 1, 2);
  ViewerRun run;
  pid_t pid = 0;
  if (posix_spawnp(&pid, "xvfb-run", &actions, nullptr, argv.data(), environ) == 0) {
    int status = 0;
    while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
    }
    run.status = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  }
  posix_spawn_file_actions_destroy(&actions);
  std::stringstream text;
  text << std::ifstream(log).rdbuf();
  run.output = text.str();
  return run;
}

/// The number after `key` in the viewer's summary, or -1.
long long summaryValue(const std::string& output, const std::string& key) {
  const size_t at = output.find(key);
  return at == std::string::npos ? -1 : std::atoll(output.c_str() + at + key.size());
}
/// The number before `unit` in the summary's first line ("20 steps, 1 drags, 0 cuts, 0 balls").
long long summaryCount(const std::string& output, const std::string& unit) {
  const size_t at = output.find(" " + unit);
  if (at == std::string::npos) return -1;
  size_t begin = at;
  while (begin > 0 && std::isdigit(static_cast<unsigned char>(output[begin - 1]))) --begin;
  return begin == at ? -1 : std::atoll(output.c_str() + begin);
}

class ViewerUnderXvfb : public ::testing::Test {
 protected:
  void SetUp() override {
    if (std::system("command -v xvfb-run > /dev/null 2>&1") != 0)
      GTEST_SKIP() << "no xvfb-run here (Debian's xvfb)";
  }
  /// Skips the test when the viewer could not open a window or make a renderer.
  bool usable(const ViewerRun& r) {
    if (r.status == kViewerNoDisplay) {
      m_skip = "no display under xvfb-run: " + r.output;
      return false;
    }
    if (r.status != 0 && r.output.find("no renderer") != std::string::npos) {
      m_skip = "no renderer here: " + r.output;
      return false;
    }
    return true;
  }
  std::string m_skip;
};

/// Pixels whose RGB differ by more than 24 somewhere, and their bounding box.
struct Changed {
  int pixels = 0, x0 = 1 << 30, y0 = 1 << 30, x1 = -1, y1 = -1;
};
Changed changedPixels(const Image& a, const Image& b) {
  Changed c;
  for (int y = 0; y < a.height; ++y) {
    for (int x = 0; x < a.width; ++x) {
      const size_t i = 4 * (size_t(y) * size_t(a.width) + size_t(x));
      int d = 0;
      for (int k = 0; k < 3; ++k)
        d = std::max(d, std::abs(int(a.rgba[i + k]) - int(b.rgba[i + k])));
      if (d <= 24) continue;
      ++c.pixels;
      c.x0 = std::min(c.x0, x);
      c.y0 = std::min(c.y0, y);
      c.x1 = std::max(c.x1, x);
      c.y1 = std::max(c.y1, y);
    }
  }
  return c;
}

// The bar lies across the middle of the picture (x 96..224, y 73..107 at 320x180); the drag
// grabs its top at the centre and pulls it to the right and up, the cut slices it at the
// centre from top to bottom. Screenshots at frame 20 with and without the input, the overlay
// off: its "sim ms" is wall-clock time and differs between runs (more so under ASan).
TEST_F(ViewerUnderXvfb, DragAndCutChangeThePictureWhereTheBodyIs) {
  test::TempDir dir("viewer_input");
  const std::string plain = (dir.path / "plain.png").string();
  const std::string dragged = (dir.path / "dragged.png").string();
  const std::string cut = (dir.path / "cut.png").string();
  const ViewerRun none =
      runViewer(dir, "none", "frame 1 key o\nframe 20 screenshot " + plain + "\nframe 20 quit\n");
  if (!usable(none)) GTEST_SKIP() << m_skip;
  ASSERT_EQ(none.status, 0) << none.output;
  const ViewerRun drag =
      runViewer(dir, "drag",
                "frame 1 key o\nframe 5 drag 160 80 200 30 20\nframe 20 screenshot " + dragged +
                    "\nframe 20 quit\n");
  ASSERT_EQ(drag.status, 0) << drag.output;
  const ViewerRun slice =
      runViewer(dir, "cut",
                "frame 1 key o\nframe 5 cut 160 30 160 140\nframe 20 screenshot " + cut +
                    "\nframe 20 quit\n");
  ASSERT_EQ(slice.status, 0) << slice.output;

  Result<Image> a = readPng(plain), b = readPng(dragged), c = readPng(cut);
  ASSERT_TRUE(a && b && c);
  ASSERT_EQ(a.value().width, kWidth);
  // The drag: the body moved, so pixels changed, and only around it (the sky and the far floor
  // stay as they were; the overlay's text is the same frame's).
  const Changed d = changedPixels(a.value(), b.value());
  std::printf("drag: %d pixels changed in x %d..%d, y %d..%d\n", d.pixels, d.x0, d.x1, d.y0, d.y1);
  EXPECT_GT(d.pixels, 150);
  EXPECT_LE(d.x0, 160);
  EXPECT_GE(d.x1, 160);
  EXPECT_GE(d.y0, 30);   // nothing changed above the body
  EXPECT_LE(d.y1, 130);  // nor far below it
  EXPECT_EQ(summaryCount(drag.output, "drags"), 1) << drag.output;
  EXPECT_EQ(summaryCount(drag.output, "cuts"), 0) << drag.output;
  EXPECT_EQ(summaryCount(drag.output, "steps"), 20) << drag.output;

  // The cut: one body became two pieces, and the picture changed at the slice.
  const long long before = summaryValue(none.output, "fragments ");
  const long long after = summaryValue(slice.output, "fragments ");
  std::printf("cut: fragments %lld -> %lld\n", before, after);
  EXPECT_EQ(before, 1) << none.output;
  EXPECT_GE(after, 2) << slice.output;
  EXPECT_EQ(summaryCount(slice.output, "cuts"), 1) << slice.output;
  const Changed s = changedPixels(a.value(), c.value());
  std::printf("cut: %d pixels changed in x %d..%d, y %d..%d\n", s.pixels, s.x0, s.x1, s.y0, s.y1);
  EXPECT_GT(s.pixels, 20);
  EXPECT_LE(s.x0, 160);
  EXPECT_GE(s.x1, 160);
}

// Every input the viewer has, with the Vulkan validation layers on: they report nothing and
// the viewer exits cleanly.
TEST_F(ViewerUnderXvfb, ValidationLayersReportNothing) {
#if !defined(GF_DEMO_HAS_VULKAN)
  GTEST_SKIP() << "built without the Vulkan renderer";
#else
  test::TempDir dir("viewer_validation");
  const std::string shot = (dir.path / "shot.png").string();
  const ViewerRun r =
      runViewer(dir, "all",
                "frame 2 key b\n"
                "frame 3 drag 160 80 120 40 6\n"
                "frame 10 cut 150 30 150 140\n"
                "frame 11 key c\nframe 12 key o\nframe 13 key 2\nframe 14 key left\n"
                "frame 15 key space\nframe 16 key s\nframe 17 key r\n"
                "frame 19 screenshot " +
                    shot + "\nframe 20 quit\n",
                {"--validation", "--renderer", "vulkan"});
  if (!usable(r)) GTEST_SKIP() << m_skip;
  // No Vulkan device or no layers: the viewer says why and exits 1 before its first frame.
  if (r.status == 1 && r.output.find("Vulkan") != std::string::npos &&
      r.output.find("graphfrac-viewer: viewer_bar:") == std::string::npos)
    GTEST_SKIP() << "no Vulkan renderer with validation layers here: " << r.output;
  std::printf("%s", r.output.c_str());
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("validation: 0 messages"), std::string::npos) << r.output;
  EXPECT_EQ(summaryCount(r.output, "drags"), 1) << r.output;
  EXPECT_EQ(summaryCount(r.output, "cuts"), 1) << r.output;
  EXPECT_EQ(summaryCount(r.output, "balls"), 1) << r.output;
  EXPECT_TRUE(readPng(shot));
#endif
}

}  // namespace
}  // namespace gf::demo

#endif  // GF_HAS_VIEWER
