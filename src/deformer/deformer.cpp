#include <omp.h>

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <stdexcept>

#include "deformer/deformer_impl.h"
#include "deformer/precompute_internal.h"
#include "hgdeform/io/fields.h"
#include "util/phases.h"
#include "util/timer.h"

namespace hgd {

Deformer::Impl::Impl(std::shared_ptr<const Geometry> geometry, const Handles& handles,
                     const DeformOptions& options, std::shared_ptr<const PrebuiltLevel> level)
    : geometry_(std::move(geometry)), handles_(handles), options_(options) {
  if (!geometry_) throw std::invalid_argument("Deformer: no geometry");
  data_.prebuilt = std::move(level);
  if (geometry_->hasFileNormals() && geometry_->file_normals->size() != geometry_->size())
    throw std::invalid_argument("Deformer: the geometry has " +
                                std::to_string(geometry_->file_normals->size()) + " normals for " +
                                std::to_string(geometry_->size()) + " points");
  data_.timings.phases.clear();
  PhaseRecording recording(&data_.timings.phases);
  PhaseClock clock;
  // The body's box: a far stray does not coarsen tolerances and steps (nor the normalised frame).
  const Eigen::AlignedBox3f box = bodyBox(*geometry_);
  const Eigen::Vector3d lo = box.min().cast<double>(), hi = box.max().cast<double>();
  centre_ = 0.5 * (lo + hi);
  const double diag = (hi - lo).norm();
  scale_ = diag > 0 ? 1.0 / diag : 1.0;
  positions_.resize(geometry_->size());  // (normals are sized when first derived)
  clock.lap("deformer.body_box");
  rebuild();
}

void Deformer::Impl::setHandles(const Handles& handles) {
  handles_ = handles;
  rebuild();
}

void Deformer::Impl::rebuild() {
  // The tables change: normals due on points a preview frame will leave alone, now; without a
  // preview the first frame derives them all again.
  if (!preview_.empty()) updateNormals();
  normals_.all_due = normals_.preview_due = false;
  // A first shape never read: the points a preview frame leaves alone keep it, so it is made
  // now, from the table and transforms it belongs to; without a preview it is replaced whole.
  if (!preview_.empty()) ensureFirstShape();
  {
    const std::lock_guard<std::mutex> lock(first_shape_.mutex);
    first_shape_.due.store(false, std::memory_order_release);
  }
  if (t_phase_log != &data_.timings.phases) data_.timings.phases.clear();  // (a new handle set)
  PhaseRecording recording(&data_.timings.phases);
  precompute(*geometry_, handles_, options_, data_);
  Stopwatch sw;
  PhaseClock clock;
  buildPreviewTable();
  data_.timings.clusters_ms += sw.lap();
  clock.lap("deformer.preview_table");
  std::vector<SolverCluster> clusters =
      solverClusters(data_.clustering, *geometry_->points, options_, centre_, scale_);
  clock.lap("solver.clusters");
  solver_.setup(std::move(clusters), data_.clustering.adjacency, data_.clustering.manipulated,
                options_.weights);
  clock.lap("solver.setup");
  frame_mode_ = false;
  local_.resize(data_.clustering.clusters.size());
  exact_.assign(data_.clustering.clusters.size(), ExactTransform{});
  unpick();
  updateShape(/*lazy=*/true);
  data_.timings.setup_ms = sw.lap();
  clock.lap("deformer.first_shape");
}

DeformerState Deformer::Impl::state() const {
  return {solver_.transforms(), frame_mode_};
}

void Deformer::Impl::restore(const DeformerState& state) {
  if (state.transforms.size() != data_.clustering.clusters.size())
    throw std::invalid_argument("Deformer::restore: the state belongs to other clusters");
  solver_.setTransforms(state.transforms);
  const int mc = data_.clustering.manipulated;
  if (state.frame_mode)
    solver_.hold(mc, state.transforms[static_cast<std::size_t>(mc)]);
  else
    solver_.release();
  frame_mode_ = state.frame_mode;
  unpick();
  updateShape();
}

void Deformer::Impl::leaveFrameMode() {
  if (!frame_mode_) return;
  solver_.release();
  frame_mode_ = false;
  unpick();
}

Eigen::Vector3d Deformer::Impl::currentNormalised(int cluster, const Eigen::Vector3d& rest) const {
  const NormalisedTransform& t = solver_.transforms()[static_cast<std::size_t>(cluster)];
  const Eigen::Vector3d g =
      normalise(data_.clustering.clusters[static_cast<std::size_t>(cluster)].barycentre);
  return t.A * (rest - g) + g + t.t;
}

SolveStats Deformer::Impl::drag(const Eigen::Vector3d& from, const Eigen::Vector3d& to) {
  if (!to.allFinite() || !from.allFinite()) throw std::invalid_argument("drag: target is not finite");
  leaveFrameMode();
  if (!hasPick() || from != last_to_) pick(from);
  const SolveStats st = dragFrame(to);
  updateShape();
  return st;
}

SolveStats Deformer::Impl::dragFrame(const Eigen::Vector3d& to) {
  const int mc = data_.clustering.manipulated;
  // Targets: the picked point at the cursor, the other points where they are now, and the
  // pin at the weighted barycentre of those targets.
  const std::size_t picked_slot = manip_rest_.size() - 2, pin = manip_rest_.size() - 1;
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  double wsum = 0;
  for (std::size_t k = 0; k < pin; ++k) {
    manip_target_[k] =
        k == picked_slot ? normalise(to - geometry_->origin) : currentNormalised(mc, manip_rest_[k]);
    c += manip_weight_[k] * manip_target_[k];
    wsum += manip_weight_[k];
  }
  manip_target_[pin] = c / wsum;
  solver_.setManipulation(manip_rest_, manip_target_, manip_weight_);
  const SolveStats st = solver_.solve(options_.gauss_newton);
  last_to_ = to;
  return st;
}

SolveStats Deformer::Impl::translateHandle(const Eigen::Vector3d& from, const Eigen::Vector3d& to) {
  if (!to.allFinite() || !from.allFinite()) throw std::invalid_argument("drag: target is not finite");
  if (!hasPick() || from != last_to_) pick(from);
  const SolveStats st = moveHandle(Eigen::Affine3d(Eigen::Translation3d(to - pickedWorld())));
  last_to_ = to;
  return st;
}

Eigen::Vector3d Deformer::Impl::pickedWorld() const {
  const Eigen::Vector3d rest = normalise(picked_rest_.cast<double>());
  return currentNormalised(data_.clustering.manipulated, rest) / scale_ + centre_ + geometry_->origin;
}

DragResult Deformer::Impl::dragTo(const Eigen::Vector3d& from, const Eigen::Vector3d& to) {
  DragResult r;
  if (!to.allFinite() || !from.allFinite()) throw std::invalid_argument("drag: target is not finite");
  leaveFrameMode();
  pick(from);
  const Eigen::Vector3d start = pickedNow().cast<double>() + geometry_->origin;
  last_to_ = from;
  const double diag = 1.0 / scale_;
  if (start == to) {  // the picked point is already there: nothing to solve, nothing moves
    r.reached = true;
    r.last.converged = true;
    return r;
  }
  // The cursor's path in frames of at most max_drag_step; a target absurdly far away gets at
  // most half the frame budget for the path (longer steps) instead of running for ever.
  const double steps = std::ceil((to - start).norm() / (options_.max_drag_step * diag));
  const int path_frames =
      static_cast<int>(std::clamp(steps, 1.0, std::max(1.0, 0.5 * options_.max_drag_frames)));
  // Frames between the first and the last change only the solver's state: the shape is
  // interpolated once at the end (the result is the same; the replay is faster).
  auto frame = [&](const Eigen::Vector3d& next) {
    const SolveStats st = dragFrame(next);
    ++r.frames;
    r.iterations += st.iterations;
    r.max_frame_iterations = std::max(r.max_frame_iterations, st.iterations);
    r.solve_ms += st.ms;
    r.last = st;
  };
  for (int f = 1; f <= path_frames; ++f) frame(start + (to - start) * (static_cast<double>(f) / path_frames));
  const double tol = options_.drag_tolerance * diag;
  while (r.frames < options_.max_drag_frames && (pickedWorld() - to).norm() > tol) frame(to);
  updateShape();
  r.interpolation_ms = interp_ms_;
  r.error = (pickedNow().cast<double>() + geometry_->origin - to).norm();
  r.reached = r.error <= tol;
  return r;
}

SolveStats Deformer::Impl::setHandleTransform(const Eigen::Affine3d& transform) {
  if (!transform.matrix().allFinite())
    throw std::invalid_argument("setHandleTransform: transform is not finite");
  return moveHandle(transform * handleTransform().inverse());
}

SolveStats Deformer::Impl::moveHandle(const Eigen::Affine3d& motion) {
  if (!motion.matrix().allFinite()) throw std::invalid_argument("moveHandle: motion is not finite");
  // No motion at all (a frame move of 0): nothing is solved, so nothing moves, not even by the
  // rounding of a solve about a far origin (what did not move comes back bit for bit).
  if (motion.matrix() == Eigen::Matrix4d::Identity()) {
    SolveStats none;
    none.converged = true;
    return none;
  }
  // A large jump (a half turn given at once) has no preferred way round for the clusters in
  // between: Gauss-Newton from the old pose would sit at the saddle and collapse them. So the
  // handle travels there as a user would move it: in steps of at most 20 degrees and a tenth
  // of the diagonal, each solve warm-starting the next.
  const Eigen::Affine3d current = handleTransform();
  const Eigen::Matrix3d rot = nearestRotation<double>(motion.linear());
  const Eigen::Matrix3d stretch = rot.transpose() * motion.linear();
  const Eigen::Vector3d c = handleCentre();  // the pivot
  const double angle = Eigen::AngleAxisd(rot).angle();
  const double travel = (motion * c - c).norm() * scale_;
  // (At most 200 steps: a handle sent absurdly far still ends, in longer steps.)
  const double wanted = std::max({1.0, std::ceil(angle / (20.0 * M_PI / 180.0)), std::ceil(travel / 0.1)});
  const int steps = static_cast<int>(std::min(wanted, 200.0));
  SolveStats total;
  const Eigen::Quaterniond q0 = Eigen::Quaterniond::Identity(), q1(rot);
  for (int k = 1; k <= steps; ++k) {
    const double s = static_cast<double>(k) / steps;
    Eigen::Affine3d step = Eigen::Affine3d::Identity();
    if (k == steps) {
      step = motion;
    } else {
      const Eigen::Matrix3d lin =
          q0.slerp(s, q1).toRotationMatrix() * ((1 - s) * Eigen::Matrix3d::Identity() + s * stretch);
      step.linear() = lin;
      step.translation() = c + s * (motion * c - c) - lin * c;
    }
    const SolveStats st = solveHandle(step * current);
    total.iterations += st.iterations;
    total.ms += st.ms;
    total.converged = st.converged;
    total.decreased = total.decreased && st.decreased;
    total.energy = st.energy;
  }
  updateShape();
  return total;
}

SolveStats Deformer::Impl::solveHandle(const Eigen::Affine3d& transform) {
  if (!frame_mode_) unpick();  // a drag after the frame move picks again
  frame_mode_ = true;
  const Eigen::Matrix3d a = transform.linear();
  const Eigen::Vector3d o = geometry_->origin;
  // The world transform in the solver's normalised frame, about the cluster's barycentre.
  const Eigen::Vector3d shift = scale_ * (a * (centre_ + o) + transform.translation() - o - centre_);
  const int mc = data_.clustering.manipulated;
  const Eigen::Vector3d g = normalise(data_.clustering.clusters[static_cast<std::size_t>(mc)].barycentre);
  solver_.hold(mc, NormalisedTransform{a, a * g + shift - g});
  return solver_.solve(options_.gauss_newton);
}

Eigen::Affine3d Deformer::Impl::handleTransform() const {
  const int mc = data_.clustering.manipulated;
  const NormalisedTransform& t = solver_.transforms()[static_cast<std::size_t>(mc)];
  const Eigen::Vector3d g = normalise(data_.clustering.clusters[static_cast<std::size_t>(mc)].barycentre);
  const Eigen::Vector3d shift = t.t + g - t.A * g;  // normalised: x -> A x + shift
  const Eigen::Vector3d o = geometry_->origin;
  Eigen::Affine3d w = Eigen::Affine3d::Identity();
  w.linear() = t.A;
  w.translation() = shift / scale_ - t.A * (centre_ + o) + o + centre_;
  return w;
}

void Deformer::Impl::reset() {
  leaveFrameMode();
  solver_.reset();
  unpick();
  updateShape();
}

void Deformer::Impl::settleFirstShape() const {
  const std::lock_guard<std::mutex> lock(first_shape_.mutex);
  if (!first_shape_.due.load(std::memory_order_relaxed)) return;
  // local_ is still the build's: updateShape() and rebuild() settle or drop this first.
  interpolatePositions(data_.table, local_, positions_, first_shape_.blend);
  first_shape_.due.store(false, std::memory_order_release);
}

void Deformer::Impl::setBlend(Blend blend) {
  options_.blend = blend;
  updateShape();
}

void Deformer::Impl::updateShape(bool lazy) {
  if (preview_.empty()) {
    // Every point is (re)made below, or marked due: a pending first shape is not needed.
    const std::lock_guard<std::mutex> lock(first_shape_.mutex);
    first_shape_.due.store(false, std::memory_order_release);
  } else {
    ensureFirstShape();  // the points the preview leaves alone must hold it
  }
  Stopwatch sw;
  const auto& tr = solver_.transforms();
  for (std::size_t c = 0; c < tr.size(); ++c) {
    const Cluster& cl = data_.clustering.clusters[c];
    const Eigen::Vector3d g = normalise(cl.barycentre);
    Eigen::Matrix3d a = tr[c].A;
    // The barycentre's image, g + t in the normalised frame, back in the local frame.
    const Eigen::Vector3d image = (g + tr[c].t) / scale_ + centre_;
    const bool identity = tr[c].A == Eigen::Matrix3d::Identity() && tr[c].t.isZero(0);
    if (cl.kind == ClusterKind::Range && !identity) a = nearestRotation(a);  // bones move rigidly
    ExactTransform& e = exact_[c];
    e.identity = identity;
    e.A = identity ? Eigen::Matrix3d::Identity() : a;
    e.b = identity ? Eigen::Vector3d::Zero() : Eigen::Vector3d(image - a * cl.barycentre);
    local_[c].set(e.A.cast<float>(), e.b.cast<float>(), cl.barycentre.cast<float>());
  }
  if (preview_.empty()) {
    if (lazy) {
      const std::lock_guard<std::mutex> lock(first_shape_.mutex);
      first_shape_.handle_done = false;
      first_shape_.blend = options_.blend;
      first_shape_.due.store(true, std::memory_order_release);
    } else {
      interpolatePositions(data_.table, local_, positions_, options_.blend);
    }
    const std::lock_guard<std::mutex> lock(normals_.mutex);
    normals_.all_due = true;
    normals_.all_transforms = local_;
    normals_.all_blend = options_.blend;
    normals_.preview_due = false;
  } else {
    interpolatePositions(preview_table_, local_, preview_points_, options_.blend);
    for (std::size_t k = 0; k < preview_.size(); ++k)
      positions_[static_cast<std::size_t>(preview_[k])] = preview_points_[k];
    const std::lock_guard<std::mutex> lock(normals_.mutex);
    normals_.preview_due = true;
  }
  interp_ms_ = sw.ms();
}

SurfaceStretch Deformer::Impl::surfaceStretch() const {
  // (Never under 1e-4 of the diagonal: a move and back, float noise on near-duplicate points
  // must not count as a split.)
  return measureSurfaceStretch(*geometry_, deformedPoints(), *data_.graph, data_.coarse, 1e-4 / scale_);
}

void Deformer::Impl::updateNormals() const {
  const std::lock_guard<std::mutex> lock(normals_.mutex);
  out_normals_.resize(geometry_->size());
  // The last full frame's (the points a preview frame left alone keep those), then the preview's.
  if (normals_.all_due) {
    interpolateNormals(data_.table, normals_.all_transforms, out_normals_, normals_.all_blend);
    normals_.all_due = false;
  }
  if (normals_.preview_due && data_.table.has_normals) {
    interpolateNormals(preview_table_, local_, preview_normals_, options_.blend);
    for (std::size_t k = 0; k < preview_.size(); ++k)
      out_normals_[static_cast<std::size_t>(preview_[k])] = preview_normals_[k];
  }
  normals_.preview_due = false;
}

const std::vector<Eigen::Vector3f>& Deformer::Impl::deformedNormals() const {
  updateNormals();
  return out_normals_;
}

// --- Deformer: the public face, each call the Impl's --------------------------------------------

Deformer::Deformer(const Geometry& geometry, const Handles& handles, const DeformOptions& options)
    : Deformer(std::make_shared<const Geometry>(geometry), handles, options) {}
Deformer::Deformer(std::shared_ptr<const Geometry> geometry, const Handles& handles,
                   const DeformOptions& options)
    : impl_(std::make_unique<Impl>(std::move(geometry), handles, options)) {}
Deformer::Deformer(std::shared_ptr<const Geometry> geometry, const Handles& handles,
                   const DeformOptions& options, std::shared_ptr<const PrebuiltLevel> level)
    : impl_(std::make_unique<Impl>(std::move(geometry), handles, options, std::move(level))) {}
Deformer::~Deformer() = default;

SolveStats Deformer::drag(const Eigen::Vector3d& from, const Eigen::Vector3d& to) {
  return impl_->drag(from, to);
}
DragResult Deformer::dragTo(const Eigen::Vector3d& from, const Eigen::Vector3d& to) {
  return impl_->dragTo(from, to);
}
SolveStats Deformer::translateHandle(const Eigen::Vector3d& from, const Eigen::Vector3d& to) {
  return impl_->translateHandle(from, to);
}
SolveStats Deformer::setHandleTransform(const Eigen::Affine3d& transform) {
  return impl_->setHandleTransform(transform);
}
SolveStats Deformer::moveHandle(const Eigen::Affine3d& motion) {
  return impl_->moveHandle(motion);
}
Eigen::Vector3d Deformer::handleCentre() const {
  return impl_->handleCentre();
}
Eigen::Affine3d Deformer::handleTransform() const {
  return impl_->handleTransform();
}
void Deformer::reset() {
  impl_->reset();
}
void Deformer::setHandles(const Handles& handles) {
  impl_->setHandles(handles);
}
DeformerState Deformer::state() const {
  return impl_->state();
}
void Deformer::restore(const DeformerState& state) {
  impl_->restore(state);
}
void Deformer::setBlend(Blend blend) {
  impl_->setBlend(blend);
}
void Deformer::setPreview(std::vector<int> points) {
  impl_->setPreview(std::move(points));
}
const std::vector<int>& Deformer::preview() const {
  return impl_->preview();
}
const std::vector<Eigen::Vector3f>& Deformer::deformedPoints() const {
  return impl_->deformedPoints();
}
const std::vector<Eigen::Vector3f>& Deformer::deformedNormals() const {
  return impl_->deformedNormals();
}
Eigen::Vector3d Deformer::deformedWorld(std::size_t i) const {
  return impl_->deformedWorld(i);
}
std::vector<std::string> Deformer::writeDeformed(Shape& shape) const {
  return impl_->writeDeformed(shape);
}
ExactInterpolation Deformer::exactInterpolation() const {
  return impl_->exactInterpolation();
}
ExactInterpolation Deformer::exactInterpolation(const InterpolationTable& table) const {
  return impl_->exactInterpolation(table);
}
std::shared_ptr<const BlockProlongation> Deformer::blockProlongation() const {
  return impl_->blockProlongation();
}
std::vector<Eigen::Affine3d> Deformer::worldTransforms() const {
  return impl_->worldTransforms();
}
const Geometry& Deformer::geometry() const {
  return impl_->geometry();
}
const Handles& Deformer::handles() const {
  return impl_->handles();
}
const std::vector<float>& Deformer::field() const {
  return impl_->field();
}
const SurfaceGraph& Deformer::surfaceGraph() const {
  return impl_->surfaceGraph();
}
const HarmonicField& Deformer::harmonicField() const {
  return impl_->harmonicField();
}
const CoarseLevel& Deformer::coarseLevel() const {
  return impl_->coarseLevel();
}
std::size_t Deformer::unreachablePoints() const {
  return impl_->unreachablePoints();
}
const Clustering& Deformer::clustering() const {
  return impl_->clustering();
}
const InterpolationTable& Deformer::interpolationTable() const {
  return impl_->interpolationTable();
}
const PieceAnalysis& Deformer::pieces() const {
  return impl_->pieces();
}
SurfaceStretch Deformer::surfaceStretch() const {
  return impl_->surfaceStretch();
}
const std::vector<NormalisedTransform>& Deformer::clusterTransforms() const {
  return impl_->clusterTransforms();
}
Energies Deformer::energies() const {
  return impl_->energies();
}
const BuildTimings& Deformer::buildTimings() const {
  return impl_->buildTimings();
}
double Deformer::lastInterpolationMs() const {
  return impl_->lastInterpolationMs();
}
int Deformer::picked() const {
  return impl_->picked();
}
double Deformer::diagonal() const {
  return impl_->diagonal();
}

}  // namespace hgd
