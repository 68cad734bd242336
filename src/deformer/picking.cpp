// Picking among the manipulated handle's points and their centre (internal to the Deformer):
// the geometry's own points, or the level's points the geometry does not hold (a streamed
// shape's), each deformed as the table's pinned rows are.
#include <algorithm>
#include <cmath>

#include "deformer/deformer_impl.h"

namespace hgd {

namespace {
constexpr std::size_t kMaxMatchPoints = 32;      // shape-matching points besides the picked one
constexpr double kPinWeight = 1e4;               // relative weight of the barycentre pin
constexpr std::size_t kExternalBlock = 1 << 16;  // external handle points a block
}  // namespace

template <typename Read>
void Deformer::Impl::readHandlePositions(Read&& read) const {
  const std::lock_guard<std::mutex> lock(first_shape_.mutex);
  if (first_shape_.due.load(std::memory_order_relaxed) && !first_shape_.handle_done) {
    // Row by row what the whole table gives (as a preview frame's points), for these only.
    std::vector<int> handle = handles_.manipulated;
    std::sort(handle.begin(), handle.end());
    handle.erase(std::unique(handle.begin(), handle.end()), handle.end());
    std::vector<Eigen::Vector3f> moved(handle.size());
    interpolatePositions(subTable(handle), local_, moved, first_shape_.blend);
    for (std::size_t k = 0; k < handle.size(); ++k)
      positions_[static_cast<std::size_t>(handle[k])] = moved[k];
    first_shape_.handle_done = true;
  }
  read(static_cast<const std::vector<Eigen::Vector3f>&>(positions_));
}

void Deformer::Impl::pick(const Eigen::Vector3d& world) {
  const Eigen::Vector3f local = (world - geometry_->origin).cast<float>();
  float best = INFINITY;
  unpick();
  if (const std::vector<Eigen::Vector3f>* ext = externalHandle()) {
    // The first point nearest, in the handle's order, as below.
    std::size_t at_best = 0;
    std::vector<Eigen::Vector3f> now;
    for (std::size_t first = 0; first < ext->size(); first += kExternalBlock) {
      const std::size_t count = std::min(kExternalBlock, ext->size() - first);
      externalPositions(first, count, now);
      for (std::size_t k = 0; k < count; ++k) {
        const float d = (now[k] - local).squaredNorm();
        if (d < best) {
          best = d;
          at_best = first + k;
        }
      }
    }
    picked_external_ = static_cast<int>(at_best);
    picked_ = data_.prebuilt->manipulated_held[at_best];
    picked_rest_ = (*ext)[at_best];
  } else {
    picked_ = handles_.manipulated.front();
    readHandlePositions([&](const std::vector<Eigen::Vector3f>& at) {
      for (int i : handles_.manipulated) {
        const float d = (at[static_cast<std::size_t>(i)] - local).squaredNorm();
        if (d < best) {
          best = d;
          picked_ = i;
        }
      }
    });
    picked_rest_ = (*geometry_->points)[static_cast<std::size_t>(picked_)].getVector3fMap();
  }
  // Shape matching on (a subsample of) the handle's cluster points plus the picked point.
  const auto& members =
      data_.clustering.clusters[static_cast<std::size_t>(data_.clustering.manipulated)].members;
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
  manip_rest_.push_back(normalise(picked_rest_.cast<double>()));
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

Eigen::Vector3d Deformer::Impl::handleCentre() const {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  if (const std::vector<Eigen::Vector3f>* ext = externalHandle()) {
    std::vector<Eigen::Vector3f> now;  // the same sum, in the same order, block by block
    for (std::size_t first = 0; first < ext->size(); first += kExternalBlock) {
      externalPositions(first, std::min(kExternalBlock, ext->size() - first), now);
      for (const Eigen::Vector3f& p : now) c += p.cast<double>() + geometry_->origin;
    }
    return c / static_cast<double>(ext->size());
  }
  readHandlePositions([&](const std::vector<Eigen::Vector3f>& at) {
    for (int i : handles_.manipulated)
      c += at[static_cast<std::size_t>(i)].cast<double>() + geometry_->origin;
  });
  return c / static_cast<double>(handles_.manipulated.size());
}

Eigen::Vector3f Deformer::Impl::pickedNow() const {
  if (picked_external_ >= 0) {
    std::vector<Eigen::Vector3f> now;
    externalPositions(static_cast<std::size_t>(picked_external_), 1, now);
    return now[0];
  }
  Eigen::Vector3f at;
  readHandlePositions(
      [&](const std::vector<Eigen::Vector3f>& p) { at = p[static_cast<std::size_t>(picked_)]; });
  return at;
}

void Deformer::Impl::externalPositions(std::size_t first, std::size_t count,
                                       std::vector<Eigen::Vector3f>& out) const {
  // Rows as the table pins a manipulated point: its rest position, the manipulated cluster's
  // own pair, no blend; the transforms and the blend the held points' positions were made with.
  const std::vector<Eigen::Vector3f>& rest = data_.prebuilt->manipulated_rest;
  const int mc = data_.clustering.manipulated;
  InterpolationTable t;
  t.pairs = data_.table.pairs;
  t.pair_centre = data_.table.pair_centre;
  const auto pair = static_cast<std::uint32_t>(
      std::lower_bound(t.pairs.begin(), t.pairs.end(), std::make_pair(mc, mc)) - t.pairs.begin());
  t.points.resize(count);
  for (std::size_t k = 0; k < count; ++k) {
    InterpolationTable::Point& r = t.points[k];
    for (int a = 0; a < 3; ++a) r.p[a] = rest[first + k][a];
    r.alpha = 0.0f;
    r.pair = pair;
  }
  out.resize(count);
  const bool first_shape = first_shape_.due.load(std::memory_order_acquire);
  interpolatePositions(t, local_, out, first_shape ? first_shape_.blend : options_.blend);
}

}  // namespace hgd
