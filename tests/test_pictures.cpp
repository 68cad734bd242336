// Pictures a person can read (issue 29, items 8 and 13), from hgdeform-render and hgdeform-view
// under a virtual display: clouds are shaded (by their normals, else eye-dome lighting) rather
// than drawn as flat silhouettes.
#include <png.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "hgdeform/io.h"
#include "support/shapes.h"
#include "test_util.h"

namespace {

struct Image {
  int width = 0, height = 0;
  std::vector<unsigned char> rgb;
  const unsigned char* at(int x, int y) const {
    return rgb.data() +
           3 * (static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x));
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

}  // namespace
