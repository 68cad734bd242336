// Pictures a person can read (issue 29, items 8 and 13), from hgdeform-render and hgdeform-view
// under a virtual display: clouds are shaded (by their normals, else eye-dome lighting) rather
// than drawn as flat silhouettes.

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "hgdeform/io/io.h"
#include "support/png_image.h"
#include "support/shapes.h"
#include "test_util.h"

namespace {

using hgdtest::Image;
using hgdtest::readPng;

/// The shape's pixels (not the white background) within rows [y0, y1) of the picture (rows
/// from the top): how many, and the standard deviation of their brightness (0..255).
struct Spread {
  int count = 0;
  double stddev = 0;
};
Spread brightnessSpread(const Image& img, int y0 = 0, int y1 = -1) {
  if (y1 < 0) y1 = img.height;
  double sum = 0, sum2 = 0;
  Spread s;
  for (int y = std::max(0, y0); y < std::min(y1, img.height); ++y)
    for (int x = 0; x < img.width; ++x) {
      const unsigned char* p = img.at(x, y);
      if (p[0] > 245 && p[1] > 245 && p[2] > 245) continue;  // background
      const double v = 0.299 * p[0] + 0.587 * p[1] + 0.114 * p[2];
      sum += v;
      sum2 += v * v;
      ++s.count;
    }
  if (s.count > 0) {
    const double mean = sum / s.count;
    s.stddev = std::sqrt(std::max(0.0, sum2 / s.count - mean * mean));
  }
  return s;
}

bool haveXvfb() {
  std::string out;
  return hgdtest::run("command -v xvfb-run", out) == 0;
}

/// Runs the command lines one after another under one virtual display; stops at the first failure.
hgdtest::CommandResult underXvfb(const std::vector<std::string>& commands) {
  std::string script;
  for (const std::string& c : commands) script += (script.empty() ? "" : " && ") + c;
  return hgdtest::shell("xvfb-run -a -s '-screen 0 1280x1024x24' sh -c " + hgdtest::quote(script));
}

/// A bumpy sphere of about n points, with its normals or without (no colours: grey).
void writeSpheres(const hgdtest::TempDir& dir, std::size_t n) {
  const hgd::Shape with = hgd::shapes::bumpySphere(n, 0.15f);
  hgd::writeShape(dir.file("normals.ply"), with);
  std::vector<Eigen::Vector3f> pts(with.size());
  for (std::size_t i = 0; i < pts.size(); ++i)
    std::memcpy(pts[i].data(), with.cloud.data.data() + i * with.cloud.point_step, 12);
  hgd::writeShape(dir.file("bare.ply"), hgd::shapes::cloudShape(pts, {}));
}

// Item 8: a grey cloud is no flat silhouette in hgdeform-render. Lit by its normals, or with
// eye-dome lighting without them, the brightness of its pixels varies across the shape: a flat
// grey cloud (what was drawn before) has a standard deviation of a few units (its anti-aliased
// rim); shaded, well above.
TEST(Pictures, RenderShadesCloudsWithAndWithoutNormals) {
  if (!haveXvfb()) GTEST_SKIP() << "xvfb-run not installed";
  hgdtest::TempDir dir;
  writeSpheres(dir, 40000);
  std::vector<std::string> runs;
  for (const char* name : {"normals", "bare"})
    runs.push_back(std::string(HGD_RENDER) + " " + dir.file(std::string(name) + ".ply") + " -o " +
                   dir.file(std::string(name) + ".png") + " --size 400x400 --view 0.3,0.4,1 --up y");
  // Both in one picture (one viewport each): each viewport shaded its own way.
  runs.push_back(std::string(HGD_RENDER) + " " + dir.file("normals.ply") + " " + dir.file("bare.ply") +
                 " -o " + dir.file("both.png") + " --size 800x400 --view 0.3,0.4,1 --up y");
  const auto r = underXvfb(runs);
  ASSERT_EQ(r.code, 0) << r.err;
  for (const char* name : {"normals", "bare"}) {
    SCOPED_TRACE(name);
    const Image img = readPng(dir.file(std::string(name) + ".png"));
    ASSERT_EQ(img.width, 400);
    const Spread s = brightnessSpread(img);
    std::printf("render %s: brightness stddev %.1f over %d pixels\n", name, s.stddev, s.count);
    EXPECT_GT(s.count, 30000) << "the sphere fills a good part of the picture";
    EXPECT_GT(s.stddev, 15.0) << "a flat silhouette";
  }
  const Image both = readPng(dir.file("both.png"));
  ASSERT_EQ(both.width, 800);
  Image left = both, right = both;
  left.width = right.width = 400;
  left.rgb.clear();
  right.rgb.clear();
  for (int y = 0; y < both.height; ++y) {
    left.rgb.insert(left.rgb.end(), both.at(0, y), both.at(400, y));
    right.rgb.insert(right.rgb.end(), both.at(400, y), both.at(400, y) + 3 * 400);
  }
  EXPECT_GT(brightnessSpread(left).count, 20000) << "the first viewport was erased";
  EXPECT_GT(brightnessSpread(left).stddev, 15.0);
  EXPECT_GT(brightnessSpread(right).count, 20000);
  EXPECT_GT(brightnessSpread(right).stddev, 15.0);
}

// Item 8 in the viewer: the same shading (the same function), and point-size keys '<' and '>'
// ('+' and '-' are the selection radius). The help is hidden ('h') and the status line left
// out so that only the shape's pixels count.
TEST(Pictures, ViewerShadesCloudsAndChangesPointSize) {
  if (!haveXvfb()) GTEST_SKIP() << "xvfb-run not installed";
  hgdtest::TempDir dir;
  writeSpheres(dir, 40000);
  hgdtest::writeText(dir.file("plain.json"), R"({"events": [{"key": "h"}]})");
  hgdtest::writeText(dir.file("bigger.json"), R"({"events": [{"key": "h"}, {"key": ">"}, {"key": ">"}]})");
  hgdtest::writeText(dir.file("smaller.json"),
                     R"({"events": [{"key": "h"}, {"key": "<"}, {"key": "<"}, {"key": "<"}]})");
  std::vector<std::string> runs;
  const std::string view = std::string(HGD_VIEW) + " --quiet --size 500x500 ";
  for (const char* name : {"normals", "bare"})
    runs.push_back(view + dir.file(std::string(name) + ".ply") + " --replay " + dir.file("plain.json") +
                   " --screenshot " + dir.file(std::string(name) + ".png"));
  hgd::writeShape(dir.file("sparse.ply"), hgd::shapes::bumpySphere(5000, 0.15f));
  for (const char* keys : {"plain", "bigger", "smaller"})
    runs.push_back(view + dir.file("sparse.ply") + " --replay " + dir.file(std::string(keys) + ".json") +
                   " --screenshot " + dir.file(std::string(keys) + ".png"));
  const auto r = underXvfb(runs);
  ASSERT_EQ(r.code, 0) << r.err << r.out;
  for (const char* name : {"normals", "bare"}) {
    SCOPED_TRACE(name);
    const Image img = readPng(dir.file(std::string(name) + ".png"));
    ASSERT_EQ(img.width, 500);
    const Spread s = brightnessSpread(img, 0, img.height - 40);  // above the status line
    std::printf("viewer %s: brightness stddev %.1f over %d pixels\n", name, s.stddev, s.count);
    EXPECT_GT(s.count, 20000);
    EXPECT_GT(s.stddev, 15.0) << "a flat silhouette";
  }
  // Bigger points cover more pixels, smaller fewer: 5,000 points (with normals: eye-dome
  // lighting would shade the background between the points too) leave gaps between them.
  const Spread plain = brightnessSpread(readPng(dir.file("plain.png")), 0, 460);
  const Spread bigger = brightnessSpread(readPng(dir.file("bigger.png")), 0, 460);
  const Spread smaller = brightnessSpread(readPng(dir.file("smaller.png")), 0, 460);
  EXPECT_GT(bigger.count, plain.count + plain.count / 5);
  EXPECT_LT(smaller.count, plain.count - plain.count / 5);
}

/// Mean column and row (from the top) of the pixels that `is` accepts, and how many, within the
/// columns [x0, x1) and rows [y0, y1).
struct Blob {
  int count = 0;
  double x = 0, y = 0;
};
template <typename Pred>
Blob blob(const Image& img, Pred is, int x0 = 0, int x1 = -1, int y0 = 0, int y1 = -1) {
  if (x1 < 0) x1 = img.width;
  if (y1 < 0) y1 = img.height;
  Blob b;
  for (int y = y0; y < y1; ++y)
    for (int x = x0; x < x1; ++x)
      if (is(img.at(x, y))) {
        ++b.count;
        b.x += x;
        b.y += y;
      }
  if (b.count > 0) {
    b.x /= b.count;
    b.y /= b.count;
  }
  return b;
}
// The colour scale's ends (blue to red, hgd::colourMap), lit or shaded: by hue, not brightness.
bool hot(const unsigned char* p) {
  return p[0] > 100 && p[0] > p[2] + 50 && p[0] > p[1] + 40;
}
bool cold(const unsigned char* p) {
  return p[2] > 90 && p[2] > p[0] + 40;
}
bool magenta(const unsigned char* p) {
  return p[0] > 150 && p[2] > 150 && p[1] < 80;
}
bool black(const unsigned char* p) {
  return p[0] < 40 && p[1] < 40 && p[2] < 40;
}

/// A bar along x (bar(): with normals) bent up at its far end: y += 0.4 x^2.
hgd::Shape bentBar(const hgd::Shape& bar) {
  hgd::Shape bent = bar;
  for (std::size_t i = 0; i < bent.size(); ++i) {
    float p[3];
    std::memcpy(p, bent.cloud.data.data() + i * bent.cloud.point_step, 12);
    p[1] += 0.4f * p[0] * p[0];
    std::memcpy(bent.cloud.data.data() + i * bent.cloud.point_step, p, 12);
  }
  return bent;
}

// Item 13: --displacement REST colours each point by its distance from the same point of REST:
// the moved end of the bar is hot (red), the still end cold (blue), with the scale drawn; an
// input that is REST itself keeps its own (grey) colours.
TEST(Pictures, DisplacementColoursTheMovedPartHot) {
  if (!haveXvfb()) GTEST_SKIP() << "xvfb-run not installed";
  hgdtest::TempDir dir;
  const hgd::Shape bar = hgd::shapes::bar(1.0f, 0.1f, 0.01f);
  hgd::writeShape(dir.file("rest.ply"), bar);
  hgd::writeShape(dir.file("bent.ply"), bentBar(bar));
  const auto r = underXvfb({std::string(HGD_RENDER) + " " + dir.file("rest.ply") + " " +
                            dir.file("bent.ply") + " --displacement " + dir.file("rest.ply") + " -o " +
                            dir.file("d.png") + " --size 1000x400 --view 0,0,1 --up y"});
  ASSERT_EQ(r.code, 0) << r.err;
  const Image img = readPng(dir.file("d.png"));
  ASSERT_EQ(img.width, 1000);
  // The rest shape (left): no displacement colours.
  EXPECT_LT(blob(img, hot, 0, 500).count, 50);
  EXPECT_LT(blob(img, cold, 0, 500, 80).count, 50);
  // The bent bar (right; below the scale at the top): seen from +z with +y up, x to the right.
  const Blob h = blob(img, hot, 500, 1000, 80), c = blob(img, cold, 500, 1000, 80);
  std::printf("hot: %d pixels at x %.0f, y %.0f; cold: %d pixels at x %.0f, y %.0f\n", h.count, h.x, h.y,
              c.count, c.x, c.y);
  EXPECT_GT(h.count, 300);
  EXPECT_GT(c.count, 300);
  EXPECT_GT(h.x, c.x + 150) << "the far end (x = 1) moved, the near end (x = 0) did not";
  EXPECT_LT(h.y, c.y) << "the moved end went up";
  // The scale: both ends of the colour map at the top right.
  EXPECT_GT(blob(img, hot, 750, 1000, 0, 80).count, 50);
  EXPECT_GT(blob(img, cold, 750, 1000, 0, 80).count, 50);
}

// Item 13: a rest shape that is not the same points is refused, naming both files.
TEST(Pictures, DisplacementNeedsTheSamePoints) {
  hgdtest::TempDir dir;
  const hgd::Shape bar = hgd::shapes::bar(1.0f, 0.1f, 0.01f);
  hgd::writeShape(dir.file("bar.ply"), bar);
  hgd::writeShape(dir.file("other.ply"), hgd::shapes::bar(1.0f, 0.1f, 0.02f));
  const auto r = hgdtest::shell("DISPLAY= " + std::string(HGD_RENDER) + " " + dir.file("bar.ply") +
                                " --displacement " + dir.file("other.ply") + " -o " + dir.file("x.png"));
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_TRUE(hgdtest::contains(r.err, dir.file("other.ply") + ": the rest shape has ")) << r.err;
  EXPECT_TRUE(hgdtest::contains(r.err, "but " + dir.file("bar.ply") + " has " + std::to_string(bar.size())))
      << r.err;
  EXPECT_TRUE(hgdtest::contains(r.err, "the same points in the same order")) << r.err;
  EXPECT_FALSE(hgdtest::exists(dir.file("x.png")));
}

/// Points on the surface of the box [lo, hi], about `per_unit2` per unit of area, in colour c.
void boxSurface(std::vector<std::string>& lines, const Eigen::Vector3f& lo, const Eigen::Vector3f& hi,
                float step, const char* colour) {
  for (int axis = 0; axis < 3; ++axis) {
    const int u = (axis + 1) % 3, v = (axis + 2) % 3;
    for (float a = lo[u]; a <= hi[u] + 1e-6f; a += step)
      for (float b = lo[v]; b <= hi[v] + 1e-6f; b += step)
        for (const float w : {lo[axis], hi[axis]}) {
          Eigen::Vector3f p;
          p[axis] = w;
          p[u] = a;
          p[v] = b;
          lines.push_back(std::to_string(p.x()) + " " + std::to_string(p.y()) + " " + std::to_string(p.z()) +
                          " " + colour);
        }
  }
}

// Item 13: the view comes from the shape. A horse-like shape with z up (as scanners and CAD
// write them: a body along x, four red legs below it, a neck and head up at one end) is seen
// from the side, legs down, not from above or below (the old fixed +y guess looked down z and
// hid the legs under the body).
TEST(Pictures, ZUpShapeIsSeenFromTheSide) {
  if (!haveXvfb()) GTEST_SKIP() << "xvfb-run not installed";
  hgdtest::TempDir dir;
  std::vector<std::string> lines;
  const float s = 0.02f;
  boxSurface(lines, {0, -0.12f, 0.5f}, {1, 0.12f, 0.8f}, s, "150 150 150");         // body
  boxSurface(lines, {0.9f, -0.08f, 0.8f}, {1.1f, 0.08f, 1.15f}, s, "150 150 150");  // neck and head
  for (const float x : {0.05f, 0.85f})
    for (const float y : {-0.1f, 0.04f})
      boxSurface(lines, {x, y, 0}, {x + 0.08f, y + 0.06f, 0.5f}, s, "220 30 30");
  std::string ply = "ply\nformat ascii 1.0\nelement vertex " + std::to_string(lines.size()) +
                    "\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\n"
                    "property uchar green\nproperty uchar blue\nend_header\n";
  for (const auto& l : lines) ply += l + "\n";
  hgdtest::writeText(dir.file("horse.ply"), ply);
  const auto r = underXvfb({std::string(HGD_RENDER) + " " + dir.file("horse.ply") + " -o " +
                            dir.file("h.png") + " --size 400x400"});
  ASSERT_EQ(r.code, 0) << r.err;
  const Image img = readPng(dir.file("h.png"));
  ASSERT_EQ(img.width, 400);
  const Blob legs = blob(img, [](const unsigned char* p) { return p[0] > 170 && p[1] < 80 && p[2] < 80; });
  const Blob body = blob(img, [](const unsigned char* p) {
    return p[0] > 100 && p[0] < 200 && std::abs(p[0] - p[1]) < 15 && std::abs(p[1] - p[2]) < 15;
  });
  std::printf("legs: %d pixels, mean row %.0f; body: %d pixels, mean row %.0f\n", legs.count, legs.y,
              body.count, body.y);
  EXPECT_GT(legs.count, 3000) << "the legs are hidden";
  EXPECT_GT(body.count, 5000);
  EXPECT_GT(legs.y, body.y + 60) << "the legs are not below the body";
}

// Item 13 in the batch report: the "after" thumbnail is coloured by displacement (hot at the
// dragged end, cold at the fixed end, with its scale), the handles are marked in both (fixed
// black, manipulated magenta), and the "before" keeps the scan's own colours.
TEST(Pictures, BatchThumbnailShowsDisplacementAndHandles) {
  if (!haveXvfb()) GTEST_SKIP() << "xvfb-run not installed";
  hgdtest::TempDir dir;
  std::filesystem::create_directories(dir.path() / "in");
  hgd::writeShape(dir.file("in/bar.ply"), hgd::shapes::bar(1.0f, 0.1f, 0.0125f));
  hgdtest::writeText(dir.file("scenario.json"), R"({"format": "hgdeform-scenario/1",
    "fixed": [{"box": {"min": [-0.1, -0.1, -0.1], "max": [0.15, 0.1, 0.1]}}],
    "manipulated": {"box": {"min": [0.85, -0.1, -0.1], "max": [1.1, 0.1, 0.1]}},
    "move": {"drag": {"from": [1, 0, 0], "to": [1, 0.35, 0]}}})");
  const auto r =
      underXvfb({std::string(HGD_TOOL) + " batch -s " + dir.file("scenario.json") + " " + dir.file("in") +
                 " -o " + dir.file("out") + " --report " + dir.file("rep") + " -q"});
  ASSERT_EQ(r.code, 0) << r.err;
  const Image img = readPng(dir.file("rep/thumbs/bar.ply.png"));
  ASSERT_EQ(img.width, 640);
  const int half = 320, top = 60;  // the scale and the legend are in the top rows
  EXPECT_LT(blob(img, hot, 0, half, top).count, 20) << "the before side is coloured by displacement";
  const Blob h = blob(img, hot, half, 640, top), c = blob(img, cold, half, 640, top);
  const Blob moved = blob(img, magenta, half, 640, top), fixed = blob(img, black, half, 640, top);
  std::printf("after: hot %d, cold %d, magenta %d, black %d pixels\n", h.count, c.count, moved.count,
              fixed.count);
  EXPECT_GT(h.count, 100);
  EXPECT_GT(c.count, 100);
  EXPECT_GT(moved.count, 30) << "the manipulated handle is not marked";
  EXPECT_GT(fixed.count, 30) << "the fixed handle is not marked";
  EXPECT_GT(blob(img, magenta, 0, half, top).count, 30);
  EXPECT_GT(blob(img, black, 0, half, top).count, 30);
  // Hot near the dragged (magenta) end, cold near the fixed (black) one.
  const auto dist = [](const Blob& a, const Blob& b) { return std::hypot(a.x - b.x, a.y - b.y); };
  EXPECT_LT(dist(h, moved), dist(h, fixed));
  EXPECT_LT(dist(c, fixed), dist(c, moved));
  EXPECT_GT(blob(img, hot, half, 640, 0, top).count + blob(img, cold, half, 640, 0, top).count, 40)
      << "no colour scale";
}

}  // namespace
