// What the streamed level's passes find (internal; streamed_level.cpp), and how the ranks of a
// split run gather it (streamed_share.cpp): each rank's part merged in rank order into what one
// process reading every record finds, point for point.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "hgdeform/io/records.h"

namespace hgd::stream {

/// Runs `local` (this rank's part of a pass) and returns "" or what it threw: a rank that fails
/// still joins the gather that follows, which throws its error on every rank.
template <typename Fn>
std::string attempt(Fn&& local) {
  try {
    local();
  } catch (const std::exception& e) {
    return e.what();
  }
  return {};
}

/// Every rank's bytes, in rank order; throws IoError on every rank when one of them `failed`.
std::vector<std::string> gatherOrThrow(StreamRanks& ranks, const std::string& failed,
                                       const std::string& mine);

/// The ranks of a split run, or null for one process (no ranks, or a single one).
inline StreamRanks* splitRanks(StreamRanks* ranks) {
  return ranks && ranks->size() > 1 ? ranks : nullptr;
}

/// The records this process reads: its rank's share, or all of them (`ranks` null).
inline RecordShare shareOf(std::uint64_t records, const StreamRanks* ranks) {
  return ranks ? hgd::shareOf(records, ranks->rank(), ranks->size()) : RecordShare{0, records};
}

/// A pass of a streamed run: in one process (`ranks` null) `local` alone, whatever it throws
/// going on as it is; in a split run `local` on every rank, then `gather(failed)` (what this
/// rank's `local` threw, or "") on every rank, which gathers the findings and throws any rank's
/// failure on every rank.
template <typename Local, typename Gather>
void runPass(StreamRanks* ranks, Local&& local, Gather&& gather) {
  if (!ranks) {
    local();
    return;
  }
  gather(attempt(local));
}

/// A coarse cell as a pass finds it: its count and its point nearest the centre.
struct CellAcc {
  std::uint32_t count = 0;
  float best_d = 0;
  std::uint64_t best = std::numeric_limits<std::uint64_t>::max();
  Eigen::Vector3f p = Eigen::Vector3f::Zero();
  Eigen::Vector3d w = Eigen::Vector3d::Zero();
  Eigen::Vector3f n = Eigen::Vector3f::Zero();
  /// Takes the point if nearer the centre, or as near and earlier in the file (coarsen's rule).
  void offer(std::uint64_t record, float d, const Eigen::Vector3f& at, const Eigen::Vector3d& world,
             const Eigen::Vector3f& normal) {
    if (best == std::numeric_limits<std::uint64_t>::max() || d < best_d || (d == best_d && record < best)) {
      best = record;
      best_d = d;
      p = at;
      w = world;
      n = normal;
    }
  }
};

/// A point the stray rule looks at.
struct Near {
  std::uint64_t record;
  Eigen::Vector3f p;
  Eigen::Vector3d w;
  Eigen::Vector3f n;
  std::uint64_t key = 0;  ///< its cell
};

/// The frame's sample (Geometry's): finite records on a stride, and those not at (0, 0, 0).
struct FrameSample {
  std::vector<Eigen::Vector3d> all, nonzero;
  std::vector<int> all_index, nonzero_index;
};

/// A record beyond the stray distance (a stray if few and alone).
struct Beyond {
  std::uint64_t record;
  Eigen::Vector3d w;
};

/// Pass 1: what is set apart, the body, the bounds, whether every kept normal is usable.
struct BodyPass {
  std::vector<Beyond> beyond;  ///< at most `cap` (more: beyond_count says so)
  std::uint64_t finite = 0, zeros = 0, far_count = 0, beyond_count = 0;
  double farthest = 0;
  Eigen::Vector3d body_lo = Eigen::Vector3d::Constant(INFINITY), body_hi = -body_lo;
  Eigen::Vector3d lo = body_lo, hi = body_hi, beyond_lo = body_lo, beyond_hi = body_hi;
  bool normals_ok = true, beyond_normals_ok = true;
};

/// Pass 2: every kept point's cell; the strays' sample; the cells of each handle list.
struct CellPass {
  std::unordered_map<std::uint64_t, CellAcc> cells;
  std::vector<Near> typical_at;
  std::vector<std::unordered_set<std::uint64_t>> list_cells;
};

/// A point of the strays' sample and its two smallest squared distances to the points met.
struct Typical {
  std::uint64_t record;
  Eigen::Vector3f p;
  float d1 = INFINITY, d2 = INFINITY;
  void meet(float dd) {
    if (dd < d1) {
      d2 = d1;
      d1 = dd;
    } else if (dd < d2) {
      d2 = dd;
    }
  }
};

// Each gathers every rank's part (throwing every rank's error on every rank) and leaves the
// merged whole in its argument on every rank.
void share(StreamRanks& ranks, const std::string& failed, FrameSample& s);
/// (`cap`: the records one process keeps in `beyond`.)
void share(StreamRanks& ranks, const std::string& failed, BodyPass& b, std::uint64_t cap);
void share(StreamRanks& ranks, const std::string& failed, std::uint64_t& count);
/// The bounds and the normals of the beyond points kept, read by their ranks: each rank's
/// (from +inf, -inf, true) met into lo, hi, ok in rank order.
void share(StreamRanks& ranks, const std::string& failed, Eigen::Vector3d& lo, Eigen::Vector3d& hi, bool& ok);
void share(StreamRanks& ranks, const std::string& failed, std::vector<Eigen::Vector3f>& at,
           std::vector<std::uint16_t>& cls);
void share(StreamRanks& ranks, const std::string& failed, CellPass& c);
/// Pass 3: the sample's distances and the sparse cells' points (each `gathered` list in record
/// order).
void share(StreamRanks& ranks, const std::string& failed, std::vector<Typical>& typ,
           std::unordered_map<std::uint64_t, std::vector<Near>>& gathered);
/// Pass 4: the near points' counts of the sparse cells' points (`sparse`: the cells, the same
/// on every rank).
void share(StreamRanks& ranks, const std::string& failed, const std::vector<std::uint64_t>& sparse,
           std::unordered_map<std::uint64_t, std::vector<int>>& near_count);
/// The handles' records (streamHandles): each list's ascending records.
void share(StreamRanks& ranks, const std::string& failed, std::vector<std::vector<std::uint64_t>>& lists);

}  // namespace hgd::stream
