// Skeletal deformation (paper §5, Fig. 6-7) and the rotation-aware blend.
#include <Eigen/Dense>
#include <cmath>

#include "hgdeform/deformer.h"
#include "support/shapes.h"
#include "test_util.h"

using hgdtest::pointsWhere;
using hgdtest::rigidResidual;

namespace {

// The points that lie wholly in one bone (both bracketing clusters are that range cluster).
std::vector<std::vector<int>> bones(const hgd::Deformer& d) {
  const auto& c = d.clustering();
  std::vector<std::vector<int>> out(c.clusters.size());
  for (std::size_t i = 0; i < c.down.size(); ++i)
    if (c.down[i] == c.up[i] &&
        c.clusters[static_cast<std::size_t>(c.down[i])].kind == hgd::ClusterKind::Range)
      out[static_cast<std::size_t>(c.down[i])].push_back(static_cast<int>(i));
  std::vector<std::vector<int>> nonempty;
  for (auto& b : out)
    if (!b.empty()) nonempty.push_back(std::move(b));
  return nonempty;
}

double boneResidual(const hgd::Deformer& d, const std::vector<int>& bone) {
  std::vector<Eigen::Vector3d> a, b;
  for (int i : bone) {
    a.push_back(d.geometry().world(static_cast<std::size_t>(i)));
    b.push_back(d.deformedWorld(static_cast<std::size_t>(i)));
  }
  return rigidResidual(a, b);
}

double meanDisplacement(const hgd::Deformer& d, double x_lo, double x_hi) {
  double sum = 0;
  int count = 0;
  for (std::size_t i = 0; i < d.geometry().size(); ++i) {
    const double x = d.geometry().world(i).x();
    if (x < x_lo || x > x_hi) continue;
    sum += (d.deformedWorld(i) - d.geometry().world(i)).norm();
    ++count;
  }
  return sum / count;
}

Eigen::Affine3d turnAbout(const Eigen::Vector3d& centre, double degrees, const Eigen::Vector3d& axis) {
  Eigen::Affine3d t = Eigen::Affine3d::Identity();
  t.translate(centre);
  t.rotate(Eigen::AngleAxisd(degrees * M_PI / 180.0, axis.normalized()));
  t.translate(-centre);
  return t;
}

// Cylinder (Fig. 7): fixed at one end, one joint in the middle, the free end turned 90 degrees.
TEST(Skeletal, CylinderWithOneJointBendsInTheJoint) {
  const hgd::Geometry g = hgd::extractGeometry(hgd::shapes::cylinder(1.0f, 0.08f, 0.01f));
  hgd::Handles h;
  h.fixed.push_back(pointsWhere(g, 0, -1, 0.04));
  h.manipulated = pointsWhere(g, 0, 0.96, 2);
  const Eigen::Affine3d turn = turnAbout({0.5, 0, 0}, 90, Eigen::Vector3d::UnitZ());
  const double diag = hgd::boundingBoxDiagonal(g);

  hgd::Handles skeletal = h;
  skeletal.joints.push_back(pointsWhere(g, 0, 0.45, 0.55));
  hgd::Deformer d(g, skeletal);
  d.setHandleTransform(turn);
  const auto b = bones(d);
  ASSERT_EQ(b.size(), 2u);
  for (const auto& bone : b) {
    const double r = boneResidual(d, bone);
    std::printf("cylinder bone of %zu points: rigid-fit residual %.2e of the diagonal\n", bone.size(),
                r / diag);
    EXPECT_LE(r, 1e-4 * diag);
  }
  // The bend is in the joint: the upper arm stays, the forearm follows the handle.
  const double upper = meanDisplacement(d, 0.05, 0.4), fore = meanDisplacement(d, 0.6, 0.95);
  double follow = 0;
  int count = 0;
  for (std::size_t i = 0; i < g.size(); ++i)
    if (g.world(i).x() > 0.6 && g.world(i).x() < 0.95) {
      follow += (d.deformedWorld(i) - turn * g.world(i)).norm();
      ++count;
    }
  std::printf("skeletal: upper arm moved %.4f, forearm %.4f (off the handle's motion by %.4f)\n", upper, fore,
              follow / count);
  EXPECT_LT(upper, 0.01 * diag);
  EXPECT_LT(follow / count, 0.02 * diag);

  // Without joints: a rubber-like "spine" that bends along the whole length.
  hgd::Deformer spine(g, h);
  spine.setHandleTransform(turn);
  const double spine_upper = meanDisplacement(spine, 0.2, 0.4);
  std::printf("spine: the same stretch of the upper part moved %.4f\n", spine_upper);
  EXPECT_GT(spine_upper, 0.02 * diag);
  EXPECT_GT(spine_upper, 10 * meanDisplacement(d, 0.2, 0.4));
}

// Two joints (elbow and wrist on a procedural arm): three rigid bones.
TEST(Skeletal, ArmWithElbowAndWristHasThreeRigidBones) {
  const hgd::Geometry g = hgd::extractGeometry(hgd::shapes::cylinder(1.5f, 0.07f, 0.01f));
  hgd::Handles h;
  h.fixed.push_back(pointsWhere(g, 0, -1, 0.04));
  h.manipulated = pointsWhere(g, 0, 1.46, 2);
  h.joints.push_back(pointsWhere(g, 0, 0.46, 0.54));  // elbow
  h.joints.push_back(pointsWhere(g, 0, 0.96, 1.04));  // wrist
  hgd::Deformer d(g, h);
  const Eigen::Vector3d from(1.5, 0.0, 0.0);
  const hgd::DragResult r = d.dragTo(from, {1.1, 0.6, 0.1});
  EXPECT_TRUE(r.reached);
  const double diag = hgd::boundingBoxDiagonal(g);
  const auto b = bones(d);
  ASSERT_EQ(b.size(), 3u);
  for (const auto& bone : b) {
    const double res = boneResidual(d, bone);
    std::printf("arm bone of %zu points: rigid-fit residual %.2e of the diagonal\n", bone.size(), res / diag);
    EXPECT_LE(res, 1e-4 * diag);
  }
}

TEST(Skeletal, OverlappingJointsMergeWithANote) {
  const hgd::Geometry g = hgd::extractGeometry(hgd::shapes::cylinder(1.0f, 0.08f, 0.02f));
  hgd::Handles h;
  h.fixed.push_back(pointsWhere(g, 0, -1, 0.04));
  h.manipulated = pointsWhere(g, 0, 0.96, 2);
  h.joints.push_back(pointsWhere(g, 0, 0.40, 0.50));
  h.joints.push_back(pointsWhere(g, 0, 0.45, 0.60));
  hgd::Deformer d(g, h);
  ASSERT_EQ(d.clustering().notes.size(), 1u);
  EXPECT_NE(d.clustering().notes[0].find("overlapping"), std::string::npos);
  EXPECT_EQ(bones(d).size(), 2u);  // one merged joint: two bones
}

// Blending: a bar twisted 180 degrees with 4 clusters. The linear blend of transforms shrinks
// the cross-section between clusters; the rotation-aware blend keeps it.
TEST(Blend, RotationAwareBlendKeepsTheCrossSectionOfATwistedBar) {
  const hgd::Geometry g = hgd::extractGeometry(hgd::shapes::bar(1.0f, 0.1f, 0.01f));
  hgd::Handles h;
  h.fixed.push_back(pointsWhere(g, 0, -1, 0.02));
  h.manipulated = pointsWhere(g, 0, 0.98, 2);
  hgd::DeformOptions opt;
  opt.clusters.isoclusters = 4;
  hgd::Deformer d(g, h, opt);
  d.setHandleTransform(turnAbout({0, 0, 0}, 180, Eigen::Vector3d::UnitX()));
  // Cross-section "area" of a slice: sqrt(det) of the covariance of its points across the bar.
  auto area = [&](double x0, bool deformed) {
    std::vector<Eigen::Vector3d> pts;
    for (std::size_t i = 0; i < g.size(); ++i)
      if (std::abs(g.world(i).x() - x0) < 0.004) pts.push_back(deformed ? d.deformedWorld(i) : g.world(i));
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (const auto& p : pts) mean += p.tail<2>();
    mean /= static_cast<double>(pts.size());
    Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
    for (const auto& p : pts) cov += (p.tail<2>() - mean) * (p.tail<2>() - mean).transpose();
    return std::sqrt(cov.determinant());
  };
  double worst[2] = {1, 1};
  const hgd::Blend modes[2] = {hgd::Blend::Linear, hgd::Blend::Rotation};
  for (int m = 0; m < 2; ++m) {
    d.setBlend(modes[m]);
    for (double x = 0.05; x < 0.95; x += 0.02) worst[m] = std::min(worst[m], area(x, true) / area(x, false));
  }
  std::printf(
      "twisted bar, 4 clusters: smallest cross-section %.1f%% of rest with the linear blend, %.1f%% with the "
      "rotation-aware blend\n",
      100 * worst[0], 100 * worst[1]);
  EXPECT_GE(worst[1], 0.95);
  EXPECT_LT(worst[0], worst[1]);
  EXPECT_LT(worst[0], 0.95);
}

}  // namespace
