#include "geometry/mesh_geometry.h"

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Simple_cartesian.h>

#include <array>
#include <cmath>
#include <algorithm>
#include <limits>
#include <map>
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
  // CGAL builds the tree and its search structure on the first query, which
  // is not thread-safe: build them here so that queries may run in parallel.
  if (!mesh.vertices.empty() && !mesh.faces.empty()) closest(mesh.vertices[0]);
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

namespace {
// Closest point of triangle abc to p (Ericson, Real-Time Collision Detection, 5.1.5).
Vec3 closest_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Vec3 bp = p - b;
  const double d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + (d1 / (d1 - d3)) * ab;
  const Vec3 cp = p - c;
  const double d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + (d2 / (d2 - d6)) * ac;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return b + ((d4 - d3) / ((d4 - d3) + (d5 - d6))) * (c - b);
  const double den = 1.0 / (va + vb + vc);
  return a + (vb * den) * ab + (vc * den) * ac;
}
}  // namespace

Vec3 closest_point_brute_force(const Mesh& mesh, const Vec3& p) {
  Vec3 best = p;
  double best_d2 = std::numeric_limits<double>::infinity();
  for (const auto& f : mesh.faces) {
    const Vec3 q = closest_on_triangle(p, mesh.vertices[static_cast<std::size_t>(f[0])], mesh.vertices[static_cast<std::size_t>(f[1])],
                                       mesh.vertices[static_cast<std::size_t>(f[2])]);
    const Vec3 d = q - p;
    if (dot(d, d) < best_d2) best_d2 = dot(d, d), best = q;
  }
  return best;
}

Mesh cut_along_spheres(const Mesh& mesh, const std::vector<Vec3>& centres, double r, std::vector<int>* face_parent) {
  constexpr double kSnap = 0.15;  // fraction of an edge within which an endpoint is moved instead of splitting
  Mesh m = mesh;
  std::vector<int> parent(m.faces.size());
  for (std::size_t f = 0; f < parent.size(); ++f) parent[f] = static_cast<int>(f);
  for (const Vec3& c : centres) {
    // Signed distance of each vertex to the sphere, once per sphere (and
    // again for the vertices a snap moves).
    std::vector<double> off(m.vertices.size());
    for (std::size_t v = 0; v < off.size(); ++v) off[v] = distance(m.vertices[v], c) - r;
    auto offset = [&](int v) { return off[static_cast<std::size_t>(v)]; };
    // Where segment a-b crosses the sphere: the root of |a + t (b - a) - c| = r in (0, 1).
    auto crossing = [&](int a, int b) {
      const Vec3 p = m.vertices[static_cast<std::size_t>(a)], d = m.vertices[static_cast<std::size_t>(b)] - p, f = p - c;
      const double A = dot(d, d), B = 2 * dot(f, d), C = dot(f, f) - r * r;
      const double q = std::sqrt(std::max(0.0, B * B - 4 * A * C));
      const double t1 = (-B - q) / (2 * A), t2 = (-B + q) / (2 * A);
      return std::clamp(t1 > 0 && t1 < 1 ? t1 : t2, 0.0, 1.0);
    };
    auto point_at = [&](int a, int b, double t) {
      const Vec3& p = m.vertices[static_cast<std::size_t>(a)];
      return p + t * (m.vertices[static_cast<std::size_t>(b)] - p);
    };
    constexpr double kOn = 1e-9;  // mm: on the sphere
    // 1. Snap endpoints near a crossing onto it: each vertex to its nearest
    //    crossing within kSnap of an edge, decided on the positions before
    //    any move (independent of the order of faces and edges).
    std::vector<std::pair<double, Vec3>> snap(m.vertices.size(), {kSnap, Vec3{0, 0, 0}});
    for (const auto& f : m.faces)
      for (int e = 0; e < 3; ++e) {
        const int a = f[static_cast<std::size_t>(e)], b = f[static_cast<std::size_t>((e + 1) % 3)];
        const double oa = offset(a), ob = offset(b);
        if (std::abs(oa) < kOn || std::abs(ob) < kOn || (oa < 0) == (ob < 0)) continue;
        const double t = crossing(a, b);
        auto& sa = snap[static_cast<std::size_t>(a)];
        auto& sb = snap[static_cast<std::size_t>(b)];
        if (t < sa.first) sa = {t, point_at(a, b, t)};
        if (1 - t < sb.first) sb = {1 - t, point_at(a, b, t)};
      }
    for (std::size_t v = 0; v < snap.size(); ++v)
      if (snap[v].first < kSnap) m.vertices[v] = snap[v].second, off[v] = distance(m.vertices[v], c) - r;
    // 2. Split the edges still crossing; each face keeps its orientation.
    auto side = [&](int v) {
      const double o = offset(v);
      return std::abs(o) < kOn ? 0 : (o < 0 ? -1 : 1);
    };
    std::map<std::pair<int, int>, int> split;
    auto mid = [&](int a, int b) {
      const std::pair<int, int> key{std::min(a, b), std::max(a, b)};
      const auto it = split.find(key);
      if (it != split.end()) return it->second;
      m.vertices.push_back(point_at(key.first, key.second, crossing(key.first, key.second)));
      off.push_back(0.0);
      const int id = static_cast<int>(m.vertices.size()) - 1;
      split.emplace(key, id);
      return id;
    };
    std::vector<std::array<int, 3>> faces;
    std::vector<int> parents;
    faces.reserve(m.faces.size());
    for (std::size_t fi = 0; fi < m.faces.size(); ++fi) {
      const auto& f = m.faces[fi];
      const int s[3] = {side(f[0]), side(f[1]), side(f[2])};
      bool cross[3];
      int n = 0;
      for (int e = 0; e < 3; ++e) n += cross[e] = s[e] * s[(e + 1) % 3] < 0;
      auto emit = [&](int x, int y, int z) { faces.push_back({x, y, z}), parents.push_back(parent[fi]); };
      if (n == 0) {
        emit(f[0], f[1], f[2]);
      } else if (n == 2) {  // vertex k alone on its side: its two edges cross
        const int k = cross[0] && cross[2] ? 0 : (cross[0] && cross[1] ? 1 : 2);
        const int a = f[static_cast<std::size_t>(k)], b = f[static_cast<std::size_t>((k + 1) % 3)], d = f[static_cast<std::size_t>((k + 2) % 3)];
        const int ab = mid(a, b), da = mid(d, a);
        emit(a, ab, da);
        // The quad ab, b, d, da along its shorter diagonal (a geometric
        // choice: a mirror-image mesh is cut into the mirror image).
        if (distance(m.vertices[static_cast<std::size_t>(ab)], m.vertices[static_cast<std::size_t>(d)]) <=
            distance(m.vertices[static_cast<std::size_t>(b)], m.vertices[static_cast<std::size_t>(da)])) {
          emit(ab, b, d);
          emit(ab, d, da);
        } else {
          emit(ab, b, da);
          emit(b, d, da);
        }
      } else {  // one crossing edge, the opposite vertex on the sphere
        const int k = cross[0] ? 0 : (cross[1] ? 1 : 2);
        const int a = f[static_cast<std::size_t>(k)], b = f[static_cast<std::size_t>((k + 1) % 3)], d = f[static_cast<std::size_t>((k + 2) % 3)];
        const int ab = mid(a, b);
        emit(a, ab, d);
        emit(ab, b, d);
      }
    }
    m.faces = std::move(faces);
    parent = std::move(parents);
  }
  if (face_parent) *face_parent = std::move(parent);
  return m;
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

double signed_distance(const ClosestPointIndex& index, const std::vector<Vec3>& fn, const Vec3& q, ClosestHit* hit) {
  const ClosestHit h = index.closest(q);
  if (hit) *hit = h;
  const double s = dot(q - h.point, fn[static_cast<std::size_t>(h.face)]);
  return s >= 0 ? h.distance : -h.distance;
}

}  // namespace ms::geometry
