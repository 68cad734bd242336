// Procedural shapes for tests, benchmarks and demos (not part of the installed library): the
// paper's test scenes made from nothing, so that they run on a clean clone.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "hgdeform/io/shape.h"

namespace hgd {
namespace shapes {

/// Builds a point-cloud Shape (float x y z nx ny nz) from points and normals.
Shape cloudShape(const std::vector<Eigen::Vector3f>& points, const std::vector<Eigen::Vector3f>& normals);

/// Surface of a box-section bar along x: [0, length] x [-w/2, w/2] x [-w/2, w/2], sampled on a
/// grid of spacing `h` (end caps included), with outward normals.
Shape bar(float length = 1.0f, float width = 0.1f, float h = 0.01f);

/// Surface of a closed cylinder along x, radius r, sampled at spacing ~h.
Shape cylinder(float length = 1.0f, float radius = 0.1f, float h = 0.01f);

/// A bumpy plane in z = 0 over [0, 1] x [0, 1]: `bumps` x `bumps` Gaussian bumps of height
/// `height`, sampled at spacing h, normals up.
Shape bumpyPlane(int bumps = 4, float height = 0.06f, float h = 0.01f);
/// Writes bumpyPlane(bumps, height, h) at `path` (a binary PLY or PCD) as writeShape would, byte
/// for byte, a row of points at a time: a plane of hundreds of millions of points in little memory.
void writeBumpyPlane(const std::string& path, int bumps, float height, float h);
/// A scenario for bumpy planes: the edge x < 0.05 fixed, the edge x > 0.95 lifted by 0.2 and
/// turned by 15 degrees (hgdeform-make-scans' and the bench's streaming rows').
inline constexpr const char* kBumpyPlaneScenario = R"({
  "format": "hgdeform-scenario/1",
  "fixed": [ { "box": { "min": [-1, -1, -1], "max": [0.05, 2, 1] } } ],
  "manipulated": { "box": { "min": [0.95, -1, -1], "max": [2, 2, 1] } },
  "move": { "frame": { "translate": [0, 0, 0.2], "rotate": { "axis": [0, 1, 0], "degrees": -15 } } }
}
)";

/// A fork lying in the xy plane: a base bar along x from 0 to 0.4, then two parallel prongs
/// from 0.4 to 1.2, separated by `gap` (surfaces of box-section bars of width w).
Shape fork(float gap = 0.04f, float w = 0.06f, float h = 0.01f);

/// A bumpy sphere (radius 1, bumps of relative height `amp`), about n points, golden-spiral
/// sampled: the benchmark shape for any size.
Shape bumpySphere(std::size_t n, float amp = 0.1f);

/// About n points sampled uniformly by area from a mesh's faces (fan-triangulated), with the
/// faces' normals: a resampled scan of any size from a mesh. Deterministic for a seed.
Shape sampleMesh(const Shape& mesh, std::size_t n, unsigned seed = 1);

/// `body` with `pieces` small dense pieces added, as a character mesh's eyes, teeth and buttons:
/// spheres of radius `radius` centred on body points chosen at random, `per_piece` points each
/// (random on the sphere), appended after the body's points. Deterministic for a seed.
std::vector<Eigen::Vector3f> withDensePieces(std::vector<Eigen::Vector3f> body, int pieces,
                                             std::size_t per_piece, float radius, unsigned seed);

/// A fork of three box-section bars (a base [0, 0.45] and two prongs [0.4, 1.2] with a gap
/// of 0.04 between them, 0.06 thick), n points sampled uniformly by area at random like a
/// resampled mesh, each with its face's normal in a random sign (resamplers do not orient).
/// `noise` adds Gaussian noise of that fraction of the diagonal; `outliers` adds that fraction
/// of n stray points, uniform in a box around the fork, after the n surface points.
struct PointsAndNormals {
  std::vector<Eigen::Vector3f> p, n;
};
PointsAndNormals sampledFork(std::size_t n, unsigned seed, double noise = 0, double outliers = 0);

/// The bar of bar() and, 0.5 beside it (y from 0.55), another object that no handle on the bar
/// reaches: the surface of a box 0.3 x 0.2 x 0.1, sampled at spacing h.
Shape barBesideABox(float h = 0.01f);

/// Triangle mesh of the same bar as bar(): vertices on the grid, two triangles per cell.
Shape barMesh(float length = 1.0f, float width = 0.1f, float h = 0.01f);

/// A four-legged animal as one closed triangle mesh (the surface of a smooth union of capsules:
/// body along x, legs down -y at x = ±0.38, z = ±0.14 reaching y = -0.75, neck and head at +x,
/// a tail at -x), meshed by marching tetrahedra on a grid of spacing h: a shape with branches
/// for quality checks. About 15,000 vertices at h = 0.02.
Shape quadruped(float h = 0.02f);

/// The quadruped's parts by position: foot `leg` (0 front right, 1 front left, 2 hind right,
/// 3 hind left; right is +z) is the vertices of that leg below y = -0.68; its shin those
/// between y = -0.6 and -0.3; its top the ring between y = -0.34 and -0.3, just below where
/// the leg meets the body (the smooth union of body and leg reaches down to y = -0.26).
std::vector<int> quadrupedFoot(const Shape& quadruped, int leg);
std::vector<int> quadrupedShin(const Shape& quadruped, int leg);
std::vector<int> quadrupedLegTop(const Shape& quadruped, int leg);

}  // namespace shapes
}  // namespace hgd
