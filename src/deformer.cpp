#include "hgdeform/deformer.h"

#include <omp.h>

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <stdexcept>

#include "hgdeform/fields.h"
#include "timer.h"

namespace hgd {

namespace {
constexpr std::size_t kMaxMatchPoints = 32;  // shape-matching points besides the picked one
constexpr double kPinWeight = 1e4;           // relative weight of the barycentre pin
}  // namespace

Deformer::Deformer(const Geometry& geometry, const Handles& handles, const DeformOptions& options)
    : Deformer(std::make_shared<const Geometry>(geometry), handles, options) {}

Deformer::Deformer(std::shared_ptr<const Geometry> geometry, const Handles& handles,
                   const DeformOptions& options)
    : geometry_(std::move(geometry)), handles_(handles), options_(options) {
  if (!geometry_) throw std::invalid_argument("Deformer: no geometry");
  if (geometry_->hasFileNormals() && geometry_->file_normals->size() != geometry_->size())
    throw std::invalid_argument("Deformer: the geometry has " +
                                std::to_string(geometry_->file_normals->size()) + " normals for " +
                                std::to_string(geometry_->size()) + " points");
  // The mesh's 1-ring, when asked for, is a graph over every vertex: full resolution.
  multires_ = options_.multires_above > 0 && geometry_->size() > options_.multires_above &&
              options_.coarse_points > 0 && options_.coarse_points < geometry_->size() &&
              !(options_.field.mesh_ring && !geometry_->faces.empty());
  if (!multires_) fieldOnEveryPoint();  // else rebuild() gives the field the handles' coarse level
  field_.setOptions(options_.field);
  // The body's box: a far stray does not coarsen tolerances and steps (nor the normalised frame).
  const Eigen::AlignedBox3f box = bodyBox(*geometry_);
  const Eigen::Vector3d lo = box.min().cast<double>(), hi = box.max().cast<double>();
  centre_ = 0.5 * (lo + hi);
  const double diag = (hi - lo).norm();
  scale_ = diag > 0 ? 1.0 / diag : 1.0;
  positions_.resize(geometry_->size());  // (normals are sized when first derived)
  rebuild();
}

void Deformer::setHandles(const Handles& handles) {
  handles_ = handles;
  rebuild();
}

void Deformer::rebuild() {
  if (handles_.manipulated.empty()) throw std::invalid_argument("Deformer: the manipulated handle is empty");
  if (handles_.fixed.empty()) throw std::invalid_argument("Deformer: no fixed handle");
  // The tables change: normals due on points a preview frame will leave alone, now; without a
  // preview the first frame derives them all again.
  if (!preview_.empty()) updateNormals();
  normals_.all_due = normals_.preview_due = false;
  Stopwatch sw;
  if (multires_) {
    auto check = [&](const std::vector<int>& idx) {
      for (const int i : idx)
        if (i < 0 || static_cast<std::size_t>(i) >= geometry_->size())
          throw std::invalid_argument("Deformer: handle index " + std::to_string(i) + " out of range");
    };
    for (const auto& f : handles_.fixed) check(f);
    check(handles_.manipulated);
    for (const auto& j : handles_.joints) check(j);
    coarse_ = coarsen(*geometry_->points, handles_, options_.coarse_points, geometry_->faces.empty());
    if (coarse_.empty()) {  // thousands of handles: no cell key holds them all
      multires_ = false;
      fieldOnEveryPoint();
    }
  }
  if (multires_) {
    buildCoarse(sw);
  } else {
    // The field object keeps normals, kNN and the graph: new handles only re-solve.
    field_.setHandles(handles_.fixed, handles_.manipulated);
    field_.compute(phi_);
    build_.field = field_.timings();
    build_.field_ms = sw.lap();
    build_.coarse_ms = 0;
    unreachable_points_ = field_.unreachable().size();

    const auto& pts = *geometry_->points;
    clustering_ = clusterField(pts, phi_, handles_, nullptr, sw);
    // Normals rotate with the shape as the file gave them (the filter may have re-oriented its
    // own copy): the file's are shared with the table, not copied.
    if (geometry_->hasFileNormals())
      table_ = buildInterpolation(phi_, handles_, clustering_, pts,
                                  pcl::PointCloud<pcl::Normal>::ConstPtr(geometry_->file_normals));
    else
      table_ = buildInterpolation(phi_, handles_, clustering_, pts, &field_.normals());
    // The per-point brackets live on in the table alone (interpolationTable().bracket()).
    clustering_.lower = {};
    clustering_.upper = {};
    clustering_.alpha = {};
    clustering_.nearest = {};
  }
  buildPreviewTable();
  build_.clusters_ms = sw.lap();

  setupSolver();
  local_.resize(clustering_.clusters.size());
  exact_.assign(clustering_.clusters.size(), ExactTransform{});
  picked_ = -1;
  updateShape();
  build_.setup_ms = sw.lap();
}

void Deformer::fieldOnEveryPoint() {
  field_.setInputCloud(geometry_->points);
  field_.setInputNormals(geometry_->hasFileNormals() ? geometry_->file_normals : nullptr);
  if (!geometry_->faces.empty()) field_.setPolygons(geometry_->faces);
}

Clustering Deformer::clusterField(const pcl::PointCloud<pcl::PointXYZ>& points, const std::vector<float>& phi,
                                  const Handles& handles, const std::vector<std::uint32_t>* weight,
                                  Stopwatch& sw) {
  const NeighborGraph& graph = field_.graph();
  // Stray points of a scan stay out of the sample (meshes have none).
  const std::vector<char>& outliers = field_.outliers();
  const std::vector<int> sample =
      sampleSurface(points, handles, options_.clusters.samples, outliers.empty() ? nullptr : &outliers);
  build_.sampling_ms = sw.lap();
  pieces_ = analysePieces(points, graph, field_.pieceLabels(), handles, sample, 2.0, weight);
  return buildClusters(points, graph, phi, handles, field_.unreachable(), sample, options_.clusters,
                       pieces_.follow, outliers);
}

void Deformer::buildCoarse(Stopwatch& sw) {
  const auto& pts = *geometry_->points;
  const std::size_t m = coarse_.points.size();
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  cloud->resize(m);
  for (std::size_t a = 0; a < m; ++a) (*cloud)[a] = pts[static_cast<std::size_t>(coarse_.points[a])];
  // The coarse level is a cloud: the file's normals, else a mesh's (where every coarse vertex
  // has one), else estimated there.
  pcl::PointCloud<pcl::Normal>::Ptr normals;
  pcl::PointCloud<pcl::Normal>::ConstPtr full =
      geometry_->hasFileNormals() ? geometry_->file_normals : nullptr;
  if (!full && !geometry_->faces.empty()) full = meshNormals(pts, geometry_->faces);
  if (full) {
    normals.reset(new pcl::PointCloud<pcl::Normal>);
    normals->resize(m);
    std::vector<char> finite(m, 0);
    std::size_t missing = 0;
    for (std::size_t a = 0; a < m; ++a) {
      (*normals)[a] = (*full)[static_cast<std::size_t>(coarse_.points[a])];
      finite[a] = (*normals)[a].getNormalVector3fMap().allFinite();
      missing += !finite[a];
    }
    // A representative without a normal (a vertex on no face) takes one of its cell's; a cell
    // with none at all leaves the coarse level to estimate them.
    for (std::size_t i = 0; i < pts.size() && missing > 0; ++i) {
      const std::uint32_t a = coarse_.anchor[i];
      if (finite[a] || !(*full)[i].getNormalVector3fMap().allFinite()) continue;
      (*normals)[a] = (*full)[i];
      finite[a] = 1;
      --missing;
    }
    if (missing > 0) normals.reset();
  }
  full.reset();
  field_.setInputCloud(cloud);
  field_.setInputNormals(normals);
  const Handles coarse_handles = coarseHandles(handles_, coarse_);
  field_.setHandles(coarse_handles.fixed, coarse_handles.manipulated);
  const double coarse_ms = sw.lap();
  std::vector<float> coarse_phi;
  field_.compute(coarse_phi);
  build_.field = field_.timings();
  sw.lap();
  std::vector<char> constrained(m, 0);
  for (const auto& f : coarse_handles.fixed)
    for (int a : f) constrained[static_cast<std::size_t>(a)] = 1;
  for (int a : coarse_handles.manipulated) constrained[static_cast<std::size_t>(a)] = 1;
  const NeighborGraph& graph = field_.graph();
  phi_ = prolongField(pts, coarse_, graph, coarse_phi, constrained);
  build_.coarse_ms = coarse_ms + sw.ms();
  build_.field_ms = build_.field.total() + build_.coarse_ms;
  sw.lap();
  unreachable_points_ = 0;
  for (const int a : field_.unreachable()) unreachable_points_ += coarse_.weight[static_cast<std::size_t>(a)];

  // Pieces and clusters on the coarse level, then every point takes its anchor's, straight into
  // the table (no per-point labels in between).
  Clustering coarse_clusters = clusterField(*cloud, coarse_phi, coarse_handles, &coarse_.weight, sw);
  pieces_.follow.clear();  // the coarse points' (each point takes its anchor's clusters)
  table_ = prolongInterpolation(coarse_clusters, coarse_, coarse_phi, phi_, handles_, pts);
  clustering_ = prolongClusters(std::move(coarse_clusters), coarse_);
  char note[200];
  std::snprintf(note, sizeof note,
                "multi-resolution: field, pieces and clusters on %zu of %zu points (voxel side %.3g); "
                "full resolution on request",
                m, pts.size(), static_cast<double>(coarse_.cell));
  clustering_.notes.emplace_back(note);
  if (geometry_->hasFileNormals()) {  // shared, not copied
    table_.normal_cloud = geometry_->file_normals;
    table_.has_normals = true;
  } else {  // a point's rest normal: its anchor's
    const auto& coarse_normals = field_.normals();
    table_.normals.resize(pts.size());
    for (std::size_t i = 0; i < pts.size(); ++i)
      table_.normals[i] = coarse_normals[coarse_.anchor[i]].getNormalVector3fMap();
    table_.has_normals = true;
  }
}

DeformerState Deformer::state() const {
  return {solver_.transforms(), frame_mode_};
}

void Deformer::restore(const DeformerState& state) {
  if (state.transforms.size() != clustering_.clusters.size())
    throw std::invalid_argument("Deformer::restore: the state belongs to other clusters");
  solver_.setTransforms(state.transforms);
  const int mc = clustering_.manipulated;
  if (state.frame_mode)
    solver_.hold(mc, state.transforms[static_cast<std::size_t>(mc)]);
  else
    solver_.release();
  frame_mode_ = state.frame_mode;
  picked_ = -1;
  updateShape();
}

void Deformer::setupSolver() {
  int n_iso = 0;
  for (const auto& cl : clustering_.clusters) n_iso += cl.kind == ClusterKind::Iso;
  std::vector<SolverCluster> sc(clustering_.clusters.size());
  for (std::size_t c = 0; c < sc.size(); ++c) {
    const Cluster& cl = clustering_.clusters[c];
    sc[c].barycentre = normalise(cl.barycentre);
    sc[c].points.reserve(cl.members.size());
    for (int i : cl.members)
      sc[c].points.push_back(
          normalise((*geometry_->points)[static_cast<std::size_t>(i)].getVector3fMap().cast<double>()));
    // The manipulated cluster is free: a frame move holds it (solveHandle), a drag matches it.
    sc[c].constant = cl.kind == ClusterKind::Fixed || cl.kind == ClusterKind::Static;
    const double w_mhc =
        options_.weights.mhc_per_cluster > 0 ? std::max(1.0, options_.weights.mhc_per_cluster * n_iso) : 1.0;
    sc[c].rot_weight = cl.kind == ClusterKind::Manipulated ? w_mhc
                       : cl.kind == ClusterKind::Range     ? options_.bone_rigidity * w_mhc
                       : cl.kind == ClusterKind::Iso       ? options_.iso_rigidity
                                                           : 1.0;
  }
  solver_.setup(std::move(sc), clustering_.adjacency, clustering_.manipulated, options_.weights);
  frame_mode_ = false;
  picked_ = -1;
}

void Deformer::leaveFrameMode() {
  if (!frame_mode_) return;
  solver_.release();
  frame_mode_ = false;
  picked_ = -1;
}

Eigen::Vector3d Deformer::currentNormalised(int cluster, const Eigen::Vector3d& rest) const {
  const NormalisedTransform& t = solver_.transforms()[static_cast<std::size_t>(cluster)];
  const Eigen::Vector3d g = normalise(clustering_.clusters[static_cast<std::size_t>(cluster)].barycentre);
  return t.A * (rest - g) + g + t.t;
}

void Deformer::pick(const Eigen::Vector3d& world) {
  const Eigen::Vector3f local = (world - geometry_->origin).cast<float>();
  float best = INFINITY;
  picked_ = handles_.manipulated.front();
  for (int i : handles_.manipulated) {
    const float d = (positions_[static_cast<std::size_t>(i)] - local).squaredNorm();
    if (d < best) {
      best = d;
      picked_ = i;
    }
  }
  // Shape matching on (a subsample of) the handle's cluster points plus the picked point.
  const auto& members = clustering_.clusters[static_cast<std::size_t>(clustering_.manipulated)].members;
  const std::size_t stride =
      std::max<std::size_t>(1, (members.size() + kMaxMatchPoints - 1) / kMaxMatchPoints);
  manip_rest_.clear();
  manip_weight_.clear();
  for (std::size_t k = 0; k < members.size(); k += stride) {
    if (members[k] == picked_) continue;
    manip_rest_.push_back(normalise(
        (*geometry_->points)[static_cast<std::size_t>(members[k])].getVector3fMap().cast<double>()));
    manip_weight_.push_back(1.0);
  }
  manip_rest_.push_back(
      normalise((*geometry_->points)[static_cast<std::size_t>(picked_)].getVector3fMap().cast<double>()));
  manip_weight_.push_back(options_.weights.picked);
  // The paper's t_MC = c - c0: the handle's weighted barycentre goes exactly to the targets'
  // weighted barycentre. Imposed as one extra matching point of overwhelming weight, so that
  // only A_MC is left to the energy.
  double wsum = 0;
  Eigen::Vector3d c0 = Eigen::Vector3d::Zero();
  for (std::size_t k = 0; k < manip_rest_.size(); ++k) {
    c0 += manip_weight_[k] * manip_rest_[k];
    wsum += manip_weight_[k];
  }
  manip_rest_.push_back(c0 / wsum);
  manip_weight_.push_back(kPinWeight * wsum);
  manip_target_.resize(manip_rest_.size());
}

SolveStats Deformer::drag(const Eigen::Vector3d& from, const Eigen::Vector3d& to) {
  if (!to.allFinite() || !from.allFinite()) throw std::invalid_argument("drag: target is not finite");
  leaveFrameMode();
  if (picked_ < 0 || from != last_to_) pick(from);
  const SolveStats st = dragFrame(to);
  updateShape();
  return st;
}

SolveStats Deformer::dragFrame(const Eigen::Vector3d& to) {
  const int mc = clustering_.manipulated;
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

SolveStats Deformer::translateHandle(const Eigen::Vector3d& from, const Eigen::Vector3d& to) {
  if (!to.allFinite() || !from.allFinite()) throw std::invalid_argument("drag: target is not finite");
  if (picked_ < 0 || from != last_to_) pick(from);
  const SolveStats st = moveHandle(Eigen::Affine3d(Eigen::Translation3d(to - pickedWorld())));
  last_to_ = to;
  return st;
}

Eigen::Vector3d Deformer::pickedWorld() const {
  const Eigen::Vector3d rest =
      normalise((*geometry_->points)[static_cast<std::size_t>(picked_)].getVector3fMap().cast<double>());
  return currentNormalised(clustering_.manipulated, rest) / scale_ + centre_ + geometry_->origin;
}

DragResult Deformer::dragTo(const Eigen::Vector3d& from, const Eigen::Vector3d& to) {
  DragResult r;
  if (!to.allFinite() || !from.allFinite()) throw std::invalid_argument("drag: target is not finite");
  leaveFrameMode();
  pick(from);
  const Eigen::Vector3d start = deformedWorld(static_cast<std::size_t>(picked_));
  last_to_ = from;
  const double diag = 1.0 / scale_;
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
  r.error = (deformedWorld(static_cast<std::size_t>(picked_)) - to).norm();
  r.reached = r.error <= tol;
  return r;
}

SolveStats Deformer::setHandleTransform(const Eigen::Affine3d& transform) {
  if (!transform.matrix().allFinite())
    throw std::invalid_argument("setHandleTransform: transform is not finite");
  return moveHandle(transform * handleTransform().inverse());
}

Eigen::Vector3d Deformer::handleCentre() const {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (int i : handles_.manipulated) c += deformedWorld(static_cast<std::size_t>(i));
  return c / static_cast<double>(handles_.manipulated.size());
}

SolveStats Deformer::moveHandle(const Eigen::Affine3d& motion) {
  if (!motion.matrix().allFinite()) throw std::invalid_argument("moveHandle: motion is not finite");
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

SolveStats Deformer::solveHandle(const Eigen::Affine3d& transform) {
  if (!frame_mode_) picked_ = -1;  // a drag after the frame move picks again
  frame_mode_ = true;
  const Eigen::Matrix3d a = transform.linear();
  const Eigen::Vector3d o = geometry_->origin;
  // The world transform in the solver's normalised frame, about the cluster's barycentre.
  const Eigen::Vector3d shift = scale_ * (a * (centre_ + o) + transform.translation() - o - centre_);
  const int mc = clustering_.manipulated;
  const Eigen::Vector3d g = normalise(clustering_.clusters[static_cast<std::size_t>(mc)].barycentre);
  solver_.hold(mc, NormalisedTransform{a, a * g + shift - g});
  return solver_.solve(options_.gauss_newton);
}

Eigen::Affine3d Deformer::handleTransform() const {
  const int mc = clustering_.manipulated;
  const NormalisedTransform& t = solver_.transforms()[static_cast<std::size_t>(mc)];
  const Eigen::Vector3d g = normalise(clustering_.clusters[static_cast<std::size_t>(mc)].barycentre);
  const Eigen::Vector3d shift = t.t + g - t.A * g;  // normalised: x -> A x + shift
  const Eigen::Vector3d o = geometry_->origin;
  Eigen::Affine3d w = Eigen::Affine3d::Identity();
  w.linear() = t.A;
  w.translation() = shift / scale_ - t.A * (centre_ + o) + o + centre_;
  return w;
}

void Deformer::reset() {
  leaveFrameMode();
  solver_.reset();
  picked_ = -1;
  updateShape();
}

void Deformer::setPreview(std::vector<int> points) {
  for (const int i : points)
    if (i < 0 || static_cast<std::size_t>(i) >= geometry_->size())
      throw std::invalid_argument("Deformer::setPreview: point index out of range");
  const bool was = !preview_.empty();
  // The old preview's normals, if due, before its table goes (a full frame's keep: they are
  // computed from its own transforms whenever asked for).
  if (normals_.preview_due) updateNormals();
  preview_request_ = std::move(points);
  buildPreviewTable();
  if (was && preview_.empty()) updateShape();  // the points left behind catch up
}

void Deformer::buildPreviewTable() {
  preview_table_ = InterpolationTable{};
  preview_.clear();
  if (preview_request_.empty()) return;
  // The manipulated handle's points too: picking reads their positions.
  preview_ = preview_request_;
  preview_.insert(preview_.end(), handles_.manipulated.begin(), handles_.manipulated.end());
  std::sort(preview_.begin(), preview_.end());
  preview_.erase(std::unique(preview_.begin(), preview_.end()), preview_.end());
  preview_table_.has_normals = table_.has_normals;
  if (table_.has_normals)
    for (const int i : preview_)
      preview_table_.normals.push_back(table_.restNormal(static_cast<std::size_t>(i)));
  preview_table_.pairs = table_.pairs;
  preview_table_.pair_centre = table_.pair_centre;
  preview_table_.points.reserve(preview_.size());
  for (const int i : preview_) preview_table_.points.push_back(table_.points[static_cast<std::size_t>(i)]);
  preview_points_.resize(preview_.size());
  preview_normals_.resize(preview_.size());
}

void Deformer::setBlend(Blend blend) {
  options_.blend = blend;
  updateShape();
}

void Deformer::updateShape() {
  Stopwatch sw;
  const auto& tr = solver_.transforms();
  for (std::size_t c = 0; c < tr.size(); ++c) {
    const Cluster& cl = clustering_.clusters[c];
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
    interpolatePositions(table_, local_, positions_, options_.blend);
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

SurfaceStretch Deformer::surfaceStretch() const {
  // The scale of "grew by more than 2% of the move": the largest displacement of any point
  // (the handle's own can be near zero when it turns about its centre while the limb beyond it
  // swings), never under 1e-4 of the diagonal (a move and back: float noise on near-duplicate
  // points must not count as a split).
  double moved = 1e-4 / scale_;
  for (std::size_t u = 0; u < positions_.size(); ++u)
    moved = std::max(moved,
                     static_cast<double>((positions_[u] - (*geometry_->points)[u].getVector3fMap()).norm()));
  // Mesh edges where there are faces (what the user sees joined), else the neighbour graph.
  if (!geometry_->faces.empty())
    return measureStretch(*geometry_->points, positions_, ringGraph(geometry_->size(), geometry_->faces),
                          moved);
  // A stray's one pair to the surface point it hangs from is no surface pair (a stray inside
  // the dragged handle moves with it, its anchor maybe not).
  const std::vector<char>& strays = field_.outliers();
  if (multires_) {  // the coarse graph's pairs, between the points that stand for their cells
    const NeighborGraph& g = field_.graph();
    std::vector<std::pair<int, int>> pairs;
    for (std::size_t a = 0; a < g.size(); ++a)
      for (const int* j = g.begin(a); j != g.end(a); ++j)
        if (static_cast<int>(a) < *j)
          pairs.emplace_back(coarse_.points[a], coarse_.points[static_cast<std::size_t>(*j)]);
    NeighborGraph none;
    none.offsets.assign(geometry_->size() + 1, 0);
    std::vector<char> shape_strays;
    if (!strays.empty() || !coarse_.strays.empty()) {
      shape_strays.assign(geometry_->size(), 0);
      for (std::size_t a = 0; a < strays.size(); ++a)
        if (strays[a]) shape_strays[static_cast<std::size_t>(coarse_.points[a])] = 1;
      for (const int i : coarse_.strays) shape_strays[static_cast<std::size_t>(i)] = 1;
    }
    return measureStretch(*geometry_->points, positions_, addEdges(none, pairs), moved,
                          shape_strays.empty() ? nullptr : &shape_strays);
  }
  return measureStretch(*geometry_->points, positions_, field_.graph(), moved,
                        strays.empty() ? nullptr : &strays);
}

void Deformer::updateNormals() const {
  const std::lock_guard<std::mutex> lock(normals_.mutex);
  out_normals_.resize(geometry_->size());
  // The last full frame's (the points a preview frame left alone keep those), then the preview's.
  if (normals_.all_due) {
    interpolateNormals(table_, normals_.all_transforms, out_normals_, normals_.all_blend);
    normals_.all_due = false;
  }
  if (normals_.preview_due && table_.has_normals) {
    interpolateNormals(preview_table_, local_, preview_normals_, options_.blend);
    for (std::size_t k = 0; k < preview_.size(); ++k)
      out_normals_[static_cast<std::size_t>(preview_[k])] = preview_normals_[k];
  }
  normals_.preview_due = false;
}

const std::vector<Eigen::Vector3f>& Deformer::deformedNormals() const {
  updateNormals();
  return out_normals_;
}

ExactInterpolation Deformer::exactInterpolation() const {
  std::vector<Eigen::Vector3d> barycentres;
  barycentres.reserve(clustering_.clusters.size());
  for (const Cluster& cl : clustering_.clusters) barycentres.push_back(cl.barycentre);
  return ExactInterpolation(table_, exact_, barycentres, options_.blend);
}

namespace {
// A shape's x/y/z read and written as doubles: straight from the record when the three share a
// floating type (a file's usual case), else through readValue/writeValue.
class XyzAccess {
 public:
  XyzAccess(pcl::PCLPointCloud2& c, const XyzFields& f)
      : c_(c),
        fx_(c.fields[static_cast<std::size_t>(f.x)]),
        fy_(c.fields[static_cast<std::size_t>(f.y)]),
        fz_(c.fields[static_cast<std::size_t>(f.z)]) {
    const std::uint8_t t = fx_.datatype;
    const bool floating = t == pcl::PCLPointField::FLOAT32 || t == pcl::PCLPointField::FLOAT64;
    type_ = floating && fy_.datatype == t && fz_.datatype == t ? t : 0;
  }
  Eigen::Vector3d get(std::size_t i) const {
    const std::uint8_t* r = c_.data.data() + i * c_.point_step;
    if (type_ == pcl::PCLPointField::FLOAT32)
      return {load<float>(r + fx_.offset), load<float>(r + fy_.offset), load<float>(r + fz_.offset)};
    if (type_ == pcl::PCLPointField::FLOAT64)
      return {load<double>(r + fx_.offset), load<double>(r + fy_.offset), load<double>(r + fz_.offset)};
    return {readValue(c_, i, fx_), readValue(c_, i, fy_), readValue(c_, i, fz_)};
  }
  void set(std::size_t i, const Eigen::Vector3d& p) {
    std::uint8_t* r = c_.data.data() + i * c_.point_step;
    if (type_ == pcl::PCLPointField::FLOAT32) {
      store(r + fx_.offset, static_cast<float>(p.x()));
      store(r + fy_.offset, static_cast<float>(p.y()));
      store(r + fz_.offset, static_cast<float>(p.z()));
    } else if (type_ == pcl::PCLPointField::FLOAT64) {
      store(r + fx_.offset, p.x());
      store(r + fy_.offset, p.y());
      store(r + fz_.offset, p.z());
    } else {
      writeValue(c_, i, fx_, p.x());
      writeValue(c_, i, fy_, p.y());
      writeValue(c_, i, fz_, p.z());
    }
  }

 private:
  template <typename T>
  static double load(const std::uint8_t* p) {
    T v;
    std::memcpy(&v, p, sizeof v);
    return static_cast<double>(v);
  }
  template <typename T>
  static void store(std::uint8_t* p, T v) {
    std::memcpy(p, &v, sizeof v);
  }
  pcl::PCLPointCloud2& c_;
  const pcl::PCLPointField &fx_, &fy_, &fz_;
  std::uint8_t type_ = 0;
};
}  // namespace

std::vector<Eigen::Affine3d> Deformer::worldTransforms() const {
  std::vector<Eigen::Affine3d> out;
  const Eigen::Vector3d o = geometry_->origin;
  for (const ExactTransform& e : exact_) {
    Eigen::Affine3d t = Eigen::Affine3d::Identity();
    t.linear() = e.A;
    t.translation() = e.b + o - e.A * o;
    out.push_back(t);
  }
  return out;
}

std::vector<std::string> Deformer::writeDeformed(Shape& shape) const {
  std::vector<std::string> warnings;
  pcl::PCLPointCloud2& c = shape.cloud;
  XyzFields f = findXyzFields(c);
  const Geometry& g = *geometry_;
  const std::size_t n = static_cast<std::size_t>(c.width) * c.height;
  if (!f.hasXyz() || g.raw_index.size() != table_.size() || g.finite_index.size() != n)
    throw std::logic_error("Deformer::writeDeformed: the shape is not the one the deformer was built on");
  // Nothing moves: every point as the file had it, to the bit (nothing read, nothing written).
  if (std::all_of(exact_.begin(), exact_.end(), [](const ExactTransform& e) { return e.identity; }))
    return warnings;
  const ExactInterpolation exact = exactInterpolation();
  const long long nn = static_cast<long long>(n);
  // In the file's order: the cloud's records are read and written in sequence.
  auto forEachPoint = [&](auto&& body) {
#pragma omp parallel for schedule(static) if (nn > kParallelMin)
    for (long long ii = 0; ii < nn; ++ii) {
      const auto i = static_cast<std::size_t>(ii);
      const int k = g.finite_index[i];
      if (k >= 0) body(i, static_cast<std::size_t>(k));
    }
  };
  // The shape must hold the rest positions (a second call on the same shape would move it twice):
  // its values give the table's float rest positions exactly, as extractGeometry made them.
  {
    std::vector<char> bad(static_cast<std::size_t>(omp_get_max_threads()), 0);
    const XyzAccess xyz(c, f);
    forEachPoint([&](std::size_t i, std::size_t k) {
      const Eigen::Vector3f p = (xyz.get(i) - g.origin).cast<float>();
      const float* r = table_.points[k].p;
      if (!(p.x() == r[0] && p.y() == r[1] && p.z() == r[2]))
        bad[static_cast<std::size_t>(omp_get_thread_num())] = 1;
    });
    if (std::find(bad.begin(), bad.end(), 1) != bad.end())
      throw std::logic_error(
          "Deformer::writeDeformed: the shape does not hold the rest positions (written to already?)");
  }
  // Integer coordinates cannot hold a deformed position: each is widened (8 and 16 bits to float,
  // 32 to double), said, never rounded or clipped.
  {
    std::vector<int> to_float, to_double;
    for (const int idx : {f.x, f.y, f.z}) {
      const std::uint8_t t = c.fields[static_cast<std::size_t>(idx)].datatype;
      if (t == pcl::PCLPointField::FLOAT32 || t == pcl::PCLPointField::FLOAT64) continue;
      (t == pcl::PCLPointField::INT32 || t == pcl::PCLPointField::UINT32 ? to_double : to_float)
          .push_back(idx);
    }
    if (!to_float.empty()) retypeFields(c, to_float, pcl::PCLPointField::FLOAT32);
    if (!to_double.empty()) retypeFields(c, to_double, pcl::PCLPointField::FLOAT64);
    if (!to_float.empty() || !to_double.empty()) {
      f = findXyzFields(c);
      warnings.push_back(
          (shape.path.empty() ? std::string("the shape") : shape.path) +
          ": x/y/z are stored as integers, which cannot hold the deformed positions: written as " +
          (to_double.empty()  ? "float"
           : to_float.empty() ? "double"
                              : "float and double"));
    }
  }
  // Normals are turned where the file's own were used (all finite and non-zero): else they are
  // left as the file had them, and that is said.
  const bool write_normals = f.hasNormals() && g.hasFileNormals() && table_.has_normals;
  if (f.hasNormals() && !write_normals)
    warnings.push_back((shape.path.empty() ? std::string("the shape") : shape.path) +
                       ": its normals were not usable (some are zero or not finite): they are written back "
                       "as they were, not turned with the shape");
  XyzAccess xyz(c, f);
  forEachPoint([&](std::size_t i, std::size_t k) {
    if (!exact.moves(k)) return;  // left as the file had it
    xyz.set(i, exact.apply(k, xyz.get(i) - g.origin) + g.origin);
    if (write_normals) {
      const Eigen::Vector3d nv = exact.applyNormal(k, table_.restNormal(k).cast<double>());
      writeValue(c, i, c.fields[f.nx], nv.x());
      writeValue(c, i, c.fields[f.ny], nv.y());
      writeValue(c, i, c.fields[f.nz], nv.z());
    }
  });
  // An OBJ's own normals ('vn', indexed apart from the vertices) turn as the normal of the
  // vertex a face pairs them with turns.
  FileExtras& x = shape.extras;
  x.obj_normals_out = x.obj_normals;
  if (!table_.has_normals) return warnings;
  for (std::size_t j = 0; j < x.obj_normals.size() && j < x.obj_normal_vertex.size(); ++j) {
    const int v = x.obj_normal_vertex[j];
    if (v < 0 || static_cast<std::size_t>(v) >= g.finite_index.size()) continue;
    const int fi = g.finite_index[static_cast<std::size_t>(v)];
    if (fi < 0 || !exact.moves(static_cast<std::size_t>(fi))) continue;
    const auto i = static_cast<std::size_t>(fi);
    const Eigen::Vector3d n0 = table_.restNormal(i).cast<double>();  // the rest normal that turns
    const Eigen::Vector3d n1 = exact.applyNormal(i, n0);
    if (!(n0.squaredNorm() > 0) || !(n1.squaredNorm() > 0) || !n0.allFinite() || !n1.allFinite()) continue;
    x.obj_normals_out[j] =
        (Eigen::Quaterniond::FromTwoVectors(n0, n1) * x.obj_normals[j].cast<double>()).cast<float>();
  }
  return warnings;
}

}  // namespace hgd
