// hgdeform-view driven as a user drives it: real X input events (XTEST, through xdotool) sent to
// its window on a private Xvfb, not replay files. Replays inject VTK events with the modifiers
// already decoded; these tests go through the X server, the keyboard map and the interactor, as
// a keyboard and a mouse do (issue 29). Skipped where Xvfb or xdotool is missing.
//
// HGD_VIEW_UNDER_TEST names another hgdeform-view to test (an older build, to show that a test
// fails without its fix).
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "hgdeform/io/geometry.h"
#include "hgdeform/io/io.h"
#include "support/png_image.h"
#include "support/shapes.h"
#include "test_util.h"

namespace {

using namespace std::chrono_literals;

/// HGD_X_SHOTS=DIR keeps the tests' pictures there (to look at them).
void keep(const std::string& png, const std::string& name) {
  const char* dir = std::getenv("HGD_X_SHOTS");
  if (dir && *dir && hgdtest::exists(png))
    std::filesystem::copy_file(png, std::string(dir) + "/" + name,
                               std::filesystem::copy_options::overwrite_existing);
}

std::string viewerBinary() {
  const char* other = std::getenv("HGD_VIEW_UNDER_TEST");
  return other && *other ? other : HGD_VIEW;
}

using hgdtest::Image;
using hgdtest::readPng;

bool differ(const Image& a, const Image& b, int x, int y) {
  const unsigned char *p = a.at(x, y), *q = b.at(x, y);
  return std::abs(p[0] - q[0]) + std::abs(p[1] - q[1]) + std::abs(p[2] - q[2]) > 30;
}

/// Pixels that differ between two pictures of one size in rows [y0, y1) (top-down).
int countDifferent(const Image& a, const Image& b, int y0, int y1) {
  if (a.width != b.width || a.height != b.height || a.rgb.empty()) return -1;
  int n = 0;
  for (int y = std::max(0, y0); y < std::min(a.height, y1); ++y)
    for (int x = 0; x < a.width; ++x) n += differ(a, b, x, y);
  return n;
}

bool haveTools() {
  std::string out;
  return hgdtest::run("command -v Xvfb && command -v xdotool", out) == 0;
}

/// A private Xvfb (with GLX) on a display number it chooses itself (-displayfd: tests running
/// at once never share a server), stopped by its pid when the object dies.
class Xvfb {
 public:
  Xvfb() {
    int fds[2];
    if (::pipe(fds) != 0) return;
    pid_ = ::fork();
    if (pid_ < 0) return;
    if (pid_ == 0) {
      ::close(fds[0]);
      std::freopen("/dev/null", "w", stdout);
      std::freopen("/dev/null", "w", stderr);
      const std::string fd = std::to_string(fds[1]);
      ::execlp("Xvfb", "Xvfb", "-displayfd", fd.c_str(), "-nolisten", "tcp", "-screen", "0", "1280x1024x24",
               static_cast<char*>(nullptr));
      ::_exit(127);
    }
    ::close(fds[1]);
    std::string number;
    char c = 0;
    while (::read(fds[0], &c, 1) == 1 && c != '\n') number += c;  // written once it accepts clients
    ::close(fds[0]);
    if (number.empty() || number.find_first_not_of("0123456789") != std::string::npos) {
      stop();
      return;
    }
    display_ = ":" + number;
  }
  ~Xvfb() { stop(); }
  Xvfb(const Xvfb&) = delete;
  Xvfb& operator=(const Xvfb&) = delete;
  const std::string& display() const { return display_; }

 private:
  void stop() {
    if (pid_ > 0) {
      ::kill(pid_, SIGTERM);
      ::waitpid(pid_, nullptr, 0);
    }
    pid_ = -1;
  }
  pid_t pid_ = -1;
  std::string display_;
};

/// hgdeform-view running on `x` with `args`, its stdout and stderr in `log`; xdotool commands
/// go to its window. The process is killed (by its pid) when the object dies.
class ViewerWindow {
 public:
  ViewerWindow(const Xvfb& x, const std::string& args, const std::string& log) : x_(x), log_(log) {
    const std::string command =
        "exec " + hgdtest::quote(viewerBinary()) + " " + args + " >" + hgdtest::quote(log) + " 2>&1";
    pid_ = ::fork();
    if (pid_ == 0) {
      ::setenv("DISPLAY", x.display().c_str(), 1);
      ::execl("/bin/sh", "sh", "-c", command.c_str(), static_cast<char*>(nullptr));
      ::_exit(127);
    }
    std::string out;
    // The title names the file: "bar.ply - hgdeform-view".
    if (xdo("search --sync --onlyvisible --name ' - hgdeform-view$'", out, 30) == 0 && !out.empty())
      window_ = out.substr(0, out.find('\n'));
    if (window_.empty()) return;
    xdo("getwindowgeometry --shell " + window_, out);
    width_ = std::atoi(out.substr(out.find("WIDTH=") + 6).c_str());
    height_ = std::atoi(out.substr(out.find("HEIGHT=") + 7).c_str());
    // Keys go where the keyboard focus is: on the window, the pointer over it (no window manager).
    xdo("mousemove --window " + window_ + " 5 5 windowfocus --sync " + window_, out);
  }
  ~ViewerWindow() {
    if (pid_ > 0) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
  }
  ViewerWindow(const ViewerWindow&) = delete;
  ViewerWindow& operator=(const ViewerWindow&) = delete;

  bool ok() const { return !window_.empty() && width_ > 0 && height_ > 0; }
  std::string title() const {
    std::string out;
    xdo("getwindowname " + window_, out);
    return out.substr(0, out.find('\n'));
  }
  /// The window's size now (asked each time: the viewer sets its size again after opening).
  int width() const { return geometry("WIDTH="); }
  int height() const { return geometry("HEIGHT="); }
  const std::string& window() const { return window_; }

  /// Runs `xdotool ARGS` on this display (at most `seconds`); returns its exit code.
  int xdo(const std::string& args, std::string& out, int seconds = 10) const {
    return hgdtest::run(
        "DISPLAY=" + x_.display() + " timeout " + std::to_string(seconds) + " xdotool " + args, out);
  }
  int xdo(const std::string& args) const {
    std::string out;
    return xdo(args, out);
  }
  /// Pointer actions (xdotool's mousemove, mousedown, ...), each run ending with a round trip
  /// to X (getmouselocation). Under load a drag was once seen to begin at the fourth motion's
  /// place instead of where the button went down; the cause is not pinned down (xdotool's
  /// XCloseDisplay syncs too, though a press goes through XTest's input queue and a move is a
  /// pointer warp), and the round trip makes sure X has handled one run's actions before the
  /// next run starts. Returns xdotool's exit code.
  int mouse(const std::string& actions, int seconds = 10) const {
    std::string out;
    return xdo(actions + " getmouselocation", out, seconds);
  }
  /// The pointer to (x, y), window pixels from its top left.
  void move(double x, double y) const { mouse(moveArgs(x, y)); }
  std::string moveArgs(double x, double y) const {
    return "mousemove --window " + window_ + " " + std::to_string(std::lround(x)) + " " +
           std::to_string(std::lround(y));
  }
  void press() const { mouse("mousedown 1"); }
  void release() const { mouse("mouseup 1"); }
  void key(const std::string& keys) const { xdo("key --delay 30 " + keys); }

  int geometry(const std::string& key) const {
    std::string out;
    xdo("getwindowgeometry --shell " + window_, out);
    const std::size_t at = out.find(key);
    return at == std::string::npos ? 0 : std::atoi(out.c_str() + at + key.size());
  }
  std::string log() const { return hgdtest::slurp(log_); }
  /// Waits (at most `seconds`) until the log holds `text` `count` times; returns whether it did.
  bool waitFor(const std::string& text, std::size_t count = 1, double seconds = 20) const {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    while (std::chrono::steady_clock::now() < end) {
      if (occurrences(log(), text) >= count) return true;
      std::this_thread::sleep_for(20ms);
    }
    return false;
  }
  /// The path named after the `n`-th (1-based) occurrence of `prefix` in the log, to the line's end.
  std::string named(const std::string& prefix, std::size_t n = 1) const {
    const std::string text = log();
    std::size_t p = std::string::npos, from = 0;
    for (std::size_t k = 0; k < n; ++k) {
      p = text.find(prefix, from);
      if (p == std::string::npos) return {};
      from = p + prefix.size();
    }
    const std::size_t end = text.find_first_of(" \n", from);
    return text.substr(from, end - from);
  }
  /// Whether the viewer still runs (waits up to `seconds` for it to end).
  bool alive(double seconds = 0) const {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    do {
      if (pid_ <= 0) return false;
      if (::waitpid(pid_, nullptr, WNOHANG) == pid_) {
        pid_ = -1;
        return false;
      }
      std::this_thread::sleep_for(20ms);
    } while (std::chrono::steady_clock::now() < end);
    return true;
  }
  /// Takes a screenshot with `k` and copies it to `to`; false if none came.
  bool shot(const std::string& to) const {
    const std::size_t n = occurrences(log(), "screenshot /") + 1;
    key("k");
    if (!waitFor("screenshot /", n)) return false;
    std::filesystem::copy_file(named("screenshot ", n), to,
                               std::filesystem::copy_options::overwrite_existing);
    return true;
  }

  static std::size_t occurrences(const std::string& text, const std::string& part) {
    std::size_t n = 0;
    for (auto p = text.find(part); p != std::string::npos; p = text.find(part, p + part.size())) ++n;
    return n;
  }

 private:
  const Xvfb& x_;
  std::string log_;
  mutable pid_t pid_ = -1;
  std::string window_;
  int width_ = 0, height_ = 0;
};

/// Where the viewer's opening view with `--view 0,0,1` draws a world point of a shape with +y up
/// (seen from +z, the camera 2.2 diagonals from the bounding box's centre, VTK's 30 degree view angle):
/// window pixels from the top left.
struct OpeningView {
  Eigen::Vector3d centre;
  double diagonal;
  Eigen::Vector2d at(const Eigen::Vector3d& w, int width, int height) const {
    const double depth = 2.2 * diagonal - (w.z() - centre.z());
    const double scale = 0.5 * height / (depth * std::tan(15.0 * M_PI / 180.0));
    return {0.5 * width + (w.x() - centre.x()) * scale, 0.5 * height - (w.y() - centre.y()) * scale};
  }
};

OpeningView openingView(const std::string& path) {
  const hgd::Geometry g = hgd::extractGeometry(hgd::readShape(path));
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(INFINITY), hi = -lo;
  for (std::size_t i = 0; i < g.size(); ++i) {
    lo = lo.cwiseMin(g.world(i));
    hi = hi.cwiseMax(g.world(i));
  }
  return {0.5 * (lo + hi), hgd::boundingBoxDiagonal(g)};
}

/// The bar (x from 0 to 1) in DIR/bar.ply with a scenario DIR/s.json: its left end fixed, its
/// right end the manipulated handle, no move.
void writeBar(hgdtest::TempDir& dir) {
  hgd::writeShape(dir.file("bar.ply"), hgd::shapes::bar(1.0f, 0.1f, 0.01f));
  hgdtest::writeText(dir.file("s.json"), R"({"format": "hgdeform-scenario/1",
    "fixed": [{"box": {"min": [-1, -1, -1], "max": [0.06, 1, 1]}}],
    "manipulated": {"box": {"min": [0.94, -1, -1], "max": [2, 1, 1]}}})");
}

/// The points of a shape file in the file's order (Geometry keeps them in Morton order, which
/// differs between a shape and its deformed copy).
std::vector<Eigen::Vector3d> filePoints(const std::string& path) {
  const hgd::Geometry g = hgd::extractGeometry(hgd::readShape(path));
  std::vector<Eigen::Vector3d> p(g.size());
  for (std::size_t i = 0; i < g.size(); ++i) p[static_cast<std::size_t>(g.raw_index[i])] = g.world(i);
  return p;
}

/// The viewer's arguments for writeBar's bar and scenario in an 800 x 600 window.
std::string barArgs(const hgdtest::TempDir& dir) {
  return hgdtest::quote(dir.file("bar.ply")) + " -s " + hgdtest::quote(dir.file("s.json")) +
         " --size 800x600 --view 0,0,1";
}

/// The corner of writeBar's bar that the drag tests press on, in the manipulated handle.
const Eigen::Vector3d kBarCorner(1.0, 0.0, 0.05);

/// Where world point `w` of the bar is on `v`'s screen in the opening view.
Eigen::Vector2d onScreen(const ViewerWindow& v, const hgdtest::TempDir& dir, const Eigen::Vector3d& w) {
  return openingView(dir.file("bar.ply")).at(w, v.width(), v.height());
}

double maxDistance(const std::string& a, const std::string& b) {
  const std::vector<Eigen::Vector3d> pa = filePoints(a), pb = filePoints(b);
  if (pa.size() != pb.size()) return INFINITY;
  double worst = 0;
  for (std::size_t i = 0; i < pa.size(); ++i) worst = std::max(worst, (pa[i] - pb[i]).norm());
  return worst;
}

/// Where the point of `rest` nearest `at` is in `shape` (the same points, moved).
Eigen::Vector3d whereIsPointNear(const std::string& rest, const std::string& shape,
                                 const Eigen::Vector3d& at) {
  const std::vector<Eigen::Vector3d> pr = filePoints(rest), ps = filePoints(shape);
  std::size_t best = 0;
  for (std::size_t i = 1; i < pr.size(); ++i)
    if ((pr[i] - at).norm() < (pr[best] - at).norm()) best = i;
  return best < ps.size() ? ps[best] : Eigen::Vector3d::Constant(NAN);
}

#define REQUIRE_X()                                                  \
  if (!haveTools()) GTEST_SKIP() << "Xvfb or xdotool not installed"; \
  const Xvfb x;                                                      \
  if (x.display().empty()) GTEST_SKIP() << "Xvfb did not start";

// Drag mode on and the button pressed at `from`, held.
::testing::AssertionResult startDrag(const ViewerWindow& v, const Eigen::Vector2d& from) {
  v.key("d");
  if (!v.waitFor("drag mode")) return ::testing::AssertionFailure() << "no drag mode\n" << v.log();
  v.move(from.x(), from.y());
  v.press();
  return ::testing::AssertionSuccess();
}

// startDrag, then the pointer glided to `to` in `steps` motions 30 ms apart; the button stays
// held.
::testing::AssertionResult holdDrag(const ViewerWindow& v, const Eigen::Vector2d& from,
                                    const Eigen::Vector2d& to, int steps) {
  if (::testing::AssertionResult started = startDrag(v, from); !started) return started;
  for (int k = 1; k <= steps; ++k) {
    const Eigen::Vector2d p = from + (to - from) * (static_cast<double>(k) / steps);
    v.move(p.x(), p.y());
    std::this_thread::sleep_for(30ms);
  }
  return ::testing::AssertionSuccess();
}

// Item 1: what you see is what you get. The far end of the bar dragged with the mouse and held
// still: a screenshot and a save (`k`, `s`) while the button is held, the button released, the
// same again. The release keeps exactly the last live frame: the pictures differ nowhere but in
// the status line, and the two saved shapes are the same point for point.
TEST(ViewerX, ReleaseKeepsWhatTheLastLiveFrameShowed) {
  REQUIRE_X();
  hgdtest::TempDir dir;
  writeBar(dir);
  const ViewerWindow v(x, barArgs(dir), dir.file("log.txt"));
  ASSERT_TRUE(v.ok()) << v.log();
  const Eigen::Vector2d from = onScreen(v, dir, kBarCorner), to = onScreen(v, dir, {0.75, 0.45, 0.05});
  ASSERT_TRUE(holdDrag(v, from, to, 12));
  std::this_thread::sleep_for(1500ms);  // held still
  v.key("k");
  ASSERT_TRUE(v.waitFor("screenshot ")) << v.log();
  const std::string held_png = v.named("screenshot ");
  std::filesystem::copy_file(held_png, dir.file("held.png"));
  v.key("s");
  ASSERT_TRUE(v.waitFor("saved ")) << v.log();
  std::filesystem::copy_file(v.named("saved "), dir.file("held.ply"));
  v.release();
  std::this_thread::sleep_for(500ms);
  v.key("k");
  ASSERT_TRUE(v.waitFor("screenshot ", 2)) << v.log();
  std::filesystem::copy_file(v.named("screenshot ", 2), dir.file("released.png"));
  v.key("s");
  ASSERT_TRUE(v.waitFor("saved ", 2)) << v.log();
  std::filesystem::copy_file(v.named("saved ", 2), dir.file("released.ply"));

  // The last live frame is the drag to where the cursor is held: the picked corner sits under
  // it (within 3 pixels at this view, 0.0065; the motions before the last were 0.04 apart).
  const Eigen::Vector3d corner = whereIsPointNear(dir.file("bar.ply"), dir.file("held.ply"), kBarCorner);
  EXPECT_LT((corner - Eigen::Vector3d(0.75, 0.45, 0.05)).norm(), 0.0065)
      << "the held frame shows the corner at " << corner.transpose() << "\n"
      << v.log();
  const double worst = maxDistance(dir.file("held.ply"), dir.file("released.ply"));
  std::printf("largest distance between the held and the released shape: %.3g\n", worst);
  EXPECT_LE(worst, 1e-6) << v.log();
  keep(dir.file("held.png"), "release-held.png");
  keep(dir.file("released.png"), "release-released.png");
  const Image held = readPng(dir.file("held.png")), released = readPng(dir.file("released.png"));
  ASSERT_FALSE(held.rgb.empty());
  // Everything above the status line (the bottom 40 rows: timings and messages).
  const int changed = countDifferent(held, released, 0, held.height - 40);
  std::printf("pixels that changed on release (above the status line): %d\n", changed);
  EXPECT_EQ(changed, 0);
}

}  // namespace

namespace {

// Item 2: capital keys from a keyboard. Shift+S saves the session as a scenario (not the shape),
// Shift+C clears the handles (not the selection), and Caps Lock makes `s` and `c` the same.
TEST(ViewerX, ShiftAndCapsLockGiveTheCapitalKeys) {
  REQUIRE_X();
  hgdtest::TempDir dir;
  writeBar(dir);
  const ViewerWindow v(x, hgdtest::quote(dir.file("bar.ply")) + " -s " + hgdtest::quote(dir.file("s.json")),
                       dir.file("log.txt"));
  ASSERT_TRUE(v.ok()) << v.log();
  v.key("shift+s");
  ASSERT_TRUE(v.waitFor("saved ")) << v.log();
  EXPECT_TRUE(hgdtest::contains(v.named("saved "), "scenario.json")) << v.log();
  EXPECT_FALSE(hgdtest::exists(dir.file("bar-deformed.ply")));
  v.key("Caps_Lock s Caps_Lock");
  ASSERT_TRUE(v.waitFor("saved ", 2)) << v.log();
  EXPECT_TRUE(hgdtest::contains(v.named("saved ", 2), "scenario")) << v.log();
  EXPECT_FALSE(hgdtest::exists(dir.file("bar-deformed.ply")));
  // With Caps Lock on, c is C, which clears every handle and move: the message says why, and
  // z brings them back (issue 49, defect 4: neither undo nor a warning could).
  v.key("Caps_Lock c Caps_Lock");
  ASSERT_TRUE(
      v.waitFor("handles cleared (z brings them back); Caps Lock is on: c clears the selection", 1, 5))
      << v.log();
  v.key("z");
  EXPECT_TRUE(v.waitFor("handles and moves back (undone)", 1, 10)) << v.log();
  v.key("s");  // Caps Lock is off again: the shape
  ASSERT_TRUE(v.waitFor("saved ", 3)) << v.log();
  EXPECT_TRUE(hgdtest::contains(v.named("saved ", 3), "deformed")) << v.log();
}

// Issue 49, defect 2: shift+click picks the point the user sees, not one behind the surface. A
// closed box seen from its front (+z) face, its back face sampled more densely than the front
// (so that a back point is often nearer the cursor on screen than any front one): five clicks
// between front points each select around a front point, and the message says where it is.
TEST(ViewerX, ShiftClickPicksTheFrontMostPoint) {
  REQUIRE_X();
  hgdtest::TempDir dir;
  std::vector<Eigen::Vector3f> box;
  auto face = [&](int n, float z) {
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) box.emplace_back(-0.5f + i / (n - 1.0f), -0.5f + j / (n - 1.0f), z);
  };
  face(41, 0.5f);    // front, 0.025 apart
  face(101, -0.5f);  // back, 0.01 apart
  for (int i = 0; i < 41; ++i)
    for (int k = 1; k < 40; ++k) {  // the four sides
      const float a = -0.5f + i / 40.0f, z = -0.5f + k / 40.0f;
      box.emplace_back(a, -0.5f, z);
      box.emplace_back(a, 0.5f, z);
      box.emplace_back(-0.5f, a, z);
      box.emplace_back(0.5f, a, z);
    }
  std::mt19937 rng(9);
  std::shuffle(box.begin(), box.end(), rng);  // random order, as scans come
  hgd::writeShape(dir.file("box.ply"), hgd::shapes::cloudShape(box, {}));
  const ViewerWindow v(x, hgdtest::quote(dir.file("box.ply")) + " --size 800x600 --view 0,0,1",
                       dir.file("log.txt"));
  ASSERT_TRUE(v.ok()) << v.log();
  const OpeningView view = openingView(dir.file("box.ply"));
  for (int k = 0; k < 5; ++k) {
    // Midway between front points (0.025 apart): about 4 pixels from the nearest ones.
    const Eigen::Vector2d at =
        view.at({-0.2 + 0.1 * k + 0.0125, 0.1 - 0.05 * k + 0.0125, 0.5}, v.width(), v.height());
    v.move(at.x(), at.y());
    v.xdo("keydown shift click 1 keyup shift");
    ASSERT_TRUE(v.waitFor("points around point", static_cast<std::size_t>(k + 1))) << v.log();
    const std::string said = v.named("points around point ", static_cast<std::size_t>(k + 1));
    const long index = std::atol(said.c_str());
    ASSERT_GE(index, 0);
    ASSERT_LT(static_cast<std::size_t>(index), box.size()) << said;
    EXPECT_EQ(box[static_cast<std::size_t>(index)].z(), 0.5f)
        << "click " << k << " picked point " << index << " at "
        << box[static_cast<std::size_t>(index)].transpose() << "\n"
        << v.log();
  }
}

// Issue 49, defect 6: a press on the handle and a release without motion moves nothing. The
// drag started from the handle's point nearest the cursor (up to 20 pixels away), so each such
// click pulled that point to the cursor. Three clicks 8 pixels off the bar's corner, then a save:
// the shape as it was. A drag after them still moves the corner by the pointer's motion.
TEST(ViewerX, AClickWithoutMotionMovesNothing) {
  REQUIRE_X();
  hgdtest::TempDir dir;
  writeBar(dir);
  const ViewerWindow v(x, barArgs(dir), dir.file("log.txt"));
  ASSERT_TRUE(v.ok()) << v.log();
  const Eigen::Vector2d corner = onScreen(v, dir, kBarCorner);
  const Eigen::Vector2d off = corner + Eigen::Vector2d(8, -8);
  ASSERT_TRUE(startDrag(v, off));
  v.release();
  for (int k = 0; k < 2; ++k) {
    v.press();
    std::this_thread::sleep_for(100ms);
    v.release();
  }
  std::this_thread::sleep_for(300ms);
  v.key("s");
  ASSERT_TRUE(v.waitFor("saved ")) << v.log();
  const double clicked = maxDistance(dir.file("bar.ply"), v.named("saved "));
  std::printf("largest motion after three clicks without motion: %.3g\n", clicked);
  EXPECT_EQ(clicked, 0.0) << v.log();
  // A drag from the same pixel by (+60, 0) pixels (still in drag mode): the corner moves right
  // by about as much.
  v.move(off.x(), off.y());
  v.press();
  for (int k = 1; k <= 6; ++k) {
    v.move(off.x() + 10 * k, off.y());
    std::this_thread::sleep_for(30ms);
  }
  std::this_thread::sleep_for(500ms);
  v.release();
  std::this_thread::sleep_for(300ms);
  v.key("s");
  ASSERT_TRUE(v.waitFor("saved ", 2)) << v.log();
  const Eigen::Vector3d moved = whereIsPointNear(dir.file("bar.ply"), v.named("saved ", 2), kBarCorner);
  const double per_pixel = (onScreen(v, dir, kBarCorner + Eigen::Vector3d(0.1, 0, 0)) - corner).x() / 0.1;
  EXPECT_NEAR(moved.x() - kBarCorner.x(), 60.0 / per_pixel, 4.0 / per_pixel) << moved.transpose() << v.log();
}

// Issue 49, defect 3: on a real keyboard < and > are Shift+comma and Shift+period. They change
// the point size in any mode; in frame mode they do not turn the handle as , and . do (VTK gives
// the unshifted character with the shift flag: only letters were shifted, so > arrived as . and
// turned the handle -5 degrees).
TEST(ViewerX, ShiftedPunctuationIsItsOwnKey) {
  REQUIRE_X();
  hgdtest::TempDir dir;
  writeBar(dir);
  const ViewerWindow v(x, hgdtest::quote(dir.file("bar.ply")) + " -s " + hgdtest::quote(dir.file("s.json")),
                       dir.file("log.txt"));
  ASSERT_TRUE(v.ok()) << v.log();
  v.key("shift+period");
  ASSERT_TRUE(v.waitFor("point size ")) << v.log();
  v.key("shift+comma");
  ASSERT_TRUE(v.waitFor("point size ", 2)) << v.log();
  v.key("t");
  ASSERT_TRUE(v.waitFor("frame mode")) << v.log();
  v.key("shift+period");
  // (in frame mode , and . turn the handle before any other binding is looked at: a > taken
  // as . never reaches the point size)
  ASSERT_TRUE(v.waitFor("point size ", 3)) << v.log();
}

}  // namespace

namespace {

/// Dark pixels (text: the overlays are drawn near-black; the shapes here are grey and coloured)
/// in the rectangle [x0, x1) x [y0, y1), rows counted from the top.
int darkPixels(const Image& img, int x0, int y0, int x1, int y1) {
  int n = 0;
  for (int y = std::max(0, y0); y < std::min(img.height, y1); ++y)
    for (int x = std::max(0, x0); x < std::min(img.width, x1); ++x) {
      const unsigned char* p = img.at(x, y);
      n += p[0] < 90 && p[1] < 90 && p[2] < 90;
    }
  return n;
}

/// Pixels that differ in the rectangle [x0, x1) x [y0, y1) (rows from the top).
int changedIn(const Image& a, const Image& b, int x0, int y0, int x1, int y1) {
  if (a.width != b.width || a.height != b.height || a.rgb.empty()) return -1;
  int n = 0;
  for (int y = std::max(0, y0); y < std::min(a.height, y1); ++y)
    for (int x = std::max(0, x0); x < std::min(a.width, x1); ++x) n += differ(a, b, x, y);
  return n;
}

// Item 5: the mode is shown at all times (the bottom-left corner of the status line changes
// with it and only with it), and shift+click picks in any mode: after an area selection made
// into a fixed handle, a shift+click in area mode (and in drag mode) selects points.
TEST(ViewerX, ModeIsShownAndShiftClickPicksInAnyMode) {
  REQUIRE_X();
  hgdtest::TempDir dir;
  writeBar(dir);
  const ViewerWindow v(x, hgdtest::quote(dir.file("bar.ply")) + " --size 800x600 --view 0,0,1",
                       dir.file("log.txt"));
  ASSERT_TRUE(v.ok()) << v.log();
  const OpeningView view = openingView(dir.file("bar.ply"));
  auto at = [&](double wx, double wy) { return view.at({wx, wy, 0.05}, v.width(), v.height()); };
  ASSERT_TRUE(v.shot(dir.file("pick.png")));
  v.key("x");
  ASSERT_TRUE(v.shot(dir.file("area.png")));
  // An area selection around the bar's left end, made with the mouse, becomes the fixed handle.
  const Eigen::Vector2d a = at(-0.05, 0.1), b = at(0.08, -0.1);
  v.move(a.x(), a.y());
  v.press();
  std::this_thread::sleep_for(100ms);
  v.move(0.5 * (a.x() + b.x()), 0.5 * (a.y() + b.y()));
  std::this_thread::sleep_for(100ms);
  v.move(b.x(), b.y());
  std::this_thread::sleep_for(100ms);
  v.release();
  ASSERT_TRUE(v.waitFor("selected ")) << v.log();
  EXPECT_FALSE(hgdtest::contains(v.log(), "selected 0 points")) << v.log();
  v.key("f");
  ASSERT_TRUE(v.waitFor("still needed")) << v.log();
  // Still in area mode: shift+click selects around the point under the cursor.
  const Eigen::Vector2d end = at(1.0, 0.0);
  v.move(end.x(), end.y());
  v.xdo("keydown shift click 1 keyup shift");
  ASSERT_TRUE(v.waitFor("points around point")) << v.log();
  EXPECT_FALSE(hgdtest::contains(v.log(), "selected 0 points around")) << v.log();
  v.key("m");
  ASSERT_TRUE(v.waitFor("handles: 1 fixed")) << v.log();
  v.key("d");
  ASSERT_TRUE(v.shot(dir.file("drag.png")));
  v.move(end.x(), end.y() + 5);  // drag mode: shift+click still picks (no drag begins)
  v.xdo("keydown shift click 1 keyup shift");
  ASSERT_TRUE(v.waitFor("points around point", 2)) << v.log();
  v.key("t");
  ASSERT_TRUE(v.shot(dir.file("frame.png")));
  v.key("t");
  ASSERT_TRUE(v.shot(dir.file("pick2.png")));
  keep(dir.file("area.png"), "mode-area.png");
  keep(dir.file("drag.png"), "mode-drag.png");
  const Image pick = readPng(dir.file("pick.png")), area = readPng(dir.file("area.png")),
              drag = readPng(dir.file("drag.png")), frame = readPng(dir.file("frame.png")),
              pick2 = readPng(dir.file("pick2.png"));
  ASSERT_FALSE(pick.rgb.empty());
  // The mode's label: the status line's first 70 pixels, its bottom 30 rows.
  auto label = [&](const Image& p, const Image& q) {
    return changedIn(p, q, 0, p.height - 30, 70, p.height);
  };
  EXPECT_GT(label(pick, area), 20);
  EXPECT_GT(label(area, drag), 20);
  EXPECT_GT(label(drag, frame), 20);
  EXPECT_GT(label(frame, pick2), 20);
  EXPECT_EQ(label(pick, pick2), 0);
}

// Item 3: `s` never replaces an earlier result: INPUT-deformed.ply, INPUT-deformed-2.ply, ...,
// each named in the status line (and on stderr); the same for `S` and `k`.
TEST(ViewerX, SavesAreNumberedNotReplaced) {
  REQUIRE_X();
  hgdtest::TempDir dir;
  writeBar(dir);
  const ViewerWindow v(x, hgdtest::quote(dir.file("bar.ply")) + " -s " + hgdtest::quote(dir.file("s.json")),
                       dir.file("log.txt"));
  ASSERT_TRUE(v.ok()) << v.log();
  v.key("s s s shift+s shift+s k k");
  ASSERT_TRUE(v.waitFor("screenshot /", 2)) << v.log();
  EXPECT_EQ(v.named("saved ", 1), dir.file("bar-deformed.ply")) << v.log();
  EXPECT_EQ(v.named("saved ", 2), dir.file("bar-deformed-2.ply")) << v.log();
  EXPECT_EQ(v.named("saved ", 3), dir.file("bar-deformed-3.ply")) << v.log();
  EXPECT_EQ(v.named("saved ", 4), dir.file("bar-scenario.json")) << v.log();
  EXPECT_EQ(v.named("saved ", 5), dir.file("bar-scenario-2.json")) << v.log();
  EXPECT_EQ(v.named("screenshot ", 2), dir.file("bar-screenshot-2.png")) << v.log();
  for (const char* f : {"bar-deformed.ply", "bar-deformed-2.ply", "bar-deformed-3.ply", "bar-scenario.json",
                        "bar-scenario-2.json", "bar-screenshot.png", "bar-screenshot-2.png"})
    EXPECT_TRUE(hgdtest::exists(dir.file(f))) << f;
}

// Item 4: with unsaved changes, `q` and `e` ask first (the status line says to press again);
// pressed again they quit. Without changes `q` quits at once. PCL's keys that make no sense
// here (g: a grid, w: a wireframe) do nothing.
TEST(ViewerX, QuitAsksWithUnsavedChangesAndPclKeysAreOff) {
  REQUIRE_X();
  hgdtest::TempDir dir;
  writeBar(dir);
  const std::string args = barArgs(dir);
  {
    const ViewerWindow v(x, args, dir.file("log1.txt"));
    ASSERT_TRUE(v.ok()) << v.log();
    ASSERT_TRUE(v.shot(dir.file("a.png")));
    v.key("g w");
    ASSERT_TRUE(v.shot(dir.file("b.png")));
    const Image a = readPng(dir.file("a.png")), b = readPng(dir.file("b.png"));
    ASSERT_FALSE(a.rgb.empty());
    // Above the status line, nothing changed.
    EXPECT_EQ(countDifferent(a, b, 0, a.height - 40), 0);
    EXPECT_EQ(v.title(), "bar.ply - hgdeform-view");  // issue 49, defect 11: the title names the file
    v.key("t Right");                                 // a frame move: an unsaved change
    ASSERT_TRUE(v.waitFor("frame mode")) << v.log();
    v.key("e");
    ASSERT_TRUE(v.waitFor("press e again")) << v.log();
    EXPECT_TRUE(hgdtest::contains(v.log(), "(s saves the shape, S the session)")) << v.log();
    EXPECT_TRUE(v.alive(1.0));
    v.key("c q");  // another key in between: asks again
    ASSERT_TRUE(v.waitFor("press q again")) << v.log();
    EXPECT_TRUE(v.alive(1.0));
    v.key("q");
    EXPECT_FALSE(v.alive(10)) << v.log();
  }
  {
    const ViewerWindow v(x, args, dir.file("log2.txt"));
    ASSERT_TRUE(v.ok()) << v.log();
    v.key("t Right s q");  // saved: quits at once
    EXPECT_FALSE(v.alive(10)) << v.log();
    EXPECT_FALSE(hgdtest::contains(v.log(), "press q again")) << v.log();
  }
  {
    // Only the handles unsaved (the scenario's handles cleared: no move): S is what saves them.
    const ViewerWindow v(x, args, dir.file("log3.txt"));
    ASSERT_TRUE(v.ok()) << v.log();
    v.key("shift+c");
    ASSERT_TRUE(v.waitFor("handles cleared")) << v.log();
    v.key("q");
    ASSERT_TRUE(v.waitFor("press q again")) << v.log();
    EXPECT_TRUE(hgdtest::contains(v.log(), "(S saves the handles as a scenario)")) << v.log();
  }
}

// Item 10: the help stays at the window's top and the status line at its bottom when the
// window is resized; `h` hides and shows the help again; a status line with warnings wraps
// instead of running off the window's right edge.
TEST(ViewerX, OverlaysFollowTheWindowAndTheStatusLineWraps) {
  REQUIRE_X();
  hgdtest::TempDir dir;
  hgd::writeShape(dir.file("bar.ply"), hgd::shapes::barBesideABox());
  hgdtest::writeText(dir.file("s.json"), R"({
    "fixed": [ { "box": { "min": [-1, -1, -1], "max": [0.5, 0.3, 1] } } ],
    "manipulated": { "box": { "min": [0.5001, -1, -1], "max": [2, 0.3, 1] } },
    "move": { "frame": { "translate": [0, 0.3, 0] } }
  })");
  const ViewerWindow v(x, barArgs(dir), dir.file("log.txt"));
  ASSERT_TRUE(v.ok()) << v.log();
  ASSERT_TRUE(v.shot(dir.file("opening.png")));  // the viewer is in its event loop
  std::string out;
  v.xdo("windowsize --sync " + v.window() + " 640 420", out);
  std::this_thread::sleep_for(300ms);
  ASSERT_TRUE(v.shot(dir.file("small.png")));
  v.xdo("windowsize --sync " + v.window() + " 1000 900", out);
  std::this_thread::sleep_for(300ms);
  ASSERT_TRUE(v.shot(dir.file("large.png")));
  v.key("h");
  ASSERT_TRUE(v.shot(dir.file("nohelp.png")));
  v.key("h");
  ASSERT_TRUE(v.shot(dir.file("help.png")));
  keep(dir.file("small.png"), "overlays-small.png");
  keep(dir.file("large.png"), "overlays-large.png");
  const Image small = readPng(dir.file("small.png")), large = readPng(dir.file("large.png")),
              nohelp = readPng(dir.file("nohelp.png")), help = readPng(dir.file("help.png"));
  ASSERT_EQ(small.width, 640);
  ASSERT_EQ(large.height, 900);
  // The help's five lines in the top 90 rows, whatever the height.
  EXPECT_GT(darkPixels(small, 0, 0, small.width, 90), 400);
  EXPECT_GT(darkPixels(large, 0, 0, large.width, 90), 400);
  EXPECT_LT(darkPixels(nohelp, 0, 0, nohelp.width, 90), 20);
  EXPECT_GT(darkPixels(help, 0, 0, help.width, 90), 400);
  // The status line (warnings: pieces apart, a surface pulled apart) at the bottom, within the
  // window: nothing dark in the last 12 columns.
  EXPECT_GT(darkPixels(small, 0, small.height - 20, small.width, small.height), 100);
  EXPECT_EQ(darkPixels(small, small.width - 12, small.height - 120, small.width, small.height), 0);
}

}  // namespace

namespace {

// Item 9: `r` returns to the opening view after the mouse turned it (PCL's `r` kept the turn).
TEST(ViewerX, RReturnsToTheOpeningView) {
  REQUIRE_X();
  hgdtest::TempDir dir;
  writeBar(dir);
  const ViewerWindow v(x, hgdtest::quote(dir.file("bar.ply")) + " --size 800x600", dir.file("log.txt"));
  ASSERT_TRUE(v.ok()) << v.log();
  ASSERT_TRUE(v.shot(dir.file("opening.png")));
  v.move(400, 300);
  v.press();
  for (int k = 1; k <= 8; ++k) v.move(400 + 20 * k, 300 + 12 * k);
  v.release();
  ASSERT_TRUE(v.shot(dir.file("turned.png")));
  v.key("r");
  ASSERT_TRUE(v.shot(dir.file("back.png")));
  const Image opening = readPng(dir.file("opening.png")), turned = readPng(dir.file("turned.png")),
              back = readPng(dir.file("back.png"));
  ASSERT_FALSE(opening.rgb.empty());
  EXPECT_GT(countDifferent(opening, turned, 0, opening.height - 40), 500);
  EXPECT_EQ(countDifferent(opening, back, 0, opening.height - 40), 0);
}

}  // namespace

namespace {

/// A bumpy square of side x side points in PATH (binary PLY).
void writePlane(const std::string& path, int side) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  ASSERT_NE(f, nullptr);
  std::fprintf(f,
               "ply\nformat binary_little_endian 1.0\nelement vertex %d\nproperty float x\nproperty float "
               "y\nproperty float z\nend_header\n",
               side * side);
  for (int i = 0; i < side; ++i)
    for (int j = 0; j < side; ++j) {
      const float x = static_cast<float>(i) / static_cast<float>(side - 1),
                  y = static_cast<float>(j) / static_cast<float>(side - 1);
      const float p[3] = {x, y, 0.03f * std::sin(20 * x) * std::cos(15 * y)};
      std::fwrite(p, sizeof p, 1, f);
    }
  std::fclose(f);
}

// Item 11: marking the handles of a large cloud builds the deformer off the GUI thread: while it
// builds, the status line says so, the view turns with the mouse and a screenshot is taken,
// all before the build ends (the old viewer froze: the screenshot came after the build).
TEST(ViewerX, DeformerBuildsWhileTheWindowResponds) {
  REQUIRE_X();
  hgdtest::TempDir dir;
  writePlane(dir.file("plane.ply"), 1000);  // 1,000,000 points
  // At full resolution: a build of seconds (on its coarse level it would end in a fraction of
  // one, before the screenshot could show anything about it). 490,000 points built in 1.5 s
  // once under CI's load, and the turn's pointer actions outlasted it: 1,000,000 take 3.2-4.4 s
  // here, and the turn is three motions (each waits for its pointer round trip), not six.
  const ViewerWindow v(x, hgdtest::quote(dir.file("plane.ply")) + " --size 640x480 --full-field --view 0,0,1",
                       dir.file("log.txt"));
  ASSERT_TRUE(v.ok()) << v.log();
  const OpeningView view = openingView(dir.file("plane.ply"));
  auto at = [&](double wx, double wy) { return view.at({wx, wy, 0.0}, v.width(), v.height()); };
  auto band = [&](double x0, double x1) {
    const Eigen::Vector2d a = at(x0, 1.05), b = at(x1, -0.05);
    v.move(a.x(), a.y());
    v.press();
    v.move(0.5 * (a.x() + b.x()), 0.5 * (a.y() + b.y()));
    v.move(b.x(), b.y());
    v.release();
  };
  ASSERT_TRUE(v.shot(dir.file("before.png")));
  v.key("x");
  band(-0.05, 0.1);
  ASSERT_TRUE(v.waitFor("selected ", 1, 60)) << v.log();
  v.key("f");
  ASSERT_TRUE(v.waitFor("still needed", 1, 60)) << v.log();
  band(0.9, 1.05);
  ASSERT_TRUE(v.waitFor("selected ", 2, 60)) << v.log();
  v.key("m x");  // the build starts; back to pick mode: the mouse turns the view
  v.move(320, 240);
  v.press();
  for (int k = 1; k <= 3; ++k) v.move(320 + 50 * k, 240 + 20 * k);
  v.release();
  ASSERT_TRUE(v.shot(dir.file("during.png")));
  v.key("s");  // issue 49, defect 7: waits for the build, then runs (it was dropped)
  ASSERT_TRUE(v.waitFor("handles: 1 fixed", 1, 300)) << v.log();
  ASSERT_TRUE(v.waitFor("saved ", 1, 60)) << v.log();
  const std::string log = v.log();
  std::printf("%s", log.c_str());
  const std::size_t building = log.find("building the deformer"),
                    shot = log.find("screenshot /", log.find("still needed")),
                    built = log.find("handles: 1 fixed");
  ASSERT_NE(shot, std::string::npos) << log;
  EXPECT_LT(shot, built) << "the screenshot waited for the build";
  EXPECT_NE(building, std::string::npos) << "the status line did not say that the deformer builds";
  EXPECT_LT(building, shot);
  const std::size_t waits = log.find("s runs when it is done"), saved = log.find("saved ");
  EXPECT_LT(waits, built) << "s did not wait for the build";
  EXPECT_LT(built, saved) << "s did not run after the build";
  const Image before = readPng(dir.file("before.png")), during = readPng(dir.file("during.png"));
  ASSERT_FALSE(before.rgb.empty());
  EXPECT_GT(countDifferent(before, during, 90, before.height - 60), 2000) << "the view did not turn";
  keep(dir.file("during.png"), "building.png");
}

}  // namespace

namespace {

// Item 1, the warnings: a drag that pulls the surface apart says so while the button is held
// (on the frame shown), not only after the release. The bar's handles touch at x = 0.5; its far
// end is lifted with the mouse and held; a screenshot taken while held comes after the warning.
TEST(ViewerX, SurfacePulledApartIsSaidWhileTheDragIsHeld) {
  REQUIRE_X();
  hgdtest::TempDir dir;
  hgd::writeShape(dir.file("bar.ply"), hgd::shapes::barBesideABox());
  hgdtest::writeText(dir.file("s.json"), R"({
    "fixed": [ { "box": { "min": [-1, -1, -1], "max": [0.5, 0.3, 1] } } ],
    "manipulated": { "box": { "min": [0.5001, -1, -1], "max": [2, 0.3, 1] } } })");
  const ViewerWindow v(x, barArgs(dir), dir.file("log.txt"));
  ASSERT_TRUE(v.ok()) << v.log();
  const Eigen::Vector2d from = onScreen(v, dir, kBarCorner), to = onScreen(v, dir, {1.0, 0.35, 0.05});
  ASSERT_TRUE(holdDrag(v, from, to, 6));
  std::this_thread::sleep_for(500ms);
  v.key("k");
  ASSERT_TRUE(v.waitFor("screenshot ")) << v.log();
  v.release();
  const std::string log = v.log();
  const std::size_t warned = log.find("pulled apart"), shot = log.find("screenshot ");
  EXPECT_NE(warned, std::string::npos) << log;
  EXPECT_LT(warned, shot) << "the warning came only after the release\n" << log;
}

}  // namespace

// Keys that would change the handles or the shape under a held drag (C clears the handles, n
// resets, f marks one) wait for the release: before, C mid-drag removed the deformer and the
// next pointer motion ended the viewer with an exception, losing the session.
TEST(ViewerX, HandleKeysWaitWhileTheDragIsHeld) {
  REQUIRE_X();
  hgdtest::TempDir dir;
  writeBar(dir);
  const ViewerWindow v(x, barArgs(dir), dir.file("log.txt"));
  ASSERT_TRUE(v.ok()) << v.log();
  const Eigen::Vector2d from = onScreen(v, dir, kBarCorner), to = onScreen(v, dir, {0.75, 0.45, 0.05});
  ASSERT_TRUE(holdDrag(v, from, (from + to) / 2, 1));
  std::this_thread::sleep_for(300ms);
  v.key("shift+c n");
  ASSERT_TRUE(v.waitFor("release the mouse button first", 2)) << v.log();
  v.move(to.x(), to.y());
  std::this_thread::sleep_for(300ms);
  v.release();
  std::this_thread::sleep_for(300ms);
  ASSERT_TRUE(v.alive()) << v.log();
  v.key("s");
  ASSERT_TRUE(v.waitFor("saved ")) << v.log();
  EXPECT_FALSE(hgdtest::contains(v.log(), "handles cleared")) << v.log();
  // The drag was kept: the bar's far end moved about as far as the cursor.
  EXPECT_GT(maxDistance(dir.file("bar.ply"), v.named("saved ")), 0.3) << v.log();
}

// A pointer that moves faster than the live frames are solved and drawn: the motions that come
// in the meantime are not drawn one by one, but the frame shown once the pointer stops is the
// one for where it stopped. Before, the viewer took the waiting motion events off X's queue
// itself; X sends one motion (a hint) until the window asks where the pointer is, so after such
// a burst no motion came again until the release: the shape stayed where the first frames left
// it while the button was held, and jumped on release.
TEST(ViewerX, TheHeldFrameIsWhereAFastPointerStopped) {
  REQUIRE_X();
  hgdtest::TempDir dir;
  writeBar(dir);
  const ViewerWindow v(x, barArgs(dir), dir.file("log.txt"));
  ASSERT_TRUE(v.ok()) << v.log();
  const Eigen::Vector3d target(0.75, 0.45, 0.05);
  const Eigen::Vector2d from = onScreen(v, dir, kBarCorner), to = onScreen(v, dir, target);
  ASSERT_TRUE(startDrag(v, from));
  // 500 motions in one xdotool run, 2 ms apart: quicker than the frames.
  std::string burst;
  for (int k = 1; k <= 500; ++k) {
    const Eigen::Vector2d p = from + (to - from) * (k / 500.0);
    burst += v.moveArgs(p.x(), p.y()) + " sleep 0.002 ";
  }
  int burst_exit = -1;
  {
    // Busy cores beside the viewer (as a build or a second program makes them): the viewer is
    // then often paused between taking a motion and drawing its frame.
    std::atomic<bool> stop{false};
    std::vector<std::thread> busy;
    for (int t = 0; t < 3; ++t)
      busy.emplace_back([&stop] {
        volatile unsigned long spin = 0;
        while (!stop.load(std::memory_order_relaxed)) spin = spin + 1;
      });
    burst_exit = v.mouse(burst, 120);
    stop = true;
    for (std::thread& t : busy) t.join();
  }
  ASSERT_EQ(burst_exit, 0) << "xdotool did not finish the motions";
  std::this_thread::sleep_for(1500ms);  // held still
  v.key("s");
  ASSERT_TRUE(v.waitFor("saved ")) << v.log();
  const Eigen::Vector3d held = whereIsPointNear(dir.file("bar.ply"), v.named("saved "), kBarCorner);
  v.release();
  // Within 3 pixels of the cursor at this view (0.0065, 1.3% of the way; the motions were 0.001
  // apart): a frame left behind before the last 1.3% of the way fails.
  EXPECT_LT((held - target).norm(), 0.0065)
      << "the held frame shows the corner at " << held.transpose() << "\n"
      << v.log();
}

namespace {

/// `s` turned by `r`: its x, y, z (and normals, by any of PCL's and PLY's names), float fields.
hgd::Shape turned(hgd::Shape s, const Eigen::Matrix3f& r) {
  const auto offset = [&](std::initializer_list<const char*> names) -> long {
    for (const auto& f : s.cloud.fields)
      for (const char* n : names)
        if (f.name == n && f.datatype == pcl::PCLPointField::FLOAT32) return static_cast<long>(f.offset);
    return -1;
  };
  const long triples[2][3] = {
      {offset({"x"}), offset({"y"}), offset({"z"})},
      {offset({"nx", "normal_x"}), offset({"ny", "normal_y"}), offset({"nz", "normal_z"})}};
  for (std::size_t i = 0; i < s.size(); ++i) {
    std::uint8_t* p = s.cloud.data.data() + i * s.cloud.point_step;
    for (const auto& t : triples) {
      if (t[0] < 0 || t[1] < 0 || t[2] < 0) continue;
      Eigen::Vector3f v;
      for (int k = 0; k < 3; ++k) std::memcpy(&v[k], p + t[k], 4);
      v = r * v;
      for (int k = 0; k < 3; ++k) std::memcpy(p + t[k], &v[k], 4);
    }
  }
  return s;
}

/// A depth camera's scan in PCL's frame (+z forward, +y down): a bumpy wall 2 m ahead, 64 x 48
/// pixels, its corners missing (NaN) as a real sensor's are; organized or not.
hgd::Shape cameraScan(bool organized) {
  std::vector<Eigen::Vector3f> points;
  for (int v = 0; v < 48; ++v)
    for (int u = 0; u < 64; ++u) {
      const float z = 2.0f + 0.08f * std::sin(0.2f * u) * std::cos(0.25f * v);
      const bool corner = (u < 6 || u > 57) && (v < 6 || v > 41);
      points.push_back(corner ? Eigen::Vector3f::Constant(NAN)
                              : Eigen::Vector3f((u - 31.5f) / 60.0f * z, (v - 23.5f) / 60.0f * z, z));
    }
  hgd::Shape s = hgd::shapes::cloudShape(points, {});
  s.cloud.is_dense = false;
  if (organized) {
    s.cloud.width = 64;
    s.cloud.height = 48;
    s.cloud.row_step = s.cloud.point_step * s.cloud.width;
  }
  s.format = hgd::FileFormat::Pcd;
  return s;
}

/// What a picture shows of a shape on the white background, above the status line (the last
/// `bottom` rows): the drawn pixels (any channel under 235), their bounding box.
struct Coverage {
  int count = 0, x0 = 1 << 30, y0 = 1 << 30, x1 = -1, y1 = -1;
  double width() const { return x1 >= x0 ? x1 - x0 + 1 : 0; }
  double height() const { return y1 >= y0 ? y1 - y0 + 1 : 0; }
};

Coverage coverage(const Image& img, int bottom = 40) {
  Coverage c;
  for (int y = 0; y < img.height - bottom; ++y)
    for (int x = 0; x < img.width; ++x) {
      const unsigned char* p = img.at(x, y);
      if (p[0] >= 235 && p[1] >= 235 && p[2] >= 235) continue;
      ++c.count;
      c.x0 = std::min(c.x0, x);
      c.x1 = std::max(c.x1, x);
      c.y0 = std::min(c.y0, y);
      c.y1 = std::max(c.y1, y);
    }
  return c;
}

/// A right-button drag from `a` to `b` (CloudCompare's pan).
void rightDrag(const ViewerWindow& v, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  v.move(a.x(), a.y());
  v.mouse("mousedown 3");
  for (int k = 1; k <= 6; ++k) {
    const Eigen::Vector2d p = a + (b - a) * (k / 6.0);
    v.move(p.x(), p.y());
  }
  v.mouse("mouseup 3");
}

// Issue 49, defect 5 and "done when": every shape the project has opens in view, whichever axis
// is up: the bunny, the Armadillo (where ../shared has it), a quadruped, a depth camera's scan
// organized and not, and a plane, each turned so that +x, +y, +z and -y are up. The opening
// picture (help and axes hidden) shows the shape across a good part of the window, near its
// middle; a right-button drag (the pan) moves it mostly off the window; `r` brings the opening
// picture back.
TEST(ViewerX, EveryShapeOpensInViewAndRFindsItAgain) {
  REQUIRE_X();
  hgdtest::TempDir dir;
  struct Input {
    std::string name;
    hgd::Shape shape;
    Eigen::Vector3f up;  // its own up
  };
  std::vector<Input> inputs;
  inputs.push_back(
      {"bunny.ply", hgd::readShape(hgdtest::datasetsDir() + "/bunny_1839.ply"), Eigen::Vector3f::UnitY()});
  const std::string armadillo = hgdtest::sharedDatasetsDir() + "/meshes/armadillo_49990.ply";
  if (hgdtest::exists(armadillo))
    inputs.push_back({"armadillo.ply", hgd::readShape(armadillo), Eigen::Vector3f::UnitY()});
  inputs.push_back({"quadruped.ply", hgd::shapes::quadruped(), Eigen::Vector3f::UnitY()});
  inputs.push_back({"organized.pcd", cameraScan(true), -Eigen::Vector3f::UnitY()});
  inputs.push_back({"unorganized.pcd", cameraScan(false), -Eigen::Vector3f::UnitY()});
  inputs.push_back({"plane.ply", hgd::shapes::bumpyPlane(), Eigen::Vector3f::UnitY()});
  const std::pair<const char*, Eigen::Vector3f> ups[4] = {{"+x", Eigen::Vector3f::UnitX()},
                                                          {"+y", Eigen::Vector3f::UnitY()},
                                                          {"+z", Eigen::Vector3f::UnitZ()},
                                                          {"-y", -Eigen::Vector3f::UnitY()}};
  for (const Input& in : inputs)
    for (const auto& [up_name, up] : ups) {
      SCOPED_TRACE(in.name + " turned " + up_name + " up");
      const Eigen::Matrix3f r = Eigen::Quaternionf::FromTwoVectors(in.up, up).toRotationMatrix();
      const std::string file = dir.file(std::string(up_name) + in.name);
      hgd::Shape s = turned(in.shape, r);
      s.path.clear();
      hgd::writeShape(file, s);
      const ViewerWindow v(x, hgdtest::quote(file) + " --size 480x360", dir.file("log.txt"));
      ASSERT_TRUE(v.ok()) << v.log();
      v.key("h a");
      ASSERT_TRUE(v.waitFor("axes hidden")) << v.log();
      const std::string tag = std::string(up_name[0] == '+' ? "p" : "m") + (up_name + 1) + in.name;
      ASSERT_TRUE(v.shot(dir.file("open.png")));
      keep(dir.file("open.png"), "open-" + tag + ".png");
      const Image opening = readPng(dir.file("open.png"));
      ASSERT_FALSE(opening.rgb.empty());
      const int w = opening.width, h = opening.height;
      const Coverage c = coverage(opening);
      std::printf("%s turned %s up: %d pixels drawn, %.0f x %.0f of %d x %d\n", in.name.c_str(), up_name,
                  c.count, c.width(), c.height(), w, h - 40);
      EXPECT_GT(c.count, w * h / 60) << "hardly anything drawn";
      EXPECT_GT(std::max(c.width() / w, c.height() / (h - 40)), 0.4) << "the shape is small in the window";
      const double cx = 0.5 * (c.x0 + c.x1), cy = 0.5 * (c.y0 + c.y1);
      EXPECT_NEAR(cx, 0.5 * w, 0.2 * w);
      EXPECT_NEAR(cy, 0.5 * (h - 40), 0.2 * (h - 40));
      rightDrag(v, {0.2 * w, 0.2 * h}, {0.95 * w, 0.9 * h});
      ASSERT_TRUE(v.shot(dir.file("moved.png")));
      const Coverage moved = coverage(readPng(dir.file("moved.png")));
      EXPECT_LT(moved.count, c.count / 2) << "the right button did not pan the shape off";
      v.key("r");
      ASSERT_TRUE(v.waitFor("the whole shape in view")) << v.log();
      ASSERT_TRUE(v.shot(dir.file("back.png")));
      keep(dir.file("back.png"), "back-" + tag + ".png");
      const Image back = readPng(dir.file("back.png"));
      EXPECT_LE(countDifferent(opening, back, 0, h - 40), w * h / 200)
          << "r did not bring the opening view back";
    }
}

}  // namespace

namespace {

/// Whether `p` is inside the polygon `loop` (even-odd rule).
bool insidePolygon(const std::vector<Eigen::Vector2d>& loop, const Eigen::Vector2d& p) {
  bool inside = false;
  for (std::size_t a = 0, b = loop.size() - 1; a < loop.size(); b = a++)
    if ((loop[a].y() > p.y()) != (loop[b].y() > p.y()) &&
        p.x() <
            (loop[b].x() - loop[a].x()) * (p.y() - loop[a].y()) / (loop[b].y() - loop[a].y()) + loop[a].x())
      inside = !inside;
  return inside;
}

/// The number `prefix` is followed by in the `n`-th line of the log that holds it.
long numberAfter(const ViewerWindow& v, const std::string& prefix, std::size_t n = 1) {
  const std::string s = v.named(prefix, n);
  return s.empty() ? -1 : std::atol(s.c_str());
}

// A loop drawn with the left button from `corners[0]` round the others and back, as a hand
// draws it: along each side in steps of about 15 pixels, and a stop at each corner long enough
// for the window to take it (X sends the motions of a drag as hints, answered with where the
// pointer is when the window asks: a corner passed quickly could be cut).
void drawLoop(const ViewerWindow& v, const std::vector<Eigen::Vector2d>& corners, bool ctrl) {
  v.move(corners[0].x(), corners[0].y());
  if (ctrl) v.xdo("keydown ctrl");
  v.press();
  // A motion of a pixel first: the first motion after a press reaches the window as a hint of
  // motion that is not always answered with the pointer's place (the lasso's first corner was
  // lost); a hand on a mouse sends many.
  v.move(corners[0].x() + 1, corners[0].y());
  std::this_thread::sleep_for(60ms);
  for (std::size_t k = 1; k <= corners.size(); ++k) {
    const Eigen::Vector2d &a = corners[k - 1], &b = corners[k % corners.size()];
    const int steps = std::max(1, static_cast<int>((b - a).norm() / 15));
    for (int j = 1; j <= steps; ++j) {
      const Eigen::Vector2d p = a + (b - a) * (static_cast<double>(j) / steps);
      v.move(p.x(), p.y());
    }
    std::this_thread::sleep_for(150ms);
  }
  v.release();
  if (ctrl) v.xdo("keyup ctrl");
}

// The lasso (`p`, as CloudCompare's segmentation and MeshLab's polygon selection): a loop drawn
// round the bar's right end selects the points whose projections fall inside it, near side and
// far (as the area selection does); drawn with ctrl held round a part of them, it deselects
// those. The counts are those of the bar's points projected by the opening view, give or take
// the points within 2 pixels of the loop.
TEST(ViewerX, LassoSelectsInsideAndCtrlDeselects) {
  REQUIRE_X();
  hgdtest::TempDir dir;
  writeBar(dir);
  const ViewerWindow v(x, barArgs(dir), dir.file("log.txt"));
  ASSERT_TRUE(v.ok()) << v.log();
  v.key("p");
  ASSERT_TRUE(v.waitFor("lasso mode")) << v.log();
  const std::vector<Eigen::Vector3d> points = filePoints(dir.file("bar.ply"));
  const OpeningView view = openingView(dir.file("bar.ply"));
  std::vector<Eigen::Vector2d> screen;  // where the opening view draws each point
  const int width = v.width(), height = v.height();
  for (const Eigen::Vector3d& p : points) screen.push_back(view.at(p, width, height));
  const auto expected = [&](const std::vector<Eigen::Vector2d>& loop, const std::vector<char>* within,
                            std::size_t& near_edge) {
    std::size_t n = 0;
    near_edge = 0;
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (within && !(*within)[i]) continue;
      const Eigen::Vector2d& s = screen[i];
      n += insidePolygon(loop, s);
      double edge = INFINITY;
      for (std::size_t a = 0; a < loop.size(); ++a) {
        const Eigen::Vector2d p = loop[a], q = loop[(a + 1) % loop.size()];
        const double t = std::clamp((s - p).dot(q - p) / (q - p).squaredNorm(), 0.0, 1.0);
        edge = std::min(edge, (p + t * (q - p) - s).norm());
      }
      near_edge += edge < 2.0;
    }
    return n;
  };
  // A diamond round the right end (not a rectangle: the lasso is no area selection).
  const Eigen::Vector2d c = onScreen(v, dir, {0.85, 0, 0});
  const std::vector<Eigen::Vector2d> diamond = {c + Eigen::Vector2d(-110, 0), c + Eigen::Vector2d(0, -90),
                                                c + Eigen::Vector2d(110, 0), c + Eigen::Vector2d(0, 90)};
  drawLoop(v, diamond, false);
  ASSERT_TRUE(v.waitFor("selected ")) << v.log();
  std::size_t edge = 0;
  const std::size_t want = expected(diamond, nullptr, edge);
  const long got = numberAfter(v, "selected ");
  std::printf("lasso: selected %ld points, %zu expected (%zu near its edge)\n", got, want, edge);
  EXPECT_GT(want, 300u);
  EXPECT_LE(std::abs(got - static_cast<long>(want)), static_cast<long>(edge)) << v.log();
  // With ctrl, a smaller square inside takes points out.
  std::vector<char> chosen(points.size(), 0);
  for (std::size_t i = 0; i < points.size(); ++i) chosen[i] = insidePolygon(diamond, screen[i]);
  const std::vector<Eigen::Vector2d> square = {c + Eigen::Vector2d(-30, -30), c + Eigen::Vector2d(30, -30),
                                               c + Eigen::Vector2d(30, 30), c + Eigen::Vector2d(-30, 30)};
  drawLoop(v, square, true);
  ASSERT_TRUE(v.waitFor("deselected ")) << v.log();
  const std::size_t want_out = expected(square, &chosen, edge);
  const long out = numberAfter(v, "deselected ");
  std::printf("ctrl+lasso: deselected %ld points, %zu expected (%zu near its edge)\n", out, want_out, edge);
  EXPECT_GT(want_out, 30u);
  EXPECT_LE(std::abs(out - static_cast<long>(want_out)), static_cast<long>(edge)) << v.log();
}

// Issue 49, defect 4 and "done when": `C` (every handle and move cleared) and `n` (back to the
// rest shape) are undone by `z`: the shape saved after the undo is the shape saved before, byte
// for byte (the handles rebuilt, the moves solved again), and `n` itself saves the rest shape.
TEST(ViewerX, ClearAndRestShapeAreUndone) {
  REQUIRE_X();
  hgdtest::TempDir dir;
  writeBar(dir);
  const ViewerWindow v(x, barArgs(dir), dir.file("log.txt"));
  ASSERT_TRUE(v.ok()) << v.log();
  v.key("t Right Up bracketleft t s");
  ASSERT_TRUE(v.waitFor("saved ")) << v.log();
  const std::string moved = v.named("saved ");
  ASSERT_GT(maxDistance(moved, dir.file("bar.ply")), 0.01);
  v.key("shift+c");
  ASSERT_TRUE(v.waitFor("handles cleared (z brings them back)")) << v.log();
  v.key("s");
  ASSERT_TRUE(v.waitFor("saved ", 2)) << v.log();
  EXPECT_EQ(maxDistance(v.named("saved ", 2), dir.file("bar.ply")), 0.0) << "C left the shape moved";
  v.key("z");
  ASSERT_TRUE(v.waitFor("handles and moves back (undone)")) << v.log();
  v.key("s");
  ASSERT_TRUE(v.waitFor("saved ", 3)) << v.log();
  EXPECT_EQ(hgdtest::slurp(v.named("saved ", 3)), hgdtest::slurp(moved))
      << "z after C is not the shape before";
  v.key("n");
  ASSERT_TRUE(v.waitFor("rest shape (z brings the moves back)")) << v.log();
  v.key("s");
  ASSERT_TRUE(v.waitFor("saved ", 4)) << v.log();
  EXPECT_EQ(maxDistance(v.named("saved ", 4), dir.file("bar.ply")), 0.0) << "n is not the rest shape";
  v.key("z");
  ASSERT_TRUE(v.waitFor("moves back (undone)", 2)) << v.log();
  v.key("s");
  ASSERT_TRUE(v.waitFor("saved ", 5)) << v.log();
  EXPECT_EQ(hgdtest::slurp(v.named("saved ", 5)), hgdtest::slurp(moved))
      << "z after n is not the shape before";
  // And the moves are in the undo history again: one more z undoes the last turn.
  v.key("z");
  ASSERT_TRUE(v.waitFor("undone", 3)) << v.log();
}

// Issue 49, defect 5: `r` fits the shape as it is now. The bar's right end moved far to the right
// in frame mode runs off the window; `r` brings all of it back, across most of the window.
TEST(ViewerX, RFitsTheDeformedShape) {
  REQUIRE_X();
  hgdtest::TempDir dir;
  writeBar(dir);
  const ViewerWindow v(x, barArgs(dir), dir.file("log.txt"));
  ASSERT_TRUE(v.ok()) << v.log();
  v.key("h a t");
  ASSERT_TRUE(v.waitFor("frame mode")) << v.log();
  std::string rights;
  for (int k = 0; k < 40; ++k) rights += " Right";
  v.key(rights);
  ASSERT_TRUE(v.waitFor("moved the handle", 40, 60)) << v.log();
  ASSERT_TRUE(v.shot(dir.file("off.png")));
  const Image off = readPng(dir.file("off.png"));
  ASSERT_FALSE(off.rgb.empty());
  const Coverage before = coverage(off);
  EXPECT_GE(before.x1, off.width - 2) << "the moved end did not run off the window";
  v.key("r");
  ASSERT_TRUE(v.shot(dir.file("fit.png")));
  keep(dir.file("fit.png"), "r-fits-deformed.png");
  const Image fit = readPng(dir.file("fit.png"));
  const Coverage after = coverage(fit);
  EXPECT_GT(after.x0, 10);
  EXPECT_LT(after.x1, fit.width - 10);
  EXPECT_GT(after.width(), 0.5 * fit.width);
}

// "Done when": every key of the help, sent as a real keysym through X (capitals with Shift and
// with Caps Lock; lower case with Caps Lock and Shift together), does what the help says: its
// message names the effect, and the views are checked on the picture. < and > change the point
// size in every mode.
TEST(ViewerX, EveryKeyDoesWhatTheHelpSays) {
  REQUIRE_X();
  hgdtest::TempDir dir;
  writeBar(dir);
  const ViewerWindow v(x, barArgs(dir), dir.file("log.txt"));
  ASSERT_TRUE(v.ok()) << v.log();
  struct Step {
    const char* keys;
    const char* says;
  };
  const Step steps[] = {
      {"h", "help hidden"},
      {"h", "help shown"},
      {"x", "area mode"},
      {"shift+period", "point size 4"},  // > in area mode
      {"x", "pick mode"},
      {"Caps_Lock shift+x Caps_Lock", "area mode"},  // Caps Lock and Shift: x
      {"x", "pick mode"},
      {"p", "lasso mode"},
      {"shift+comma", "point size 3"},  // < in lasso mode
      {"p", "pick mode"},
      {"d", "drag mode"},
      {"shift+period", "point size 4"},
      {"d", "pick mode"},
      {"t", "frame mode"},
      {"Right", "moved the handle by"},
      {"bracketleft", "turned the handle 5 degrees"},
      {"bracketright", "turned the handle -5 degrees"},
      {"comma", "turned the handle 5 degrees"},
      {"period", "turned the handle -5 degrees"},
      {"shift+comma", "point size 3"},  // < in frame mode: not a turn
      {"t", "pick mode"},
      {"shift+period", "point size 4"},  // and in pick mode
      {"shift+comma", "point size 3"},
      {"@keydown ctrl click 4 keyup ctrl", "point size 4"},  // ctrl+wheel, as in CloudCompare
      {"@keydown ctrl click 5 keyup ctrl", "point size 3"},
      {"plus", "selection radius"},
      {"minus", "selection radius"},
      {"equal", "selection radius"},
      {"c", "selection cleared"},
      {"f", "nothing selected"},
      {"m", "nothing selected"},
      {"j", "nothing selected"},
      {"l", "drags keep the handle's orientation"},
      {"l", "drags turn the handle"},
      {"v", "view: the harmonic field"},
      {"v", "view: the clusters"},
      {"v", "view: colours"},
      {"o", "rest overlay on"},
      {"o", "rest overlay off"},
      {"i", "shading off"},
      {"i", "shading on"},
      {"a", "axes hidden"},
      {"a", "axes shown"},
      {"u", "up axis +z"},
      {"u", "up axis +x"},
      {"r", "the whole shape in view"},
      {"z", "undone"},
      {"y", "redone"},
      {"n", "rest shape (z brings the moves back)"},
      {"z", "moves back (undone)"},
      {"shift+c", "handles cleared"},
      {"z", "handles and moves back (undone)"},
      {"Caps_Lock c Caps_Lock", "handles cleared (z brings them back); Caps Lock is on"},
      {"z", "handles and moves back (undone)"},
      {"k", "screenshot "},
      {"s", "saved "},
      {"shift+s", "saved "},
      {"Caps_Lock s Caps_Lock", "saved "},
      {"w", "'w' does nothing here"},
  };
  std::string log_before;
  for (const Step& s : steps) {
    SCOPED_TRACE(std::string(s.keys) + " should say '" + s.says + "'");
    const std::size_t n = ViewerWindow::occurrences(v.log(), s.says) + 1;
    if (s.keys[0] == '@') {  // pointer actions, over the window's middle
      v.move(0.5 * v.width(), 0.5 * v.height());
      v.mouse(s.keys + 1);
    } else {
      v.key(s.keys);
    }
    ASSERT_TRUE(v.waitFor(s.says, n, 10)) << v.log().substr(std::min(v.log().size(), log_before.size()));
    log_before = v.log();
  }
  EXPECT_TRUE(hgdtest::contains(v.named("saved ", 1), "bar-deformed")) << v.log();
  EXPECT_TRUE(hgdtest::contains(v.named("saved ", 2), "bar-scenario")) << v.log();
  EXPECT_TRUE(hgdtest::contains(v.named("saved ", 3), "bar-scenario-2")) << v.log();
  // The standard views, on the picture: the bar seen from the front and from above lies across
  // the window; from its left or right end it is a small square.
  v.key("h a u u u u");  // (help and axes off, the up axis back to +y)
  ASSERT_TRUE(v.waitFor("up axis +y")) << v.log();
  struct View {
    const char* key;
    const char* says;
    bool wide;
  };
  for (const View& view :
       {View{"1", "front view", true}, View{"2", "back view", true}, View{"3", "left view", false},
        View{"4", "right view", false}, View{"5", "top view", true}, View{"6", "bottom view", true}}) {
    SCOPED_TRACE(view.says);
    v.key(view.key);
    ASSERT_TRUE(v.waitFor(view.says)) << v.log();
    ASSERT_TRUE(v.shot(dir.file("view.png")));
    keep(dir.file("view.png"), std::string("view-") + view.key + ".png");
    const Image img = readPng(dir.file("view.png"));
    const Coverage c = coverage(img);
    std::printf("%s: %.0f x %.0f pixels\n", view.says, c.width(), c.height());
    if (view.wide) {
      EXPECT_GT(c.width(), 0.5 * img.width);
      EXPECT_LT(c.height(), 0.25 * img.height);
    } else {
      EXPECT_LT(c.width(), 0.25 * img.width);
      EXPECT_LT(c.height(), 0.25 * img.height);
    }
  }
  // The right button pans (CloudCompare's gesture), in pick mode and in area mode: the bar
  // follows the pointer. (VTK's own right button zooms: the bar would grow about its middle.)
  v.key("1");
  for (const char* mode : {"pick", "area"}) {
    SCOPED_TRACE(std::string("a right-button pan in ") + mode + " mode");
    if (std::string(mode) == "area") {
      v.key("x");
      ASSERT_TRUE(v.waitFor("area mode", 3)) << v.log();
    }
    ASSERT_TRUE(v.shot(dir.file("before.png")));
    const Eigen::Vector2d from(0.5 * v.width(), 0.5 * v.height());
    const Eigen::Vector2d by =
        std::string(mode) == "area" ? Eigen::Vector2d(-80, -50) : Eigen::Vector2d(80, 50);
    rightDrag(v, from, from + by);
    ASSERT_TRUE(v.shot(dir.file("after.png")));
    const Coverage a = coverage(readPng(dir.file("before.png"))),
                   b = coverage(readPng(dir.file("after.png")));
    std::printf("%s mode: the bar moved by (%d, %d) and (%d, %d) at its corners\n", mode, b.x0 - a.x0,
                b.y0 - a.y0, b.x1 - a.x1, b.y1 - a.y1);
    for (const int d : {b.x0 - a.x0, b.x1 - a.x1}) EXPECT_NEAR(d, by.x(), 12);
    for (const int d : {b.y0 - a.y0, b.y1 - a.y1}) EXPECT_NEAR(d, by.y(), 12);
  }
  const std::size_t picks = ViewerWindow::occurrences(v.log(), "pick mode") + 1;
  v.key("x r");
  ASSERT_TRUE(v.waitFor("pick mode", picks)) << v.log();
  // Shading off stays off when the shape is drawn again (a frame move). In the three-quarter view
  // the lit bar's faces are of several greys, darker where they turn from the light; unlit, its
  // points have their one grey (207; their anti-aliased rims only lighter). The share of the grey
  // pixels of the bar's middle (no handle there) darker than 195:
  const auto darker = [&](const std::string& png) {
    const Image img = readPng(png);
    int all = 0, dark = 0;
    for (int y = 0; y < img.height - 40; ++y)
      for (int xx = img.width * 35 / 100; xx < img.width * 65 / 100; ++xx) {
        const unsigned char* p = img.at(xx, y);
        if (p[0] >= 235 || std::abs(p[0] - p[1]) > 6 || std::abs(p[1] - p[2]) > 6) continue;
        ++all;
        dark += p[0] < 195;
      }
    return all ? static_cast<double>(dark) / all : 0.0;
  };
  v.key("r");  // the three-quarter view
  ASSERT_TRUE(v.shot(dir.file("lit.png")));
  keep(dir.file("lit.png"), "lit.png");
  const std::size_t moves = ViewerWindow::occurrences(v.log(), "moved the handle by") + 1;
  v.key("i t Right t");
  ASSERT_TRUE(v.waitFor("moved the handle by", moves)) << v.log();
  ASSERT_TRUE(v.shot(dir.file("unlit.png")));
  keep(dir.file("unlit.png"), "unlit.png");
  const double lit = darker(dir.file("lit.png")), unlit = darker(dir.file("unlit.png"));
  std::printf("grey pixels darker than 195: %.1f%% of the lit bar, %.1f%% of the unlit one\n", 100 * lit,
              100 * unlit);
  EXPECT_LT(unlit, 0.01);
  EXPECT_GT(lit, 0.1);
  v.key("q");
  ASSERT_TRUE(v.waitFor("press q again")) << v.log();  // a move since the last save
  v.key("e");                                          // q and e are one key
  EXPECT_FALSE(v.alive(10)) << v.log();
}

}  // namespace
