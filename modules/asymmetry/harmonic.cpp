#include "asymmetry/harmonic.h"

#include "asymmetry/measures.h"

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <Eigen/OrderingMethods>

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>

namespace ms::asymmetry {
namespace {

// Cotangent stiffness matrix (symmetric PSD): ½ Σ (cot α + cot β) per edge.
Eigen::SparseMatrix<double> stiffness(const Mesh& m) {
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
  Eigen::SparseMatrix<double> L(n, n);
  L.setFromTriplets(t.begin(), t.end());
  return L;
}

}  // namespace

struct HarmonicFieldSolver::Impl {
  const Mesh& mesh;
  double radius;
  Eigen::SparseMatrix<double> L;   // cotangent stiffness matrix, PSD
  std::vector<int> perm;           // vertex -> row of the fill-reducing (AMD) order, computed once
  Eigen::SparseMatrix<double> Lp;  // L in that order (both triangles)
  // One factor per Dirichlet set: the full system in AMD order with the
  // constrained rows and columns replaced by the identity, so every set shares
  // the ordering and only the numeric factorisation is repeated.
  using Ldlt = Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower, Eigen::NaturalOrdering<int>>;
  std::map<std::vector<int>, std::unique_ptr<Ldlt>> cache;

  Impl(const Mesh& m, double r) : mesh(m), radius(r), L(stiffness(m)) {
    Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> pinv;
    Eigen::AMDOrdering<int>()(L, pinv);
    const Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> p = pinv.inverse();
    perm.assign(p.indices().data(), p.indices().data() + p.size());
    Lp = L.twistedBy(p);
  }

  std::unique_ptr<Ldlt> factorise(const std::vector<int>& constrained) const {
    std::vector<char> fixed(L.rows(), 0);
    for (int v : constrained) fixed[perm[v]] = 1;
    Eigen::SparseMatrix<double> A = Lp;
    for (int c = 0; c < A.outerSize(); ++c)
      for (Eigen::SparseMatrix<double>::InnerIterator it(A, c); it; ++it)
        if (fixed[it.row()] || fixed[it.col()]) it.valueRef() = it.row() == it.col() ? 1.0 : 0.0;
    auto f = std::make_unique<Ldlt>(A);
    if (f->info() != Eigen::Success) throw std::runtime_error("harmonic field: factorisation failed");
    return f;
  }

  static std::vector<int> key(const std::vector<int>& da, const std::vector<int>& db) {
    std::vector<int> k = da;
    k.insert(k.end(), db.begin(), db.end());
    std::sort(k.begin(), k.end());
    if (std::adjacent_find(k.begin(), k.end()) != k.end())
      throw std::invalid_argument("harmonic field: the two Dirichlet disks overlap");
    return k;
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

void HarmonicFieldSolver::prepare(const std::vector<std::pair<Vec3, Vec3>>& pairs) {
  std::vector<std::vector<int>> todo;
  for (const auto& [a, b] : pairs) {
    std::vector<int> k;
    try {
      k = Impl::key(disk(a), disk(b));
    } catch (const std::invalid_argument&) {
      continue;  // solve() reports it for that pair
    }
    if (!impl_->cache.count(k) && std::find(todo.begin(), todo.end(), k) == todo.end()) todo.push_back(std::move(k));
  }
  std::vector<std::unique_ptr<Impl::Ldlt>> done(todo.size());
#pragma omp parallel for schedule(dynamic)
  for (int i = 0; i < static_cast<int>(todo.size()); ++i) {
    try {
      done[i] = impl_->factorise(todo[i]);
    } catch (const std::exception&) {
      // left out: solve() factorises again and reports the failure for that pair
    }
  }
  for (std::size_t i = 0; i < todo.size(); ++i)
    if (done[i]) impl_->cache[todo[i]] = std::move(done[i]);
}

std::vector<double> HarmonicFieldSolver::solve(const Vec3& a, const Vec3& b) {
  const std::vector<int> da = disk(a), db = disk(b);
  const auto k = Impl::key(da, db);
  auto& slot = impl_->cache[k];
  if (!slot) slot = impl_->factorise(k);
  const int n = static_cast<int>(impl_->mesh.vertices.size());
  const auto& perm = impl_->perm;
  std::vector<char> fixed(n, 0);
  for (int v : k) fixed[v] = 1;
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(n);  // in AMD order
  for (int v : db) {
    rhs[perm[v]] = 1.0;
    for (Eigen::SparseMatrix<double>::InnerIterator it(impl_->L, v); it; ++it)  // -L_fc u_c
      if (!fixed[it.row()]) rhs[perm[it.row()]] -= it.value();
  }
  const Eigen::VectorXd x = slot->solve(rhs);
  std::vector<double> u(n);
  for (int i = 0; i < n; ++i) u[i] = x[perm[i]];
  return u;
}

struct SurfaceSmoother::Impl {
  explicit Impl(const Mesh& m) : mesh(m) {}
  const Mesh& mesh;
  std::vector<double> area;  // lumped: one third of the incident faces
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver;
};

SurfaceSmoother::SurfaceSmoother(const Mesh& mesh, double sigma) : impl_(std::make_unique<Impl>(mesh)) {
  impl_->area = asymmetry::vertex_areas(mesh);
  Eigen::SparseMatrix<double> S = (0.5 * sigma * sigma) * stiffness(mesh);
  for (int i = 0; i < S.rows(); ++i) S.coeffRef(i, i) += std::max(impl_->area[i], 1e-12);
  impl_->solver.compute(S);
  if (impl_->solver.info() != Eigen::Success) throw std::runtime_error("surface smoothing: factorisation failed");
}
SurfaceSmoother::~SurfaceSmoother() = default;
const std::vector<double>& SurfaceSmoother::vertex_areas() const { return impl_->area; }

std::vector<double> SurfaceSmoother::solve_load(const std::vector<double>& b) const {
  const Eigen::VectorXd x = impl_->solver.solve(Eigen::Map<const Eigen::VectorXd>(b.data(), static_cast<Eigen::Index>(b.size())));
  return std::vector<double>(x.data(), x.data() + x.size());
}

std::vector<double> SurfaceSmoother::smooth(const std::vector<double>& r) const {
  std::vector<double> b(r.size());
  for (std::size_t i = 0; i < r.size(); ++i) b[i] = impl_->area[i] * r[i];
  return solve_load(b);
}

std::vector<double> SurfaceSmoother::smooth_face_angles(const std::vector<double>& angle,
                                                        const std::vector<double>& weight) const {
  // Loads M·r of the per-face (sin, cos, 1)·weight spread a third to each
  // corner; the kernel's normalisation cancels in atan2, the weight's smoothed
  // load only tells where no face is in reach.
  const auto& m = impl_->mesh;
  const std::size_t n = m.vertices.size();
  std::vector<double> sn(n, 0.0), cs(n, 0.0), w(n, 0.0);
  for (std::size_t f = 0; f < m.faces.size(); ++f) {
    if (!(weight[f] > 0) || !std::isfinite(angle[f])) continue;
    const double ws = weight[f] * std::sin(angle[f]) / 3.0, wc = weight[f] * std::cos(angle[f]) / 3.0;
    for (int k = 0; k < 3; ++k) {
      sn[m.faces[f][k]] += ws;
      cs[m.faces[f][k]] += wc;
      w[m.faces[f][k]] += weight[f] / 3.0;
    }
  }
  const auto ss = solve_load(sn), sc = solve_load(cs), sw = solve_load(w);
  std::vector<double> out(n, std::nan(""));
  for (std::size_t i = 0; i < n; ++i)
    if (sw[i] > 1e-6) out[i] = std::atan2(ss[i], sc[i]);
  return out;
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
