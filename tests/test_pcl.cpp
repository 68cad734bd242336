// The typed PCL entry (<hgdeform/pcl.h>) on clouds shaped like scans: random order, an
// organized layout with NaN holes, coordinates far from the origin, normals with random signs,
// every extra field set. The reference is a different path: the same cloud saved as a PCD by
// PCL, deformed from the file, and loaded back by PCL.
#include <gtest/gtest.h>
#include <pcl/io/pcd_io.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "hgdeform/app/pcl.h"
#include "hgdeform/app/runner.h"
#include "hgdeform/io/io.h"
#include "test_util.h"

namespace {

constexpr int kWidth = 80, kHeight = 40;              // organized, as a range camera writes
const Eigen::Vector3d kOffset(1200.0, -800.0, 35.0);  // georeferenced-ish: far from the origin

template <typename PointT>
void setExtras(PointT& p, std::mt19937& rng, std::size_t i) {
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  if constexpr (pcl::traits::has_field<PointT, pcl::fields::intensity>::value) p.intensity = 100.0f * u(rng);
  if constexpr (pcl::traits::has_field<PointT, pcl::fields::label>::value)
    p.label = static_cast<std::uint32_t>(i % 7);
  if constexpr (pcl::traits::has_field<PointT, pcl::fields::rgb>::value ||
                pcl::traits::has_field<PointT, pcl::fields::rgba>::value) {
    p.r = static_cast<std::uint8_t>(rng() & 255);
    p.g = static_cast<std::uint8_t>(rng() & 255);
    p.b = static_cast<std::uint8_t>(rng() & 255);
  }
  if constexpr (pcl::traits::has_field<PointT, pcl::fields::rgba>::value)
    p.a = static_cast<std::uint8_t>(rng() & 255);
  if constexpr (pcl::traits::has_field<PointT, pcl::fields::curvature>::value) p.curvature = u(rng);
}

// A 1 x 0.2 plate (z = 0.02 sin(3x)), points in random order in an 80 x 40 organized grid with
// 4% NaN holes; normals (where the type has them) with random signs.
template <typename PointT>
pcl::PointCloud<PointT> plate(unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> ux(0.0, 1.0), uy(0.0, 0.2), u(0.0, 1.0);
  pcl::PointCloud<PointT> c(kWidth, kHeight);
  c.is_dense = false;
  c.sensor_origin_ = Eigen::Vector4f(1.0f, 2.0f, 3.0f, 0.0f);
  c.sensor_orientation_ = Eigen::Quaternionf(Eigen::AngleAxisf(0.3f, Eigen::Vector3f::UnitY()));
  for (std::size_t i = 0; i < c.size(); ++i) {
    PointT& p = c[i];
    setExtras(p, rng, i);
    if (u(rng) < 0.04) {
      p.x = p.y = p.z = std::numeric_limits<float>::quiet_NaN();
      continue;
    }
    const double x = ux(rng), y = uy(rng), z = 0.02 * std::sin(3.0 * x);
    p.x = static_cast<float>(x + kOffset.x());
    p.y = static_cast<float>(y + kOffset.y());
    p.z = static_cast<float>(z + kOffset.z());
    if constexpr (pcl::traits::has_normal_v<PointT>) {
      Eigen::Vector3f n(static_cast<float>(-0.06 * std::cos(3.0 * x)), 0.0f, 1.0f);
      n.normalize();
      if (u(rng) < 0.5) n = -n;
      p.normal_x = n.x();
      p.normal_y = n.y();
      p.normal_z = n.z();
    }
  }
  return c;
}

hgd::Scenario plateScenario() {
  hgd::Scenario s;
  s.fix(hgd::Region::box(kOffset + Eigen::Vector3d(-1, -1, -1), kOffset + Eigen::Vector3d(0.1, 1, 1)))
      .manipulate(
          hgd::Region::box(kOffset + Eigen::Vector3d(0.9, -1, -1), kOffset + Eigen::Vector3d(2, 1, 1)))
      .drag(kOffset + Eigen::Vector3d(1.0, 0.1, 0.0), kOffset + Eigen::Vector3d(0.95, 0.1, 0.3));
  return s;
}

template <typename T>
class PclDeform : public ::testing::Test {};
using PointTypes =
    ::testing::Types<pcl::PointXYZ, pcl::PointXYZI, pcl::PointXYZL, pcl::PointXYZRGB, pcl::PointXYZRGBA,
                     pcl::PointNormal, pcl::PointXYZINormal, pcl::PointXYZRGBNormal>;
TYPED_TEST_SUITE(PclDeform, PointTypes);

// deform() against the file path: the same cloud saved by PCL, deformed by readShape +
// deformShape + writeShape, loaded back by PCL. Every field but x/y/z (and the normal) is
// byte for byte the input's; NaN points stay NaN at their index; the layout is kept.
TYPED_TEST(PclDeform, MatchesTheFilePathAndKeepsEveryOtherField) {
  using PointT = TypeParam;
  const pcl::PointCloud<PointT> in = plate<PointT>(7);
  const hgd::Scenario sc = plateScenario();
  pcl::PointCloud<PointT> out;
  const hgd::DeformReport rep = hgd::deform(in, sc, out);
  EXPECT_TRUE(rep.reached);

  hgdtest::TempDir dir;
  const std::string src = (dir.path() / "in.pcd").string(), dst = (dir.path() / "out.pcd").string();
  ASSERT_EQ(pcl::io::savePCDFileBinary(src, in), 0);
  hgd::Shape shape = hgd::readShape(src);
  hgd::deformShape(shape, sc);
  hgd::writeShape(dst, shape);
  pcl::PointCloud<PointT> ref;
  ASSERT_EQ(pcl::io::loadPCDFile(dst, ref), 0);

  ASSERT_EQ(out.width, in.width);
  ASSERT_EQ(out.height, in.height);
  ASSERT_EQ(out.size(), in.size());
  EXPECT_EQ(out.is_dense, in.is_dense);
  EXPECT_TRUE(out.sensor_origin_.isApprox(in.sensor_origin_));
  EXPECT_TRUE(out.sensor_orientation_.isApprox(in.sensor_orientation_));
  double worst = 0, moved = 0;
  std::size_t nan_points = 0;
  for (std::size_t i = 0; i < in.size(); ++i) {
    const PointT &a = in[i], &b = out[i];
    if (!std::isfinite(a.x)) {
      ++nan_points;
      EXPECT_FALSE(std::isfinite(b.x)) << i;
    } else {
      worst = std::max(worst, static_cast<double>((b.getVector3fMap() - ref[i].getVector3fMap()).norm()));
      moved = std::max(moved, static_cast<double>((b.getVector3fMap() - a.getVector3fMap()).norm()));
    }
    PointT masked = b;  // every byte but the position and the normal must be the input's
    masked.x = a.x;
    masked.y = a.y;
    masked.z = a.z;
    if constexpr (pcl::traits::has_normal_v<PointT>) {
      const Eigen::Vector3f n = b.getNormalVector3fMap(), nr = ref[i].getNormalVector3fMap();
      if (std::isfinite(a.x)) {
        EXPECT_LT((n - nr).norm(), 1e-5f) << i;
        EXPECT_NEAR(n.norm(), 1.0f, 1e-4f) << i;
      }
      masked.normal_x = a.normal_x;
      masked.normal_y = a.normal_y;
      masked.normal_z = a.normal_z;
    }
    ASSERT_EQ(std::memcmp(&masked, &a, sizeof(PointT)), 0)
        << "point " << i << ": a field other than x/y/z changed";
  }
  std::printf("%zu NaN points; largest difference from the file path %.3g, largest move %.3g\n", nan_points,
              worst, moved);
  EXPECT_GT(nan_points, 50u);
  // Both paths compute in the same local frame from the same floats: measured 0 for every type;
  // 1e-6 allows for a different summation order, far below one float step at 1200 (1.2e-4).
  EXPECT_LE(worst, 1e-6) << "largest difference from the file path";
  EXPECT_GT(moved, 0.25) << "the dragged end moved";
}

// In place: output may be the input.
TEST(PclDeformInPlace, OutputMayBeTheInput) {
  pcl::PointCloud<pcl::PointXYZRGB> a = plate<pcl::PointXYZRGB>(3), b = a, separate;
  hgd::deform(a, plateScenario(), separate);
  hgd::deform(b, plateScenario(), b);
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (std::isfinite(separate[i].x)) {
      ASSERT_EQ((separate[i].getVector3fMap() - b[i].getVector3fMap()).norm(), 0.0f);
    }
  }
}

pcl::Indices indicesWhere(const pcl::PointCloud<pcl::PointXYZRGB>& c, double lo, double hi) {
  pcl::Indices idx;
  for (std::size_t i = 0; i < c.size(); ++i)
    if (std::isfinite(c[i].x) && c[i].x - kOffset.x() >= lo && c[i].x - kOffset.x() <= hi)
      idx.push_back(static_cast<pcl::index_t>(i));
  return idx;
}

// The stage with handles as pcl::Indices and setHandleTransform against deform() with box
// regions and a frame move doing the same: two different routes to the same handles and motion.
TEST(HandleDeformation, IndicesAndTransformMatchAScenarioWithRegionsAndAFrameMove) {
  const auto cloud = std::make_shared<pcl::PointCloud<pcl::PointXYZRGB>>(plate<pcl::PointXYZRGB>(11));
  Eigen::Affine3d t = Eigen::Affine3d::Identity();
  const Eigen::Vector3d pivot = kOffset + Eigen::Vector3d(0.95, 0.1, 0.0);
  t.translate(pivot + Eigen::Vector3d(0, 0, 0.15));
  t.rotate(Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitY()));
  t.translate(-pivot);

  hgd::HandleDeformation<pcl::PointXYZRGB> hd;
  hd.setInputCloud(cloud);
  hd.setFixedHandles({indicesWhere(*cloud, -1, 0.1)});
  hd.setManipulatedHandle(indicesWhere(*cloud, 0.9, 2));
  hd.setHandleTransform(t);
  pcl::PointCloud<pcl::PointXYZRGB> staged;
  hd.getDeformedCloud(staged);

  hgd::Scenario sc;
  hgd::FrameMove f;
  f.translate = Eigen::Vector3d(0, 0, 0.15);
  f.axis = Eigen::Vector3d::UnitY();
  f.degrees = 0.5 * 180.0 / M_PI;
  f.centre = pivot;
  sc.fix(hgd::Region::box(kOffset + Eigen::Vector3d(-1, -1, -1), kOffset + Eigen::Vector3d(0.1, 1, 1)))
      .manipulate(
          hgd::Region::box(kOffset + Eigen::Vector3d(0.9, -1, -1), kOffset + Eigen::Vector3d(2, 1, 1)))
      .frame(f);
  pcl::PointCloud<pcl::PointXYZRGB> scripted;
  hgd::deform(*cloud, sc, scripted);

  double worst = 0, tip = 0;
  for (std::size_t i = 0; i < cloud->size(); ++i) {
    if (!std::isfinite((*cloud)[i].x)) continue;
    worst = std::max(worst,
                     static_cast<double>((staged[i].getVector3fMap() - scripted[i].getVector3fMap()).norm()));
    tip = std::max(tip,
                   static_cast<double>((staged[i].getVector3fMap() - (*cloud)[i].getVector3fMap()).norm()));
  }
  std::printf("stage vs scenario: largest difference %.3g (tip moved %.3g)\n", worst, tip);
  EXPECT_LE(worst, 1e-6) << "stage vs scenario";  // measured 0
  EXPECT_GT(tip, 0.15);

  // New handles on the same stage (normals and kNN kept) give what a fresh stage gives.
  hd.setManipulatedHandle(indicesWhere(*cloud, 0.4, 0.5));
  hd.setHandleTransform(t);
  pcl::PointCloud<pcl::PointXYZRGB> again, fresh;
  hd.getDeformedCloud(again);
  hgd::HandleDeformation<pcl::PointXYZRGB> hd2;
  hd2.setInputCloud(cloud);
  hd2.setFixedHandles({indicesWhere(*cloud, -1, 0.1)});
  hd2.setManipulatedHandle(indicesWhere(*cloud, 0.4, 0.5));
  hd2.setHandleTransform(t);
  hd2.getDeformedCloud(fresh);
  double diff = 0;
  for (std::size_t i = 0; i < cloud->size(); ++i)
    if (std::isfinite((*cloud)[i].x))
      diff =
          std::max(diff, static_cast<double>((again[i].getVector3fMap() - fresh[i].getVector3fMap()).norm()));
  std::printf("new handles on a used stage vs a fresh stage: %.3g\n", diff);
  EXPECT_LE(diff, 1e-6);  // measured 0
}

// A second scenario with another isovalue count (and then another blend) on the same stage is
// built as a fresh stage builds it: the stage, the runner and Python share one session, whose
// rebuild rule makes a new deformer when the isovalue count changes. Compared bit for bit with
// deform() on the second scenario alone.
TEST(HandleDeformation, ASecondScenarioWithOtherClustersIsBuiltAsAFreshOne) {
  const auto cloud = std::make_shared<pcl::PointCloud<pcl::PointXYZ>>(plate<pcl::PointXYZ>(13));
  hgd::Scenario s12 = plateScenario(), s5 = plateScenario();
  s12.clusters = 12;
  s5.clusters = 5;
  hgd::HandleDeformation<pcl::PointXYZ> hd;
  hd.setInputCloud(cloud);
  hd.setScenario(s12);
  pcl::PointCloud<pcl::PointXYZ> first, second, expected;
  hd.getDeformedCloud(first);
  const std::size_t clusters12 = hd.runner().deformer().clustering().clusters.size();
  hd.setScenario(s5);
  hd.getDeformedCloud(second);
  const std::size_t clusters5 = hd.runner().deformer().clustering().clusters.size();
  hgd::deform(*cloud, s5, expected);
  std::printf("clusters: %zu at 12 isovalues, %zu at 5\n", clusters12, clusters5);
  EXPECT_LT(clusters5, clusters12);
  std::size_t differ = 0, moved = 0;
  for (std::size_t i = 0; i < cloud->size(); ++i) {
    if (!std::isfinite((*cloud)[i].x)) continue;
    differ += std::memcmp(&second[i], &expected[i], sizeof(float) * 3) != 0;
    moved += std::memcmp(&second[i], &first[i], sizeof(float) * 3) != 0;
  }
  EXPECT_EQ(differ, 0u) << "the second scenario on a used stage vs deform() with it";
  EXPECT_GT(moved, 100u) << "the isovalue count changes the result";
  EXPECT_EQ(hd.runner().report().isovalues, 5);

  // The blend alone: applied to the same deformer, as a fresh stage with that blend gives.
  hgd::Scenario linear = s5;
  linear.blend = hgd::Blend::Linear;
  const hgd::Deformer* before = &hd.runner().deformer();
  hd.setScenario(linear);
  pcl::PointCloud<pcl::PointXYZ> blended, blended_expected;
  hd.getDeformedCloud(blended);
  EXPECT_EQ(before, &hd.runner().deformer()) << "a blend change rebuilt the deformer";
  hgd::deform(*cloud, linear, blended_expected);
  differ = 0;
  for (std::size_t i = 0; i < cloud->size(); ++i)
    if (std::isfinite((*cloud)[i].x))
      differ += std::memcmp(&blended[i], &blended_expected[i], sizeof(float) * 3) != 0;
  EXPECT_EQ(differ, 0u) << "the linear blend on a used stage vs deform() with it";
}

// Interactive frames: the cursor moves in 40 steps; the picked point follows it.
TEST(HandleDeformation, DragFramesFollowTheCursor) {
  const auto cloud = std::make_shared<pcl::PointCloud<pcl::PointXYZRGB>>(plate<pcl::PointXYZRGB>(5));
  hgd::HandleDeformation<pcl::PointXYZRGB> hd;
  hd.setInputCloud(cloud);
  hd.setFixedHandles({indicesWhere(*cloud, -1, 0.1)});
  hd.setManipulatedHandle(indicesWhere(*cloud, 0.9, 2));
  // The picked point: the manipulated point nearest the press.
  const Eigen::Vector3d press = kOffset + Eigen::Vector3d(0.97, 0.1, 0.0);
  std::size_t picked = 0;
  double best = 1e9;
  for (auto i : indicesWhere(*cloud, 0.9, 2)) {
    const double d = ((*cloud)[static_cast<std::size_t>(i)].getVector3fMap().cast<double>() - press).norm();
    if (d < best) best = d, picked = static_cast<std::size_t>(i);
  }
  const Eigen::Vector3d from = (*cloud)[picked].getVector3fMap().cast<double>();
  const Eigen::Vector3d target = from + Eigen::Vector3d(-0.05, 0.0, 0.25);
  Eigen::Vector3d cur = from;
  for (int k = 1; k <= 40; ++k) {
    const Eigen::Vector3d next = from + (target - from) * (k / 40.0);
    hd.drag(cur, next);
    cur = next;
  }
  for (int k = 0; k < 20; ++k) hd.drag(target, target);  // held there
  pcl::PointCloud<pcl::PointXYZRGB> out;
  hd.getDeformedCloud(out);
  const double error = (out[picked].getVector3fMap().cast<double>() - target).norm();
  std::printf("picked point %.3g from the cursor after 60 frames\n", error);
  EXPECT_LT(error, 2e-3);  // measured 6.3e-4 (the drag tolerance is 1e-4 of the diagonal per frame)
  hd.reset();
  hd.getDeformedCloud(out);
  EXPECT_LT((out[picked].getVector3fMap().cast<double>() - from).norm(), 1e-4);
}

TEST(HandleDeformation, MissingInputOrHandlesAreClearErrors) {
  hgd::HandleDeformation<pcl::PointXYZ> hd;
  pcl::PointCloud<pcl::PointXYZ> out;
  EXPECT_THROW(hd.getDeformedCloud(out), std::invalid_argument);
  const auto cloud = std::make_shared<pcl::PointCloud<pcl::PointXYZ>>(plate<pcl::PointXYZ>(1));
  hd.setInputCloud(cloud);
  try {
    hd.drag(Eigen::Vector3d::Zero(), Eigen::Vector3d::Ones());
    FAIL() << "no handles";
  } catch (const hgd::ScenarioError& e) {
    EXPECT_TRUE(hgdtest::contains(e.what(), "fixed handle")) << e.what();
  }
  hd.setFixedHandles({{0, 1, 2}});
  hd.setManipulatedHandle({static_cast<pcl::index_t>(cloud->size())});  // past the end
  try {
    hd.drag(Eigen::Vector3d::Zero(), Eigen::Vector3d::Ones());
    FAIL() << "index past the end";
  } catch (const hgd::ScenarioError& e) {
    EXPECT_TRUE(hgdtest::contains(e.what(), "/manipulated")) << e.what();
  }
}

// A scenario built in code is the scenario its JSON describes.
TEST(ScenarioBuilder, MatchesTheParsedJsonAndNamesItsRegions) {
  hgd::Scenario s;
  hgd::FrameMove f;
  f.translate = Eigen::Vector3d(0.5, 0, 0);
  f.axis = Eigen::Vector3d::UnitX();
  f.degrees = 30;
  s.fix(hgd::Region::box(Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(0, 1, 1)))
      .fix(hgd::Region::sphere(Eigen::Vector3d(5, 5, 5), 0.1))
      .manipulate(hgd::Region::sphere(Eigen::Vector3d(1, 0, 0), 0.2))
      .drag(Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(1, 0.5, 0))
      .frame(f);
  s.blend = hgd::Blend::Linear;
  const std::string json =
      R"({"fixed": [{"box": {"min": [-1, -1, -1], "max": [0, 1, 1]}}, {"sphere": {"center": [5, 5, 5], "radius": 0.1}}],
          "manipulated": {"sphere": {"center": [1, 0, 0], "radius": 0.2}}, "blend": "linear",
          "move": [{"drag": {"from": [1, 0, 0], "to": [1, 0.5, 0]}},
                   {"frame": {"translate": [0.5, 0, 0], "rotate": {"axis": [1, 0, 0], "degrees": 30}}}]})";
  EXPECT_EQ(hgd::scenarioToJson(s), hgd::scenarioToJson(hgd::parseScenario(json, "s.json")));
  // The second fixed sphere selects nothing on the plate: the error names it as a file would.
  const pcl::PointCloud<pcl::PointXYZ> c = plate<pcl::PointXYZ>(2);
  pcl::PointCloud<pcl::PointXYZ> out;
  hgd::Scenario t;
  t.fix(hgd::Region::box(kOffset + Eigen::Vector3d(-1, -1, -1), kOffset + Eigen::Vector3d(0.1, 1, 1)))
      .fix(hgd::Region::sphere(Eigen::Vector3d(5, 5, 5), 0.1))
      .manipulate(
          hgd::Region::box(kOffset + Eigen::Vector3d(0.9, -1, -1), kOffset + Eigen::Vector3d(2, 1, 1)));
  try {
    hgd::deform(c, t, out);
    FAIL() << "an empty region was accepted";
  } catch (const hgd::ScenarioError& e) {
    EXPECT_TRUE(hgdtest::contains(e.what(), "/fixed/1")) << e.what();
  }
}

}  // namespace
