// A Deformer on a streamed coarse level (hgdeform/deformer/streamed.h).
#include <algorithm>
#include <numeric>
#include <stdexcept>

#include "hgdeform/deformer/streamed.h"
#include "multires/record_blocks.h"
#include "multires/streamed_passes.h"
#include "util/pack.h"

namespace hgd {

StreamedDeformer streamedDeformer(const RecordLayout& layout, const StreamedLevel& level,
                                  const RecordHandles& handles, const DeformOptions& options,
                                  StreamRanks* ranks) {
  ranks = stream::splitRanks(ranks);
  if (level.coarse.empty()) throw std::invalid_argument("streamedDeformer: the coarse level is empty");
  // The points held: the coarse points, as Geometry has them; the manipulated handle's points
  // apart, their rest positions only (the Deformer picks among them and takes their centre).
  struct Held {
    std::uint64_t record;
    Eigen::Vector3f p;
    Eigen::Vector3f n;
    std::uint32_t key;  // Morton
  };
  struct Manipulated {
    std::uint64_t record;
    Eigen::Vector3f p;
    std::uint32_t key;
  };
  std::vector<std::pair<std::uint64_t, std::uint32_t>> reps;  // (record, coarse point), by record
  for (std::size_t a = 0; a < level.coarse_record.size(); ++a)
    reps.emplace_back(level.coarse_record[a], static_cast<std::uint32_t>(a));
  std::sort(reps.begin(), reps.end());
  std::vector<Held> held;
  std::vector<Manipulated> manipulated;
  manipulated.reserve(handles.manipulated.size());  // (at most: not a point more, no doubling)
  stream::runPass(
      ranks,
      [&] {
        streamPass("held points");
        stream::Blocks blocks(layout, 1 << 16);
        blocks.share(stream::shareOf(layout.count, ranks));
        std::size_t r = 0, m = 0;
        const std::vector<std::uint64_t>& manip = handles.manipulated;
        blocks.each([&](std::uint64_t i, std::size_t k) {
          while (r < reps.size() && reps[r].first < i) ++r;
          while (m < manip.size() && manip[m] < i) ++m;
          const bool is_rep = r < reps.size() && reps[r].first == i,
                     is_manip = m < manip.size() && manip[m] == i;
          if (!is_rep && !is_manip) return;
          const Eigen::Vector3d w = blocks.world(k);
          if (!w.allFinite() || !level.kept(i, w)) return;
          const Eigen::Vector3f p = level.local(w);
          const std::uint32_t key = level.mortonKey(w);
          if (is_manip) manipulated.push_back({i, p, key});
          if (!is_rep) return;
          Held h{i, p, Eigen::Vector3f::Zero(), key};
          if (level.file_normals) blocks.normal(k, h.n);
          held.push_back(h);
        });
      },
      [&](const std::string& failed) {  // every rank's (sorted below: the order they come in does not matter)
        pack::Writer w;
        if (failed.empty()) w.putBytes(held).putBytes(manipulated);
        std::vector<Held> all_held;
        std::vector<Manipulated> all_manipulated;
        for (const std::string& part : stream::gatherOrThrow(*ranks, failed, w.bytes())) {
          pack::Reader in(part);
          std::vector<Held> h;
          std::vector<Manipulated> m;
          in.getBytes(h);
          in.getBytes(m);
          all_held.insert(all_held.end(), h.begin(), h.end());
          all_manipulated.insert(all_manipulated.end(), m.begin(), m.end());
        }
        held = std::move(all_held);
        manipulated = std::move(all_manipulated);
      });
  const auto geometryOrder = [](const auto& a, const auto& b) {  // Geometry's: Morton key, then record
    return a.key != b.key ? a.key < b.key : a.record < b.record;
  };
  std::sort(held.begin(), held.end(), geometryOrder);
  std::sort(manipulated.begin(), manipulated.end(), geometryOrder);
  auto g = std::make_shared<Geometry>();
  g->origin = level.origin;
  g->body = level.body;
  g->far_points = level.far_points;
  g->warnings = level.warnings;
  g->points->resize(held.size());
  if (level.file_normals) g->file_normals->resize(held.size());
  g->raw_index.resize(held.size());
  for (std::size_t k = 0; k < held.size(); ++k) {
    (*g->points)[k].getVector3fMap() = held[k].p;
    if (level.file_normals) (*g->file_normals)[k].getNormalVector3fMap() = held[k].n;
    g->raw_index[k] = static_cast<int>(held[k].record);
  }
  g->points->width = static_cast<std::uint32_t>(held.size());
  g->points->height = 1;
  g->points->is_dense = true;

  StreamedDeformer out;
  // The handles among the held points.
  const auto among = [&](const std::vector<std::uint64_t>& records) {
    std::vector<int> idx;
    for (std::size_t k = 0; k < held.size(); ++k)
      if (std::binary_search(records.begin(), records.end(), held[k].record))
        idx.push_back(static_cast<int>(k));
    return idx;
  };
  for (const auto& f : handles.fixed) out.handles.fixed.push_back(among(f));
  out.handles.manipulated = among(handles.manipulated);
  for (const auto& j : handles.joints) out.handles.joints.push_back(among(j));
  // The level on them.
  auto pre = std::make_shared<PrebuiltLevel>();
  CoarseLevel& c = pre->level;
  c.cell = level.cell;
  c.weight = level.weight;
  c.points.assign(level.coarse.size(), -1);
  c.anchor.resize(held.size());
  for (std::size_t k = 0; k < held.size(); ++k) {
    const auto it =
        std::lower_bound(reps.begin(), reps.end(), std::make_pair(held[k].record, std::uint32_t{0}));
    c.points[it->second] = static_cast<int>(k);  // (every point held is a coarse point)
    c.anchor[k] = it->second;
  }
  if (std::find(c.points.begin(), c.points.end(), -1) != c.points.end())
    throw std::logic_error("streamedDeformer: a coarse point was not found in the file");
  pre->handles.fixed = level.coarse_fixed;
  pre->handles.manipulated = level.coarse_manipulated;
  pre->handles.joints = level.coarse_joints;
  pre->shape_points = static_cast<std::size_t>(level.points);
  pre->manipulated_rest.reserve(manipulated.size());
  pre->manipulated_held.reserve(manipulated.size());
  for (const Manipulated& q : manipulated) {
    pre->manipulated_rest.push_back(q.p);
    const auto it = std::lower_bound(reps.begin(), reps.end(), std::make_pair(q.record, std::uint32_t{0}));
    const bool rep = it != reps.end() && it->first == q.record;
    pre->manipulated_held.push_back(rep ? c.points[it->second] : -1);
  }
  std::vector<Manipulated>().swap(manipulated);
  out.geometry = g;
  out.level = pre;
  out.deformer = std::make_unique<Deformer>(out.geometry, out.handles, options, out.level);
  return out;
}

}  // namespace hgd
