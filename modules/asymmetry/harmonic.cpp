#include "asymmetry/harmonic.h"

#include "asymmetry/measures.h"

#include <Eigen/Dense>
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

  Impl(const Mesh& m, double r) : mesh(m), radius(r), L(stiffness(m)) {}

  // The per-set path's shared ordering, computed on its first use.
  void ensure_order() {
    if (!perm.empty()) return;
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

  // Shared path (after prepare): one factorisation of the whole Laplacian with
  // the vertices D of every prepared disk eliminated last (F = the rest, in AMD
  // order). Its trailing block is the Schur complement S of F onto D, so a
  // constraint set C within D leaves the small dense harmonic system
  // S_OO u_O = -S_OC u_C on the other disks' vertices O, and the same factor
  // gives u_F = -L_FF^-1 L_FD u_D in one solve. The D block is shifted by eps
  // (L is singular: constants) and the shift taken back out of S exactly.
  // Same field as factorising each set, at one factorisation in all.
  struct Shared {
    std::vector<int> d_of;  // vertex -> index in D, or -1
    std::vector<int> row;   // vertex -> row of the permuted system (F first, D last)
    int nf = 0, nd = 0;
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower, Eigen::NaturalOrdering<int>> factor;
    Eigen::MatrixXd S_eps;  // Schur complement onto D with the shift (as factorised)
    Eigen::MatrixXd S;      // the true one
  };
  std::unique_ptr<Shared> shared;
  static constexpr double kShift = 1.0;

  bool build_shared(const std::vector<int>& disk_vertices) {
    auto sh = std::make_unique<Shared>();
    const int n = static_cast<int>(L.rows());
    sh->d_of.assign(n, -1);
    std::vector<int> d_vertex, f_vertex, f_of(n, -1);
    for (int v : disk_vertices)
      if (sh->d_of[v] < 0) sh->d_of[v] = static_cast<int>(d_vertex.size()), d_vertex.push_back(v);
    for (int v = 0; v < n; ++v)
      if (sh->d_of[v] < 0) f_of[v] = static_cast<int>(f_vertex.size()), f_vertex.push_back(v);
    sh->nf = static_cast<int>(f_vertex.size());
    sh->nd = static_cast<int>(d_vertex.size());
    if (sh->nf == 0 || sh->nd == 0) return false;
    // AMD order of L_FF, then D.
    std::vector<Eigen::Triplet<double>> tff;
    for (int c = 0; c < L.outerSize(); ++c)
      for (Eigen::SparseMatrix<double>::InnerIterator it(L, c); it; ++it)
        if (f_of[it.row()] >= 0 && f_of[c] >= 0) tff.emplace_back(f_of[it.row()], f_of[c], it.value());
    Eigen::SparseMatrix<double> LFF(sh->nf, sh->nf);
    LFF.setFromTriplets(tff.begin(), tff.end());
    Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> pinv;
    Eigen::AMDOrdering<int>()(LFF, pinv);
    const Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> pf = pinv.inverse();
    sh->row.assign(n, -1);
    for (int i = 0; i < sh->nf; ++i) sh->row[f_vertex[i]] = pf.indices()[i];
    for (int j = 0; j < sh->nd; ++j) sh->row[d_vertex[j]] = sh->nf + j;
    std::vector<Eigen::Triplet<double>> t;
    t.reserve(static_cast<std::size_t>(L.nonZeros()) + d_vertex.size());
    for (int c = 0; c < L.outerSize(); ++c)
      for (Eigen::SparseMatrix<double>::InnerIterator it(L, c); it; ++it) t.emplace_back(sh->row[it.row()], sh->row[c], it.value());
    for (int j = 0; j < sh->nd; ++j) t.emplace_back(sh->nf + j, sh->nf + j, kShift);
    Eigen::SparseMatrix<double> A(n, n);
    A.setFromTriplets(t.begin(), t.end());
    sh->factor.compute(A);
    if (sh->factor.info() != Eigen::Success) return false;
    // Trailing block of the factor: S_eps = L_DD diag(d_D) L_DD^T.
    Eigen::MatrixXd Ld = Eigen::MatrixXd::Identity(sh->nd, sh->nd);
    const auto& Lf = sh->factor.matrixL().nestedExpression();
    for (int c = sh->nf; c < n; ++c)
      for (Eigen::SparseMatrix<double>::InnerIterator it(Lf, c); it; ++it)
        if (it.row() > c) Ld(it.row() - sh->nf, c - sh->nf) = it.value();
    const Eigen::VectorXd dd = sh->factor.vectorD().tail(sh->nd);
    sh->S_eps = Ld * dd.asDiagonal() * Ld.transpose();
    sh->S = sh->S_eps - kShift * Eigen::MatrixXd::Identity(sh->nd, sh->nd);
    shared = std::move(sh);
    return true;
  }

  // The field for constraint set (da = 0, db = 1) on the shared path; false
  // when a disk vertex is outside the prepared disks.
  bool solve_shared(const std::vector<int>& da, const std::vector<int>& db, std::vector<double>& u) const {
    if (!shared) return false;
    const Shared& sh = *shared;
    const int nd = sh.nd;
    std::vector<int> role(nd, 0);  // 0 free, 1 fixed at 0, 2 fixed at 1
    for (int v : da) {
      if (sh.d_of[v] < 0) return false;
      role[sh.d_of[v]] = 1;
    }
    for (int v : db) {
      if (sh.d_of[v] < 0) return false;
      role[sh.d_of[v]] = 2;
    }
    std::vector<int> free;
    for (int j = 0; j < nd; ++j)
      if (!role[j]) free.push_back(j);
    Eigen::VectorXd ud = Eigen::VectorXd::Zero(nd);
    for (int j = 0; j < nd; ++j)
      if (role[j] == 2) ud[j] = 1.0;
    if (!free.empty()) {
      const int no = static_cast<int>(free.size());
      Eigen::MatrixXd So(no, no);
      Eigen::VectorXd rhs = Eigen::VectorXd::Zero(no);
      for (int a = 0; a < no; ++a) {
        for (int b = 0; b < no; ++b) So(a, b) = sh.S(free[a], free[b]);
        for (int j = 0; j < nd; ++j)
          if (role[j] == 2) rhs[a] -= sh.S(free[a], j);
      }
      const Eigen::VectorXd uo = So.ldlt().solve(rhs);
      for (int a = 0; a < no; ++a) ud[free[a]] = uo[a];
    }
    // A [x_F; x_D] = [0; S_eps u_D] has x_D = u_D and x_F = -L_FF^-1 L_FD u_D.
    const int n = static_cast<int>(L.rows());
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(n);
    rhs.tail(nd) = sh.S_eps * ud;
    const Eigen::VectorXd x = sh.factor.solve(rhs);
    u.resize(static_cast<std::size_t>(n));
    for (int v = 0; v < n; ++v) u[static_cast<std::size_t>(v)] = sh.d_of[v] >= 0 ? ud[sh.d_of[v]] : x[sh.row[v]];
    return true;
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

std::size_t HarmonicFieldSolver::factorisations() const { return impl_->cache.size() + (impl_->shared ? 1 : 0); }

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
  // Every disk of every pair goes into one shared factorisation; pairs whose
  // disks overlap are left to solve(), which reports them.
  std::vector<int> all;
  for (const auto& [a, b] : pairs) {
    const auto da = disk(a), db = disk(b);
    try {
      Impl::key(da, db);
    } catch (const std::invalid_argument&) {
      continue;
    }
    all.insert(all.end(), da.begin(), da.end());
    all.insert(all.end(), db.begin(), db.end());
  }
  std::sort(all.begin(), all.end());
  all.erase(std::unique(all.begin(), all.end()), all.end());
  impl_->shared.reset();
  if (!all.empty()) impl_->build_shared(all);  // on failure solve() factorises per set
}

bool HarmonicFieldSolver::solve_prepared(const Vec3& a, const Vec3& b, std::vector<double>& u) const {
  const std::vector<int> da = disk(a), db = disk(b);
  Impl::key(da, db);  // throws for overlapping disks
  return impl_->solve_shared(da, db, u);
}

std::vector<double> HarmonicFieldSolver::solve(const Vec3& a, const Vec3& b) {
  const std::vector<int> da = disk(a), db = disk(b);
  const auto k = Impl::key(da, db);
  {
    std::vector<double> u;
    if (impl_->solve_shared(da, db, u)) return u;
  }
  impl_->ensure_order();
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
