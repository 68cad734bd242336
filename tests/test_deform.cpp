// The paper's demonstrations as checks (ALGORITHM.md §6).
#include <Eigen/Dense>
#include <cmath>

#include "hgdeform/deformer.h"
#include "hgdeform/shapes.h"
#include "test_util.h"

using hgdtest::pointsWhere;

namespace {

// Bar (Fig. 2): one end fixed, the other dragged sideways by half the bar's length.
TEST(Deform, BarDragBendsSmoothly) {
  const hgd::Shape shape = hgd::shapes::bar(1.0f, 0.1f, 0.01f);
  const hgd::Geometry g = hgd::extractGeometry(shape);
  hgd::Handles h;
  h.fixed.push_back(pointsWhere(g, 0, -1, 0.05));
  h.manipulated = pointsWhere(g, 0, 0.95, 2);
  hgd::DeformOptions opt;
  opt.clusters.isoclusters = 10;
  hgd::Deformer d(g, h, opt);
  const double diag = hgd::boundingBoxDiagonal(g);
  const Eigen::Vector3d from(1.0, 0.0, 0.05);
  const Eigen::Vector3d to = from + Eigen::Vector3d(0, 0.5, 0);
  const hgd::DragResult r = d.dragTo(from, to);
  std::printf("bar: %d frames, %d iterations (max %d/frame), error %.3g, clusters %zu\n", r.frames,
              r.iterations, r.max_frame_iterations, r.error, d.clustering().clusters.size());
  EXPECT_TRUE(r.reached);
  EXPECT_LE(r.error, 1e-3 * diag);
  for (int i : h.fixed[0])
    EXPECT_LE((d.deformedWorld(static_cast<std::size_t>(i)) - g.world(static_cast<std::size_t>(i))).norm(),
              1e-6 * diag);
  // Displacement grows monotonically along the bar (binned by x).
  std::vector<double> sum(20, 0), cnt(20, 0);
  for (std::size_t i = 0; i < g.size(); ++i) {
    const int b = std::min(19, static_cast<int>(g.world(i).x() * 20));
    sum[static_cast<std::size_t>(b)] += (d.deformedWorld(i) - g.world(i)).norm();
    cnt[static_cast<std::size_t>(b)] += 1;
  }
  for (int b = 1; b < 20; ++b)
    EXPECT_GE(sum[static_cast<std::size_t>(b)] / cnt[static_cast<std::size_t>(b)],
              sum[static_cast<std::size_t>(b - 1)] / cnt[static_cast<std::size_t>(b - 1)] - 1e-6)
        << "bin " << b;
  // Reaching 0.5 sideways forces the bar (0.9 long between its handles) to stretch by ~10%:
  // Rot(A) stays within that, and no cluster folds.
  for (const auto& t : d.clusterTransforms()) {
    EXPECT_GT(t.A.determinant(), 0);
    EXPECT_LT(hgd::rotationResidual(t.A), 0.1);
  }
}

// The same bar dragged to where a bent bar of unchanged length can reach: every cluster
// transform is then nearly a rotation.
TEST(Deform, BarArcDragKeepsClustersRigid) {
  const hgd::Shape shape = hgd::shapes::bar(1.0f, 0.1f, 0.01f);
  const hgd::Geometry g = hgd::extractGeometry(shape);
  hgd::Handles h;
  h.fixed.push_back(pointsWhere(g, 0, -1, 0.05));
  h.manipulated = pointsWhere(g, 0, 0.95, 2);
  hgd::DeformOptions opt;
  opt.clusters.isoclusters = 10;
  hgd::Deformer d(g, h, opt);
  // An arc of length 0.95 leaving x = 0.05 along +x, bent by 1.19 rad, ends near (0.79, 0.5).
  const hgd::DragResult r = d.dragTo({1.0, 0.0, 0.05}, {0.79, 0.5, 0.05});
  EXPECT_TRUE(r.reached);
  double worst = 0;
  for (const auto& t : d.clusterTransforms()) {
    EXPECT_GT(t.A.determinant(), 0);
    worst = std::max(worst, hgd::rotationResidual(t.A));
  }
  std::printf("arc drag: worst Rot(A) %.4g\n", worst);
  EXPECT_LT(worst, 0.005);
}

}  // namespace
