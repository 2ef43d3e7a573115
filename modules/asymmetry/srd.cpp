#include "asymmetry/srd.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "asymmetry/measures.h"
#include "geometry/mesh_geometry.h"

namespace ms::asymmetry {
namespace {
constexpr double kPi = 3.14159265358979323846;

bool contains(const Configuration& c, const std::string& n) { return c.a == n || c.b == n || c.c == n || c.d == n; }

// Distance of every vertex from the centre: Euclidean, on the patch the edge
// graph reaches within 1.5 × the outer radius (so the other side of a thin
// plate or a neighbouring process stays out); +inf elsewhere. Euclidean rather
// than edge-graph geodesic distance: the latter is biased by edge directions
// and starts at the nearest vertex rather than at the centre, which breaks
// mirror equivariance (docs/method.md, SRD).
std::vector<double> distances_from(const Mesh& mesh, const geometry::EdgeGraph& graph, const Vec3& centre,
                                   const SrdOptions& o) {
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<double> dist(mesh.vertices.size(), inf);
  geometry::dijkstra(graph, {geometry::nearest_vertex(mesh, centre)}, 1.5 * o.rings * o.ring_width_mm, dist);
  for (std::size_t v = 0; v < dist.size(); ++v)
    if (dist[v] < inf) dist[v] = norm(mesh.vertices[v] - centre);
  return dist;
}

// Linear (soft) binning: weight w split between the two nearest bin centres,
// so a small shift of an angle or a distance moves mass continuously.
struct Soft {
  int i0, i1;
  double w0, w1;
};
Soft soft_angle(double theta, int B) {
  const double x = (theta + kPi) / (2 * kPi) * B - 0.5;  // bin centres at integers
  const double fl = std::floor(x);
  const double t = x - fl;
  const int i = static_cast<int>(fl);
  return {((i % B) + B) % B, ((i + 1) % B + B) % B, 1 - t, t};
}
// -1 when beyond the outer radius; the innermost and outermost halves clamp.
Soft soft_ring(double d, const SrdOptions& o) {
  if (!(d < o.rings * o.ring_width_mm)) return {-1, -1, 0, 0};
  const double x = d / o.ring_width_mm - 0.5;
  if (x <= 0) return {0, 0, 1, 0};
  if (x >= o.rings - 1) return {o.rings - 1, o.rings - 1, 1, 0};
  const int i = static_cast<int>(std::floor(x));
  return {i, i + 1, 1 - (x - i), x - i};
}

Srd describe(const std::string& name, const Mesh& mesh, const std::vector<double>& dist,
             const std::vector<double>& face_area, const std::vector<double>& vertex_area,
             const std::vector<AngleField>& fields, const SrdOptions& o) {
  Srd d{name, {}};
  const int B = o.bins;
  // Distance of each element: vertex distance, or the mean over a face's corners.
  std::vector<double> face_dist(mesh.faces.size());
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    const auto& t = mesh.faces[f];
    face_dist[f] = (dist[t[0]] + dist[t[1]] + dist[t[2]]) / 3.0;  // inf if any corner is out of reach
  }
  for (const auto& field : fields) {
    if (!contains(field.config, name)) continue;
    // Per-face fields (raw θ) or per-vertex fields.
    const bool per_vertex = field.theta.size() == vertex_area.size() && field.theta.size() != face_area.size();
    const auto& el_dist = per_vertex ? dist : face_dist;
    const auto& area = per_vertex ? vertex_area : face_area;
    SrdBlock blk{field.name, field.mirrored, std::vector<double>(static_cast<std::size_t>(o.rings * B), 0.0)};
    std::vector<double> total(o.rings, 0.0);
    for (std::size_t e = 0; e < el_dist.size(); ++e) {
      if (std::isnan(field.theta[e])) continue;
      const Soft r = soft_ring(el_dist[e], o);
      if (r.i0 < 0) continue;
      const Soft b = soft_angle(field.theta[e], B);
      for (const auto& [ri, rw] : {std::make_pair(r.i0, r.w0), std::make_pair(r.i1, r.w1)}) {
        if (rw == 0) continue;
        blk.histogram[ri * B + b.i0] += area[e] * rw * b.w0;
        blk.histogram[ri * B + b.i1] += area[e] * rw * b.w1;
        total[ri] += area[e] * rw;
      }
    }
    for (int r = 0; r < o.rings; ++r)
      if (total[r] > 0)
        for (int k = 0; k < B; ++k) blk.histogram[r * B + k] /= total[r];
    d.blocks.push_back(std::move(blk));
  }
  return d;
}


// Circular Wasserstein-1 (radians) between two normalised histograms of B bins;
// y's bins reversed (its angles negated) when reverse.
double circular_w1(const double* x, const double* y, int B, bool reverse) {
  std::vector<double> c(B);
  double acc = 0;
  for (int b = 0; b < B; ++b) {
    acc += x[b] - (reverse ? y[B - 1 - b] : y[b]);
    c[b] = acc;
  }
  std::vector<double> s = c;
  std::nth_element(s.begin(), s.begin() + B / 2, s.end());
  const double med = s[B / 2];
  double w = 0;
  for (int b = 0; b < B; ++b) w += std::abs(c[b] - med);
  return w * 2 * kPi / B;
}
}  // namespace

Srd compute_srd(const Mesh& mesh, const std::string& name, const Vec3& centre, const std::vector<AngleField>& fields,
                const SrdOptions& options) {
  const auto graph = geometry::edge_graph(mesh);
  const auto area = geometry::face_areas(mesh);
  return describe(name, mesh, distances_from(mesh, graph, centre, options), area, vertex_areas(mesh), fields,
                  options);
}

SrdResult compute_srds(const Mesh& mesh, const SafResult& saf, const SrdOptions& options) {
  SrdResult out;
  out.options = options;
  if (saf.fields.empty()) return out;
  const auto graph = geometry::edge_graph(mesh);
  const auto area = geometry::face_areas(mesh);
  const auto varea = vertex_areas(mesh);
  for (const auto& [name, p] : saf.disk_centres.points) {
    Srd d = describe(name, mesh, distances_from(mesh, graph, p, options), area, varea, saf.fields, options);
    if (!d.blocks.empty()) out.descriptors[name] = std::move(d);
  }
  std::vector<SrdTwin> midline;
  for (const auto& [name, d] : out.descriptors) {
    const std::string twin = mirror_label(name);
    const auto it = out.descriptors.find(twin);
    if (it == out.descriptors.end() || (twin != name && name > twin)) continue;  // each pair once, _L first
    SrdTwin t{name, twin};
    t.mirror_mismatch = srd_distance(d, it->second, options.bins, true, true);
    t.handedness = srd_distance(d, it->second, options.bins, true, false);
    (twin == name ? midline : out.twins).push_back(t);
  }
  out.twins.insert(out.twins.end(), midline.begin(), midline.end());
  return out;
}

double srd_distance(const Srd& a, const Srd& b, int bins, bool as_mirror, bool reverse_bins) {
  double sum = 0;
  int n = 0;
  for (const auto& x : a.blocks) {
    const auto y = std::find_if(b.blocks.begin(), b.blocks.end(), [&](const SrdBlock& k) {
      return k.configuration == x.configuration && k.mirrored == (as_mirror ? !x.mirrored : x.mirrored);
    });
    if (y == b.blocks.end() || y->histogram.size() != x.histogram.size()) continue;
    const int rings = static_cast<int>(x.histogram.size()) / bins;
    for (int r = 0; r < rings; ++r) {
      const double* hx = x.histogram.data() + r * bins;
      const double* hy = y->histogram.data() + r * bins;
      double sx = 0, sy = 0;
      for (int k = 0; k < bins; ++k) sx += hx[k], sy += hy[k];
      if (sx == 0 || sy == 0) continue;
      sum += circular_w1(hx, hy, bins, reverse_bins);
      ++n;
    }
  }
  return n ? sum / n : -1;
}

}  // namespace ms::asymmetry
