// The local frame of a shape's points (internal; Geometry and the streamed build): its centre and
// size from an even sample, and which points lie so far from it that they are set apart.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace hgd::frame {

constexpr double kFarFactor = 1e6;    // a point this many times the shape's size away is set apart
constexpr double kStrayFactor = 16;   // and one this many times, when such points are few:
constexpr double kStrayShare = 0.01;  // at most this share of the points
constexpr double kMaxOffset = 1e12;   // and any point this far from the shape's centre
constexpr double kMaxExtent = 1e11;   // a shape larger than this is refused

struct RobustFrame {
  Eigen::Vector3d centre;  ///< the per-axis median
  double extent = 0;       ///< the shape's size: twice the largest per-axis interquartile range
};

/// The median and spread of an even sample of the points: those whose index in the file
/// (`file_index`, parallel to `world`) is a multiple of `step` (frameSampleStep). Far strays,
/// however many digits they have, cannot move either. A choice by file index, not by rank among
/// the finite points, is one a pass over the file can make without counting first. A sample the
/// strided records leave empty (every one NaN) is every point.
RobustFrame robustFrame(const std::vector<Eigen::Vector3d>& world, const std::vector<int>& file_index,
                        std::size_t step);

/// Of points beyond 16 sizes (`at`), those alone: no other of them within one size `r` (`centre`:
/// the frame's). Their positions in `at`, ascending.
std::vector<std::size_t> aloneAmong(const std::vector<Eigen::Vector3d>& at, const Eigen::Vector3d& centre,
                                    double r);

/// The frame's limits from its size: beyond `far` a point is set apart; beyond `stray` (and
/// alone, and few) too; within `body` it is the shape's body.
struct FrameLimits {
  double far = 0, stray = 0, body = 0;
};
FrameLimits frameLimits(const RobustFrame& frame);

/// Throws IoError (naming `path`) when the frame spans more than kMaxExtent: corrupt coordinates.
void refuseExtent(const std::string& path, const RobustFrame& frame);

/// The warnings of what is set apart, prefixed with "path: " when `path` is not empty: `zeros`
/// 'no return' points at (0, 0, 0) `distance` from a shape of size `extent`; `count` points
/// more than `beyond` from it, the farthest `farthest` away.
std::string noReturnWarning(const std::string& path, std::size_t zeros, double distance, double extent);
std::string farWarning(const std::string& path, std::size_t count, double beyond, double extent,
                       double farthest);

/// A position's Morton key (10 bits an axis, x in the lowest) in the cube from `lo` whose side
/// `scale` maps to 1023 (Geometry's space-filling order; beyond it, the edge cells).
inline std::uint32_t mortonKey(const Eigen::Vector3d& w, const Eigen::Vector3d& lo, double scale) {
  auto spread = [](std::uint32_t v) {  // 10 bits -> every third of 30
    std::uint32_t x = v & 0x3ffu;
    x = (x | (x << 16)) & 0x030000ffu;
    x = (x | (x << 8)) & 0x0300f00fu;
    x = (x | (x << 4)) & 0x030c30c3u;
    x = (x | (x << 2)) & 0x09249249u;
    return x;
  };
  const Eigen::Vector3d q = ((w - lo) * scale).cwiseMax(0.0).cwiseMin(1023.0);
  return spread(static_cast<std::uint32_t>(q.x())) | (spread(static_cast<std::uint32_t>(q.y())) << 1) |
         (spread(static_cast<std::uint32_t>(q.z())) << 2);
}

}  // namespace hgd::frame
