// The cluster transforms (the paper's §4; docs/method.md, section 5): one affine map per free
// cluster, found by Gauss–Newton on w_Detail E_Detail + w_Prop E_Prop + w_Manip E_Manip +
// w_Length E_Length.
//
// Coordinates here are normalised (the deformer scales the shape to a unit bounding-box
// diagonal) so that the weights mean the same for any unit. Each transform is written about
// its cluster's rest barycentre g: T x = A (x - g) + g + t.
#pragma once

#include <Eigen/Core>
#include <Eigen/Sparse>
#include <memory>
#include <vector>

namespace hgd {

struct SolverWeights {
  double detail = 1, prop = 10, length = 20, manip = 100;
  /// w_MHC = mhc_per_cluster * n_IC (the paper's 1.2 · n_IC); <= 0 means 1 (uniform).
  double mhc_per_cluster = 1.2;
  double picked = 10;  ///< shape-matching weight of the picked point (the others weigh 1)
};

/// One cluster as the solver sees it.
struct SolverCluster {
  std::vector<Eigen::Vector3d> points;  ///< rest positions of its members (normalised)
  Eigen::Vector3d barycentre = Eigen::Vector3d::Zero();
  bool constant = false;  ///< fixed and static clusters (identity; a frame move holds the MC instead)
  double rot_weight = 1;  ///< multiplies Rot(A) in E_Detail (w_MHC for the MC)
};

/// A cluster's affine transform in the solver's normalised frame (the shape's local frame
/// moved to the bounding box's centre and scaled to a unit diagonal), about the cluster's rest
/// barycentre g: x -> A (x - g) + g + t. See LocalTransform (the shape's local frame) and
/// Deformer::handleTransform (world coordinates).
struct NormalisedTransform {
  Eigen::Matrix3d A = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
};
/// The name before 0.2; it did not say the frame.
using Transform [[deprecated("renamed hgd::NormalisedTransform (the frame it is in)")]] = NormalisedTransform;

struct Energies {
  double detail = 0, prop = 0, manip = 0, length = 0;  ///< weighted contributions
  double total() const { return detail + prop + manip + length; }
};

struct SolveStats {
  int iterations = 0;
  bool converged = false;
  bool decreased = true;  ///< false when a step could not decrease the energy
  Energies energy;
  double ms = 0;
};

struct GaussNewtonOptions {
  int max_iterations = 20;
  double tolerance = 1e-4;  ///< stop when the relative decrease of the energy falls below this
  /// Reweighted E_Prop (not in the paper; 0, the default, is the paper's solve): after the
  /// solve, this many rounds each weigh every adjacent pair's E_Prop by the inverse square root
  /// of its mean squared mismatch (normalised to a mean of 1 over the pairs that move; a floor
  /// at 10^-4 of the mean) and solve again. The bending gathers at a few pairs, as ARAP's does
  /// at joints: closer to ARAP (docs/method.md, "Shape quality"), at several times a frame's
  /// cost, less stable under resampling, and a sharp bend of a thin part can be pulled apart
  /// (the report says where). Each solve starts from uniform weights; the rounds stop when the
  /// mismatch is rounding or a round cannot lower its energy; the stats' energy is the paper's
  /// and whether it decreased is the first solve's.
  int reweight_rounds = 0;
};

class BlockCholesky;  // the solver's factorisation (internal)

class ClusterSolver {
 public:
  ClusterSolver();
  ~ClusterSolver();
  ClusterSolver(const ClusterSolver&) = delete;  // owns its factorisation: moved, not copied
  ClusterSolver& operator=(const ClusterSolver&) = delete;
  ClusterSolver(ClusterSolver&&) noexcept;
  ClusterSolver& operator=(ClusterSolver&&) noexcept;

  /// Precomputes everything that does not change per frame: the constant parts of the normal
  /// equations (E_Prop is linear), their sparsity pattern and its symbolic factorisation (all
  /// here: a solve only refreshes values and factorises numerically).
  /// `manipulated` is the index of the MC (or -1); `edges` are adjacent cluster pairs.
  void setup(std::vector<SolverCluster> clusters, const std::vector<std::pair<int, int>>& edges,
             int manipulated, const SolverWeights& weights);

  /// Shape matching of the manipulated handle (direct manipulation): rest positions x0 and
  /// targets x of its points, with weights. Replaces the previous targets.
  void setManipulation(const std::vector<Eigen::Vector3d>& rest, const std::vector<Eigen::Vector3d>& target,
                       const std::vector<double>& weight);
  /// Removes E_Manip.
  void clearManipulation();

  /// Holds a free cluster at `transform` (frame mode: the manipulated cluster moved by the
  /// user): the solve treats it as constant, exactly, and E_Manip is removed when it is the
  /// manipulated cluster. A switch on the normal equations' values, not a new setup: the held
  /// cluster keeps its unknowns and the symbolic analysis stays. Called again, it only moves
  /// the held transform. One cluster at a time.
  void hold(int cluster, const NormalisedTransform& transform);
  /// Frees the held cluster again (its transform is the next solve's warm start).
  void release();
  /// The held cluster, or -1.
  int held() const { return held_; }

  /// Gauss–Newton from the current transforms (warm start).
  SolveStats solve(const GaussNewtonOptions& options = {});

  Energies energies() const { return evaluate(x_); }
  const std::vector<NormalisedTransform>& transforms() const { return transforms_; }
  std::size_t unknowns() const { return static_cast<std::size_t>(x_.size()); }
  /// Resets every free transform to the identity.
  void reset();
  /// Sets all transforms (free ones become the warm start); sizes must match the clusters.
  void setTransforms(const std::vector<NormalisedTransform>& transforms);

 private:
  void assembleConstant();
  void analyzePattern();
  Energies evaluate(const Eigen::VectorXd& x) const;
  void unpack(const Eigen::VectorXd& x);
  Eigen::Vector3d translationOf(const Eigen::VectorXd& x, int cluster) const;

  struct Pair {  // an adjacent pair: second moments of the union about each barycentre
    int i, j;
    Eigen::Matrix4d sii, sij, sjj;
    Eigen::Vector4d mi, mj;
    double count;
    double rest_length;
    double omega = 1;  ///< E_Prop's reweighting (GaussNewtonOptions::reweight_rounds), else 1
  };
  SolveStats solveOnce(const GaussNewtonOptions& options);
  /// A pair's E_Prop (unweighted; its points' squared mismatch) under the transforms ui, uj.
  double propOf(const Pair& p, const Eigen::Matrix<double, 3, 4>& ui,
                const Eigen::Matrix<double, 3, 4>& uj) const;
  /// Sets each pair's omega from its current mismatch; false when nothing bends.
  bool reweightPairs();
  std::vector<SolverCluster> clusters_;
  std::vector<Pair> pairs_;
  std::vector<int> var_;  ///< cluster -> first unknown, or -1 when constant
  int manipulated_ = -1;
  SolverWeights w_;
  std::vector<NormalisedTransform> transforms_;
  Eigen::VectorXd x_;
  // E_Manip as a quadratic: S (4x4 weighted moments), targets folded into rhs.
  bool manip_active_ = false;
  Eigen::Matrix4d manip_s_ = Eigen::Matrix4d::Zero();
  Eigen::Matrix<double, 4, 3> manip_b_ = Eigen::Matrix<double, 4, 3>::Zero();  // sum w ỹ (x - g)^T
  double manip_c_ = 0;                                                         // sum w |x - g|^2
  Eigen::SparseMatrix<double> h_const_;  ///< w_Prop·JᵀJ of E_Prop (+ E_Manip when active), full pattern
  Eigen::SparseMatrix<double> h_;
  std::vector<int> rot_at_;     ///< per free block: h_ value positions of its 9x9 A-A part
  std::vector<int> length_at_;  ///< per pair: of the 3x3 t-t parts (ii, jj, ij, ji; -1 if constant)
  std::unique_ptr<BlockCholesky> factor_;
  bool constant_ready_ = false;  ///< h_const_ holds the current E_Manip and hold
  int held_ = -1;                ///< a free cluster held constant (hold()), or -1
  /// Whether a cluster moves in this solve: it has unknowns and is not held.
  bool moves(int cluster) const { return var_[static_cast<std::size_t>(cluster)] >= 0 && cluster != held_; }
};

/// Rot(A): the six squared residuals of A from a rotation-like matrix (paper §4).
double rotationResidual(const Eigen::Matrix3d& a);

}  // namespace hgd
