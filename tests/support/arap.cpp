#include "support/arap.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>

#ifdef HGD_HAVE_CGAL
#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/Surface_mesh_deformation.h>
#endif

namespace hgdbench {

#ifdef HGD_HAVE_CGAL

bool haveCgalArap() {
  return true;
}

ArapTimes cgalArap(const std::vector<Eigen::Vector3d>& points,
                   const std::vector<std::array<int, 3>>& triangles, const std::vector<int>& fixed,
                   const std::vector<int>& handle, const Eigen::Vector3d& move, int frames, int iterations) {
  using Kernel = CGAL::Simple_cartesian<double>;
  using Point = Kernel::Point_3;
  using Mesh = CGAL::Surface_mesh<Point>;
  using Vertex = Mesh::Vertex_index;
  using Deformation = CGAL::Surface_mesh_deformation<Mesh>;
  using Clock = std::chrono::steady_clock;
  const auto ms = [](Clock::time_point t0) {
    return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  };

  ArapTimes out;
  Mesh mesh;
  std::vector<Vertex> v;
  v.reserve(points.size());
  for (const auto& p : points) v.push_back(mesh.add_vertex(Point(p.x(), p.y(), p.z())));
  for (const auto& t : triangles) {
    const auto f = mesh.add_face(v[static_cast<std::size_t>(t[0])], v[static_cast<std::size_t>(t[1])],
                                 v[static_cast<std::size_t>(t[2])]);
    if (f == Mesh::null_face())
      ++out.faces_refused;
    else
      ++out.faces;
  }
  out.vertices = mesh.number_of_vertices();

  const auto t0 = Clock::now();
  Deformation deformation(mesh);
  deformation.insert_roi_vertices(mesh.vertices().begin(), mesh.vertices().end());
  for (const int i : fixed) deformation.insert_control_vertex(v[static_cast<std::size_t>(i)]);
  for (const int i : handle) deformation.insert_control_vertex(v[static_cast<std::size_t>(i)]);
  if (!deformation.preprocess()) throw std::runtime_error("CGAL ARAP: the factorisation failed");
  out.preprocess_ms = ms(t0);

  for (int k = 1; k <= frames; ++k) {
    const auto f0 = Clock::now();
    const Eigen::Vector3d step = move * (static_cast<double>(k) / frames);
    for (const int i : handle) {
      const Eigen::Vector3d& p = points[static_cast<std::size_t>(i)];
      deformation.set_target_position(v[static_cast<std::size_t>(i)],
                                      Point(p.x() + step.x(), p.y() + step.y(), p.z() + step.z()));
    }
    deformation.deform(static_cast<unsigned int>(iterations), 0.0);
    out.frame_ms.push_back(ms(f0));
  }
  return out;
}

ArapResult cgalArapConverged(const std::vector<Eigen::Vector3d>& points,
                             const std::vector<std::array<int, 3>>& triangles, const std::vector<int>& fixed,
                             const std::vector<int>& handle, const Eigen::Vector3d& translation,
                             double tolerance, int max_iterations, int chunk,
                             const std::function<bool(const std::vector<Eigen::Vector3d>&, int)>& stop) {
  using Kernel = CGAL::Simple_cartesian<double>;
  using Point = Kernel::Point_3;
  using Mesh = CGAL::Surface_mesh<Point>;
  using Vertex = Mesh::Vertex_index;
  using Deformation = CGAL::Surface_mesh_deformation<Mesh>;
  const auto t0 = std::chrono::steady_clock::now();

  ArapResult out;
  Mesh mesh;
  std::vector<Vertex> v;
  v.reserve(points.size());
  for (const auto& p : points) v.push_back(mesh.add_vertex(Point(p.x(), p.y(), p.z())));
  for (const auto& t : triangles) {
    const auto f = mesh.add_face(v[static_cast<std::size_t>(t[0])], v[static_cast<std::size_t>(t[1])],
                                 v[static_cast<std::size_t>(t[2])]);
    if (f == Mesh::null_face())
      ++out.faces_refused;
    else
      ++out.faces;
  }
  Deformation deformation(mesh);
  deformation.insert_roi_vertices(mesh.vertices().begin(), mesh.vertices().end());
  const auto fail = [&] {
    return std::runtime_error("CGAL ARAP: the factorisation failed (" + std::to_string(points.size()) +
                              " vertices, " + std::to_string(out.faces) + " faces, " +
                              std::to_string(out.faces_refused) + " refused)");
  };
  Eigen::AlignedBox3d box;
  for (const auto& p : points) box.extend(p);
  const double limit = tolerance * box.diagonal().norm();
  std::vector<Eigen::Vector3d> before(points);
  const auto position = [&](std::size_t i) {
    const Point& q = mesh.point(v[i]);
    return Eigen::Vector3d(q.x(), q.y(), q.z());
  };
  const auto put = [&](std::size_t i, const Eigen::Vector3d& p) {
    deformation.set_target_position(v[i], Point(p.x(), p.y(), p.z()));
  };
  for (const int i : fixed) deformation.insert_control_vertex(v[static_cast<std::size_t>(i)]);
  for (const int i : handle) deformation.insert_control_vertex(v[static_cast<std::size_t>(i)]);
  if (!deformation.preprocess()) throw fail();
  for (const int i : fixed) put(static_cast<std::size_t>(i), points[static_cast<std::size_t>(i)]);
  for (const int i : handle)
    put(static_cast<std::size_t>(i), points[static_cast<std::size_t>(i)] + translation);
  out.converged = false;
  while (out.iterations < max_iterations) {
    for (std::size_t i = 0; i < points.size(); ++i) before[i] = position(i);
    deformation.deform(static_cast<unsigned>(chunk), 0.0);
    out.iterations += chunk;
    double change = 0;
    for (std::size_t i = 0; i < points.size(); ++i)
      change = std::max(change, (position(i) - before[i]).norm());
    if (stop) {
      std::vector<Eigen::Vector3d> now(points.size());
      for (std::size_t i = 0; i < points.size(); ++i) now[i] = position(i);
      if (stop(now, out.iterations)) {
        out.converged = true;
        break;
      }
    } else if (change <= limit) {
      out.converged = true;
      break;
    }
  }
  out.positions.resize(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) out.positions[i] = position(i);
  out.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

#else

bool haveCgalArap() {
  return false;
}

ArapTimes cgalArap(const std::vector<Eigen::Vector3d>&, const std::vector<std::array<int, 3>>&,
                   const std::vector<int>&, const std::vector<int>&, const Eigen::Vector3d&, int, int) {
  throw std::runtime_error("this build has no CGAL (install libcgal-dev and configure again)");
}

ArapResult cgalArapConverged(const std::vector<Eigen::Vector3d>&, const std::vector<std::array<int, 3>>&,
                             const std::vector<int>&, const std::vector<int>&, const Eigen::Vector3d&, double,
                             int, int, const std::function<bool(const std::vector<Eigen::Vector3d>&, int)>&) {
  throw std::runtime_error("this build has no CGAL (install libcgal-dev and configure again)");
}

#endif

}  // namespace hgdbench
