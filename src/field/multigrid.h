// The multilevel solver of the harmonic field (internal).
#pragma once

#include <Eigen/Sparse>

#include "hgdeform/field/harmonic_field.h"

namespace hgd {

using RowMat = Eigen::SparseMatrix<double, Eigen::RowMajor, int>;

/// Multigrid-preconditioned conjugate gradients on the symmetric positive definite `a`; x is
/// the solution. False when it does not reach options.tolerance in options.max_iterations;
/// throws when the coarsest level cannot be factorised.
bool solveMultilevel(const RowMat& a, const Eigen::VectorXd& b, Eigen::VectorXd& x,
                     const FieldOptions& options, int& iterations);

}  // namespace hgd
