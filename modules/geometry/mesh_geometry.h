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

// Per-vertex values of `mesh` at arbitrary points: barycentric interpolation
// at each point's closest point on the surface (e.g. a map carried from one
// triangulation of a surface to another).
std::vector<double> values_at(const Mesh& mesh, const ClosestPointIndex& index, const std::vector<double>& values,
                              const std::vector<Vec3>& points);

// Unit outward normals and areas of the faces of an outward-oriented mesh.
std::vector<Vec3> face_normals(const Mesh& mesh);
std::vector<double> face_areas(const Mesh& mesh);
// Area-weighted vertex normals (unit).
std::vector<Vec3> vertex_normals(const Mesh& mesh);

int nearest_vertex(const Mesh& mesh, const Vec3& p);

// Closest point of the surface to p by visiting every face: for a handful of
// queries, cheaper than building a ClosestPointIndex.
Vec3 closest_point_brute_force(const Mesh& mesh, const Vec3& p);

// The mesh cut along the spheres of radius r around each centre, so that the
// vertices within r of a centre make a disk whose border lies on the circle
// itself, not wherever the triangulation put its vertices: an edge crossing a
// sphere is split at the crossing, or, when the crossing is within 15 % of the
// edge from an endpoint, that endpoint is moved along the edge onto it (no
// slivers). The original vertices keep their indices (new ones follow);
// face_parent (optional) receives each new face's face in the input.
Mesh cut_along_spheres(const Mesh& mesh, const std::vector<Vec3>& centres, double r, std::vector<int>* face_parent = nullptr);

// Vertex graph of a mesh (compressed rows, unique neighbours) with edge
// lengths in mm, built once for repeated Dijkstra runs.
struct EdgeGraph {
  std::vector<std::size_t> start;  // vertex v's neighbours: nbr[start[v] .. start[v + 1])
  std::vector<int> nbr;
  std::vector<double> len;
};
EdgeGraph edge_graph(const Mesh& mesh);

// Multi-source Dijkstra on the edge graph up to radius (mm). dist (size n)
// must hold +inf where nothing has been reached; sources start at 0. owner
// (optional, size n) receives the index in sources of the nearest source;
// touched (optional) the vertices reached.
void dijkstra(const EdgeGraph& graph, const std::vector<int>& sources, double radius, std::vector<double>& dist,
              std::vector<int>* owner = nullptr, std::vector<int>* touched = nullptr);

// Geodesic (edge-graph Dijkstra) Voronoi partition: each vertex gets the index
// of the nearest seed vertex; distances returned in dist (mm).
std::vector<int> geodesic_voronoi(const Mesh& mesh, const std::vector<int>& seed_vertices, std::vector<double>* dist = nullptr);

// Signed distance of q to the mesh, positive outside (sign from the normal of
// the closest triangle); the closest point itself in *hit when asked.
double signed_distance(const ClosestPointIndex& index, const std::vector<Vec3>& face_normals, const Vec3& q,
                       ClosestHit* hit = nullptr);

}  // namespace ms::geometry
