// Shape quality of a deformation, measured from positions alone (rest and deformed, same
// order), so that hgdeform and any peer (CGAL's ARAP) are judged by the same rule.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <vector>

namespace hgd {
namespace quality {

/// Local distortion: for each point, its k nearest rest neighbours, the rotation that best maps
/// their rest offsets onto their deformed offsets (Kabsch), and the mean residual over the mean
/// rest offset length; the mean over all points. 0 for a rigid motion; scaling by s gives |s-1|.
double localDistortion(const std::vector<Eigen::Vector3d>& rest, const std::vector<Eigen::Vector3d>& deformed,
                       int k = 10);

/// The same measure, point by point (the residual over the mean offset length of each point).
std::vector<double> localDistortions(const std::vector<Eigen::Vector3d>& rest,
                                     const std::vector<Eigen::Vector3d>& deformed, int k = 10);

/// A stop rule for an iterative peer (hgdbench::cgalArapConverged): true once the local
/// distortion of the positions it is given changed less than `relative` over the last two calls
/// (two chunks of iterations). `last`, when given, receives the latest distortion.
std::function<bool(const std::vector<Eigen::Vector3d>&, int)> distortionSettles(
    const std::vector<Eigen::Vector3d>& rest, double relative = 0.005, double* last = nullptr);

/// The mean displacement of `points` between rest and deformed.
double meanDisplacement(const std::vector<Eigen::Vector3d>& rest,
                        const std::vector<Eigen::Vector3d>& deformed, const std::vector<int>& points);

/// How much a part lengthened: the distance between the centroids of `a` and of `b` deformed
/// over the same at rest, minus 1 (0 for a rigid motion, s - 1 for a uniform scale by s,
/// negative when it shortened). 0 when either set is empty or the centroids coincide at rest.
double lengthChange(const std::vector<Eigen::Vector3d>& rest, const std::vector<Eigen::Vector3d>& deformed,
                    const std::vector<int>& a, const std::vector<int>& b);

/// A part that should keep its length, by the points at its two ends (a leg's foot and top).
struct Part {
  std::vector<int> a, b;
};

/// The largest lengthChange, in absolute value, over `parts` (0 for none).
double largestLengthChange(const std::vector<Eigen::Vector3d>& rest,
                           const std::vector<Eigen::Vector3d>& deformed, const std::vector<Part>& parts);

}  // namespace quality
}  // namespace hgd
