// The peer: CGAL's as-rigid-as-possible surface deformation (Surface_mesh_deformation,
// ORIGINAL_ARAP) on the same mesh and handles as hgdeform, for the benchmark's timings and for
// the quality checks of the bench and the tests. Its own file: CGAL's headers are heavy and
// optional (built only when CMake finds CGAL; haveCgalArap() says whether this build has it).
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <functional>
#include <vector>

namespace hgdbench {

bool haveCgalArap();

struct ArapTimes {
  std::size_t vertices = 0, faces = 0;
  std::size_t faces_refused = 0;  ///< faces CGAL's halfedge mesh could not take (non-manifold)
  double preprocess_ms = 0;       ///< region of interest, control vertices, factorisation
  std::vector<double> frame_ms;   ///< per frame: new handle targets, then deform()
};

/// CGAL::Surface_mesh_deformation (ORIGINAL_ARAP, its default) on a triangle mesh: every
/// vertex in the region of interest, `fixed` and `handle` as control vertices. In frame k of
/// `frames`, the handle's targets are its rest positions moved by move·k/frames, and deform()
/// runs exactly `iterations` iterations (tolerance 0). Throws std::runtime_error when CGAL is
/// not built in or its factorisation fails.
ArapTimes cgalArap(const std::vector<Eigen::Vector3d>& points,
                   const std::vector<std::array<int, 3>>& triangles, const std::vector<int>& fixed,
                   const std::vector<int>& handle, const Eigen::Vector3d& move, int frames, int iterations);

struct ArapResult {
  std::vector<Eigen::Vector3d> positions;  ///< every vertex, deformed
  std::size_t faces = 0, faces_refused = 0;
  int iterations = 0;  ///< ARAP iterations run
  bool converged = false;
  double ms = 0;  ///< preprocess and every iteration
};

/// ARAP run to convergence from the rest shape: `fixed` stay, each `handle` vertex goes to its
/// rest position moved by `translation`; iterated in chunks of `chunk` iterations until no vertex
/// moves more than `tolerance` (× the bounding box diagonal) over a chunk, or, when `stop` is
/// given, until stop(positions, iterations so far) says so; at most `max_iterations`. Throws
/// std::runtime_error when CGAL is not built in or its factorisation fails.
ArapResult cgalArapConverged(const std::vector<Eigen::Vector3d>& points,
                             const std::vector<std::array<int, 3>>& triangles, const std::vector<int>& fixed,
                             const std::vector<int>& handle, const Eigen::Vector3d& translation,
                             double tolerance = 1e-5, int max_iterations = 1000, int chunk = 10,
                             const std::function<bool(const std::vector<Eigen::Vector3d>&, int)>& stop = {});

}  // namespace hgdbench
