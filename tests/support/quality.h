// Shape quality of a deformation, measured from positions alone (rest and deformed, same
// order), so that hgdeform and any peer (CGAL's ARAP) are judged by the same rule.
#pragma once

#include <Eigen/Core>
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

/// The mean displacement of `points` between rest and deformed.
double meanDisplacement(const std::vector<Eigen::Vector3d>& rest,
                        const std::vector<Eigen::Vector3d>& deformed, const std::vector<int>& points);

}  // namespace quality
}  // namespace hgd
