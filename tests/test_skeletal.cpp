// Skeletal deformation (paper §5, Fig. 6-7) and the blends: eq. (1) and the rotation-aware blend
// recomputed from the cluster transforms, independently of hgd::interpolate.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <memory>

#include "hgdeform/deformer/deformer.h"
#include "hgdeform/graph/knn.h"
#include "support/shapes.h"
#include "test_util.h"

using hgdtest::endHandles;
using hgdtest::pointsWhere;

namespace {

// The Deformer's clusters with every point's two clusters and blend factor, as interpolation
// applies them (the Deformer keeps those in its table alone).
hgd::Clustering bracketed(const hgd::Deformer& d) {
  hgd::Clustering c = d.clustering();
  const hgd::InterpolationTable& t = d.interpolationTable();
  c.lower.resize(t.size());
  c.upper.resize(t.size());
  c.alpha.resize(t.size());
  c.nearest.resize(t.size());
  for (std::size_t i = 0; i < t.size(); ++i) {
    const hgd::InterpolationTable::Bracket b = t.bracket(i);
    c.lower[i] = b.lower;
    c.upper[i] = b.upper;
    c.alpha[i] = b.alpha;
    c.nearest[i] = b.nearest();
  }
  return c;
}

// The points that lie wholly in one bone (both bracketing clusters are that range cluster).
std::vector<std::vector<int>> bones(const hgd::Deformer& d) {
  const hgd::Clustering c = bracketed(d);
  std::vector<std::vector<int>> out(c.clusters.size());
  for (std::size_t i = 0; i < c.lower.size(); ++i)
    if (c.lower[i] == c.upper[i] &&
        c.clusters[static_cast<std::size_t>(c.lower[i])].kind == hgd::ClusterKind::Range)
      out[static_cast<std::size_t>(c.lower[i])].push_back(static_cast<int>(i));
  std::vector<std::vector<int>> nonempty;
  for (auto& b : out)
    if (!b.empty()) nonempty.push_back(std::move(b));
  return nonempty;
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

// The test's own polar decomposition: the rotation nearest `a` (by SVD, a proper rotation).
Eigen::Matrix3d rotationPart(const Eigen::Matrix3d& a) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(a, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d u = svd.matrixU();
  if ((u * svd.matrixV().transpose()).determinant() < 0) u.col(2) *= -1;
  return u * svd.matrixV().transpose();
}

// The best rigid motion (Kabsch) taking `before` to `after`.
struct Rigid {
  Eigen::Matrix3d r = Eigen::Matrix3d::Identity();
  Eigen::Vector3d from = Eigen::Vector3d::Zero(), to = Eigen::Vector3d::Zero();
  Eigen::Vector3d operator()(const Eigen::Vector3d& x) const { return r * (x - from) + to; }
  double degrees() const { return Eigen::AngleAxisd(r).angle() * 180 / M_PI; }
};
Rigid rigidFit(const std::vector<Eigen::Vector3d>& before, const std::vector<Eigen::Vector3d>& after) {
  Rigid f;
  for (std::size_t i = 0; i < before.size(); ++i) {
    f.from += before[i];
    f.to += after[i];
  }
  f.from /= static_cast<double>(before.size());
  f.to /= static_cast<double>(after.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < before.size(); ++i) cov += (after[i] - f.to) * (before[i] - f.from).transpose();
  f.r = rotationPart(cov);
  return f;
}

std::vector<Eigen::Vector3d> deformedWorld(const hgd::Deformer& d) {
  std::vector<Eigen::Vector3d> out(d.geometry().size());
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = d.deformedWorld(i);
  return out;
}

// Eq. (1) recomputed for every point from the cluster transforms (as the solver left them) and
// the point's harmonic value, by docs/method.md's definitions, without hgd::interpolate and
// without the clustering's blend factors. A point between clusters lo and hi (the clustering's
// `down` and `up`: which clusters bracket it on its own branch) has
//   alpha = (phi - phi_lo) / (phi_hi - phi_lo),
// phi_C the cluster's harmonic value: its isovalue, 0 for a fixed handle, 1 for the manipulated
// one; for a bone, the end of its band that faces the point (FacingEnd, the code's choice) or
// its mean harmonic value (Mean, the paper's). Handle points take their handle's transform,
// bone points their bone's (snapped to its nearest rotation unless `snap` is false).
//   linear:   p' = ((1 - alpha) T_lo + alpha T_hi) p, normals by the inverse transpose;
//   rotation: p' = R(alpha) (p - c) + (1 - alpha) T_lo(c)' + alpha T_hi(c)', c the mean of the two
//             barycentres, R(alpha) the normalised lerp of the two rotations' quaternions on one
//             hemisphere, T(c)' the image of c under the cluster's rigid part; normals by R(alpha).
enum class BoneValue { FacingEnd, Mean };
struct Recomputed {
  std::vector<Eigen::Vector3d> p, n;  // world positions, unit normals
  int blended = 0;                    // points between two different clusters
  int beside_bone = 0;                // of those, points with a bone on one side
};
Recomputed equationOne(const hgd::Deformer& d, hgd::Blend blend, BoneValue bone_value = BoneValue::FacingEnd,
                       bool snap = true) {
  const hgd::Geometry& g = d.geometry();
  const hgd::Clustering c = bracketed(d);
  // The solver works on the shape scaled to a unit diagonal, each transform about its cluster's
  // barycentre g: x -> A (x - g) + g + t there, so x -> A (x - g) + g + t * diagonal here.
  const double diag = hgd::boundingBoxDiagonal(g);
  const std::size_t nc = c.clusters.size();
  std::vector<Eigen::Matrix3d> a(nc);
  std::vector<Eigen::Vector3d> bary(nc), image(nc);              // local frame: barycentre and where it goes
  std::vector<double> seen_from_above(nc), seen_from_below(nc);  // phi_C for points above / below C
  for (std::size_t k = 0; k < nc; ++k) {
    const hgd::Cluster& cl = c.clusters[k];
    const hgd::NormalisedTransform& t = d.clusterTransforms()[k];
    const bool bone = cl.kind == hgd::ClusterKind::Range;
    a[k] = bone && snap ? rotationPart(t.A) : t.A;
    bary[k] = cl.barycentre;
    image[k] = cl.barycentre + t.t * diag;
    seen_from_above[k] = seen_from_below[k] = cl.harmonic_value;  // a bone's phi is its mean harmonic value
    if (bone && bone_value == BoneValue::FacingEnd)
      for (const hgd::Band& b : c.bands)
        if (b.kind == hgd::Band::Kind::Range && b.lo < cl.harmonic_value && cl.harmonic_value < b.hi) {
          seen_from_above[k] = b.hi;
          seen_from_below[k] = b.lo;
        }
  }
  std::vector<int> own(g.size(), -1);  // handle points: their handle's cluster
  for (const hgd::Cluster& cl : c.clusters)
    if (cl.kind == hgd::ClusterKind::Fixed)
      for (int i : d.handles().fixed[static_cast<std::size_t>(cl.handle)])
        own[static_cast<std::size_t>(i)] = cl.id;
  for (int i : d.handles().manipulated) own[static_cast<std::size_t>(i)] = c.manipulated;

  Recomputed e;
  e.p.resize(g.size());
  e.n.resize(g.size());
  for (std::size_t i = 0; i < g.size(); ++i) {
    const Eigen::Vector3d x = (*g.points)[i].getVector3fMap().cast<double>();
    const Eigen::Vector3d n0 = (*g.file_normals)[i].getNormalVector3fMap().cast<double>();
    auto lo = static_cast<std::size_t>(c.lower[i]), hi = static_cast<std::size_t>(c.upper[i]);
    if (own[i] >= 0) lo = hi = static_cast<std::size_t>(own[i]);
    if (lo == hi) {
      e.p[i] = a[lo] * (x - bary[lo]) + image[lo] + g.origin;
      e.n[i] = (a[lo].inverse().transpose() * n0).normalized();
      continue;
    }
    ++e.blended;
    e.beside_bone +=
        c.clusters[lo].kind == hgd::ClusterKind::Range || c.clusters[hi].kind == hgd::ClusterKind::Range;
    const double phi_lo = seen_from_above[lo], phi_hi = seen_from_below[hi];
    const double alpha = std::clamp((d.field()[i] - phi_lo) / (phi_hi - phi_lo), 0.0, 1.0);
    if (blend == hgd::Blend::Linear) {
      const Eigen::Matrix3d m = (1 - alpha) * a[lo] + alpha * a[hi];
      const Eigen::Vector3d b =
          (1 - alpha) * (image[lo] - a[lo] * bary[lo]) + alpha * (image[hi] - a[hi] * bary[hi]);
      e.p[i] = m * x + b + g.origin;
      e.n[i] = (m.inverse().transpose() * n0).normalized();
    } else {
      const Eigen::Matrix3d r_lo = rotationPart(a[lo]), r_hi = rotationPart(a[hi]);
      const Eigen::Vector3d centre = 0.5 * (bary[lo] + bary[hi]);
      const Eigen::Vector3d c_lo = r_lo * (centre - bary[lo]) + image[lo];
      const Eigen::Vector3d c_hi = r_hi * (centre - bary[hi]) + image[hi];
      const Eigen::Quaterniond q_lo(r_lo);
      Eigen::Quaterniond q_hi(r_hi);
      if (q_lo.dot(q_hi) < 0) q_hi.coeffs() = -q_hi.coeffs();
      Eigen::Quaterniond q;
      q.coeffs() = (1 - alpha) * q_lo.coeffs() + alpha * q_hi.coeffs();
      const Eigen::Matrix3d r = q.normalized().toRotationMatrix();
      e.p[i] = r * (x - centre) + (1 - alpha) * c_lo + alpha * c_hi + g.origin;
      e.n[i] = r * n0;
    }
  }
  return e;
}

// The step where a bone ends in a joint: for every bone, the points of the gap beyond each of
// its ends that lie within 5% of the gap's width (in phi) from that end, and how far each is
// from where the bone's own rigid motion (fitted to the deformed points of the bone) puts it.
// The largest over all bone ends, as a fraction of the diagonal. A blend that is continuous at
// the bone's end gives at most 5% of the step to the next cluster; one that jumps gives the jump.
double jumpAtBoneEnds(const hgd::Deformer& d, const std::vector<Eigen::Vector3d>& deformed, int* counted) {
  const hgd::Geometry& g = d.geometry();
  const hgd::Clustering c = bracketed(d);
  double worst = 0;
  *counted = 0;
  for (const hgd::Cluster& bone : c.clusters) {
    if (bone.kind != hgd::ClusterKind::Range) continue;
    double lo = 0, hi = 0;  // the bone's band
    for (const hgd::Band& b : c.bands)
      if (b.kind == hgd::Band::Kind::Range && b.lo < bone.harmonic_value && bone.harmonic_value < b.hi) {
        lo = b.lo;
        hi = b.hi;
      }
    std::vector<Eigen::Vector3d> before, after;
    for (std::size_t i = 0; i < g.size(); ++i)
      if (c.lower[i] == bone.id && c.upper[i] == bone.id) {
        before.push_back(g.world(i));
        after.push_back(deformed[i]);
      }
    const Rigid motion = rigidFit(before, after);
    for (std::size_t i = 0; i < g.size(); ++i) {
      if (c.lower[i] == c.upper[i]) continue;
      const double phi = d.field()[i];
      bool near = false;
      if (c.lower[i] == bone.id) {  // above the bone: the gap runs from hi to the next cluster
        const double next = c.clusters[static_cast<std::size_t>(c.upper[i])].harmonic_value;
        near = phi - hi <= 0.05 * (next - hi);
      } else if (c.upper[i] == bone.id) {  // below it: from the previous cluster to lo
        const double previous = c.clusters[static_cast<std::size_t>(c.lower[i])].harmonic_value;
        near = lo - phi <= 0.05 * (lo - previous);
      }
      if (!near) continue;
      ++*counted;
      worst = std::max(worst, (deformed[i] - motion(g.world(i))).norm());
    }
  }
  return worst / hgd::boundingBoxDiagonal(g);
}

// The step where a bone meets a handle (no gap lies between them to blend across): how far
// the bone's points next to the handle (among the 8 nearest neighbours of a handle point) are
// from where the handle's rigid motion (fitted to the handle's deformed points) puts them. The
// largest over all handles, as a fraction of the diagonal.
double stepAtHandleEdges(const hgd::Deformer& d, const std::vector<Eigen::Vector3d>& deformed) {
  const hgd::Geometry& g = d.geometry();
  const hgd::Clustering c = bracketed(d);
  std::vector<std::vector<int>> handles = d.handles().fixed;
  handles.push_back(d.handles().manipulated);
  const hgd::KnnTable knn = hgd::computeKnn(*g.points, 8);
  double worst = 0;
  for (const std::vector<int>& handle : handles) {
    std::vector<char> in(g.size(), 0);
    std::vector<Eigen::Vector3d> before, after;
    for (int i : handle) {
      in[static_cast<std::size_t>(i)] = 1;
      before.push_back(g.world(static_cast<std::size_t>(i)));
      after.push_back(deformed[static_cast<std::size_t>(i)]);
    }
    const Rigid motion = rigidFit(before, after);
    for (int i : handle)
      for (int m = 0; m < knn.k; ++m) {
        const auto j = static_cast<std::size_t>(knn.row(static_cast<std::size_t>(i))[m]);
        if (in[j] || c.lower[j] != c.upper[j] ||
            c.clusters[static_cast<std::size_t>(c.lower[j])].kind != hgd::ClusterKind::Range)
          continue;
        worst = std::max(worst, (deformed[j] - motion(g.world(j))).norm());
      }
  }
  return worst / hgd::boundingBoxDiagonal(g);
}

// How far the bend has turned along the shape: the angle of the best rigid fit of each slice
// |x - x0| <= 0.01 of the rest shape, x0 from `from` to `to` in steps of 0.005.
std::vector<double> bendAngles(const hgd::Geometry& g, const std::vector<Eigen::Vector3d>& deformed,
                               double from, double to) {
  std::vector<double> out;
  for (double x0 = from; x0 <= to + 1e-9; x0 += 0.005) {
    std::vector<Eigen::Vector3d> before, after;
    for (std::size_t i = 0; i < g.size(); ++i)
      if (std::abs(g.world(i).x() - x0) <= 0.01) {
        before.push_back(g.world(i));
        after.push_back(deformed[i]);
      }
    out.push_back(rigidFit(before, after).degrees());
  }
  return out;
}

// The Fig. 7 cylinder: fixed at one end, one joint in the middle, the free end turned 90
// degrees about the joint's centre.
struct Cylinder {
  hgd::Geometry g = hgd::extractGeometry(hgd::shapes::cylinder(1.0f, 0.08f, 0.01f));
  hgd::Handles h;
  Eigen::Affine3d turn = turnAbout({0.5, 0, 0}, 90, Eigen::Vector3d::UnitZ());
  Cylinder() {
    h.fixed.push_back(pointsWhere(g, 0, -1, 0.04));
    h.manipulated = pointsWhere(g, 0, 0.96, 2);
  }
  std::unique_ptr<hgd::Deformer> skeletal(const hgd::DeformOptions& options = {}) const {
    hgd::Handles s = h;
    s.joints.push_back(pointsWhere(g, 0, 0.45, 0.55));
    auto d = std::make_unique<hgd::Deformer>(g, s, options);
    d->setHandleTransform(turn);
    return d;
  }
};

// The arm: elbow and wrist on a longer cylinder, the hand dragged up and back.
struct Arm {
  hgd::Geometry g = hgd::extractGeometry(hgd::shapes::cylinder(1.5f, 0.07f, 0.01f));
  hgd::Handles h;
  Arm() {
    h.fixed.push_back(pointsWhere(g, 0, -1, 0.04));
    h.manipulated = pointsWhere(g, 0, 1.46, 2);
    h.joints.push_back(pointsWhere(g, 0, 0.46, 0.54));  // elbow
    h.joints.push_back(pointsWhere(g, 0, 0.96, 1.04));  // wrist
  }
  std::unique_ptr<hgd::Deformer> dragged() const {
    auto d = std::make_unique<hgd::Deformer>(g, h);
    EXPECT_EQ(bones(*d).size(), 3u);
    const hgd::DragResult r = d->dragTo({1.5, 0.0, 0.0}, {1.1, 0.6, 0.1});
    EXPECT_TRUE(r.reached);
    return d;
  }
};

TEST(Skeletal, CylinderWithOneJointBendsInTheJoint) {
  const Cylinder cyl;
  const hgd::Geometry& g = cyl.g;
  const double diag = hgd::boundingBoxDiagonal(g);
  const auto d = cyl.skeletal();
  ASSERT_EQ(bones(*d).size(), 2u);
  // The bend is in the joint: the upper arm stays, the forearm follows the handle.
  const double upper = meanDisplacement(*d, 0.05, 0.4);
  double follow = 0;
  int count = 0;
  for (std::size_t i = 0; i < g.size(); ++i)
    if (g.world(i).x() > 0.6 && g.world(i).x() < 0.95) {
      follow += (d->deformedWorld(i) - cyl.turn * g.world(i)).norm();
      ++count;
    }
  follow /= count;
  std::printf("skeletal: upper arm moved %.2e of the diagonal, forearm off the handle's motion by %.2e\n",
              upper / diag, follow / diag);
  EXPECT_LT(upper, 0.0045 * diag);   // measured 2.9e-3 of the diagonal
  EXPECT_LT(follow, 0.0045 * diag);  // measured 2.9e-3

  // Without joints: a rubber-like "spine" that bends along the whole length.
  hgd::Deformer spine(g, cyl.h);
  spine.setHandleTransform(cyl.turn);
  const double spine_upper = meanDisplacement(spine, 0.2, 0.4), bone_upper = meanDisplacement(*d, 0.2, 0.4);
  std::printf("spine: the same stretch of the upper part moved %.2e of the diagonal (%.0f times the bone)\n",
              spine_upper / diag, spine_upper / bone_upper);
  EXPECT_GT(spine_upper, 0.022 * diag);    // measured 0.028
  EXPECT_GT(spine_upper, 8 * bone_upper);  // measured 12 times
}

// Where a bone ends in a joint, the blend starts from the bone's own transform: the points of
// the joint next to the bone's end move with the bone. The paper's formula (a bone counts with
// its mean harmonic value, eq. 1) would make them jump; its figure is recomputed here from the
// same cluster transforms, for docs/method.md.
TEST(Skeletal, NoJumpWhereABoneEndsInAJoint) {
  const Cylinder cyl;
  const Arm arm;
  const std::unique_ptr<hgd::Deformer> shapes[2] = {cyl.skeletal(), arm.dragged()};
  const char* names[2] = {"cylinder turned 90 degrees", "arm dragged"};
  for (int s = 0; s < 2; ++s) {
    const hgd::Deformer& d = *shapes[s];
    int ours_points = 0, paper_points = 0;
    const double ours = jumpAtBoneEnds(d, deformedWorld(d), &ours_points);
    const double paper =
        jumpAtBoneEnds(d, equationOne(d, hgd::Blend::Rotation, BoneValue::Mean).p, &paper_points);
    std::printf(
        "%s: points next to a bone's end (%d) off the bone's rigid motion by %.2e of the diagonal; with the "
        "paper's mean harmonic value for bones, %.2e\n",
        names[s], ours_points, ours, paper);
    EXPECT_GE(ours_points, 40);
    EXPECT_EQ(ours_points, paper_points);
    EXPECT_LE(ours, 2e-4);        // measured 1.1e-4 (cylinder) and 4.4e-5 (arm)
    EXPECT_GE(paper, 30 * ours);  // measured 7.1e-3 and 2.6e-3: 64 and 59 times ours
  }
}

// The joint bends smoothly: slice by slice along the cylinder (slices 0.005 apart), the turn
// grows from the upper arm's to the forearm's without ever going back, all of it inside the
// joint, and no one step takes more than 30% of the whole bend.
TEST(Skeletal, TheJointBendsSmoothly) {
  const Cylinder cyl;
  const auto d = cyl.skeletal();
  const std::vector<double> turn = bendAngles(cyl.g, deformedWorld(*d), 0.3, 0.7);  // x0 = 0.3 + 0.005 k
  double step = 0, back = 0, outside = 0;
  for (std::size_t k = 1; k < turn.size(); ++k) {
    step = std::max(step, turn[k] - turn[k - 1]);
    back = std::max(back, turn[k - 1] - turn[k]);
    const double x0 = 0.3 + 0.005 * static_cast<double>(k);
    // Slices wholly in a bone (the joint is 0.45 to 0.55, a slice reaches 0.01 either side).
    if (x0 <= 0.44 || x0 - 0.005 >= 0.56) outside = std::max(outside, std::abs(turn[k] - turn[k - 1]));
  }
  const double bend = turn.back() - turn.front();
  std::printf("joint: bend %.1f degrees, largest step %.1f, largest step back %.2f, outside the joint %.3f\n",
              bend, step, back, outside);
  EXPECT_GT(bend, 80);          // measured 87.0 (the handle turns 90)
  EXPECT_LE(back, 0.05);        // measured 0
  EXPECT_LE(outside, 0.05);     // measured 0
  EXPECT_LE(step, 0.3 * bend);  // measured 20.4 degrees, 0.23 of the bend
}

// A bone's transform is replaced by its nearest rotation when it is applied. Where a bone ends
// in a joint that is harmless (the blend starts from the snapped transform: see above). Where a
// bone meets a handle no gap lies between them to blend across: the bone's own transform is not
// quite the handle's, so there is a step at the handle's edge even without the snap, and what
// the snap changes adds to it. The solver's bone transforms are near rotations, and the snap
// adds at most a little to the step (the unsnapped figure is recomputed from the same transforms).
TEST(Skeletal, TheSnapToARotationChangesBonesLittle) {
  const Cylinder cyl;
  const Arm arm;
  const std::unique_ptr<hgd::Deformer> shapes[2] = {cyl.skeletal(), arm.dragged()};
  const char* names[2] = {"cylinder turned 90 degrees", "arm dragged"};
  const double rot_bound[2] = {4e-3, 1.1e-4};     // measured 3.2e-3 and 8.0e-5
  const double step_bound[2] = {7.5e-3, 1.7e-3};  // measured 6.0e-3 and 1.3e-3 of the diagonal
  for (int s = 0; s < 2; ++s) {
    const hgd::Deformer& d = *shapes[s];
    double rot = 0;
    for (std::size_t k = 0; k < d.clustering().clusters.size(); ++k)
      if (d.clustering().clusters[k].kind == hgd::ClusterKind::Range)
        rot = std::max(rot, hgd::rotationResidual(d.clusterTransforms()[k].A));
    const double snapped = stepAtHandleEdges(d, deformedWorld(d));
    const double unsnapped =
        stepAtHandleEdges(d, equationOne(d, hgd::Blend::Rotation, BoneValue::FacingEnd, false).p);
    std::printf(
        "%s: bones' Rot(A) before the snap at most %.2e; step where a bone meets a handle %.2e of the "
        "diagonal (%.2e unsnapped)\n",
        names[s], rot, snapped, unsnapped);
    EXPECT_LE(rot, rot_bound[s]);
    EXPECT_LE(snapped, step_bound[s]);
    EXPECT_LE(snapped, 1.75 * unsnapped);  // measured 1.42 and 1.50 times
  }
}

TEST(Skeletal, OverlappingJointsMergeWithANote) {
  const hgd::Geometry g = hgd::extractGeometry(hgd::shapes::cylinder(1.0f, 0.08f, 0.02f));
  hgd::Handles h = endHandles(g, 0.04, 0.96);
  h.joints.push_back(pointsWhere(g, 0, 0.40, 0.50));
  h.joints.push_back(pointsWhere(g, 0, 0.45, 0.60));
  hgd::Deformer d(g, h);
  ASSERT_EQ(d.clustering().notes.size(), 1u);
  EXPECT_NE(d.clustering().notes[0].find("overlapping"), std::string::npos);
  EXPECT_EQ(bones(d).size(), 2u);  // one merged joint: two bones
}

// Every point's position and normal is eq. (1) (or the rotation blend as docs/method.md defines
// it) of its two clusters' transforms, recomputed here in double precision: on a bar (handles
// and isoclusters), and on the cylinder and the arm, where points beside bones blend from the
// bones' facing ends.
TEST(Blend, EveryPointIsTheBlendOfItsTwoClusters) {
  const hgd::Geometry bar_g = hgd::extractGeometry(hgd::shapes::bar(1.0f, 0.1f, 0.01f));
  hgd::Handles bar_h;
  bar_h.fixed.push_back(pointsWhere(bar_g, 0, -1, 0.05));
  bar_h.manipulated = pointsWhere(bar_g, 0, 0.95, 2);
  hgd::DeformOptions bar_options;
  bar_options.clusters.isovalues = 10;
  auto bar = std::make_unique<hgd::Deformer>(bar_g, bar_h, bar_options);
  bar->dragTo({1.0, 0.0, 0.05}, {0.79, 0.5, 0.05});
  const Cylinder cyl;
  const Arm arm;
  std::unique_ptr<hgd::Deformer> shapes[3] = {std::move(bar), cyl.skeletal(), arm.dragged()};
  const char* names[3] = {"bar", "cylinder", "arm"};
  for (int s = 0; s < 3; ++s) {
    hgd::Deformer& d = *shapes[s];
    const double diag = hgd::boundingBoxDiagonal(d.geometry());
    for (const hgd::Blend blend : {hgd::Blend::Linear, hgd::Blend::Rotation}) {
      d.setBlend(blend);
      const Recomputed e = equationOne(d, blend);
      double worst = 0, worst_normal = 0;
      for (std::size_t i = 0; i < d.geometry().size(); ++i) {
        worst = std::max(worst, (d.deformedWorld(i) - e.p[i]).norm());
        worst_normal = std::max(worst_normal, (d.deformedNormals()[i].cast<double>() - e.n[i]).norm());
      }
      std::printf(
          "%s, %s blend: %d points blended (%d beside a bone); largest difference %.2e of the "
          "diagonal, normals %.2e\n",
          names[s], hgd::blendName(blend), e.blended, e.beside_bone, worst / diag, worst_normal);
      EXPECT_GE(e.blended, 400);
      if (s > 0) {
        EXPECT_GE(e.beside_bone, 200);
      }
      // Float arithmetic in interpolate(): measured at most 1.5e-7 of the diagonal, 2.7e-7 for normals.
      EXPECT_LE(worst, 1e-6 * diag) << names[s] << ", " << hgd::blendName(blend);
      EXPECT_LE(worst_normal, 1e-6) << names[s] << ", " << hgd::blendName(blend);
    }
  }
}

// Blending: a bar twisted 180 degrees with 4 clusters. The linear blend of transforms shrinks
// the cross-section between clusters; the rotation-aware blend keeps it.
TEST(Blend, RotationAwareBlendKeepsTheCrossSectionOfATwistedBar) {
  const hgd::Geometry g = hgd::extractGeometry(hgd::shapes::bar(1.0f, 0.1f, 0.01f));
  hgd::Handles h = endHandles(g, 0.02, 0.98);
  hgd::DeformOptions opt;
  opt.clusters.isovalues = 4;
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
  EXPECT_GE(worst[1], 0.99);  // measured 100.0%
  EXPECT_LT(worst[0], 0.35);  // measured 24.3%
}

}  // namespace
