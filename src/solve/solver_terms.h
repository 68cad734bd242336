// The cluster solver's terms (internal; the solve stage's files): a cluster's transform as one
// 3 x 4 block, the Rot residuals, and the Kronecker blocks of the normal equations.
#pragma once

#include <Eigen/Core>

#include "hgdeform/solve/solver.h"

namespace hgd::solver_terms {

using Mat34 = Eigen::Matrix<double, 3, 4>;
using Vec12 = Eigen::Matrix<double, 12, 1>;
using Mat12 = Eigen::Matrix<double, 12, 12>;

inline Mat34 toU(const NormalisedTransform& tr) {
  Mat34 u;
  u.leftCols<3>() = tr.A;
  u.col(3) = tr.t;
  return u;
}

// The six Rot residuals and their Jacobian with respect to (a1, a2, a3).
inline void rotResiduals(const Eigen::Matrix3d& a, Eigen::Matrix<double, 6, 1>& r,
                         Eigen::Matrix<double, 6, 9>& j) {
  const Eigen::Vector3d c1 = a.col(0), c2 = a.col(1), c3 = a.col(2);
  r << c1.dot(c2), c1.dot(c3), c2.dot(c3), c1.dot(c1) - 1, c2.dot(c2) - 1, c3.dot(c3) - 1;
  j.setZero();
  j.block<1, 3>(0, 0) = c2.transpose();
  j.block<1, 3>(0, 3) = c1.transpose();
  j.block<1, 3>(1, 0) = c3.transpose();
  j.block<1, 3>(1, 6) = c1.transpose();
  j.block<1, 3>(2, 3) = c3.transpose();
  j.block<1, 3>(2, 6) = c2.transpose();
  j.block<1, 3>(3, 0) = 2 * c1.transpose();
  j.block<1, 3>(4, 3) = 2 * c2.transpose();
  j.block<1, 3>(5, 6) = 2 * c3.transpose();
}

// (S ⊗ I3) for the ordering u = [a1; a2; a3; t].
inline Mat12 kron(const Eigen::Matrix4d& s) {
  Mat12 k = Mat12::Zero();
  for (int a = 0; a < 4; ++a)
    for (int b = 0; b < 4; ++b) k.block<3, 3>(3 * a, 3 * b) = s(a, b) * Eigen::Matrix3d::Identity();
  return k;
}

}  // namespace hgd::solver_terms
