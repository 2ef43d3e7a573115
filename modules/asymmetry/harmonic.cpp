#include "asymmetry/harmonic.h"

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>

namespace ms::asymmetry {

struct HarmonicFieldSolver::Impl {
  const Mesh& mesh;
  double radius;
  Eigen::SparseMatrix<double> L;  // cotangent stiffness matrix, PSD
  struct Factor {
    std::vector<int> free_index;  // vertex -> row in the reduced system, -1 if constrained
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> llt;
  };
  std::map<std::vector<int>, std::unique_ptr<Factor>> cache;

  Impl(const Mesh& m, double r) : mesh(m), radius(r) {
    const int n = static_cast<int>(m.vertices.size());
    std::vector<Eigen::Triplet<double>> t;
    t.reserve(m.faces.size() * 12);
    for (const auto& f : m.faces)
      for (int k = 0; k < 3; ++k) {
        const int i = f[k], j = f[(k + 1) % 3], o = f[(k + 2) % 3];
        const Vec3 a = m.vertices[i] - m.vertices[o], b = m.vertices[j] - m.vertices[o];
        const double cr = norm(cross(a, b));
        const double cot = cr > 1e-12 ? dot(a, b) / cr : 0.0;
        const double w = 0.5 * cot;
        t.emplace_back(i, j, -w);
        t.emplace_back(j, i, -w);
        t.emplace_back(i, i, w);
        t.emplace_back(j, j, w);
      }
    L.resize(n, n);
    L.setFromTriplets(t.begin(), t.end());
  }
};

HarmonicFieldSolver::HarmonicFieldSolver(const Mesh& mesh, double r) : impl_(std::make_unique<Impl>(mesh, r)) {}
HarmonicFieldSolver::~HarmonicFieldSolver() = default;

std::size_t HarmonicFieldSolver::factorisations() const { return impl_->cache.size(); }

std::vector<int> HarmonicFieldSolver::disk(const Vec3& p) const {
  std::vector<int> out;
  int nearest = -1;
  double best = 1e300;
  const auto& V = impl_->mesh.vertices;
  for (std::size_t i = 0; i < V.size(); ++i) {
    const double d = distance(V[i], p);
    if (d <= impl_->radius) out.push_back(static_cast<int>(i));
    if (d < best) best = d, nearest = static_cast<int>(i);
  }
  if (out.empty() && nearest >= 0) out.push_back(nearest);
  return out;
}

std::vector<double> HarmonicFieldSolver::solve(const Vec3& a, const Vec3& b) {
  const std::vector<int> da = disk(a), db = disk(b);
  std::vector<int> key = da;
  key.insert(key.end(), db.begin(), db.end());
  std::sort(key.begin(), key.end());
  if (std::adjacent_find(key.begin(), key.end()) != key.end())
    throw std::invalid_argument("harmonic field: the two Dirichlet disks overlap");
  const int n = static_cast<int>(impl_->mesh.vertices.size());
  auto& slot = impl_->cache[key];
  if (!slot) {
    slot = std::make_unique<Impl::Factor>();
    slot->free_index.assign(n, 0);
    for (int v : key) slot->free_index[v] = -1;
    int nf = 0;
    for (int i = 0; i < n; ++i)
      if (slot->free_index[i] >= 0) slot->free_index[i] = nf++;
    std::vector<Eigen::Triplet<double>> t;
    for (int c = 0; c < impl_->L.outerSize(); ++c)
      for (Eigen::SparseMatrix<double>::InnerIterator it(impl_->L, c); it; ++it) {
        const int fi = slot->free_index[it.row()], fj = slot->free_index[it.col()];
        if (fi >= 0 && fj >= 0) t.emplace_back(fi, fj, it.value());
      }
    Eigen::SparseMatrix<double> A(nf, nf);
    A.setFromTriplets(t.begin(), t.end());
    slot->llt.compute(A);
    if (slot->llt.info() != Eigen::Success) throw std::runtime_error("harmonic field: factorisation failed");
  }
  std::vector<double> u(n, 0.0);
  for (int v : db) u[v] = 1.0;
  const auto& fi = slot->free_index;
  const int nf = static_cast<int>(std::count_if(fi.begin(), fi.end(), [](int x) { return x >= 0; }));
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(nf);
  for (int v : db)  // columns of the u = 1 vertices: rhs = -L_fc u_c
    for (Eigen::SparseMatrix<double>::InnerIterator it(impl_->L, v); it; ++it)
      if (fi[it.row()] >= 0) rhs[fi[it.row()]] -= it.value();
  const Eigen::VectorXd x = slot->llt.solve(rhs);
  for (int i = 0; i < n; ++i)
    if (fi[i] >= 0) u[i] = x[fi[i]];
  return u;
}

std::vector<Vec3> face_gradients(const Mesh& m, const std::vector<double>& u) {
  std::vector<Vec3> g(m.faces.size());
  for (std::size_t fi = 0; fi < m.faces.size(); ++fi) {
    const auto& f = m.faces[fi];
    const Vec3 &p0 = m.vertices[f[0]], &p1 = m.vertices[f[1]], &p2 = m.vertices[f[2]];
    const Vec3 c = cross(p1 - p0, p2 - p0);
    const double a2 = norm(c);  // twice the area
    if (a2 < 1e-14) {
      g[fi] = {0, 0, 0};
      continue;
    }
    const Vec3 n = (1.0 / a2) * c;
    const Vec3 e0 = p2 - p1, e1 = p0 - p2, e2 = p1 - p0;  // edges opposite 0, 1, 2 (counter-clockwise)
    g[fi] = (1.0 / a2) * (u[f[0]] * cross(n, e0) + u[f[1]] * cross(n, e1) + u[f[2]] * cross(n, e2));
  }
  return g;
}

}  // namespace ms::asymmetry
