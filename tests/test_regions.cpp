// Scenario regions for scans: per-point field values (labels, intensity ranges) and cylinders,
// checked against selections the tests compute themselves, and their errors with JSON paths.
#include <pcl/PCLPointCloud2.h>

#include <cmath>
#include <limits>
#include <numeric>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "hgdeform/app/regions.h"
#include "hgdeform/app/scenario.h"
#include "hgdeform/deformer/deformer.h"
#include "hgdeform/io/fields.h"
#include "hgdeform/io/io.h"
#include "support/shapes.h"
#include "test_util.h"

using hgdtest::contains;
using hgdtest::quote;
using hgdtest::shell;
using hgdtest::TempDir;

namespace {

/// A labelled scan as a depth camera's segmentation would give it: an organized 48x36 cloud of
/// a bumpy sheet whose samples sit in random raster cells, 10% of them NaN, with an intensity
/// (float, random) and a label (uint32: 1 at the left end, 2 at the right end, 0 between).
struct LabelledScan {
  hgd::Shape shape;
  std::vector<unsigned> label;   ///< per file point, NaN points included
  std::vector<float> intensity;  ///< per file point
  std::vector<bool> finite;      ///< per file point
};

LabelledScan labelledScan(unsigned seed) {
  constexpr int kW = 48, kH = 36;
  LabelledScan s;
  auto& c = s.shape.cloud;
  c.width = kW;
  c.height = kH;
  c.is_dense = false;
  const char* names[] = {"x", "y", "z", "intensity", "label"};
  for (int k = 0; k < 5; ++k) {
    pcl::PCLPointField f;
    f.name = names[k];
    f.offset = static_cast<std::uint32_t>(4 * k);
    f.datatype = k < 4 ? pcl::PCLPointField::FLOAT32 : pcl::PCLPointField::UINT32;
    f.count = 1;
    c.fields.push_back(f);
  }
  c.point_step = 20;
  c.row_step = c.point_step * kW;
  c.data.assign(static_cast<std::size_t>(c.row_step) * kH, 0);
  s.shape.format = hgd::FileFormat::Pcd;

  std::mt19937 rng(seed);
  std::vector<int> cell(kW * kH);
  std::iota(cell.begin(), cell.end(), 0);
  std::shuffle(cell.begin(), cell.end(), rng);  // sample k goes to raster cell cell[k]
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  const std::size_t n = cell.size();
  s.label.resize(n);
  s.intensity.resize(n);
  s.finite.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    const auto p = static_cast<std::size_t>(cell[k]);
    const float x = static_cast<float>(k % kW) / (kW - 1), y = 0.75f * static_cast<float>(k / kW) / (kH - 1);
    const float z = 0.03f * std::sin(9.0f * x) * std::cos(7.0f * y);
    s.finite[p] = unit(rng) >= 0.1f;
    const float nan = std::numeric_limits<float>::quiet_NaN();
    s.label[p] = x < 0.15f ? 1u : x > 0.85f ? 2u : 0u;
    s.intensity[p] = unit(rng);
    if (k % 97 == 0) s.intensity[p] = 0.25f;  // on the bounds of the range tested below
    if (k % 89 == 0) s.intensity[p] = 0.5f;
    const float xyz[3] = {s.finite[p] ? x : nan, s.finite[p] ? y : nan, s.finite[p] ? z : nan};
    for (int a = 0; a < 3; ++a) hgd::writeValue(c, p, c.fields[static_cast<std::size_t>(a)], xyz[a]);
    hgd::writeValue(c, p, c.fields[3], s.intensity[p]);
    hgd::writeValue(c, p, c.fields[4], s.label[p]);
  }
  return s;
}

/// File indices of the points a region list selected.
std::set<long long> fileIndices(const hgd::Geometry& g, const std::vector<int>& selected) {
  std::set<long long> out;
  for (int i : selected) out.insert(g.raw_index[static_cast<std::size_t>(i)]);
  return out;
}

std::string scenarioJson(const std::string& fixed, const std::string& manipulated,
                         const std::string& rest = "") {
  return R"({"format": "hgdeform-scenario/1", "fixed": [)" + fixed + R"(], "manipulated": )" + manipulated +
         rest + "}";
}

/// The ScenarioError message of parsing (and resolving on `shape`) a scenario, or "".
std::string errorOf(const std::string& json, const hgd::Shape& shape) {
  try {
    const hgd::Scenario s = hgd::parseScenario(json, "s.json");
    const hgd::Geometry g = hgd::extractGeometry(shape);
    hgd::resolveHandles(s, g, shape);
  } catch (const hgd::ScenarioError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

// "label == 1 fixed": exactly the finite points the test labelled 1, wherever the file put them,
// and none of the NaN points that carry the label too. The scan goes through a PCD file.
TEST(Regions, FieldEqualsSelectsTheLabelledPoints) {
  TempDir dir;
  const LabelledScan scan = labelledScan(3);
  hgd::writeShape(dir.file("scan.pcd"), scan.shape);
  const hgd::Shape shape = hgd::readShape(dir.file("scan.pcd"));
  ASSERT_EQ(shape.cloud.height, 36u);
  const hgd::Geometry g = hgd::extractGeometry(shape);
  const hgd::Scenario sc = hgd::parseScenario(scenarioJson(R"({"field": {"name": "label", "equals": 1}})",
                                                           R"({"field": {"name": "label", "equals": 2}})"),
                                              "s.json");
  const hgd::Handles h = hgd::resolveHandles(sc, g, shape);
  std::set<long long> want1, want2;
  std::size_t nan_labelled = 0;
  for (std::size_t p = 0; p < scan.label.size(); ++p) {
    if (!scan.finite[p]) {
      nan_labelled += scan.label[p] == 1;
      continue;
    }
    if (scan.label[p] == 1) want1.insert(static_cast<long long>(p));
    if (scan.label[p] == 2) want2.insert(static_cast<long long>(p));
  }
  ASSERT_GT(nan_labelled, 0u) << "the test needs NaN points with the label";
  ASSERT_GT(want1.size(), 50u);
  ASSERT_EQ(h.fixed.size(), 1u);
  EXPECT_EQ(fileIndices(g, h.fixed[0]), want1);
  EXPECT_EQ(fileIndices(g, h.manipulated), want2);
  // The static constructor selects the same.
  EXPECT_EQ(hgd::selectRegion(hgd::Region::field("label", 1), g, shape, "s.json"), h.fixed[0]);
}

TEST(Regions, FieldRangeIsInclusiveAndMayBeOneSided) {
  const LabelledScan scan = labelledScan(5);
  const hgd::Geometry g = hgd::extractGeometry(scan.shape);
  auto expected = [&](float lo, float hi) {
    std::set<long long> out;
    for (std::size_t p = 0; p < scan.intensity.size(); ++p)
      if (scan.finite[p] && scan.intensity[p] >= lo && scan.intensity[p] <= hi)
        out.insert(static_cast<long long>(p));
    return out;
  };
  const hgd::Scenario sc =
      hgd::parseScenario(scenarioJson(R"({"field": {"name": "intensity", "min": 0.25, "max": 0.5}})",
                                      R"({"field": {"name": "intensity", "min": 0.9}})"),
                         "s.json");
  const auto want = expected(0.25f, 0.5f);
  std::size_t on_bounds = 0;
  for (long long p : want)
    on_bounds += scan.intensity[static_cast<std::size_t>(p)] == 0.25f ||
                 scan.intensity[static_cast<std::size_t>(p)] == 0.5f;
  ASSERT_GT(on_bounds, 4u) << "the test needs points on the bounds";
  const hgd::Handles h = hgd::resolveHandles(sc, g, scan.shape);
  EXPECT_EQ(fileIndices(g, h.fixed[0]), want);
  EXPECT_EQ(fileIndices(g, h.manipulated), expected(0.9f, 2.0f));
  const auto below =
      hgd::selectRegion(hgd::Region::fieldRange("intensity", -std::numeric_limits<double>::infinity(), 0.1),
                        g, scan.shape, "s");
  EXPECT_EQ(fileIndices(g, below), expected(-1.0f, 0.1f));
}

// Within r of the segment, flat caps: against a brute-force distance to the segment.
TEST(Regions, CylinderMatchesBruteForceDistanceToSegment) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<Eigen::Vector3f> pts(20000);
  for (auto& p : pts) p = Eigen::Vector3f(u(rng), u(rng), u(rng)) + Eigen::Vector3f(100, 200, -50);
  const hgd::Geometry g = hgd::extractGeometry(hgd::shapes::cloudShape(pts, {}));
  const Eigen::Vector3d a(99.7, 199.6, -50.2), b(100.5, 200.4, -49.5);
  const double r = 0.3;
  std::set<long long> want, near_caps;
  for (std::size_t i = 0; i < g.size(); ++i) {
    const Eigen::Vector3d p = g.world(i);
    const Eigen::Vector3d d = b - a;
    const double along = (p - a).dot(d) / d.norm();
    const double off_axis = (p - a).cross(d).norm() / d.norm();
    if (along >= 0 && along <= d.norm() && off_axis <= r) want.insert(g.raw_index[i]);
    // Inside the infinite cylinder but past a cap: a sphere-capped selection would take some.
    if ((along < 0 || along > d.norm()) && off_axis <= r) near_caps.insert(g.raw_index[i]);
  }
  ASSERT_GT(want.size(), 500u);
  ASSERT_GT(near_caps.size(), 50u);
  const hgd::Scenario sc = hgd::parseScenario(
      scenarioJson(
          R"({"cylinder": {"start": [99.7, 199.6, -50.2], "end": [100.5, 200.4, -49.5], "radius": 0.3}})",
          R"({"sphere": {"center": [101, 201, -49], "radius": 0.2}})"),
      "s.json");
  const hgd::Handles h = hgd::resolveHandles(sc, g);  // no field region: the shape is not needed
  EXPECT_EQ(fileIndices(g, h.fixed[0]), want);
  EXPECT_EQ(hgd::selectRegion(hgd::Region::cylinder(a, b, r), g, "s.json"), h.fixed[0]);
}

TEST(Regions, ErrorsNameTheirJsonPath) {
  const hgd::Shape shape = labelledScan(7).shape;
  const std::string fix = R"({"field": {"name": "label", "equals": 1}})";
  const std::string manip = R"({"field": {"name": "label", "equals": 2}})";
  ASSERT_EQ(errorOf(scenarioJson(fix, manip), shape), "");
  const struct {
    std::string json, message;
  } cases[] = {
      {scenarioJson(R"({"field": {"name": "labels", "equals": 1}})", manip),
       "s.json: /fixed/0/field/name: the shape has no field 'labels' (its fields: x, y, z, intensity, "
       "label)"},
      {scenarioJson(fix, R"({"field": {"name": "label", "equals": 2, "max": 3}})"),
       "s.json: /manipulated/field/max: cannot go with equals (one value, or a range)"},
      {scenarioJson(fix, R"({"field": {"name": "intensity", "min": 0.6, "max": 0.5}})"),
       "s.json: /manipulated/field/min: must not exceed max"},
      {scenarioJson(fix, R"({"field": {"name": "intensity"}})"),
       "s.json: /manipulated/field: needs equals, or min and/or max"},
      {scenarioJson(fix, R"({"field": {"name": "", "equals": 1}})"),
       "s.json: /manipulated/field/name: must be a field name"},
      {scenarioJson(fix, R"({"field": {"name": "label", "equals": 7}})"),
       "s.json: /manipulated: selects no point of the shape"},
      {scenarioJson(fix, manip, R"(, "joints": [{"field": {"name": "intensity", "min": 5}}])"),
       "s.json: /joints/0: selects no point of the shape"},
      {scenarioJson(fix, R"({"field": {"name": "rgb", "min": 0}})"),
       "s.json: /manipulated/field/min: a packed colour (rgb) has no order: select one colour with equals"},
      {scenarioJson(fix, R"({"field": {"name": "rgb", "equals": 0.5}})"),
       "s.json: /manipulated/field/equals: must be the packed colour as an integer (0xRRGGBB, from 0 to "
       "16777215)"},
      {scenarioJson(fix, R"({"cylinder": {"start": [0, 0, 0], "end": [1, 0, 0], "radius": 0}})"),
       "s.json: /manipulated/cylinder/radius: must be a positive number"},
      {scenarioJson(fix, R"({"cylinder": {"start": [0, 0, 0], "end": [1, 0, 0], "radius": -2}})"),
       "s.json: /manipulated/cylinder/radius: must be a positive number"},
      {scenarioJson(fix, R"({"cylinder": {"start": [1, 2, 3], "end": [1, 2, 3], "radius": 1}})"),
       "s.json: /manipulated/cylinder/end: must differ from start"},
      {scenarioJson(fix, R"({"cylinder": {"start": [1, 2, 3], "radius": 1}})"),
       "s.json: /manipulated/cylinder/end: is required"},
      {scenarioJson(fix, R"({"cylinder": {"start": [1, 2, 3], "end": [1, 2, 4], "radius": 1, "r": 1}})"),
       "s.json: /manipulated/cylinder/r: unknown key (expected one of: start, end, radius)"},
      {scenarioJson(fix, R"({"cylinder": {"start": [50, 50, 50], "end": [51, 50, 50], "radius": 0.1}})"),
       "s.json: /manipulated: selects no point of the shape"},
  };
  for (const auto& c : cases) EXPECT_EQ(errorOf(c.json, shape), c.message) << c.json;
  // A shape without the field (the bar has x, y, z and normals).
  EXPECT_TRUE(
      contains(errorOf(scenarioJson(fix, manip), hgd::shapes::bar()),
               "s.json: /manipulated/field/name: the shape has no field 'label' (its fields: x, y, z"));
  // Without the shape, a field region cannot be resolved: said, not guessed.
  const hgd::Geometry g = hgd::extractGeometry(shape);
  try {
    hgd::resolveHandles(hgd::parseScenario(scenarioJson(fix, manip), "s.json"), g);
    ADD_FAILURE() << "resolved a field region without the shape";
  } catch (const hgd::ScenarioError& e) {
    EXPECT_TRUE(contains(e.what(), "s.json: /manipulated/field: a field region needs the shape's fields"))
        << e.what();
  }
}

// A packed colour selects by its 0xRRGGBB value, whatever alpha the writer put in.
TEST(Regions, PackedRgbEqualsSelectsOneColour) {
  std::vector<Eigen::Vector3f> pts;
  for (int i = 0; i < 200; ++i) pts.emplace_back(0.01f * static_cast<float>(i), 0.0f, 0.0f);
  hgd::Shape shape = hgd::shapes::cloudShape(pts, {});
  const int k = hgd::addFloatField(shape.cloud, "rgb");
  const auto& f = shape.cloud.fields[static_cast<std::size_t>(k)];
  std::set<long long> red;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const std::uint32_t packed = i % 3 == 0 ? 0xFFFF0000u : 0xFF0000FFu;
    if (i % 3 == 0) red.insert(static_cast<long long>(i));
    std::memcpy(shape.cloud.data.data() + i * shape.cloud.point_step + f.offset, &packed, 4);
  }
  const hgd::Geometry g = hgd::extractGeometry(shape);
  EXPECT_EQ(fileIndices(g, hgd::selectRegion(hgd::Region::field("rgb", 0xFF0000), g, shape, "s")), red);
  // A range over packed colours, built in code (the parser refuses it): refused here too.
  try {
    hgd::selectRegion(hgd::Region::fieldRange("rgb", 0, 0xFF), g, shape, "s");
    ADD_FAILURE() << "a range of packed colours was accepted";
  } catch (const hgd::ScenarioError& e) {
    EXPECT_TRUE(contains(e.what(), "s: region/field: a packed colour (rgb) has no order")) << e.what();
  }
}

TEST(Regions, NewKindsRoundTripThroughScenarioJson) {
  hgd::Scenario s;
  s.fixed = {hgd::Region::field("label", 1), hgd::Region::fieldRange("intensity", 0.25, 0.5),
             hgd::Region::fieldRange("intensity", -std::numeric_limits<double>::infinity(), 0.125),
             hgd::Region::field("rgb", 0xFF8000), hgd::Region::field("height", 0.1)};
  s.manipulated = hgd::Region::cylinder({0, 0, 1}, {0.5, 0.25, 2}, 0.3);
  s.joints = {hgd::Region::fieldRange("intensity", 0.75, std::numeric_limits<double>::infinity())};
  const std::string text = hgd::scenarioToJson(s);
  EXPECT_TRUE(contains(text, "\"equals\": 1,")) << text;  // a label stays an integer
  const hgd::Scenario back = hgd::parseScenario(text, "saved.json");
  ASSERT_EQ(back.fixed.size(), s.fixed.size());
  for (std::size_t i = 0; i < s.fixed.size(); ++i) {
    SCOPED_TRACE(i);
    EXPECT_EQ(back.fixed[i].kind, hgd::Region::Kind::Field);
    EXPECT_EQ(back.fixed[i].field_name, s.fixed[i].field_name);
    EXPECT_EQ(back.fixed[i].equals, s.fixed[i].equals);
    EXPECT_EQ(back.fixed[i].field_min, s.fixed[i].field_min);
    EXPECT_EQ(back.fixed[i].field_max, s.fixed[i].field_max);
  }
  EXPECT_EQ(back.manipulated.kind, hgd::Region::Kind::Cylinder);
  EXPECT_EQ(back.manipulated.start, s.manipulated.start);
  EXPECT_EQ(back.manipulated.end, s.manipulated.end);
  EXPECT_EQ(back.manipulated.radius, 0.3);
  ASSERT_EQ(back.joints.size(), 1u);
  EXPECT_EQ(back.joints[0].field_min, 0.75);
  EXPECT_EQ(back.joints[0].field_max, std::numeric_limits<double>::infinity());
  EXPECT_EQ(hgd::scenarioToJson(back), text);
}

// `hgdeform deform` with "label 1 fixed, label 2 moved": the labelled ends do what the
// scenario says, in a PCD that keeps its layout, NaNs and fields.
TEST(Regions, DeformCliWithFieldRegions) {
  TempDir dir;
  const LabelledScan scan = labelledScan(13);
  hgd::writeShape(dir.file("scan.pcd"), scan.shape);
  hgdtest::writeText(dir.file("s.json"), scenarioJson(R"({"field": {"name": "label", "equals": 1}})",
                                                      R"({"field": {"name": "label", "equals": 2}})",
                                                      R"(, "move": {"frame": {"translate": [0, 0, 0.2]}})"));
  const auto r = shell(quote(HGD_TOOL) + " deform " + quote(dir.file("scan.pcd")) + " --scenario " +
                       quote(dir.file("s.json")) + " -o " + quote(dir.file("out.pcd")));
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  const hgd::Shape in = hgd::readShape(dir.file("scan.pcd")), out = hgd::readShape(dir.file("out.pcd"));
  ASSERT_EQ(out.cloud.width, in.cloud.width);
  ASSERT_EQ(out.cloud.height, in.cloud.height);
  ASSERT_GE(hgd::findField(out.cloud, "label"), 0);
  const auto& c = out.cloud;
  const int z = hgd::findField(c, "z");
  std::size_t fixed = 0, moved = 0;
  for (std::size_t p = 0; p < scan.label.size(); ++p) {
    const double z1 = hgd::readValue(c, p, c.fields[static_cast<std::size_t>(z)]);
    const double z0 = hgd::readValue(in.cloud, p, in.cloud.fields[static_cast<std::size_t>(z)]);
    if (!scan.finite[p]) {
      EXPECT_TRUE(std::isnan(z1)) << p;
      continue;
    }
    if (scan.label[p] == 1) {
      EXPECT_NEAR(z1, z0, 1e-6) << p;
      ++fixed;
    } else if (scan.label[p] == 2) {
      EXPECT_NEAR(z1, z0 + 0.2, 1e-5) << p;
      ++moved;
    }
  }
  EXPECT_GT(fixed, 50u);
  EXPECT_GT(moved, 50u);
  // A field the scan does not have: the CLI says which region and which field.
  hgdtest::writeText(dir.file("bad.json"), scenarioJson(R"({"field": {"name": "class", "equals": 1}})",
                                                        R"({"field": {"name": "label", "equals": 2}})"));
  const auto bad = shell(quote(HGD_TOOL) + " deform " + quote(dir.file("scan.pcd")) + " --scenario " +
                         quote(dir.file("bad.json")) + " -o " + quote(dir.file("bad.pcd")));
  EXPECT_NE(bad.code, 0);
  EXPECT_TRUE(contains(bad.err, "/fixed/0/field/name: the shape has no field 'class'")) << bad.err;
  EXPECT_FALSE(hgdtest::exists(dir.file("bad.pcd")));
}
