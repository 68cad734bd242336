// hgdeform-view under a virtual display: a replayed session saves the shape that
// `hgdeform deform` gives on the saved scenario; screenshots show what the user would see.
#include <png.h>

#include <cstdio>
#include <fstream>
#include <string>

#include "hgdeform/geometry.h"
#include "hgdeform/io.h"
#include "hgdeform/shapes.h"
#include "test_util.h"

namespace {

struct Image {
  int width = 0, height = 0;
  std::vector<unsigned char> rgb;
  const unsigned char* at(int x, int y) const {
    return rgb.data() + 3 * (static_cast<std::size_t>(y) * width + x);
  }
};

Image readPng(const std::string& path) {
  Image img;
  png_image png;
  std::memset(&png, 0, sizeof png);
  png.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&png, path.c_str())) return img;
  png.format = PNG_FORMAT_RGB;
  img.width = static_cast<int>(png.width);
  img.height = static_cast<int>(png.height);
  img.rgb.resize(PNG_IMAGE_SIZE(png));
  if (!png_image_finish_read(&png, nullptr, img.rgb.data(), 0, nullptr)) img.rgb.clear();
  return img;
}

// Pixels within `tol` of a colour (0..255 per channel).
int countNear(const Image& img, int r, int g, int b, int tol = 40) {
  int n = 0;
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) {
      const unsigned char* p = img.at(x, y);
      if (std::abs(p[0] - r) < tol && std::abs(p[1] - g) < tol && std::abs(p[2] - b) < tol) ++n;
    }
  return n;
}

int countDifferent(const Image& a, const Image& b) {
  if (a.width != b.width || a.height != b.height) return -1;
  int n = 0;
  for (std::size_t i = 0; i + 2 < a.rgb.size(); i += 3)
    if (std::abs(a.rgb[i] - b.rgb[i]) + std::abs(a.rgb[i + 1] - b.rgb[i + 1]) +
            std::abs(a.rgb[i + 2] - b.rgb[i + 2]) >
        30)
      ++n;
  return n;
}

bool haveXvfb() {
  std::string out;
  return hgdtest::run("command -v xvfb-run", out) == 0;
}

std::string viewer(const std::string& args) {
  return "xvfb-run -a -s '-screen 0 1280x1024x24' " + std::string(HGD_VIEW) + " " + args;
}

double maxDistance(const std::string& a, const std::string& b, double& diag) {
  const hgd::Geometry ga = hgd::extractGeometry(hgd::readShape(a)),
                      gb = hgd::extractGeometry(hgd::readShape(b));
  diag = hgd::boundingBoxDiagonal(ga);
  if (ga.size() != gb.size()) return INFINITY;
  double worst = 0;
  for (std::size_t i = 0; i < ga.size(); ++i) {  // the same file point in both
    const int j = gb.finite_index[static_cast<std::size_t>(ga.raw_index[i])];
    if (j < 0) return INFINITY;
    worst = std::max(worst, (ga.world(i) - gb.world(static_cast<std::size_t>(j))).norm());
  }
  return worst;
}

TEST(Viewer, ReplayedDragSavesWhatDeformGivesAndScreenshotsShowIt) {
  if (!haveXvfb()) GTEST_SKIP() << "xvfb-run not installed";
  hgdtest::TempDir dir;
  hgd::writeShape(dir.file("bar.ply"), hgd::shapes::bar(1.0f, 0.1f, 0.01f));
  const std::string d = dir.path().string() + "/";
  hgdtest::writeText(dir.file("events.json"), R"({"events": [
    {"pick": {"world": [0, 0, 0.05], "radius": 0.06}}, {"key": "f"},
    {"pick": {"world": [1, 0, 0.05], "radius": 0.06}}, {"key": "m"},
    {"screenshot": ")" + d + R"(before.png"},
    {"drag": {"from": {"world": [1, 0, 0.05]}, "to": {"world": [0.8, 0.4, 0.05]}, "steps": 15}},
    {"save": ")" + d + R"(viewer.ply"}, {"save_scenario": ")" +
                                                  d + R"(session.json"},
    {"screenshot": ")" + d + R"(after.png"},
    {"view": "field"}, {"screenshot": ")" + d + R"(field.png"}
  ]})");
  std::string out;
  ASSERT_EQ(
      hgdtest::run(viewer(dir.file("bar.ply") + " --replay " + dir.file("events.json") + " --quiet"), out), 0)
      << out;
  ASSERT_EQ(hgdtest::run(std::string(HGD_TOOL) + " deform " + dir.file("bar.ply") + " -s " +
                             dir.file("session.json") + " -o " + dir.file("cli.ply") + " -q",
                         out),
            0)
      << out;
  double diag = 1;
  const double worst = maxDistance(dir.file("viewer.ply"), dir.file("cli.ply"), diag);
  std::printf("viewer session vs hgdeform deform on its scenario: max distance %.2e of the diagonal\n",
              worst / diag);
  EXPECT_LE(worst, 1e-5 * diag);
  // The drag did something: the far end moved.
  double moved = 0;
  EXPECT_GT(maxDistance(dir.file("bar.ply"), dir.file("viewer.ply"), moved), 0.2);

  const Image before = readPng(d + "before.png"), after = readPng(d + "after.png"),
              field = readPng(d + "field.png");
  ASSERT_GT(before.width, 0);
  ASSERT_FALSE(before.rgb.empty());
  ASSERT_FALSE(after.rgb.empty());
  ASSERT_FALSE(field.rgb.empty());
  // Not blank: the shape is drawn (grey points on white).
  EXPECT_GT(countNear(before, 191, 191, 184), 500);
  EXPECT_GT(countDifferent(before, after), 500);
  // The field's colour map: its cyan and yellow appear in field view and not in colour view.
  const int cyan = countNear(field, 89, 204, 230, 30), yellow = countNear(field, 242, 217, 77, 30);
  std::printf("field view: %d cyan-ish and %d yellow-ish pixels (colour view: %d, %d)\n", cyan, yellow,
              countNear(after, 89, 204, 230, 30), countNear(after, 242, 217, 77, 30));
  EXPECT_GT(cyan, 200);
  EXPECT_GT(yellow, 200);
  EXPECT_LT(countNear(after, 89, 204, 230, 30), 20);
}

TEST(Viewer, FrameKeysAndUndoReplayThroughTheScenario) {
  if (!haveXvfb()) GTEST_SKIP() << "xvfb-run not installed";
  hgdtest::TempDir dir;
  hgd::writeShape(dir.file("bar.pcd"), hgd::shapes::bar(1.0f, 0.1f, 0.02f));
  const std::string d = dir.path().string() + "/";
  hgdtest::writeText(dir.file("events.json"), R"({"events": [
    {"area": {"from": [-0.01, -0.06, -0.06], "to": [0.03, 0.06, 0.06]}}, {"key": "f"},
    {"pick": {"world": [1, 0, 0.05], "radius": 0.07}}, {"key": "m"},
    {"key": "t"}, {"key": "Up"}, {"key": "Up"}, {"key": "bracketleft"}, {"key": "["}, {"key": "Right"},
    {"key": "z"}, {"key": "z"}, {"key": "y"},
    {"save": ")" + d + R"(viewer.pcd"}, {"save_scenario": ")" +
                                                  d + R"(session.json"}
  ]})");
  std::string out;
  ASSERT_EQ(
      hgdtest::run(viewer(dir.file("bar.pcd") + " --replay " + dir.file("events.json") + " --quiet"), out), 0)
      << out;
  std::ifstream in(dir.file("session.json"));
  const std::string scenario((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(scenario.find("\"frame\""), std::string::npos) << scenario;
  ASSERT_EQ(hgdtest::run(std::string(HGD_TOOL) + " deform " + dir.file("bar.pcd") + " -s " +
                             dir.file("session.json") + " -o " + dir.file("cli.pcd") + " -q",
                         out),
            0)
      << out;
  double diag = 1;
  EXPECT_LE(maxDistance(dir.file("viewer.pcd"), dir.file("cli.pcd"), diag), 1e-5 * diag);
  double moved = 0;
  EXPECT_GT(maxDistance(dir.file("bar.pcd"), dir.file("viewer.pcd"), moved), 0.01);
}

TEST(Viewer, BadInputGivesAClearError) {
  if (!haveXvfb()) GTEST_SKIP() << "xvfb-run not installed";
  hgdtest::TempDir dir;
  std::string out;
  EXPECT_EQ(hgdtest::run(viewer(dir.file("missing.ply")), out), 1);
  EXPECT_NE(out.find("missing.ply"), std::string::npos) << out;
  EXPECT_EQ(hgdtest::run(std::string(HGD_VIEW) + " --bogus", out), 2);
  // Without a display the viewer says so instead of aborting inside VTK.
  hgd::writeShape(dir.file("bar.ply"), hgd::shapes::bar(1.0f, 0.1f, 0.05f));
  EXPECT_EQ(hgdtest::run("env -u DISPLAY " + std::string(HGD_VIEW) + " " + dir.file("bar.ply"), out), 1);
  EXPECT_NE(out.find("display"), std::string::npos) << out;
}

// No output of the viewer or the renderer replaces an input: --screenshot, and the replay
// events screenshot, save and save_scenario, named as the shape, the scenario or the replay.
TEST(Viewer, NoOutputReplacesAnInput) {
  hgdtest::TempDir dir;
  const std::string bar = dir.file("bar.ply"), sc = dir.file("s.json"), ev = dir.file("events.json");
  hgd::writeShape(bar, hgd::shapes::bar(1.0f, 0.1f, 0.05f));
  hgdtest::writeText(sc, R"({"format": "hgdeform-scenario/1",
    "fixed": [{"box": {"min": [-1, -1, -1], "max": [0.1, 1, 1]}}],
    "manipulated": {"box": {"min": [0.9, -1, -1], "max": [2, 1, 1]}}})");
  const std::string bar_before = hgdtest::slurp(bar), sc_before = hgdtest::slurp(sc);
  std::string out;
  // The renderer refuses before it needs a display.
  EXPECT_EQ(hgdtest::run(std::string(HGD_RENDER) + " " + bar + " -o " + bar, out), 1);
  EXPECT_NE(out.find("refusing to overwrite the input"), std::string::npos) << out;
  if (haveXvfb()) {
    hgdtest::writeText(ev, R"({"events": []})");
    EXPECT_EQ(hgdtest::run(viewer(bar + " -s " + sc + " --replay " + ev + " --screenshot " + bar), out), 1);
    EXPECT_NE(out.find("refusing to overwrite the input"), std::string::npos) << out;
    for (const std::string& event :
         {R"({"screenshot": ")" + bar + "\"}", R"({"save": ")" + bar + "\"}",
          R"({"save_scenario": ")" + sc + "\"}", R"({"screenshot": ")" + ev + "\"}"}) {
      const std::string events = R"({"events": [)" + event + "]}";
      hgdtest::writeText(ev, events);
      EXPECT_NE(hgdtest::run(viewer(bar + " -s " + sc + " --replay " + ev + " --quiet"), out), 0) << event;
      EXPECT_NE(out.find("refusing to overwrite the input"), std::string::npos) << event << ": " << out;
      EXPECT_EQ(hgdtest::slurp(ev), events) << event;
    }
  }
  EXPECT_EQ(hgdtest::slurp(bar), bar_before);
  EXPECT_EQ(hgdtest::slurp(sc), sc_before);
}

// A malformed replay (docs/replay.md) is refused as a whole before any event runs: exit 1 (no
// crash: run() gives -1 for a signal), the JSON path of the problem on stderr, and no output of
// the valid events before the bad one.
TEST(Viewer, MalformedReplayIsRefusedBeforeAnyEventRuns) {
  if (!haveXvfb()) GTEST_SKIP() << "xvfb-run not installed";
  hgdtest::TempDir dir;
  const std::string bar = dir.file("bar.ply"), ev = dir.file("events.json");
  hgd::writeShape(bar, hgd::shapes::bar(1.0f, 0.1f, 0.05f));
  struct Case {
    std::string event, message;  // the bad event (third in the file), what stderr says of it
  };
  const std::vector<Case> cases = {
      {R"({"drag": {"from": {"world": [1, 0, 0.05]}}})", "/events/2/drag/to: missing"},
      {R"({"drag": {"to": {"world": [1, 0, 0.05]}}})", "/events/2/drag/from: missing"},
      {R"({"pick": {"world": [1, 0]}})", "/events/2/pick/world: must be an array of 3 numbers"},
      {R"({"pick": {"screen": [10]}})", "/events/2/pick/screen: must be an array of 2 numbers"},
      {R"({"area": {"screen": [0, 0, 10]}})", "/events/2/area/screen: must be an array of 4 numbers"},
      {R"({"area": {"from": [0, 0, 0]}})", "/events/2/area/to: missing"},
      {R"({"drag": {"from": {"world": [1, 0, 0.05]}, "to": {"screen": [5]}}})",
       "/events/2/drag/to/screen: must be an array of 2 numbers"},
      {R"({"pick": {"world": [1, "0", 0.05]}})", "/events/2/pick/world/1: must be a number"},
      {R"({"pick": {"world": [1, null, 0.05]}})", "/events/2/pick/world/1: must be a number"},
      {R"({"drag": {"from": {"world": [1, 0, 0.05]}, "to": {"world": [0.8, 1e999, 0.05]}}})",
       "/events/2/drag/to/world/1: must be a finite number"},
      {R"({"radius": -1e999})", "/events/2/radius: must be a finite number"},
      {R"({"radius": 0})", "/events/2/radius: must be a positive number"},
      {R"({"zoom": 2})", "/events/2/zoom: unknown key (expected one of: key, radius, pick"},
      {R"({"pick": {"world": [1, 0, 0.05], "size": 3}})", "/events/2/pick/size: unknown key"},
      {R"({"pick": {"world": [1, 0, 0.05], "screen": [1, 2]}})",
       "/events/2/pick: must have exactly one of: world, screen"},
      {R"({"key": "f", "radius": 0.1})", "/events/2: an event must have exactly one of: key, radius"},
      {R"({})", "/events/2: an event must have exactly one of: key, radius"},
      {R"("f")", "/events/2: must be an object"},
      {R"([{"key": "f"}])", "/events/2: must be an object"},
      {R"({"key": ""})", "/events/2/key: must be a non-empty string"},
      {R"({"save": 3})", "/events/2/save: must be a non-empty string"},
      {R"({"view": "depth"})", R"(/events/2/view: must be "colours", "field" or "clusters")"},
      {R"({"drag": {"from": {"world": [1, 0, 0.05]}, "to": {"world": [0.8, 0.4, 0.05]}, "steps": 0}})",
       "/events/2/drag/steps: must be an integer from 1 to 10000"},
      {R"({"drag": {"from": {"world": [1, 0, 0.05]}, "to": {"world": [0.8, 0.4, 0.05]}, "steps": 2.5}})",
       "/events/2/drag/steps: must be an integer from 1 to 10000"},
      {R"({"pick": {"world": [1e16, 0, 0]}})", "/events/2/pick/world/0: must be a coordinate between"},
      {R"({"key": "f", "key": "m"})", "/events/2/key: duplicate key"},
      // An output naming an input is refused with the rest, before the events ahead of it.
      {R"({"save": ")" + bar + R"("})", "/events/2/save: " + bar + ": refusing to overwrite the input"},
  };
  const std::string bar_before = hgdtest::slurp(bar);
  for (std::size_t i = 0; i < cases.size(); ++i) {
    const std::string early = dir.file("early" + std::to_string(i));
    const std::string events = R"({"events": [{"save": ")" + early + R"(.ply"}, {"screenshot": ")" + early +
                               R"(.png"}, )" + cases[i].event + R"(, {"save": ")" + early +
                               R"(-late.ply"}]})";
    hgdtest::writeText(ev, events);
    const hgdtest::CommandResult r = hgdtest::shell(viewer(bar + " --replay " + ev + " --quiet"));
    EXPECT_EQ(r.code, 1) << cases[i].event << "\n" << r.err;
    EXPECT_TRUE(hgdtest::contains(r.err, "hgdeform-view: " + ev + ": " + cases[i].message))
        << cases[i].event << "\n"
        << r.err;
    for (const char* suffix : {".ply", ".png", ".png.tmp.png", "-late.ply"})
      EXPECT_FALSE(hgdtest::exists(early + suffix)) << cases[i].event << ": wrote " << early << suffix;
  }
  // The bare array form: the JSON paths are those of the file.
  hgdtest::writeText(ev, R"([{"save": ")" + dir.file("early.ply") + R"("}, {"pick": {"world": [0, 0]}}])");
  const hgdtest::CommandResult r = hgdtest::shell(viewer(bar + " --replay " + ev + " --quiet"));
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_TRUE(hgdtest::contains(r.err, ev + ": /1/pick/world: must be an array of 3 numbers")) << r.err;
  EXPECT_FALSE(hgdtest::exists(dir.file("early.ply")));
  // Not a replay at all, and not JSON.
  for (const auto& [text, message] : std::vector<std::pair<std::string, std::string>>{
           {R"({"events": {}})", ": /events: must be an array of events"},
           {R"({"events": [], "format": 1})", ": /format: unknown key (expected one of: events)"},
           {"5", ": /: must be an object {\"events\": [...]} (or an array of events)"},
           {R"({"events": [)", ": invalid JSON: "}}) {
    hgdtest::writeText(ev, text);
    const hgdtest::CommandResult bad = hgdtest::shell(viewer(bar + " --replay " + ev + " --quiet"));
    EXPECT_EQ(bad.code, 1) << text << "\n" << bad.err;
    EXPECT_TRUE(hgdtest::contains(bad.err, ev + message)) << text << "\n" << bad.err;
  }
  EXPECT_EQ(hgdtest::slurp(bar), bar_before);
}

// The example of README.md and docs/replay.md replays, with --screenshot, --size and --stats
// (its one drag of 20 steps: 20 frames while moving and one at the release).
TEST(Viewer, DocumentedBunnyReplayRuns) {
  if (!haveXvfb()) GTEST_SKIP() << "xvfb-run not installed";
  hgdtest::TempDir dir;
  const std::string shot = dir.file("viewer.png");
  const std::string events = hgdtest::datasetsDir() + "/../docs/viewer_bunny_events.json";
  const hgdtest::CommandResult r =
      hgdtest::shell(viewer(hgdtest::datasetsDir() + "/bunny_1839.ply --replay " + events + " --screenshot " +
                            shot + " --size 900x650 --stats --quiet"));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(hgdtest::contains(r.out, "frames 21: solve ")) << r.out;
  const Image img = readPng(shot);
  EXPECT_EQ(img.width, 900);
  EXPECT_EQ(img.height, 650);
  EXPECT_FALSE(img.rgb.empty());
}

// DISPLAY names an X server that is not there: a clear error and exit 1, not VTK's abort.
// The CLI11 conventions of every tool: --version, and exit 2 for usage errors (no display needed).
TEST(Viewer, VersionAndUsageErrors) {
  std::string out;
  struct Tool {
    std::string path, name, args;  // args: enough for a run that would go on
  };
  for (const Tool& t :
       {Tool{HGD_VIEW, "hgdeform-view", " x.ply"}, Tool{HGD_RENDER, "hgdeform-render", " x.ply -o x.png"}}) {
    EXPECT_EQ(hgdtest::run(t.path + " --version", out), 0) << t.name;
    EXPECT_EQ(out.rfind(t.name + " ", 0), 0u) << out;
    EXPECT_EQ(hgdtest::run(t.path + t.args + " --bogus-option", out), 2) << t.name;
    EXPECT_NE(out.find("--bogus-option"), std::string::npos) << out;
    EXPECT_EQ(hgdtest::run(t.path, out), 2) << t.name << ": no input";
  }
  EXPECT_EQ(hgdtest::run(std::string(HGD_VIEW) + " x.ply --size 10x10", out), 2) << out;
  EXPECT_EQ(hgdtest::run(std::string(HGD_RENDER) + " x.ply -o x.png --view 0,0,0", out), 2) << out;
}

TEST(Viewer, AbsentXServerIsAClearError) {
  hgdtest::TempDir dir;
  hgd::writeShape(dir.file("bar.ply"), hgd::shapes::bar(1.0f, 0.1f, 0.05f));
  std::string out;
  for (const std::string& tool :
       {std::string(HGD_VIEW) + " " + dir.file("bar.ply"),
        std::string(HGD_RENDER) + " " + dir.file("bar.ply") + " -o " + dir.file("p.png")}) {
    EXPECT_EQ(hgdtest::run("DISPLAY=:4711 " + tool, out), 1) << tool;
    EXPECT_NE(out.find("cannot open the X display ':4711'"), std::string::npos) << out;
  }
  EXPECT_FALSE(hgdtest::exists(dir.file("p.png")));
}

}  // namespace
