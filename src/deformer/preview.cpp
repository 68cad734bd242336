// The preview frame (internal to the Deformer): a few points (the picked region and the
// manipulated handle) interpolated alone while a drag is live, from a sub-table of the whole.
#include <algorithm>
#include <stdexcept>

#include "deformer/deformer_impl.h"

namespace hgd {

void Deformer::Impl::setPreview(std::vector<int> points) {
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

void Deformer::Impl::buildPreviewTable() {
  preview_table_ = InterpolationTable{};
  preview_.clear();
  if (preview_request_.empty()) return;
  // The manipulated handle's points too: picking reads their positions.
  preview_ = preview_request_;
  preview_.insert(preview_.end(), handles_.manipulated.begin(), handles_.manipulated.end());
  std::sort(preview_.begin(), preview_.end());
  preview_.erase(std::unique(preview_.begin(), preview_.end()), preview_.end());
  preview_table_ = subTable(preview_);
  preview_points_.resize(preview_.size());
  preview_normals_.resize(preview_.size());
}

InterpolationTable Deformer::Impl::subTable(const std::vector<int>& points) const {
  InterpolationTable t;
  t.has_normals = data_.table.has_normals;
  if (data_.table.has_normals)
    for (const int i : points) t.normals.push_back(data_.table.restNormal(static_cast<std::size_t>(i)));
  t.pairs = data_.table.pairs;
  t.pair_centre = data_.table.pair_centre;
  t.points.reserve(points.size());
  for (const int i : points) t.points.push_back(data_.table.points[static_cast<std::size_t>(i)]);
  return t;
}

}  // namespace hgd
