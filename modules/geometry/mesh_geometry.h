// Mesh queries shared by the landmark, reference and asymmetry stages.
// The closest-point index wraps a CGAL AABB tree behind a pimpl so that CGAL
// headers stay out of every other translation unit.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "core/types.h"

namespace ms::geometry {

struct ClosestHit {
  Vec3 point;        // closest point on the surface
  int face = -1;     // triangle containing it
  Vec3 bary{1, 0, 0};  // barycentric coordinates of point in that triangle
  double distance = 0;
};

class ClosestPointIndex {
 public:
  explicit ClosestPointIndex(const Mesh& mesh);
  ~ClosestPointIndex();
  ClosestPointIndex(const ClosestPointIndex&) = delete;
  ClosestPointIndex& operator=(const ClosestPointIndex&) = delete;
  ClosestHit closest(const Vec3& query) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Unit outward normals and areas of the faces of an outward-oriented mesh.
std::vector<Vec3> face_normals(const Mesh& mesh);
std::vector<double> face_areas(const Mesh& mesh);
// Area-weighted vertex normals (unit).
std::vector<Vec3> vertex_normals(const Mesh& mesh);

int nearest_vertex(const Mesh& mesh, const Vec3& p);

// Geodesic (edge-graph Dijkstra) Voronoi partition: each vertex gets the index
// of the nearest seed vertex; distances returned in dist (mm).
std::vector<int> geodesic_voronoi(const Mesh& mesh, const std::vector<int>& seed_vertices, std::vector<double>* dist = nullptr);

// Signed distance of q to the mesh, positive outside (sign from the normal of
// the closest triangle).
double signed_distance(const ClosestPointIndex& index, const std::vector<Vec3>& face_normals, const Vec3& q);

}  // namespace ms::geometry
