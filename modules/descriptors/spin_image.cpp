#include "descriptors/spin_image.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <mutex>
#include <stdexcept>

#include "geometry/mesh_geometry.h"

namespace ms::descriptors {

double mesh_resolution(const Mesh& mesh) {
  double sum = 0;
  std::size_t n = 0;
  for (const auto& f : mesh.faces)
    for (int k = 0; k < 3; ++k) {
      sum += distance(mesh.vertices[static_cast<std::size_t>(f[static_cast<std::size_t>(k)])],
                      mesh.vertices[static_cast<std::size_t>(f[static_cast<std::size_t>((k + 1) % 3)])]);
      ++n;
    }
  return n ? sum / static_cast<double>(n) : 0.0;
}

double signed_normal_angle(const Vec3& p, const Vec3& n, const Vec3& x, const Vec3& nx) {
  const double angle = std::acos(std::clamp(dot(n, nx), -1.0, 1.0));
  const Vec3 d = x - p;
  const Vec3 radial = d - dot(d, n) * n;  // from the normal ray of p out to x
  // Leaning towards the ray: the part of nx across the ray points back to it.
  return dot(nx, radial) <= 0 ? angle : -angle;
}

namespace {

// Uniform grid over the vertices for fixed-radius queries.
class Grid {
 public:
  Grid(const std::vector<Vec3>& pts, double cell) : pts_(pts), cell_(cell) {
    lo_ = {1e300, 1e300, 1e300};
    Vec3 hi{-1e300, -1e300, -1e300};
    for (const auto& p : pts)
      for (int a = 0; a < 3; ++a) lo_[a] = std::min(lo_[a], p[a]), hi[a] = std::max(hi[a], p[a]);
    for (int a = 0; a < 3; ++a) n_[a] = pts.empty() ? 1 : std::max(1, static_cast<int>((hi[a] - lo_[a]) / cell_) + 1);
    start_.assign(static_cast<std::size_t>(n_[0]) * n_[1] * n_[2] + 1, 0);
    std::vector<std::size_t> cell_of(pts.size());
    for (std::size_t i = 0; i < pts.size(); ++i) ++start_[(cell_of[i] = index(pts[i])) + 1];
    for (std::size_t c = 1; c < start_.size(); ++c) start_[c] += start_[c - 1];
    items_.resize(pts.size());
    std::vector<std::size_t> fill(start_.begin(), start_.end() - 1);
    for (std::size_t i = 0; i < pts.size(); ++i) items_[fill[cell_of[i]]++] = static_cast<int>(i);
  }
  // Indices of the points within r of q (unordered).
  void within(const Vec3& q, double r, std::vector<int>& out) const {
    out.clear();
    int a0[3], a1[3];
    for (int a = 0; a < 3; ++a) {
      a0[a] = std::max(0, static_cast<int>(std::floor((q[a] - r - lo_[a]) / cell_)));
      a1[a] = std::min(n_[a] - 1, static_cast<int>(std::floor((q[a] + r - lo_[a]) / cell_)));
    }
    const double r2 = r * r * (1 + 1e-12);
    for (int k = a0[2]; k <= a1[2]; ++k)
      for (int j = a0[1]; j <= a1[1]; ++j)
        for (int i = a0[0]; i <= a1[0]; ++i) {
          const std::size_t c = static_cast<std::size_t>(i) + static_cast<std::size_t>(n_[0]) * (j + static_cast<std::size_t>(n_[1]) * k);
          for (std::size_t s = start_[c]; s < start_[c + 1]; ++s) {
            const Vec3 d = pts_[static_cast<std::size_t>(items_[s])] - q;
            if (dot(d, d) <= r2) out.push_back(items_[s]);
          }
        }
  }

 private:
  std::size_t index(const Vec3& p) const {
    std::size_t c[3];
    for (int a = 0; a < 3; ++a)
      c[a] = static_cast<std::size_t>(std::clamp(static_cast<int>((p[a] - lo_[a]) / cell_), 0, n_[a] - 1));
    return c[0] + static_cast<std::size_t>(n_[0]) * (c[1] + static_cast<std::size_t>(n_[1]) * c[2]);
  }
  const std::vector<Vec3>& pts_;
  double cell_;
  Vec3 lo_;
  int n_[3];
  std::vector<std::size_t> start_;
  std::vector<int> items_;
};

// Adds w to a bins x bins image at continuous (row, col) in bin units
// (bin i spans [i, i + 1)), shared bilinearly between the nearest centres.
void splat(std::vector<double>& img, int bins, double row, double col, double w) {
  auto split = [bins](double c, int& i0, double& f) {
    const double u = c - 0.5;
    i0 = static_cast<int>(std::floor(u));
    f = u - i0;
    if (i0 < 0) i0 = 0, f = 0;
    if (i0 >= bins - 1) i0 = bins - 1, f = 0;
  };
  int r0, c0;
  double fr, fc;
  split(row, r0, fr);
  split(col, c0, fc);
  const auto at = [&](int r, int c) -> double& { return img[static_cast<std::size_t>(r * bins + c)]; };
  at(r0, c0) += w * (1 - fr) * (1 - fc);
  if (fc > 0) at(r0, c0 + 1) += w * (1 - fr) * fc;
  if (fr > 0) at(r0 + 1, c0) += w * fr * (1 - fc);
  if (fr > 0 && fc > 0) at(r0 + 1, c0 + 1) += w * fr * fc;
}

}  // namespace

struct SpinImages::Impl {
  Mesh mesh;
  Options opt;
  double resolution = 0;
  std::vector<double> area;     // vertex areas (a third of each incident face)
  std::vector<Vec3> normal;     // area-weighted vertex normals (outward)
  std::unique_ptr<Grid> grid;
  mutable std::once_flag lrf_once;
  mutable std::vector<Vec3> lrf_normal;  // z of the frame of radius normal_radius at every vertex

  // Distance-weighted scatter of the neighbours within radius about vertex v
  // (SHOT's M), as the 6 entries of a symmetric matrix; false when too few.
  bool scatter(int v, double radius, std::vector<int>& nb, Eigen::Matrix3d& M) const {
    const Vec3& p = mesh.vertices[static_cast<std::size_t>(v)];
    grid->within(p, radius, nb);
    double xx = 0, xy = 0, xz = 0, yy = 0, yz = 0, zz = 0, wsum = 0;
    for (int i : nb) {
      const Vec3 d = mesh.vertices[static_cast<std::size_t>(i)] - p;
      const double w = radius - std::sqrt(dot(d, d));
      xx += w * d[0] * d[0], xy += w * d[0] * d[1], xz += w * d[0] * d[2];
      yy += w * d[1] * d[1], yz += w * d[1] * d[2], zz += w * d[2] * d[2];
      wsum += w;
    }
    if (nb.size() < 3 || wsum <= 0) return false;
    M << xx, xy, xz, xy, yy, yz, xz, yz, zz;
    M /= wsum;
    return true;
  }

  // z axis of the frame (smallest eigenvector, outward): the ISI's normals.
  Vec3 frame_z(int v, double radius, std::vector<int>& nb) const {
    Eigen::Matrix3d M;
    const Vec3& n0 = normal[static_cast<std::size_t>(v)];
    if (!scatter(v, radius, nb, M)) return n0;
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
    es.computeDirect(M, Eigen::ComputeEigenvectors);  // ascending eigenvalues
    Vec3 z{es.eigenvectors()(0, 0), es.eigenvectors()(1, 0), es.eigenvectors()(2, 0)};
    return dot(z, n0) < 0 ? -1.0 * z : z;
  }

  Frame frame(int v, double radius, std::vector<int>& nb) const {
    const Vec3& p = mesh.vertices[static_cast<std::size_t>(v)];
    Frame f;
    const Vec3& n0 = normal[static_cast<std::size_t>(v)];
    Eigen::Matrix3d M;
    if (!scatter(v, radius, nb, M)) {  // too few neighbours: the vertex normal and any tangent
      f.z = n0;
      const Vec3 t = std::abs(n0[0]) < 0.9 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
      f.x = normalized(t - dot(t, n0) * n0);
      f.y = cross(f.z, f.x);
      return f;
    }
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
    es.computeDirect(M);  // ascending eigenvalues
    const auto ev = es.eigenvectors();
    f.z = {ev(0, 0), ev(1, 0), ev(2, 0)};
    f.x = {ev(0, 2), ev(1, 2), ev(2, 2)};
    if (dot(f.z, n0) < 0) f.z = -1.0 * f.z;
    long balance = 0;
    for (int i : nb) balance += dot(mesh.vertices[static_cast<std::size_t>(i)] - p, f.x) >= 0 ? 1 : -1;
    if (balance < 0) f.x = -1.0 * f.x;
    f.x = normalized(f.x - dot(f.x, f.z) * f.z);
    f.y = cross(f.z, f.x);
    return f;
  }

  const std::vector<Vec3>& neighbour_normals() const {
    std::call_once(lrf_once, [this] {
      lrf_normal.resize(mesh.vertices.size());
      const long n = static_cast<long>(mesh.vertices.size());
#pragma omp parallel
      {
        std::vector<int> nb;
#pragma omp for schedule(dynamic, 256)
        for (long v = 0; v < n; ++v) lrf_normal[static_cast<std::size_t>(v)] = frame_z(static_cast<int>(v), opt.normal_radius_mm, nb);
      }
    });
    return lrf_normal;
  }

  // Raw image at vertex v; nb is scratch.
  void image(Kind kind, int v, std::vector<double>& img, std::vector<int>& nb) const {
    const int bins = opt.bins;
    const double R = opt.support_radius_mm;
    img.assign(static_cast<std::size_t>(bins * bins), 0.0);
    const Vec3& p = mesh.vertices[static_cast<std::size_t>(v)];
    const bool isi = kind == Kind::kImprovedSpinImage;
    const std::vector<Vec3>& nrm = isi ? neighbour_normals() : normal;
    // The reference normal: the frame's z at lrf_radius (the neighbour normal
    // itself when the two radii agree, as by default).
    const Vec3 n = !isi ? normal[static_cast<std::size_t>(v)]
                        : opt.lrf_radius_mm == opt.normal_radius_mm ? nrm[static_cast<std::size_t>(v)]
                                                                     : frame_z(v, opt.lrf_radius_mm, nb);
    const double cos_support = std::cos(opt.support_angle_deg * M_PI / 180);
    const double support = opt.support_angle_deg * M_PI / 180;
    grid->within(p, R, nb);
    for (int i : nb) {
      const auto iu = static_cast<std::size_t>(i);
      const Vec3& nx = nrm[iu];
      // Boundary included, with slack for round-off: meshes from voxel masks
      // have many exactly perpendicular normal pairs (flat staircase facets),
      // which a strict test would split at random under rigid motion.
      if (dot(n, nx) < cos_support - 1e-9) continue;
      const Vec3 d = mesh.vertices[iu] - p;
      const double beta = dot(d, n);
      const double alpha = std::sqrt(std::max(0.0, dot(d, d) - beta * beta));
      const double row = alpha / R * bins;
      const double col = isi ? (signed_normal_angle(p, n, mesh.vertices[iu], nx) + support) / (2 * support) * bins
                             : (beta + R) / (2 * R) * bins;
      splat(img, bins, row, col, area[iu]);
    }
  }
};

SpinImages::SpinImages(const Mesh& mesh, const Options& options) : impl_(std::make_unique<Impl>()) {
  if (options.bins < 2) throw std::invalid_argument("descriptors: bins must be at least 2");
  if (!(options.support_angle_deg > 0 && options.support_angle_deg <= 180))
    throw std::invalid_argument("descriptors: support angle must be in (0, 180] degrees");
  auto& m = *impl_;
  m.mesh = mesh;
  m.opt = options;
  m.resolution = mesh_resolution(mesh);
  if (m.opt.support_radius_mm <= 0) m.opt.support_radius_mm = 10 * m.resolution;
  if (m.opt.lrf_radius_mm <= 0) m.opt.lrf_radius_mm = m.opt.support_radius_mm;
  if (m.opt.normal_radius_mm <= 0) m.opt.normal_radius_mm = m.opt.support_radius_mm;
  if (!(m.opt.support_radius_mm > 0)) throw std::invalid_argument("descriptors: the mesh has no edges");
  m.normal = geometry::vertex_normals(mesh);
  m.area.assign(mesh.vertices.size(), 0.0);
  const auto fa = geometry::face_areas(mesh);
  for (std::size_t f = 0; f < mesh.faces.size(); ++f)
    for (int k : mesh.faces[f]) m.area[static_cast<std::size_t>(k)] += fa[f] / 3;
  const double cell = std::max({m.opt.support_radius_mm, m.opt.lrf_radius_mm, m.opt.normal_radius_mm}) / 2;
  m.grid = std::make_unique<Grid>(m.mesh.vertices, cell);
}

SpinImages::~SpinImages() = default;
double SpinImages::resolution() const { return impl_->resolution; }
double SpinImages::support_radius() const { return impl_->opt.support_radius_mm; }
int SpinImages::length() const { return impl_->opt.bins * impl_->opt.bins; }
const Options& SpinImages::options() const { return impl_->opt; }

Frame SpinImages::frame(int vertex, double radius) const {
  std::vector<int> nb;
  return impl_->frame(vertex, radius, nb);
}

std::vector<double> SpinImages::image(Kind kind, int vertex) const {
  std::vector<double> img;
  std::vector<int> nb;
  impl_->image(kind, vertex, img, nb);
  return img;
}

std::vector<float> SpinImages::compute(Kind kind, const std::vector<int>& vertices) const {
  const int len = length();
  if (kind == Kind::kImprovedSpinImage) impl_->neighbour_normals();  // once, before the parallel loop
  std::vector<float> out(vertices.size() * static_cast<std::size_t>(len), 0.0f);
  const long n = static_cast<long>(vertices.size());
#pragma omp parallel
  {
    std::vector<double> img;
    std::vector<int> nb;
#pragma omp for schedule(dynamic, 16)
    for (long k = 0; k < n; ++k) {
      impl_->image(kind, vertices[static_cast<std::size_t>(k)], img, nb);
      double ss = 0;
      for (double x : img) ss += x * x;
      const double s = ss > 0 ? 1 / std::sqrt(ss) : 0;
      float* dst = out.data() + static_cast<std::size_t>(k) * static_cast<std::size_t>(len);
      for (int i = 0; i < len; ++i) dst[i] = static_cast<float>(img[static_cast<std::size_t>(i)] * s);
    }
  }
  return out;
}

}  // namespace ms::descriptors
