#include "geometry/mesh_geometry.h"

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Simple_cartesian.h>

#include <cmath>
#include <algorithm>
#include <limits>
#include <queue>

namespace ms::geometry {

namespace {
using K = CGAL::Simple_cartesian<double>;
using Point = K::Point_3;
using Triangle = K::Triangle_3;
using Iterator = std::vector<Triangle>::const_iterator;
using Primitive = CGAL::AABB_triangle_primitive<K, Iterator>;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<K, Primitive>>;
}  // namespace

struct ClosestPointIndex::Impl {
  std::vector<Triangle> triangles;
  Tree tree;
};

ClosestPointIndex::ClosestPointIndex(const Mesh& mesh) : impl_(std::make_unique<Impl>()) {
  auto P = [&](int i) {
    const Vec3& v = mesh.vertices[static_cast<std::size_t>(i)];
    return Point(v[0], v[1], v[2]);
  };
  impl_->triangles.reserve(mesh.faces.size());
  for (const auto& f : mesh.faces) impl_->triangles.emplace_back(P(f[0]), P(f[1]), P(f[2]));
  impl_->tree.rebuild(impl_->triangles.cbegin(), impl_->triangles.cend());
  impl_->tree.accelerate_distance_queries();
}

ClosestPointIndex::~ClosestPointIndex() = default;

ClosestHit ClosestPointIndex::closest(const Vec3& q) const {
  const Point qp(q[0], q[1], q[2]);
  const auto pp = impl_->tree.closest_point_and_primitive(qp);
  ClosestHit h;
  h.point = {pp.first.x(), pp.first.y(), pp.first.z()};
  h.face = static_cast<int>(pp.second - impl_->triangles.cbegin());
  h.distance = distance(h.point, q);
  // barycentric coordinates of the closest point
  const Triangle& t = *pp.second;
  const Vec3 a{t[0].x(), t[0].y(), t[0].z()}, b{t[1].x(), t[1].y(), t[1].z()}, c{t[2].x(), t[2].y(), t[2].z()};
  const Vec3 v0 = b - a, v1 = c - a, v2 = h.point - a;
  const double d00 = dot(v0, v0), d01 = dot(v0, v1), d11 = dot(v1, v1), d20 = dot(v2, v0), d21 = dot(v2, v1);
  const double den = d00 * d11 - d01 * d01;
  if (std::abs(den) > 1e-20) {
    const double v = (d11 * d20 - d01 * d21) / den, w = (d00 * d21 - d01 * d20) / den;
    h.bary = {1.0 - v - w, v, w};
  }
  return h;
}

std::vector<double> values_at(const Mesh& mesh, const ClosestPointIndex& index, const std::vector<double>& values,
                              const std::vector<Vec3>& points) {
  std::vector<double> out(points.size(), 0.0);
  if (values.size() != mesh.vertices.size() || mesh.faces.empty()) return out;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const ClosestHit h = index.closest(points[i]);
    const auto& f = mesh.faces[static_cast<std::size_t>(h.face)];
    for (int k = 0; k < 3; ++k) out[i] += h.bary[k] * values[static_cast<std::size_t>(f[k])];
  }
  return out;
}

std::vector<Vec3> face_normals(const Mesh& m) {
  std::vector<Vec3> n(m.faces.size());
  for (std::size_t i = 0; i < m.faces.size(); ++i) {
    const auto& f = m.faces[i];
    const Vec3 c = cross(m.vertices[f[1]] - m.vertices[f[0]], m.vertices[f[2]] - m.vertices[f[0]]);
    const double l = norm(c);
    n[i] = l > 0 ? (1.0 / l) * c : Vec3{0, 0, 0};
  }
  return n;
}

std::vector<double> face_areas(const Mesh& m) {
  std::vector<double> a(m.faces.size());
  for (std::size_t i = 0; i < m.faces.size(); ++i) {
    const auto& f = m.faces[i];
    a[i] = 0.5 * norm(cross(m.vertices[f[1]] - m.vertices[f[0]], m.vertices[f[2]] - m.vertices[f[0]]));
  }
  return a;
}

std::vector<Vec3> vertex_normals(const Mesh& m) {
  std::vector<Vec3> n(m.vertices.size(), Vec3{0, 0, 0});
  for (const auto& f : m.faces) {
    const Vec3 c = cross(m.vertices[f[1]] - m.vertices[f[0]], m.vertices[f[2]] - m.vertices[f[0]]);
    for (int k = 0; k < 3; ++k) n[f[k]] = n[f[k]] + c;
  }
  for (auto& v : n) {
    const double l = norm(v);
    if (l > 0) v = (1.0 / l) * v;
  }
  return n;
}

int nearest_vertex(const Mesh& m, const Vec3& p) {
  int best = -1;
  double bd = std::numeric_limits<double>::max();
  for (std::size_t i = 0; i < m.vertices.size(); ++i) {
    const Vec3 d = m.vertices[i] - p;
    const double dd = dot(d, d);
    if (dd < bd) {
      bd = dd;
      best = static_cast<int>(i);
    }
  }
  return best;
}

EdgeGraph edge_graph(const Mesh& mesh) {
  const std::size_t n = mesh.vertices.size();
  std::vector<std::vector<int>> adj(n);
  for (const auto& f : mesh.faces)
    for (int e = 0; e < 3; ++e) {
      const int a = f[e], b = f[(e + 1) % 3];
      adj[static_cast<std::size_t>(a)].push_back(b);
      adj[static_cast<std::size_t>(b)].push_back(a);
    }
  EdgeGraph g;
  g.start.assign(n + 1, 0);
  for (std::size_t i = 0; i < n; ++i) {
    auto& l = adj[i];
    std::sort(l.begin(), l.end());
    l.erase(std::unique(l.begin(), l.end()), l.end());
    g.start[i + 1] = g.start[i] + l.size();
  }
  g.nbr.reserve(g.start[n]);
  g.len.reserve(g.start[n]);
  for (std::size_t i = 0; i < n; ++i)
    for (int j : adj[i]) {
      g.nbr.push_back(j);
      g.len.push_back(distance(mesh.vertices[i], mesh.vertices[static_cast<std::size_t>(j)]));
    }
  return g;
}

void dijkstra(const EdgeGraph& g, const std::vector<int>& sources, double radius, std::vector<double>& dist,
              std::vector<int>* owner, std::vector<int>* touched) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  using Item = std::pair<double, int>;
  std::priority_queue<Item, std::vector<Item>, std::greater<Item>> q;
  for (std::size_t s = 0; s < sources.size(); ++s) {
    const int v = sources[s];
    if (v < 0) continue;
    if (touched && dist[static_cast<std::size_t>(v)] == kInf) touched->push_back(v);
    dist[static_cast<std::size_t>(v)] = 0;
    if (owner) (*owner)[static_cast<std::size_t>(v)] = static_cast<int>(s);
    q.push({0.0, v});
  }
  while (!q.empty()) {
    const auto [d, v] = q.top();
    q.pop();
    if (d > dist[static_cast<std::size_t>(v)]) continue;
    for (std::size_t e = g.start[static_cast<std::size_t>(v)]; e < g.start[static_cast<std::size_t>(v) + 1]; ++e) {
      const int w = g.nbr[e];
      const double nd = d + g.len[e];
      if (nd > radius || nd >= dist[static_cast<std::size_t>(w)]) continue;
      if (touched && dist[static_cast<std::size_t>(w)] == kInf) touched->push_back(w);
      dist[static_cast<std::size_t>(w)] = nd;
      if (owner) (*owner)[static_cast<std::size_t>(w)] = (*owner)[static_cast<std::size_t>(v)];
      q.push({nd, w});
    }
  }
}

std::vector<int> geodesic_voronoi(const Mesh& m, const std::vector<int>& seeds, std::vector<double>* dist_out) {
  const std::size_t n = m.vertices.size();
  std::vector<double> dist(n, std::numeric_limits<double>::infinity());
  std::vector<int> owner(n, -1);
  dijkstra(edge_graph(m), seeds, std::numeric_limits<double>::infinity(), dist, &owner);
  if (dist_out) *dist_out = std::move(dist);
  return owner;
}

double signed_distance(const ClosestPointIndex& index, const std::vector<Vec3>& fn, const Vec3& q) {
  const ClosestHit h = index.closest(q);
  const double s = dot(q - h.point, fn[static_cast<std::size_t>(h.face)]);
  return s >= 0 ? h.distance : -h.distance;
}

}  // namespace ms::geometry
