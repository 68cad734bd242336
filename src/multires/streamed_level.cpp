// The coarse level by passes over a file's records (hgdeform/multires/streamed.h): the rules of
// extractGeometry (io/geometry.cpp, io/frame.h) and coarsen (multires/coarsen.cpp,
// coarse_cells.cpp, coarse_strays.cpp) applied as records stream by. Every choice those rules
// make depends on the points and their file indices, not on their order in memory, so the level
// is theirs, point for point (tests/test_stream.cpp).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <numeric>
#include <queue>
#include <unordered_map>
#include <unordered_set>

#include "graph/nearest.h"
#include "graph/stray_rule.h"
#include "hgdeform/io/fields.h"
#include "hgdeform/io/geometry.h"
#include "hgdeform/io/io.h"
#include "hgdeform/multires/streamed.h"
#include "io/frame.h"
#include "multires/coarse_grid.h"
#include "multires/record_blocks.h"
#include "multires/streamed_passes.h"

namespace hgd {

namespace {

using coarse::Grid;
using stream::Beyond;
using stream::Blocks;
using stream::CellAcc;
using stream::Near;

bool isZero(const Eigen::Vector3d& w) {
  return w.x() == 0 && w.y() == 0 && w.z() == 0;
}

/// Walks ascending record lists alongside a pass over ascending records.
class SortedCursor {
 public:
  explicit SortedCursor(const std::vector<std::uint64_t>& v) : v_(v) {}
  bool has(std::uint64_t record) {
    while (at_ < v_.size() && v_[at_] < record) ++at_;
    return at_ < v_.size() && v_[at_] == record;
  }

 private:
  const std::vector<std::uint64_t>& v_;
  std::size_t at_ = 0;
};

}  // namespace

StreamedLevel streamCoarseLevel(const RecordLayout& layout, const RecordHandles& handles,
                                const StreamedLevelOptions& options) {
  return streamCoarseLevel(
      layout, [&](const StreamedLevel&) -> const RecordHandles& { return handles; }, options);
}

StreamedLevel streamCoarseLevel(const RecordLayout& layout,
                                const std::function<const RecordHandles&(const StreamedLevel&)>& handles_of,
                                const StreamedLevelOptions& options) {
  using namespace frame;
  const std::string& path = layout.shape.path;
  StreamedLevel out;
  const std::uint64_t n_records = layout.count;
  out.records = n_records;
  if (n_records == 0) throw IoError(path + ": no points");
  if (n_records > static_cast<std::uint64_t>(std::numeric_limits<int>::max()))
    throw IoError(path + ": " + std::to_string(n_records) + " points, more than 2,147,483,647");
  Blocks blocks(layout, options.block);
  // A split run: this rank reads its share, and each pass's findings are gathered (share()).
  StreamRanks* const ranks = stream::splitRanks(options.ranks);
  blocks.share(stream::shareOf(n_records, ranks));
  const auto pass = [&](auto&& local, auto&& gather) { stream::runPass(ranks, local, gather); };

  // The frame's sample: the finite records at file indices on a stride (Geometry's).
  streamPass("frame");
  const std::size_t step = frameSampleStep(n_records);
  stream::FrameSample fs;
  pass(
      [&] {
        blocks.strided(step, [&](std::uint64_t i, std::size_t k) {
          const Eigen::Vector3d w = blocks.world(k);
          if (!w.allFinite()) return;
          fs.all.push_back(w);
          fs.all_index.push_back(static_cast<int>(i));
          if (!isZero(w)) {
            fs.nonzero.push_back(w);
            fs.nonzero_index.push_back(static_cast<int>(i));
          }
        });
      },
      [&](const std::string& failed) { stream::share(*ranks, failed, fs); });
  const std::vector<Eigen::Vector3d>&sample = fs.all, &sample_nz = fs.nonzero;
  const std::vector<int>&sample_index = fs.all_index, &sample_nz_index = fs.nonzero_index;
  const auto unreproducible = [&] {
    throw IoError(path +
                  ": cannot build the coarse level by passes: no finite point of the frame's sample "
                  "(every record at a multiple of " +
                  std::to_string(step) + "); read the whole file instead");
  };
  // A scanner's 'no return' points at (0, 0, 0), set apart when the shape lies far from them.
  RobustFrame nz;
  double nz_distance = 0;
  if (!sample_nz.empty()) {
    nz = robustFrame(sample_nz, sample_nz_index, step);
    nz_distance = nz.centre.cwiseAbs().maxCoeff();
    out.zeros_apart = nz_distance > 1000 * nz.extent;
  }
  if (sample.empty()) unreproducible();
  const RobustFrame fr = out.zeros_apart ? nz : robustFrame(sample, sample_index, step);
  refuseExtent(path, fr);
  out.frame_centre = fr.centre;
  const FrameLimits limits = frameLimits(fr);
  out.far = limits.far;
  out.stray_distance = limits.stray;
  const double body = limits.body;

  // The strays' typical-distance sample: the kept points at file indices on a stride.
  const std::size_t stray_stride = coarse::straySampleStride(n_records);

  // Pass 1: what is set apart, the body, the bounds, whether every kept normal is usable.
  streamPass("body");
  const std::uint64_t beyond_cap = n_records / 100 + 1;
  stream::BodyPass bp;
  bp.normals_ok = blocks.hasNormals();
  pass(
      [&] {
        blocks.each([&](std::uint64_t i, std::size_t k) {
          const Eigen::Vector3d w = blocks.world(k);
          if (!w.allFinite()) return;
          ++bp.finite;
          if (out.zeros_apart && isZero(w)) {
            ++bp.zeros;
            return;
          }
          const double d = (w - fr.centre).cwiseAbs().maxCoeff();
          if (d > out.far) {
            ++bp.far_count;
            bp.farthest = std::max(bp.farthest, d);
            return;
          }
          Eigen::Vector3f nv;
          const bool has_normal = blocks.normal(k, nv);
          if (d > out.stray_distance && fr.extent > 0) {  // a stray, if few and alone
            ++bp.beyond_count;
            if (bp.beyond.size() < beyond_cap) bp.beyond.push_back({i, w});
            bp.beyond_lo = bp.beyond_lo.cwiseMin(w);
            bp.beyond_hi = bp.beyond_hi.cwiseMax(w);
            bp.beyond_normals_ok = bp.beyond_normals_ok && has_normal;
            return;
          }
          if (d <= body) {
            bp.body_lo = bp.body_lo.cwiseMin(w);
            bp.body_hi = bp.body_hi.cwiseMax(w);
          }
          bp.lo = bp.lo.cwiseMin(w);
          bp.hi = bp.hi.cwiseMax(w);
          bp.normals_ok = bp.normals_ok && has_normal;
        });
      },
      [&](const std::string& failed) { stream::share(*ranks, failed, bp, beyond_cap); });
  const std::vector<Beyond>& beyond = bp.beyond;
  const bool beyond_overflow = bp.beyond_count > beyond_cap;
  const std::uint64_t finite = bp.finite, zeros = bp.zeros;
  std::uint64_t far_count = bp.far_count;
  double farthest = bp.farthest;
  const Eigen::Vector3d body_lo = bp.body_lo, body_hi = bp.body_hi;
  Eigen::Vector3d lo = bp.lo, hi = bp.hi;
  bool normals_ok = bp.normals_ok;
  if (finite == 0)
    throw IoError(path + ": no finite points (all " + std::to_string(n_records) + " are NaN/inf)");
  if (sample_nz.empty() && finite > 0) {
    // Every sampled record is at (0, 0, 0): Geometry's frame of the others would be a sample of
    // every one of them, which needs another pass; only a shape of nothing but zeros is this.
    std::uint64_t nonzero = 0;
    pass(
        [&] {
          blocks.each([&](std::uint64_t, std::size_t k) {
            const Eigen::Vector3d w = blocks.world(k);
            nonzero += w.allFinite() && !isZero(w);
          });
        },
        [&](const std::string& failed) { stream::share(*ranks, failed, nonzero); });
    if (nonzero > 0) unreproducible();
  }
  const std::uint64_t m = finite - zeros;  // Geometry's world after the zeros
  if (!beyond_overflow && !beyond.empty() &&
      static_cast<double>(beyond.size()) <= kStrayShare * static_cast<double>(m)) {
    std::vector<Eigen::Vector3d> at;
    for (const Beyond& b : beyond) at.push_back(b.w);
    for (const std::size_t k : aloneAmong(at, fr.centre, fr.extent)) {
      out.far_strays.push_back(beyond[k].record);
      ++far_count;
      farthest = std::max(farthest, (beyond[k].w - fr.centre).cwiseAbs().maxCoeff());
    }
  }
  // The beyond points kept: all of them, or all but the strays.
  if (out.far_strays.empty()) {
    lo = lo.cwiseMin(bp.beyond_lo);
    hi = hi.cwiseMax(bp.beyond_hi);
    normals_ok = normals_ok && bp.beyond_normals_ok;
  } else {
    streamPass("beyond");  // a few records read alone: not a pass over the file
    // This rank's (all of them in one process), then met into lo, hi and normals_ok as one
    // process meets them, in file order.
    Eigen::Vector3d kept_lo = Eigen::Vector3d::Constant(INFINITY), kept_hi = -kept_lo;
    bool kept_normals = true;
    pass(
        [&] {
          Blocks one(layout, 1);
          const RecordShare mine = stream::shareOf(n_records, ranks);
          for (const Beyond& b : beyond) {
            if (b.record < mine.first || b.record >= mine.last ||
                std::binary_search(out.far_strays.begin(), out.far_strays.end(), b.record))
              continue;
            kept_lo = kept_lo.cwiseMin(b.w);
            kept_hi = kept_hi.cwiseMax(b.w);
            Eigen::Vector3f nv;
            one.load(b.record, 1);
            kept_normals = kept_normals && one.normal(0, nv);
          }
        },
        [&](const std::string& failed) { stream::share(*ranks, failed, kept_lo, kept_hi, kept_normals); });
    lo = lo.cwiseMin(kept_lo);
    hi = hi.cwiseMax(kept_hi);
    normals_ok = normals_ok && kept_normals;
  }
  out.points = m - far_count;
  if (zeros > 0) out.warnings.push_back(noReturnWarning(path, zeros, nz_distance, nz.extent));
  out.far_points = far_count + zeros;
  if (far_count > 0)
    out.warnings.push_back(farWarning(path, far_count, out.far_strays.empty() ? out.far : out.stray_distance,
                                      fr.extent, farthest));
  if (out.points == 0) throw IoError(path + ": no finite points");
  out.origin = (0.5 * (body_lo + body_hi)).array().round().matrix();
  out.body = Eigen::AlignedBox3f((body_lo - out.origin).cast<float>(), (body_hi - out.origin).cast<float>());
  out.file_normals = normals_ok;
  const double morton_extent = (body_hi - body_lo).maxCoeff();
  out.morton_lo = body_lo;
  out.morton_scale = morton_extent > 0 ? 1023.0 / morton_extent : 0.0;

  // The handles, now that what is kept is known.
  streamPass("handles");
  const RecordHandles& handles = handles_of(out);
  // The coarse level's size and classes (coarsen's).
  const std::size_t target =
      options.points_per_coarse > 0
          ? std::min<std::size_t>(options.coarse_points,
                                  static_cast<std::size_t>(out.points / options.points_per_coarse))
          : options.coarse_points;
  const std::size_t classes = 2 + handles.fixed.size() + handles.joints.size();
  const int class_bits = coarse::bitsFor(classes - 1);
  if (target == 0 || 3 * coarse::kMaxAxisBits + class_bits >= 64 || classes > 65535) return out;
  {
    // The lists merged (each ascends); a record in several has the class that pins last: the
    // manipulated handle's, else the last fixed list's, else the last joint's. Counted first,
    // then written: no copy of the lists, no sort.
    std::vector<std::pair<const std::vector<std::uint64_t>*, int>> lists;  // precedence ascending
    for (std::size_t k = 0; k < handles.joints.size(); ++k)
      lists.emplace_back(&handles.joints[k], static_cast<int>(2 + handles.fixed.size() + k));
    for (std::size_t k = 0; k < handles.fixed.size(); ++k)
      lists.emplace_back(&handles.fixed[k], static_cast<int>(2 + k));
    lists.emplace_back(&handles.manipulated, 1);
    const auto merge = [&](auto&& emit) {
      // The lists' heads in a heap (smallest record first, then the list of highest precedence):
      // N log L, whatever the number of joints.
      using Head = std::pair<std::uint64_t, std::size_t>;  // (record, list)
      const auto later = [](const Head& x, const Head& y) {
        return x.first != y.first ? x.first > y.first : x.second < y.second;
      };
      std::priority_queue<Head, std::vector<Head>, decltype(later)> heads(later);
      std::vector<std::size_t> at(lists.size(), 0);
      for (std::size_t l = 0; l < lists.size(); ++l)
        if (!lists[l].first->empty()) heads.emplace((*lists[l].first)[0], l);
      while (!heads.empty()) {
        const std::uint64_t record = heads.top().first;
        const int cls = lists[heads.top().second].second;  // the highest precedence of this record's
        while (!heads.empty() && heads.top().first == record) {
          const std::size_t l = heads.top().second;
          heads.pop();
          if (++at[l] < lists[l].first->size()) heads.emplace((*lists[l].first)[at[l]], l);
        }
        emit(record << 16 | static_cast<std::uint64_t>(cls));
      }
    };
    std::size_t count = 0;
    merge([&](std::uint64_t) { ++count; });
    out.record_class.reserve(count);
    merge([&](std::uint64_t v) { out.record_class.push_back(v); });
  }

  // A pass over the points Geometry keeps: fn(record, row, world, local position, class).
  const auto eachKept = [&](auto&& fn) {
    StreamedLevel::ClassCursor cc(out);
    SortedCursor stray_far(out.far_strays);
    blocks.each([&](std::uint64_t i, std::size_t k) {
      const Eigen::Vector3d w = blocks.world(k);
      if (!w.allFinite() || (out.zeros_apart && isZero(w))) return;
      const double d = (w - fr.centre).cwiseAbs().maxCoeff();
      if (d > out.far || (d > out.stray_distance && stray_far.has(i))) return;
      fn(i, k, w, out.local(w), cc.of(i));
    });
  };

  // The grid's sizing subset (the grid must be known before the cells): the kept points at file
  // indices on a stride.
  const std::size_t grid_stride = coarse::gridSampleStride(n_records, target);
  streamPass("grid");
  std::vector<Eigen::Vector3f> grid_at;
  std::vector<std::uint16_t> grid_cls;
  pass(
      [&] {
        blocks.strided(grid_stride, [&](std::uint64_t i, std::size_t k) {
          const Eigen::Vector3d w = blocks.world(k);
          if (!w.allFinite() || !out.kept(i, w)) return;
          grid_at.push_back(out.local(w));
          grid_cls.push_back(static_cast<std::uint16_t>(out.classOf(i)));
        });
      },
      [&](const std::string& failed) { stream::share(*ranks, failed, grid_at, grid_cls); });
  const Grid grid = coarse::sizeGrid(out.local(lo), out.local(hi), target, class_bits, grid_at, grid_cls);
  out.cell = grid.h;
  out.grid_lo = grid.lo;
  out.axis_bits = grid.axis_bits;

  // Pass 2: every kept point's cell: its count and its point nearest the centre; the cells of
  // each handle's points.
  streamPass("cells");
  stream::CellPass cp;
  std::unordered_map<std::uint64_t, CellAcc>& cells = cp.cells;
  std::vector<Near>& typical_at = cp.typical_at;         // the strays' typical-distance sample
  std::vector<const std::vector<std::uint64_t>*> lists;  // fixed, manipulated, joints
  for (const auto& f : handles.fixed) lists.push_back(&f);
  lists.push_back(&handles.manipulated);
  for (const auto& j : handles.joints) lists.push_back(&j);
  std::vector<std::unordered_set<std::uint64_t>>& list_cells = cp.list_cells;
  list_cells.resize(lists.size());
  pass(
      [&] {
        std::vector<SortedCursor> in_list;
        for (const auto* l : lists) in_list.emplace_back(*l);
        eachKept(
            [&](std::uint64_t i, std::size_t k, const Eigen::Vector3d& w, const Eigen::Vector3f& p, int cls) {
              float centre2 = 0;
              const std::uint64_t key = grid.key(p, cls, centre2);
              Eigen::Vector3f nv = Eigen::Vector3f::Zero();
              if (out.file_normals) blocks.normal(k, nv);
              for (std::size_t l = 0; l < lists.size(); ++l)
                if (in_list[l].has(i)) list_cells[l].insert(key);
              CellAcc& cell = cells[key];
              ++cell.count;
              cell.offer(i, centre2, p, w, nv);
              if (i % stray_stride == 0) typical_at.push_back({i, p, w, nv, key});
            });
      },
      [&](const std::string& failed) { stream::share(*ranks, failed, cp); });
  std::vector<std::uint64_t> keys;
  keys.reserve(cells.size());
  for (const auto& c : cells) keys.push_back(c.first);
  std::sort(keys.begin(), keys.end());

  // The strays of sparse cells (coarse_strays.cpp's rule, without its search's shortcuts).
  streamPass("strays");
  std::vector<std::uint64_t> level_strays;
  std::unordered_map<std::uint64_t, std::vector<Near>> gathered;
  std::unordered_set<std::uint64_t> stray_set;
  const int ab = grid.axis_bits;
  const std::uint64_t axis_mask = (std::uint64_t{1} << ab) - 1;
  const auto around = [&](std::uint64_t key, auto&& fn) {  // the 27 cells of every class
    const auto x = static_cast<long long>(key & axis_mask),
               y = static_cast<long long>((key >> ab) & axis_mask),
               z = static_cast<long long>((key >> (2 * ab)) & axis_mask);
    const auto top = static_cast<long long>(axis_mask);
    for (std::size_t c = 0; c < classes; ++c)
      for (long long dz = -1; dz <= 1; ++dz)
        for (long long dy = -1; dy <= 1; ++dy)
          for (long long dx = -1; dx <= 1; ++dx) {
            if (x + dx < 0 || y + dy < 0 || z + dz < 0 || x + dx > top || y + dy > top || z + dz > top)
              continue;
            fn((static_cast<std::uint64_t>(c) << (3 * ab)) |
               (static_cast<std::uint64_t>(z + dz) << (2 * ab)) | (static_cast<std::uint64_t>(y + dy) << ab) |
               static_cast<std::uint64_t>(x + dx));
          }
  };
  if (options.find_strays && !keys.empty()) {
    std::vector<std::uint32_t> sizes;
    for (const std::uint64_t key : keys) sizes.push_back(cells[key].count);
    std::nth_element(sizes.begin(), sizes.begin() + static_cast<long>(sizes.size() / 2), sizes.end());
    const std::size_t median = sizes[sizes.size() / 2];
    const std::size_t few = std::max<std::size_t>(2, median / 4);
    std::vector<std::uint64_t> sparse;
    if (median >= 4)
      for (const std::uint64_t key : keys)
        if (cells[key].count <= few && (key >> (3 * ab)) == 0) sparse.push_back(key);
    if (!sparse.empty()) {
      // Without holding the points around them: the sample's second-nearest distances are
      // kept up to date as the points near them stream by (pass 3, which also gathers the
      // sparse cells' own points), and then each sparse cell's point counts the points near it
      // as they stream by (pass 4). What a point meets is order-free: the two smallest distances,
      // a count.
      using stream::Typical;
      std::vector<Typical> typ;
      for (const Near& t : typical_at) typ.push_back({t.record, t.p});
      std::unordered_set<std::uint64_t> sparse_set(sparse.begin(), sparse.end());
      // Cell -> what a point in it meets: the sample points, and the sparse cells, in the 27
      // cells around it of every class (the cells that exist): one look-up a point.
      std::unordered_map<std::uint64_t, std::vector<std::uint32_t>> sample_near, sparse_near;
      for (std::size_t k = 0; k < typ.size(); ++k)
        around(typical_at[k].key, [&](std::uint64_t key) {  // its cell (with its class)
          if (cells.count(key)) sample_near[key].push_back(static_cast<std::uint32_t>(k));
        });
      for (std::size_t s = 0; s < sparse.size(); ++s)
        around(sparse[s], [&](std::uint64_t key) {
          if (cells.count(key)) sparse_near[key].push_back(static_cast<std::uint32_t>(s));
        });
      // Pass 3.
      pass(
          [&] {
            eachKept([&](std::uint64_t i, std::size_t k, const Eigen::Vector3d& w, const Eigen::Vector3f& p,
                         int cls) {
              const std::uint64_t key = grid.key(p, cls);
              if (const auto it = sample_near.find(key); it != sample_near.end())
                for (const std::uint32_t t : it->second) {
                  Typical& s = typ[t];
                  if (s.record != i) s.meet((p - s.p).squaredNorm());
                }
              if (sparse_set.count(key)) {
                Eigen::Vector3f nv = Eigen::Vector3f::Zero();
                if (out.file_normals) blocks.normal(k, nv);
                gathered[key].push_back({i, p, w, nv});
              }
            });
          },
          [&](const std::string& failed) { stream::share(*ranks, failed, typ, gathered); });
      std::vector<float> typical;
      for (const Typical& t : typ)
        if (std::isfinite(t.d2) && t.d2 > 0) typical.push_back(t.d2);
      const float limit2 = typical.empty() ? 0.0f : std::min(grid.h * grid.h, strayLimit2(typical));
      if (limit2 > 0) {
        // Pass 4: the near points of every sparse cell's point.
        std::unordered_map<std::uint64_t, std::vector<int>> near_count;  // per sparse cell, per point
        for (const std::uint64_t key : sparse) near_count[key].assign(gathered[key].size(), 0);
        pass(
            [&] {
              std::vector<std::pair<const std::vector<Near>*, std::vector<int>*>> of;  // per sparse cell
              for (const std::uint64_t key : sparse) of.emplace_back(&gathered[key], &near_count[key]);
              eachKept([&](std::uint64_t i, std::size_t, const Eigen::Vector3d&, const Eigen::Vector3f& p,
                           int cls) {
                const auto it = sparse_near.find(grid.key(p, cls));
                if (it == sparse_near.end()) return;
                for (const std::uint32_t s : it->second) {
                  const std::vector<Near>& pts = *of[s].first;
                  std::vector<int>& count = *of[s].second;
                  for (std::size_t q = 0; q < pts.size(); ++q)
                    count[q] += pts[q].record != i && (p - pts[q].p).squaredNorm() <= limit2;
                }
              });
            },
            [&](const std::string& failed) { stream::share(*ranks, failed, sparse, near_count); });
        for (const std::uint64_t key : sparse)
          for (std::size_t q = 0; q < gathered[key].size(); ++q)
            if (near_count[key][q] < 2) {
              level_strays.push_back(gathered[key][q].record);
              stray_set.insert(gathered[key][q].record);
            }
      }
      // A cell with strays stands by its nearest point that is not one.
      for (const std::uint64_t key : sparse) {
        CellAcc fresh;
        for (const Near& q : gathered[key]) {
          if (stray_set.count(q.record)) continue;
          float centre2 = 0;
          grid.key(q.p, 0, centre2);
          ++fresh.count;
          fresh.offer(q.record, centre2, q.p, q.w, q.n);
        }
        if (fresh.count != cells[key].count) cells[key] = fresh;
      }
    }
  }
  std::sort(level_strays.begin(), level_strays.end());

  // The coarse points, cells in key order.
  std::vector<std::uint32_t> morton;
  for (const std::uint64_t key : keys) {
    const CellAcc& c = cells[key];
    if (c.count == 0) continue;
    out.cell_key.push_back(key);
    out.cell_id.push_back(static_cast<std::uint32_t>(out.coarse.size()));
    out.coarse.push_back(pcl::PointXYZ(c.p.x(), c.p.y(), c.p.z()));
    pcl::Normal nn;
    nn.getNormalVector3fMap() = c.n;
    out.normals.push_back(nn);
    out.coarse_record.push_back(c.best);
    out.weight.push_back(c.count);
    morton.push_back(out.mortonKey(c.w));
  }
  if (out.coarse.empty()) return out;
  if (!out.file_normals) out.normals.clear();
  // The handles on the coarse level: their points' cells (no handle point is a stray: strays are
  // free points).
  for (std::size_t l = 0; l < lists.size(); ++l) {
    std::vector<int> ids;
    for (const std::uint64_t key : list_cells[l]) {
      const auto it = std::lower_bound(out.cell_key.begin(), out.cell_key.end(), key);
      if (it != out.cell_key.end() && *it == key)
        ids.push_back(static_cast<int>(out.cell_id[static_cast<std::size_t>(it - out.cell_key.begin())]));
    }
    std::sort(ids.begin(), ids.end());
    if (l < handles.fixed.size())
      out.coarse_fixed.push_back(std::move(ids));
    else if (l == handles.fixed.size())
      out.coarse_manipulated = std::move(ids);
    else
      out.coarse_joints.push_back(std::move(ids));
  }
  // Their ranks in Geometry's order: by Morton key, then file order.
  std::vector<std::uint32_t> order(out.coarse.size());
  std::iota(order.begin(), order.end(), 0u);
  std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
    return morton[a] != morton[b] ? morton[a] < morton[b] : out.coarse_record[a] < out.coarse_record[b];
  });
  out.morton_rank.resize(order.size());
  for (std::size_t r = 0; r < order.size(); ++r) out.morton_rank[order[r]] = static_cast<std::uint32_t>(r);
  // A stray hangs from the nearest coarse point (as coarsen's: the targets in the same order).
  if (!level_strays.empty()) {
    pcl::PointCloud<pcl::PointXYZ> both = out.coarse;
    std::vector<int> targets(out.coarse.size()), queries;
    std::iota(targets.begin(), targets.end(), 0);
    for (const auto& [key, list] : gathered)
      for (const Near& q : list)
        if (stray_set.count(q.record)) {
          (void)key;
          queries.push_back(static_cast<int>(both.size()));
          both.push_back(pcl::PointXYZ(q.p.x(), q.p.y(), q.p.z()));
          out.strays.push_back(q.record);
        }
    const std::vector<int> nearest = nearestAmong(both, targets, queries);
    std::vector<std::size_t> by_record(out.strays.size());
    std::iota(by_record.begin(), by_record.end(), std::size_t{0});
    std::sort(by_record.begin(), by_record.end(),
              [&](std::size_t a, std::size_t b) { return out.strays[a] < out.strays[b]; });
    std::vector<std::uint64_t> sorted;
    for (const std::size_t s : by_record) {
      const auto a = static_cast<std::size_t>(std::max(0, nearest[s]));
      sorted.push_back(out.strays[s]);
      out.stray_anchor.push_back(static_cast<std::uint32_t>(a));
      ++out.weight[a];
    }
    out.strays = std::move(sorted);
  }
  return out;
}

}  // namespace hgd
