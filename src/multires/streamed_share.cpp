// The streamed level's passes gathered over the ranks of a split run (multires/streamed_passes.h):
// each rank packs what it found in its share of the records; every rank merges every part, in
// rank order (the file's order), into what one process finds reading every record.
#include <algorithm>
#include <cmath>
#include <utility>

#include "hgdeform/io/io.h"
#include "multires/streamed_passes.h"
#include "util/pack.h"

namespace hgd::stream {

std::vector<std::string> gatherOrThrow(StreamRanks& ranks, const std::string& failed,
                                       const std::string& mine) {
  pack::Writer w;
  w.put(failed).put(mine);
  std::vector<std::string> all = ranks.allgather(w.bytes());
  std::vector<std::string> parts(all.size());
  for (std::size_t r = 0; r < all.size(); ++r) {
    pack::Reader in(all[r]);
    std::string error;
    in.get(error);
    if (!error.empty())
      throw IoError(static_cast<int>(r) == ranks.rank() ? error
                                                        : error + " (on rank " + std::to_string(r) + ")");
    in.get(parts[r]);
  }
  return parts;
}

namespace {

/// Every rank's part as packed by `put`, read back by `get` in rank order.
template <typename Put, typename Get>
void gatherEach(StreamRanks& ranks, const std::string& failed, Put&& put, Get&& get) {
  pack::Writer w;
  if (failed.empty()) put(w);
  for (const std::string& part : gatherOrThrow(ranks, failed, w.bytes())) {
    pack::Reader in(part);
    get(in);
  }
}

}  // namespace

void share(StreamRanks& ranks, const std::string& failed, FrameSample& s) {
  FrameSample whole;
  gatherEach(
      ranks, failed,
      [&](pack::Writer& w) { w.putBytes(s.all).put(s.all_index).putBytes(s.nonzero).put(s.nonzero_index); },
      [&](pack::Reader& in) {
        std::vector<Eigen::Vector3d> a, nz;
        in.getBytes(a);
        whole.all.insert(whole.all.end(), a.begin(), a.end());
        in.append(whole.all_index);
        in.getBytes(nz);
        whole.nonzero.insert(whole.nonzero.end(), nz.begin(), nz.end());
        in.append(whole.nonzero_index);
      });
  s = std::move(whole);
}

void share(StreamRanks& ranks, const std::string& failed, BodyPass& b, std::uint64_t cap) {
  BodyPass whole;
  gatherEach(
      ranks, failed,
      [&](pack::Writer& w) {
        w.put(b.finite).put(b.zeros).put(b.far_count).put(b.beyond_count).put(b.farthest);
        for (const Eigen::Vector3d* v : {&b.body_lo, &b.body_hi, &b.lo, &b.hi, &b.beyond_lo, &b.beyond_hi})
          w.put(v->x()).put(v->y()).put(v->z());
        w.put(b.normals_ok).put(b.beyond_normals_ok);
      },
      [&](pack::Reader& in) {
        whole.finite += in.get<std::uint64_t>();
        whole.zeros += in.get<std::uint64_t>();
        whole.far_count += in.get<std::uint64_t>();
        whole.beyond_count += in.get<std::uint64_t>();
        whole.farthest = std::max(whole.farthest, in.get<double>());
        Eigen::Vector3d v[6];
        for (auto& x : v) {
          const double a = in.get<double>(), bb = in.get<double>(), c = in.get<double>();
          x = Eigen::Vector3d(a, bb, c);
        }
        whole.body_lo = whole.body_lo.cwiseMin(v[0]);
        whole.body_hi = whole.body_hi.cwiseMax(v[1]);
        whole.lo = whole.lo.cwiseMin(v[2]);
        whole.hi = whole.hi.cwiseMax(v[3]);
        whole.beyond_lo = whole.beyond_lo.cwiseMin(v[4]);
        whole.beyond_hi = whole.beyond_hi.cwiseMax(v[5]);
        whole.normals_ok = in.get<bool>() && whole.normals_ok;
        whole.beyond_normals_ok = in.get<bool>() && whole.beyond_normals_ok;
      });
  // The points beyond, when few enough to be listed (else the list is not used: not sent).
  if (whole.beyond_count <= cap)
    gatherEach(
        ranks, "", [&](pack::Writer& w) { w.putBytes(b.beyond); },
        [&](pack::Reader& in) {
          std::vector<Beyond> beyond;
          in.getBytes(beyond);
          whole.beyond.insert(whole.beyond.end(), beyond.begin(), beyond.end());
        });
  b = std::move(whole);
}

void share(StreamRanks& ranks, const std::string& failed, std::uint64_t& count) {
  std::uint64_t sum = 0;
  gatherEach(
      ranks, failed, [&](pack::Writer& w) { w.put(count); },
      [&](pack::Reader& in) { sum += in.get<std::uint64_t>(); });
  count = sum;
}

void share(StreamRanks& ranks, const std::string& failed, Eigen::Vector3d& lo, Eigen::Vector3d& hi,
           bool& ok) {
  Eigen::Vector3d l = Eigen::Vector3d::Constant(INFINITY), h = -l;
  bool all = true;
  gatherEach(
      ranks, failed,
      [&](pack::Writer& w) {
        w.put(lo.x()).put(lo.y()).put(lo.z()).put(hi.x()).put(hi.y()).put(hi.z()).put(ok);
      },
      [&](pack::Reader& in) {
        double v[6];
        for (double& x : v) x = in.get<double>();
        l = l.cwiseMin(Eigen::Vector3d(v[0], v[1], v[2]));
        h = h.cwiseMax(Eigen::Vector3d(v[3], v[4], v[5]));
        all = in.get<bool>() && all;
      });
  lo = l;
  hi = h;
  ok = all;
}

void share(StreamRanks& ranks, const std::string& failed, std::vector<Eigen::Vector3f>& at,
           std::vector<std::uint16_t>& cls) {
  std::vector<Eigen::Vector3f> all_at;
  std::vector<std::uint16_t> all_cls;
  gatherEach(
      ranks, failed, [&](pack::Writer& w) { w.putBytes(at).put(cls); },
      [&](pack::Reader& in) {
        std::vector<Eigen::Vector3f> a;
        in.getBytes(a);
        all_at.insert(all_at.end(), a.begin(), a.end());
        in.append(all_cls);
      });
  at = std::move(all_at);
  cls = std::move(all_cls);
}

void share(StreamRanks& ranks, const std::string& failed, CellPass& c) {
  CellPass whole;
  whole.list_cells.resize(c.list_cells.size());
  gatherEach(
      ranks, failed,
      [&](pack::Writer& w) {
        std::vector<std::pair<std::uint64_t, CellAcc>> cells(c.cells.begin(), c.cells.end());
        w.putBytes(cells).putBytes(c.typical_at);
        for (const auto& l : c.list_cells) w.put(std::vector<std::uint64_t>(l.begin(), l.end()));
      },
      [&](pack::Reader& in) {
        std::vector<std::pair<std::uint64_t, CellAcc>> cells;
        in.getBytes(cells);
        for (const auto& [key, part] : cells) {  // counts add up; the nearest point wins
          CellAcc& cell = whole.cells[key];
          cell.count += part.count;
          cell.offer(part.best, part.best_d, part.p, part.w, part.n);
        }
        std::vector<Near> typical;
        in.getBytes(typical);
        whole.typical_at.insert(whole.typical_at.end(), typical.begin(), typical.end());
        for (auto& l : whole.list_cells) {
          std::vector<std::uint64_t> keys;
          in.get(keys);
          l.insert(keys.begin(), keys.end());
        }
      });
  c = std::move(whole);
}

void share(StreamRanks& ranks, const std::string& failed, std::vector<Typical>& typ,
           std::unordered_map<std::uint64_t, std::vector<Near>>& gathered) {
  std::vector<Typical> all_typ = typ;  // the sample is every rank's; its distances start afresh
  for (Typical& t : all_typ) t.d1 = t.d2 = INFINITY;
  std::unordered_map<std::uint64_t, std::vector<Near>> all_gathered;
  gatherEach(
      ranks, failed,
      [&](pack::Writer& w) {
        std::vector<float> d;
        for (const Typical& t : typ) d.insert(d.end(), {t.d1, t.d2});
        w.put(d).put<std::uint64_t>(gathered.size());
        for (const auto& [key, list] : gathered) w.put(key).putBytes(list);
      },
      [&](pack::Reader& in) {
        std::vector<float> d;
        in.get(d);
        if (d.size() != 2 * all_typ.size()) throw std::logic_error("stream::share: samples of other sizes");
        for (std::size_t k = 0; k < all_typ.size(); ++k) {  // the two smallest of all that were met
          all_typ[k].meet(d[2 * k]);
          all_typ[k].meet(d[2 * k + 1]);
        }
        const auto lists = in.get<std::uint64_t>();
        for (std::uint64_t l = 0; l < lists; ++l) {
          const auto key = in.get<std::uint64_t>();
          std::vector<Near> list;
          in.getBytes(list);
          std::vector<Near>& into = all_gathered[key];
          into.insert(into.end(), list.begin(), list.end());
        }
      });
  typ = std::move(all_typ);
  gathered = std::move(all_gathered);
}

void share(StreamRanks& ranks, const std::string& failed, const std::vector<std::uint64_t>& sparse,
           std::unordered_map<std::uint64_t, std::vector<int>>& near_count) {
  std::unordered_map<std::uint64_t, std::vector<int>> sum;
  for (const std::uint64_t key : sparse) sum[key].assign(near_count[key].size(), 0);
  gatherEach(
      ranks, failed,
      [&](pack::Writer& w) {
        for (const std::uint64_t key : sparse) w.put(near_count[key]);
      },
      [&](pack::Reader& in) {
        for (const std::uint64_t key : sparse) {
          std::vector<int> c;
          in.get(c);
          std::vector<int>& into = sum[key];
          if (c.size() != into.size()) throw std::logic_error("stream::share: counts of other sizes");
          for (std::size_t q = 0; q < c.size(); ++q) into[q] += c[q];
        }
      });
  near_count = std::move(sum);
}

void share(StreamRanks& ranks, const std::string& failed, std::vector<std::vector<std::uint64_t>>& lists) {
  std::vector<std::vector<std::uint64_t>> whole(lists.size());
  gatherEach(
      ranks, failed,
      [&](pack::Writer& w) {
        for (const auto& l : lists) w.put(l);
      },
      [&](pack::Reader& in) {
        for (auto& l : whole) in.append(l);
      });
  lists = std::move(whole);
}

}  // namespace hgd::stream
