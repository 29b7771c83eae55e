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
#include "scene/bullet_scene.h"
#include "scene/scene.h"
#include "viewer_app.h"
#include "viewer_panel.h"

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
      "frame 4 screenshot out/a.png\n"
      "frame 6 scene block\n"
      "frame 7 window out/w.png\n",
      "s.txt");
  ASSERT_TRUE(r) << r.error().message;
  const std::vector<ScriptCommand>& c = r.value();
  ASSERT_EQ(c.size(), 7u);
  EXPECT_EQ(c[0].kind, ScriptCommand::Kind::Drag);
  EXPECT_EQ(c[0].frame, 2);
  EXPECT_EQ(c[0].frames, 5);
  EXPECT_EQ(c[0].y2, 40);
  EXPECT_EQ(c[1].kind, ScriptCommand::Kind::Cut);  // frame 3, in file order
  EXPECT_EQ(c[1].x1, 1.5);
  EXPECT_EQ(c[2].kind, ScriptCommand::Kind::Key);
  EXPECT_EQ(c[2].key, scriptKey("space"));
  EXPECT_EQ(c[3].path, "out/a.png");
  EXPECT_EQ(c[4].kind, ScriptCommand::Kind::Scene);
  EXPECT_EQ(c[4].path, "block");
  EXPECT_EQ(c[5].kind, ScriptCommand::Kind::Window);
  EXPECT_EQ(c[5].path, "out/w.png");
  EXPECT_EQ(c[6].kind, ScriptCommand::Kind::Quit);
}

TEST(ViewerScript, SceneNamesResolveToThePickersEntries) {
  const std::vector<std::string> offered = {"s/bar.json", "s/block.json"};
  EXPECT_EQ(resolveScene("block", offered), "s/block.json");
  EXPECT_EQ(resolveScene("block.json", offered), "s/block.json");
  // Not an entry, or a path: as given (the load then says what is wrong with it).
  EXPECT_EQ(resolveScene("blocks", offered), "blocks");
  EXPECT_EQ(resolveScene("t/block.json", offered), "t/block.json");
  // The picker offers the scene's folder, sorted.
  const std::vector<std::string> here =
      siblingScenes(GF_SOURCE_DIR "/tests/data/scenes/viewer/bar.json");
  ASSERT_GE(here.size(), 2u);
  EXPECT_TRUE(std::is_sorted(here.begin(), here.end()));
  EXPECT_EQ(resolveScene("block", here), GF_SOURCE_DIR "/tests/data/scenes/viewer/block.json");
}

TEST(ViewerScript, ErrorsNameTheLine) {
  for (const char* bad : {"frame 0 quit", "frame 2 drag 1 2 3", "frame 2 key F1", "frame 2 jump",
                          "frame 2 quit now", "quit", "frame 2 drag 1 2 3 4 0", "frame 2 scene"}) {
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
constexpr const char* kOtherScene = GF_SOURCE_DIR "/tests/data/scenes/viewer/block.json";
constexpr int kWidth = 320, kHeight = 180;

struct ViewerRun {
  int status = -1;
  std::string output;
};

/// Runs `xvfb-run -a -f AUTH graphfrac-viewer SCENE --size 320x180 --script SCRIPT args...`, its
/// stdout and stderr to a file. The X authority file lives in the test's directory: without
/// -f, xvfb-run makes a temporary directory of its own and exits 5 instead of the viewer's
/// status when removing it fails, which it sometimes does when several run at once.
ViewerRun runViewer(const test::TempDir& dir, const std::string& name, const std::string& script,
                    const std::vector<std::string>& extra = {}, const std::string& scene = kScene) {
  const std::string scriptPath = (dir.path / (name + ".txt")).string();
  std::ofstream(scriptPath) << script;
  const std::string log = (dir.path / (name + ".log")).string();
  const std::string auth = (dir.path / (name + ".xauth")).string();
  std::ofstream{auth};
  std::vector<std::string> args = {
      "xvfb-run",    "-a",      "-f",     auth,
      GF_VIEWER_EXE, scene,     "--size", std::to_string(kWidth) + "x" + std::to_string(kHeight),
      "--script",    scriptPath};
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

/// Changed pixels (as changedPixels counts them) with y in [y0, y1).
int changedInRows(const Image& a, const Image& b, int y0, int y1) {
  int n = 0;
  for (int y = std::max(y0, 0); y < std::min(y1, a.height); ++y)
    for (int x = 0; x < a.width; ++x) {
      const size_t i = 4 * (size_t(y) * size_t(a.width) + size_t(x));
      for (int k = 0; k < 3; ++k)
        if (std::abs(int(a.rgba[i + k]) - int(b.rgba[i + k])) > 24) {
          ++n;
          break;
        }
    }
  return n;
}

/// Mean red and blue of `image` over the pixels where `a` and `b` differ (as changedPixels).
struct RedBlue {
  double red = 0, blue = 0;
  int pixels = 0;
};
RedBlue meanRedBlue(const Image& image, const Image& a, const Image& b) {
  RedBlue m;
  for (size_t i = 0; i + 3 < a.rgba.size(); i += 4) {
    int d = 0;
    for (size_t k = 0; k < 3; ++k)
      d = std::max(d, std::abs(int(a.rgba[i + k]) - int(b.rgba[i + k])));
    if (d <= 24) continue;
    m.red += image.rgba[i];
    m.blue += image.rgba[i + 2];
    ++m.pixels;
  }
  if (m.pixels > 0) {
    m.red /= m.pixels;
    m.blue /= m.pixels;
  }
  return m;
}

// The C and O keys against the same frame without them. The overlay is text in a box at the
// top left (two lines at 320 px: rows 4..32), so turning it on changes those rows only. The
// strain colours change the bar only, and follow --strain: the resting bar's strain is far
// below 0.05, so it is drawn at the map's blue end, and far above 1e-6, so it is drawn red.
TEST_F(ViewerUnderXvfb, StrainColoursAndOverlayChangeThePicture) {
  test::TempDir dir("viewer_toggles");
  const std::string plain = (dir.path / "plain.png").string();
  const std::string overlay = (dir.path / "overlay.png").string();
  const std::string strain = (dir.path / "strain.png").string();
  const std::string strained = (dir.path / "strained.png").string();
  const ViewerRun none =
      runViewer(dir, "none", "frame 1 key o\nframe 20 screenshot " + plain + "\nframe 20 quit\n");
  if (!usable(none)) GTEST_SKIP() << m_skip;
  ASSERT_EQ(none.status, 0) << none.output;
  // The overlay is on by default; pressing O twice leaves it on.
  const ViewerRun text = runViewer(
      dir, "overlay",
      "frame 1 key o\nframe 2 key o\nframe 20 screenshot " + overlay + "\nframe 20 quit\n");
  ASSERT_EQ(text.status, 0) << text.output;
  const ViewerRun low =
      runViewer(dir, "strain",
                "frame 1 key o\nframe 1 key c\nframe 20 screenshot " + strain + "\nframe 20 quit\n",
                {"--strain", "0.05"});
  ASSERT_EQ(low.status, 0) << low.output;
  const ViewerRun high = runViewer(
      dir, "strained",
      "frame 1 key o\nframe 1 key c\nframe 20 screenshot " + strained + "\nframe 20 quit\n",
      {"--strain", "1e-6"});
  ASSERT_EQ(high.status, 0) << high.output;

  Result<Image> a = readPng(plain), o = readPng(overlay), c = readPng(strain),
                h = readPng(strained);
  ASSERT_TRUE(a && o && c && h);
  const Changed t = changedPixels(a.value(), o.value());
  std::printf("overlay: %d pixels changed in x %d..%d, y %d..%d\n", t.pixels, t.x0, t.x1, t.y0,
              t.y1);
  EXPECT_GT(t.pixels, 300);
  EXPECT_GE(t.x0, 4);
  EXPECT_GE(t.y0, 4);
  EXPECT_LT(t.y1, 32);

  const Changed s = changedPixels(a.value(), c.value());
  const Changed sh = changedPixels(a.value(), h.value());
  std::printf("strain: %d / %d pixels changed in x %d..%d, y %d..%d (--strain 0.05 / 1e-6)\n",
              s.pixels, sh.pixels, s.x0, s.x1, s.y0, s.y1);
  EXPECT_GT(s.pixels, 500);
  // The bar lies in x 96..224, y 73..107; its colour changes, not its shadow or the floor.
  EXPECT_GE(s.x0, 90);
  EXPECT_LE(s.x1, 230);
  EXPECT_GE(s.y0, 60);
  EXPECT_LE(s.y1, 115);
  const RedBlue blue = meanRedBlue(c.value(), a.value(), c.value());
  const RedBlue red = meanRedBlue(h.value(), a.value(), h.value());
  std::printf(
      "strain: mean red %.1f blue %.1f over %d px (0.05); red %.1f blue %.1f over %d px "
      "(1e-6)\n",
      blue.red, blue.blue, blue.pixels, red.red, red.blue, red.pixels);
  EXPECT_GT(blue.blue, blue.red + 30);
  EXPECT_GT(red.red, red.blue + 30);
}

// A scene picked by a script (as in the panel's list) replaces the running one: its bodies are
// the world's, and the picture is the one a viewer started on that scene shows after as many
// steps. A scene that does not load leaves the running one as it was, with the error shown.
TEST_F(ViewerUnderXvfb, PickingASceneShowsItsBodies) {
  test::TempDir dir("viewer_scenes");
  const std::string bar9 = (dir.path / "bar9.png").string();
  const std::string bar10 = (dir.path / "bar10.png").string();
  const std::string block5 = (dir.path / "block5.png").string();
  const std::string picked9 = (dir.path / "picked9.png").string();
  const std::string broken9 = (dir.path / "broken9.png").string();
  const std::string broken10 = (dir.path / "broken10.png").string();
  const ViewerRun bar =
      runViewer(dir, "bar",
                "frame 1 key o\nframe 9 screenshot " + bar9 +
                    "\nframe 10 key o\nframe 10 screenshot " + bar10 + "\nframe 10 quit\n");
  if (!usable(bar)) GTEST_SKIP() << m_skip;
  ASSERT_EQ(bar.status, 0) << bar.output;
  const ViewerRun block =
      runViewer(dir, "block", "frame 1 key o\nframe 5 screenshot " + block5 + "\nframe 5 quit\n",
                {}, kOtherScene);
  ASSERT_EQ(block.status, 0) << block.output;
  // Loaded before frame 5's step, so the viewer's frame 9 is the block's 5th step.
  const ViewerRun picked = runViewer(
      dir, "picked",
      "frame 1 key o\nframe 5 scene block\nframe 9 screenshot " + picked9 + "\nframe 9 quit\n");
  ASSERT_EQ(picked.status, 0) << picked.output;
  const std::string brokenScene = (dir.path / "broken.json").string();
  {
    std::ifstream in(kScene);
    std::stringstream text;
    text << in.rdbuf();
    std::string json = text.str();
    const size_t at = json.find("\"E\": 2e5");
    ASSERT_NE(at, std::string::npos);
    json.replace(at, 8, "\"E\": -2e5");
    std::ofstream(brokenScene) << json;
  }
  const ViewerRun broken =
      runViewer(dir, "broken",
                "frame 1 key o\nframe 5 scene " + brokenScene + "\nframe 9 screenshot " + broken9 +
                    "\nframe 10 key o\nframe 10 screenshot " + broken10 + "\nframe 10 quit\n");
  ASSERT_EQ(broken.status, 0) << broken.output;

  // The bodies: the summary lists what the world holds, against the scene files' meshes.
  Result<scene::Scene> barScene = scene::loadScene(kScene);
  Result<scene::Scene> blockScene = scene::loadScene(kOtherScene);
  ASSERT_TRUE(barScene && blockScene);
  const long long barTets =
      static_cast<long long>(barScene.value().bodies.at(0).def.mesh.tetCount());
  const long long blockTets =
      static_cast<long long>(blockScene.value().bodies.at(0).def.mesh.tetCount());
  ASSERT_NE(barTets, blockTets);
  std::printf("bodies: bar %lld tets, block %lld tets\n%s", barTets, blockTets,
              picked.output.c_str());
  EXPECT_EQ(summaryValue(bar.output, "body bar: "), barTets) << bar.output;
  EXPECT_EQ(summaryValue(picked.output, "body block: "), blockTets) << picked.output;
  EXPECT_EQ(picked.output.find("body bar: "), std::string::npos) << picked.output;
  EXPECT_NE(picked.output.find("graphfrac-viewer: viewer_block: "), std::string::npos)
      << picked.output;

  // The picture: the block's own, not the bar's.
  Result<Image> a = readPng(bar9), b = readPng(block5), p = readPng(picked9);
  ASSERT_TRUE(a && b && p);
  const Changed fromBar = changedPixels(a.value(), p.value());
  const Changed fromBlock = changedPixels(b.value(), p.value());
  std::printf("picked: %d pixels differ from the bar's frame 9, %d from the block's frame 5\n",
              fromBar.pixels, fromBlock.pixels);
  EXPECT_GT(fromBar.pixels, 500);
  EXPECT_LE(fromBlock.pixels, 5);

  // The scene that does not load: the error names the file and the field; the bar runs on as
  // if nothing was picked, and the overlay shows the error on a line of its own below its two.
  std::printf("broken:\n%s", broken.output.c_str());
  EXPECT_NE(broken.output.find(brokenScene), std::string::npos) << broken.output;
  EXPECT_NE(broken.output.find("not loaded: "), std::string::npos) << broken.output;
  EXPECT_EQ(summaryValue(broken.output, "body bar: "), barTets) << broken.output;
  EXPECT_NE(broken.output.find("graphfrac-viewer: viewer_bar: 10 steps"), std::string::npos)
      << broken.output;
  Result<Image> k9 = readPng(broken9), a10 = readPng(bar10), k10 = readPng(broken10);
  ASSERT_TRUE(k9 && a10 && k10);
  EXPECT_EQ(changedPixels(a.value(), k9.value()).pixels, 0);
  const int errorRows = changedInRows(a10.value(), k10.value(), 32, 44);
  std::printf("broken: %d pixels of the overlay's third line differ\n", errorRows);
  EXPECT_GT(errorRows, 100);
}

/// The lines of a file.
std::vector<std::string> readLines(const std::string& path) {
  std::vector<std::string> lines;
  std::ifstream in(path);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}
/// The first line that starts with `prefix`, or "".
std::string lineStarting(const std::vector<std::string>& lines, const std::string& prefix) {
  for (const std::string& l : lines)
    if (l.rfind(prefix, 0) == 0) return l;
  return {};
}

// The panel's text (written by the script's `panel` command, the lines the panel draws) against
// the world's own figures: the same scene stepped as many times in this process gives the
// solver's iterations and residual and the fracture counts; the picked body's material is the
// scene file's; the timings' parts add up to no more than their whole.
TEST_F(ViewerUnderXvfb, PanelShowsTheWorldsFigures) {
  test::TempDir dir("viewer_panel");
  const std::string before = (dir.path / "before.txt").string();
  const std::string after = (dir.path / "after.txt").string();
  const ViewerRun r =
      runViewer(dir, "panel",
                "frame 4 panel " + before + "\nframe 5 drag 160 80 160 80 2\nframe 8 panel " +
                    after + "\nframe 8 quit\n");
  if (!usable(r)) GTEST_SKIP() << m_skip;
  ASSERT_EQ(r.status, 0) << r.output;
  const std::vector<std::string> p4 = readLines(before), p8 = readLines(after);
  for (const std::string& l : p4) std::printf("panel: %s\n", l.c_str());
  for (const std::string& l : p8) std::printf("panel after the drag: %s\n", l.c_str());

  Result<scene::Scene> loaded = scene::loadScene(kScene);
  ASSERT_TRUE(loaded) << loaded.error().message;
  const scene::Scene& sc = loaded.value();
  Result<std::unique_ptr<scene::BulletScene>> made = scene::BulletScene::create(sc);
  ASSERT_TRUE(made) << made.error().message;
  scene::BulletScene& sim = *made.value();
  StepStatus last;
  for (int i = 0; i < 4; ++i) last = sim.step();
  ASSERT_TRUE(last.ok()) << last.message;
  ASSERT_GT(last.newtonIterations, 0);
  const FractureStats fs = sim.world().fractureStats(sim.body(0));

  int frame = 0;
  double t = 0, dt = 0;
  ASSERT_EQ(
      std::sscanf(lineStarting(p4, "frame ").c_str(), "frame %d t %lf s dt %lf s", &frame, &t, &dt),
      3);
  EXPECT_EQ(frame, 4);
  EXPECT_NEAR(dt, sc.dt, 5e-4 * sc.dt);  // printed to 4 digits
  EXPECT_NEAR(t, 4 * sc.dt, 5e-4);

  int newton = -1, linear = -1;
  double residual = -1;
  ASSERT_EQ(std::sscanf(lineStarting(p4, "solver: ").c_str(),
                        "solver: %d Newton, %d linear iterations, residual %le", &newton, &linear,
                        &residual),
            3);
  EXPECT_EQ(newton, last.newtonIterations);
  EXPECT_EQ(linear, last.linearIterations);
  EXPECT_NEAR(residual, last.residual, 5e-3 * last.residual);  // printed to 3 digits

  long long fragments = -1, broken = -1, edges = -1;
  size_t handed = 99;
  ASSERT_EQ(std::sscanf(lineStarting(p4, "fragments ").c_str(),
                        "fragments %lld, broken edges %lld of %lld, handed to Bullet %zu",
                        &fragments, &broken, &edges, &handed),
            4);
  EXPECT_EQ(fragments, fs.fragments);
  EXPECT_EQ(broken, fs.brokenEdges);
  EXPECT_EQ(edges, fs.edgeCount);
  EXPECT_EQ(handed, sim.handedOff());

  double total = -1, world = -1, bullet = -1, elements = -1, assembly = -1, solve = -1,
         fracture = -1, contact = -1, surface = -1;
  // The first "frame" line is the step count, the second the frame's timings.
  ASSERT_GE(p4.size(), 2u);
  ASSERT_EQ(
      std::sscanf(p4[1].c_str(), "frame %lf ms: world %lf, Bullet %lf", &total, &world, &bullet),
      3);
  ASSERT_EQ(std::sscanf(lineStarting(p4, "  elements ").c_str(),
                        "  elements %lf assembly %lf solve %lf", &elements, &assembly, &solve),
            3);
  ASSERT_EQ(std::sscanf(lineStarting(p4, "  fracture ").c_str(),
                        "  fracture %lf contact %lf surface %lf", &fracture, &contact, &surface),
            3);
  EXPECT_GT(total, 0);
  EXPECT_LE(world + bullet, total + 0.1 + 1e-9);  // each printed to 0.05 ms
  EXPECT_LE(elements + assembly + solve + fracture + contact, world + 0.25 + 1e-9);
  EXPECT_GT(world, 0);

  // Nothing picked before the drag; the bar's material after it.
  EXPECT_EQ(lineStarting(p4, "picked: "), "");
  const scene::SceneBody& bar = sc.bodies.at(0);
  EXPECT_EQ(lineStarting(p8, "picked: "),
            "picked: " + bar.name + " (" + materialModelName(bar.def.material.model) + ")");
  double E = -1, nu = -1, rho = -1, strength = -1, radius = -1;
  ASSERT_EQ(
      std::sscanf(lineStarting(p8, "  E ").c_str(), "  E %lf Pa nu %lf rho %lf", &E, &nu, &rho), 3);
  EXPECT_NEAR(E, bar.def.material.youngsModulus, 5e-3 * bar.def.material.youngsModulus);
  EXPECT_NEAR(nu, bar.def.material.poissonRatio, 5e-3 * bar.def.material.poissonRatio);
  EXPECT_NEAR(rho, bar.def.material.density, 5e-4 * bar.def.material.density);
  ASSERT_TRUE(bar.def.fracture.enabled);
  ASSERT_EQ(std::sscanf(lineStarting(p8, "  strength ").c_str(), "  strength %lf Pa R_d %lf",
                        &strength, &radius),
            2);
  EXPECT_NEAR(strength, bar.def.fracture.strength, 5e-3 * bar.def.fracture.strength);
  EXPECT_NEAR(radius, bar.def.fracture.radius, 1e-9 + 5e-3 * bar.def.fracture.radius);
  std::sscanf(lineStarting(p8, "frame ").c_str(), "frame %d", &frame);
  EXPECT_EQ(frame, 8);
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

// ---- presentation: the Vulkan swapchain and the GL fallback ----

/// The summary's "present:" value ("vulkan", "gl (why)"), or "" when it has none.
std::string presentLine(const std::string& output) {
  const std::string key = "  present:    ";
  const size_t at = output.find(key);
  if (at == std::string::npos) return "";
  const size_t end = output.find('\n', at);
  return output.substr(at + key.size(), end - at - key.size());
}

/// Pixels whose RGB differ at all.
int differingPixels(const Image& a, const Image& b) {
  if (a.width != b.width || a.height != b.height) return -1;
  int n = 0;
  for (size_t i = 0; i < a.rgba.size(); i += 4)
    n += a.rgba[i] != b.rgba[i] || a.rgba[i + 1] != b.rgba[i + 1] || a.rgba[i + 2] != b.rgba[i + 2];
  return n;
}

// The script of the presentation tests: a drag and a cut of the bar, the overlay off (its sim ms
// is wall-clock time), the panel hidden (H) for a window capture at frame 20 and shown again for
// one at frame 24.
std::string presentScript(const test::TempDir& dir, const std::string& tag) {
  const auto file = [&](const char* what) { return (dir.path / (tag + what)).string(); };
  return "frame 1 key o\n"
         "frame 3 drag 160 80 120 40 6\n"
         "frame 10 cut 150 30 150 140\n"
         "frame 19 key h\n"
         "frame 20 screenshot " +
         file("_shot.png") + "\nframe 20 window " + file("_window.png") +
         "\nframe 22 key h\n"
         "frame 24 screenshot " +
         file("_shot24.png") + "\nframe 24 window " + file("_panel.png") + "\nframe 24 quit\n";
}

// The default under Xvfb, with the validation layers on for the renderer's and the window's
// Vulkan devices: the window presents through the swapchain, the layers say nothing, and the
// swapchain image read back just before it is presented is the renderer's picture, pixel for
// pixel with the panel hidden (no scaling, no colour change, no rows flipped) and with the panel
// over part of it when shown. A swapchain image that the picture was not copied into fails the
// first comparison.
TEST_F(ViewerUnderXvfb, PresentsThroughAVulkanSwapchainByDefault) {
#if !defined(GF_DEMO_HAS_VULKAN)
  GTEST_SKIP() << "built without Vulkan";
#else
  test::TempDir dir("viewer_present_vulkan");
  const ViewerRun r = runViewer(dir, "vk", presentScript(dir, "vk"), {"--validation"});
  if (!usable(r)) GTEST_SKIP() << m_skip;
  if (r.output.find("renderer:   Vulkan") == std::string::npos)
    GTEST_SKIP() << "no Vulkan device with validation layers here: " << r.output;
  std::printf("%s", r.output.c_str());
  ASSERT_EQ(r.status, 0) << r.output;
  // A device renders with Vulkan here, so a window system that Vulkan presents to is expected.
  EXPECT_EQ(presentLine(r.output), "vulkan") << r.output;
  EXPECT_NE(r.output.find("validation: 0 messages from the Vulkan validation layers"),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("validation: 0 messages from the window's Vulkan device"),
            std::string::npos)
      << r.output;
  EXPECT_EQ(r.output.find("validation: error"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("validation: warning"), std::string::npos) << r.output;

  Result<Image> shot = readPng((dir.path / "vk_shot.png").string());
  Result<Image> window = readPng((dir.path / "vk_window.png").string());
  Result<Image> shot24 = readPng((dir.path / "vk_shot24.png").string());
  Result<Image> panel = readPng((dir.path / "vk_panel.png").string());
  ASSERT_TRUE(shot && window && shot24 && panel);
  ASSERT_EQ(window.value().width, kWidth);
  ASSERT_EQ(window.value().height, kHeight);
  EXPECT_EQ(differingPixels(shot.value(), window.value()), 0);
  // The panel covers part of the window, not all of it: the rest is still the picture.
  const int underPanel = differingPixels(shot24.value(), panel.value());
  EXPECT_GT(underPanel, kWidth * kHeight / 50);
  EXPECT_LT(underPanel, kWidth * kHeight);
#endif
}

// Presentation does not change the picture: the same drag and cut presented with Vulkan and
// with GL give identical screenshots, and both windows show them unchanged (the panel hidden).
TEST_F(ViewerUnderXvfb, VulkanAndGlPresentTheSamePicture) {
#if !defined(GF_DEMO_HAS_VULKAN)
  GTEST_SKIP() << "built without Vulkan";
#else
  test::TempDir dir("viewer_present_both");
  const ViewerRun vk = runViewer(dir, "vk", presentScript(dir, "vk"), {"--present", "vulkan"});
  if (!usable(vk)) GTEST_SKIP() << m_skip;
  if (vk.status == 1 && vk.output.find("--present vulkan is not available") != std::string::npos)
    GTEST_SKIP() << "no Vulkan device presents here: " << vk.output;
  ASSERT_EQ(vk.status, 0) << vk.output;
  const ViewerRun gl = runViewer(dir, "gl", presentScript(dir, "gl"), {"--present", "gl"});
  ASSERT_EQ(gl.status, 0) << gl.output;
  EXPECT_EQ(presentLine(vk.output), "vulkan") << vk.output;
  EXPECT_EQ(presentLine(gl.output), "gl") << gl.output;
  EXPECT_EQ(summaryCount(vk.output, "drags"), 1) << vk.output;
  EXPECT_EQ(summaryCount(vk.output, "cuts"), 1) << vk.output;
  EXPECT_EQ(summaryCount(gl.output, "cuts"), 1) << gl.output;
  for (const char* what : {"_shot.png", "_window.png", "_shot24.png"}) {
    Result<Image> a = readPng((dir.path / (std::string("vk") + what)).string());
    Result<Image> b = readPng((dir.path / (std::string("gl") + what)).string());
    ASSERT_TRUE(a && b) << what;
    EXPECT_EQ(differingPixels(a.value(), b.value()), 0) << what;
  }
  Result<Image> glShot = readPng((dir.path / "gl_shot.png").string());
  Result<Image> glWindow = readPng((dir.path / "gl_window.png").string());
  ASSERT_TRUE(glShot && glWindow);
  EXPECT_EQ(differingPixels(glShot.value(), glWindow.value()), 0);
#endif
}

// Without a Vulkan driver (the loader pointed at none): auto falls back to GL and says why, and
// a forced --present vulkan fails with the reason instead of running.
TEST_F(ViewerUnderXvfb, WithoutVulkanAutoFallsBackToGlAndForcedVulkanFails) {
  test::TempDir dir("viewer_present_novulkan");
  const std::string none = (dir.path / "no_icd.json").string();
  const char* old = std::getenv("VK_ICD_FILENAMES");
  const std::string saved = old ? old : "";
  setenv("VK_ICD_FILENAMES", none.c_str(), 1);
  const ViewerRun fallback =
      runViewer(dir, "auto", "frame 3 quit\n", {"--renderer", "gl", "--present", "auto"});
  const ViewerRun forced =
      runViewer(dir, "forced", "frame 3 quit\n", {"--renderer", "gl", "--present", "vulkan"});
  if (old)
    setenv("VK_ICD_FILENAMES", saved.c_str(), 1);
  else
    unsetenv("VK_ICD_FILENAMES");
  if (!usable(fallback)) GTEST_SKIP() << m_skip;
  ASSERT_EQ(fallback.status, 0) << fallback.output;
  const std::string line = presentLine(fallback.output);
  EXPECT_EQ(line.rfind("gl (", 0), 0u) << fallback.output;
  EXPECT_GT(line.size(), std::string("gl ()").size()) << fallback.output;
  EXPECT_EQ(forced.status, 1) << forced.output;
  EXPECT_NE(forced.output.find("--present vulkan is not available: "), std::string::npos)
      << forced.output;
  EXPECT_EQ(presentLine(forced.output), "") << forced.output;
}

}  // namespace
}  // namespace gf::demo

#endif  // GF_HAS_VIEWER
