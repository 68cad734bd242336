// hgdeform-render under a virtual display: its pictures are written like every other output,
// in the file's colours and the right way up.
#include <pcl/conversions.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <sys/stat.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include "hgdeform/io/fields.h"
#include "hgdeform/io/io.h"
#include "support/pictures.h"
#include "support/png_image.h"
#include "support/shapes.h"
#include "test_util.h"

namespace {

using hgdtest::blob;
using hgdtest::Blob;
using hgdtest::cameraScan;
using hgdtest::haveXvfb;
using hgdtest::Image;
using hgdtest::readPng;

// A PNG is written like every other output (the issue: the picture went to a fixed temporary
// OUT.tmp.png renamed over OUT, so an input of that name was lost, and a link or a FIFO at OUT
// was replaced by a file): an input named like that temporary stays, a symbolic link is
// followed and stays a link, a FIFO is written to, and nothing else is left beside the output.
TEST(Render, PngIsWrittenLikeEveryOtherOutput) {
  if (!haveXvfb()) GTEST_SKIP() << "xvfb-run not installed";
  namespace fs = std::filesystem;
  hgdtest::TempDir dir;
  const std::string bar = dir.file("bar.ply"), shot = dir.file("shot.png"), in = dir.file("shot.png.tmp.png");
  hgd::writeShape(bar, hgd::shapes::bar(1.0f, 0.1f, 0.05f));
  fs::copy_file(bar, in);
  const std::string in_before = hgdtest::slurp(in);
  fs::create_directories(dir.path() / "pics");
  fs::create_symlink("pics/real.png", dir.file("link.png"));
  const std::string fifo = dir.file("pipe.png"), got = dir.file("got.png");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const std::string render = std::string(HGD_RENDER) + " ";
  const std::string script =
      render + hgdtest::quote(in) + " -o " + hgdtest::quote(shot) + " --size 64x48 && " + render +
      hgdtest::quote(bar) + " -o " + hgdtest::quote(dir.file("link.png")) +
      " --size 64x48 && { timeout 20 cat " + hgdtest::quote(fifo) + " > " + hgdtest::quote(got) + " & " +
      render + hgdtest::quote(bar) + " -o " + hgdtest::quote(fifo) + " --size 64x48; s=$?; wait; exit $s; }";
  const hgdtest::CommandResult r =
      hgdtest::shell("xvfb-run -a -s '-screen 0 1280x1024x24' sh -c " + hgdtest::quote(script));
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(hgdtest::slurp(in) == in_before) << "the input named like the temporary file was replaced";
  EXPECT_EQ(readPng(shot).width, 64);
  EXPECT_TRUE(fs::is_symlink(dir.file("link.png")));
  EXPECT_EQ(readPng(dir.file("pics/real.png")).width, 64);
  EXPECT_TRUE(fs::is_fifo(fifo));
  EXPECT_EQ(readPng(got).width, 64);
  const std::vector<std::string> names = dir.list();
  EXPECT_EQ(std::set<std::string>(names.begin(), names.end()),
            (std::set<std::string>{"bar.ply", "shot.png.tmp.png", "shot.png", "pics", "link.png", "pipe.png",
                                   "got.png"}));
  std::vector<std::string> pics;
  for (const auto& e : fs::directory_iterator(dir.path() / "pics"))
    pics.push_back(e.path().filename().string());
  EXPECT_EQ(pics, std::vector<std::string>{"real.png"});
}

// A full disk (a link named .png to /dev/full): the picture cannot be written, exit 1, the
// link stays and nothing is left beside it.
TEST(Render, FullDiskIsAnError) {
  if (!haveXvfb()) GTEST_SKIP() << "xvfb-run not installed";
  if (!hgdtest::exists("/dev/full")) GTEST_SKIP() << "no /dev/full";
  namespace fs = std::filesystem;
  hgdtest::TempDir dir;
  const std::string bar = dir.file("bar.ply"), full = dir.file("full.png");
  hgd::writeShape(bar, hgd::shapes::bar(1.0f, 0.1f, 0.05f));
  fs::create_symlink("/dev/full", full);
  const hgdtest::CommandResult r =
      hgdtest::shell("xvfb-run -a -s '-screen 0 1280x1024x24' " + std::string(HGD_RENDER) + " " +
                     hgdtest::quote(bar) + " -o " + hgdtest::quote(full) + " --size 64x48");
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_TRUE(hgdtest::contains(r.err, full + ": cannot write: No space left on device")) << r.err;
  EXPECT_TRUE(fs::is_symlink(full));
  const std::vector<std::string> names = dir.list();
  EXPECT_EQ(std::set<std::string>(names.begin(), names.end()),
            (std::set<std::string>{"bar.ply", "full.png"}));
}

// --- hgdeform-render: colours and the up axis ----------------------------------------------

/// Runs hgdeform-render once per argument list, all under one virtual display (every xvfb-run
/// start is a chance to race other test runs for a display number). Stops at the first failure.
hgdtest::CommandResult renderAll(const std::vector<std::string>& runs) {
  std::string script;
  for (const std::string& args : runs)
    script += (script.empty() ? "" : " && ") + std::string(HGD_RENDER) + " " + args;
  return hgdtest::shell("xvfb-run -a -s '-screen 0 1280x1024x24' sh -c " + hgdtest::quote(script));
}

/// A 40x30 sheet in the plane z = 2, its left half (x < 0) red and its right half blue, with
/// colours stored as `how` says: "rgb" (PCL's packed float), "rgba" (packed uint32),
/// "uchar" (red/green/blue 0..255), "float1" (0..1) or "float255" (floats 0..255).
hgd::Shape halfRedHalfBlue(const std::string& how) {
  std::vector<Eigen::Vector3f> pts;
  for (int j = 0; j < 30; ++j)
    for (int i = 0; i < 40; ++i) pts.emplace_back(-0.5f + i / 39.0f, -0.35f + 0.7f * j / 29.0f, 2.0f);
  hgd::Shape s = hgd::shapes::cloudShape(pts, {});
  auto& c = s.cloud;
  auto addField = [&](const std::string& name, std::uint8_t type) {
    pcl::PCLPointField f;
    f.name = name;
    f.datatype = type;
    f.count = 1;
    f.offset = c.point_step;
    const std::uint32_t old_step = c.point_step, size = static_cast<std::uint32_t>(hgd::datatypeSize(type));
    std::vector<std::uint8_t> data(pts.size() * (old_step + size), 0);
    for (std::size_t i = 0; i < pts.size(); ++i)
      std::memcpy(&data[i * (old_step + size)], &c.data[i * old_step], old_step);
    c.point_step = old_step + size;
    c.row_step = c.point_step * c.width;
    c.data = data;
    c.fields.push_back(f);
    return c.fields.back();
  };
  if (how == "rgb" || how == "rgba") {
    const auto f = addField(how, how == "rgb" ? pcl::PCLPointField::FLOAT32 : pcl::PCLPointField::UINT32);
    for (std::size_t i = 0; i < pts.size(); ++i) {
      const std::uint32_t v = pts[i].x() < 0 ? 0xFFFF0000u : 0xFF0000FFu;
      std::memcpy(&c.data[i * c.point_step + f.offset], &v, 4);
    }
  } else {
    const std::uint8_t type = how == "uchar" ? pcl::PCLPointField::UINT8 : pcl::PCLPointField::FLOAT32;
    const double full = how == "float1" ? 1.0 : 255.0;
    for (const char* name : {"red", "green", "blue"}) addField(name, type);
    for (std::size_t i = 0; i < pts.size(); ++i) {
      const bool red = pts[i].x() < 0;
      hgd::writeValue(c, i, c.fields[c.fields.size() - 3], red ? full : 0);
      hgd::writeValue(c, i, c.fields[c.fields.size() - 2], 0);
      hgd::writeValue(c, i, c.fields[c.fields.size() - 1], red ? 0 : full);
    }
  }
  return s;
}

// A cloud coloured half red, half blue is drawn red and blue (not grey), red on the left,
// whichever way the file stores its colours.
TEST(Render, DrawsTheFileColours) {
  if (!haveXvfb()) GTEST_SKIP() << "xvfb-run not installed";
  hgdtest::TempDir dir;
  const std::vector<std::string> kinds = {"rgb", "rgba", "uchar", "float1", "float255"};
  std::vector<std::string> runs;
  for (const std::string& how : kinds) {
    hgd::writeShape(dir.file(how + ".pcd"), halfRedHalfBlue(how));
    runs.push_back(dir.file(how + ".pcd") + " -o " + dir.file(how + ".png") +
                   " --size 400x300 --view 0,0,-1 --up y");
  }
  const auto r = renderAll(runs);
  ASSERT_EQ(r.code, 0) << r.err;
  for (const std::string& how : kinds) {
    SCOPED_TRACE(how);
    const Image img = readPng(dir.file(how + ".png"));
    ASSERT_EQ(img.width, 400);
    const Blob red = blob(img, 255, 0, 0), blue = blob(img, 0, 0, 255), grey = blob(img, 191, 191, 184);
    EXPECT_GT(red.count, 3000);
    EXPECT_GT(blue.count, 3000);
    EXPECT_LT(grey.count, 100);
    // Seen from -z with +y up, +x is on the left: the red half (x < 0) on the right.
    EXPECT_GT(red.x, 200);
    EXPECT_LT(blue.x, 200);
  }
}

// The camera-frame scan comes out the right way up (its top rows at the top of the picture) and
// not mirrored (its right columns on the right): `auto` takes -y up for it, and the default
// view from the sensor's side. The same points unorganized are still in the camera's frame (all
// ahead of it): -y up too (issue 49, defect 5: they came out upside down, as --up y shows them).
TEST(Render, CameraFrameScanIsTheRightWayUp) {
  if (!haveXvfb()) GTEST_SKIP() << "xvfb-run not installed";
  hgdtest::TempDir dir;
  hgdtest::writeCameraScans(dir);
  struct Case {
    std::string input, options;
    bool red_on_top;
  };
  const std::vector<Case> cases = {Case{"scan.pcd", "", true}, Case{"scan.pcd", "--up -y", true},
                                   Case{"scan.pcd", "--up y", false}, Case{"flat.pcd", "", true}};
  std::vector<std::string> runs;
  for (std::size_t k = 0; k < cases.size(); ++k)
    runs.push_back(dir.file(cases[k].input) + " -o " + dir.file(std::to_string(k) + ".png") +
                   " --size 400x300 " + cases[k].options);
  const auto r = renderAll(runs);
  ASSERT_EQ(r.code, 0) << r.err;
  for (std::size_t k = 0; k < cases.size(); ++k) {
    const Case& c = cases[k];
    SCOPED_TRACE(c.input + " " + c.options);
    const Image img = readPng(dir.file(std::to_string(k) + ".png"));
    ASSERT_EQ(img.height, 300);
    const Blob red = blob(img, 255, 0, 0), green = blob(img, 0, 255, 0);
    ASSERT_GT(red.count, 500);
    ASSERT_GT(green.count, 500);
    EXPECT_EQ(red.y < 150, c.red_on_top) << "red rows at " << red.y;
    if (c.red_on_top) {
      EXPECT_GT(green.x, 200) << "the picture is mirrored";
    }
  }
  std::string out;
  EXPECT_EQ(
      hgdtest::run(
          std::string(HGD_RENDER) + " " + dir.file("scan.pcd") + " -o " + dir.file("x.png") + " --up w", out),
      2);  // a usage error
  EXPECT_NE(out.find("the up axis must be x, y, z, -x, -y, -z or auto, not 'w'"), std::string::npos) << out;
}

}  // namespace
