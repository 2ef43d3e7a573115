// Harmonic fields on a triangle mesh (METHOD.md §3), Eigen sparse Cholesky.
// Shape after geometry-central's solvers: build once per mesh, factorise once
// per Dirichlet constraint set, reuse for every solve with that set.
#pragma once

#include <memory>
#include <utility>
#include <vector>

#include "core/types.h"

namespace ms::asymmetry {

class HarmonicFieldSolver {
 public:
  // disk_radius_mm: Dirichlet disks are the vertices within this Euclidean
  // distance of a landmark (at least its nearest vertex), so the field does not
  // depend on mesh resolution.
  explicit HarmonicFieldSolver(const Mesh& mesh, double disk_radius_mm = 2.0);
  ~HarmonicFieldSolver();
  HarmonicFieldSolver(const HarmonicFieldSolver&) = delete;
  HarmonicFieldSolver& operator=(const HarmonicFieldSolver&) = delete;

  // u = 0 on the disk around a, u = 1 on the disk around b, L u = 0 elsewhere.
  // Throws std::invalid_argument if the two disks overlap.
  std::vector<double> solve(const Vec3& a, const Vec3& b);
  // Prepare for these (a, b) pairs: one factorisation of the Laplacian outside
  // all their disks and its Schur complement onto the disk vertices, after
  // which solve() for any pair of prepared disks is a small dense solve and one
  // back-substitution (the same field as a factorisation per constraint set).
  // Optional: without it solve() factorises each constraint set on demand.
  void prepare(const std::vector<std::pair<Vec3, Vec3>>& pairs);
  // solve() on the prepared factorisation only: thread-safe; false (u
  // untouched) when a disk is outside the prepared ones.
  bool solve_prepared(const Vec3& a, const Vec3& b, std::vector<double>& u) const;
  std::vector<int> disk(const Vec3& p) const;
  std::size_t factorisations() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Heat-kernel smoothing on the surface: x = (M + t L)^-1 M r with lumped
// vertex areas M and the cotangent stiffness L, t = σ²/2 (σ in mm). Factorised
// once per mesh and σ; each smooth() is one back-substitution.
class SurfaceSmoother {
 public:
  SurfaceSmoother(const Mesh& mesh, double sigma_mm);
  ~SurfaceSmoother();
  SurfaceSmoother(const SurfaceSmoother&) = delete;
  SurfaceSmoother& operator=(const SurfaceSmoother&) = delete;
  std::vector<double> smooth(const std::vector<double>& per_vertex) const;
  // Heat-kernel circular mean of a per-face angle, weighted per face (the
  // face's area; 0 = masked): smoothed (cos, sin), so there is no branch cut at
  // ±π. Per-vertex angle in (-π, π], NaN where no weighted face is in reach.
  std::vector<double> smooth_face_angles(const std::vector<double>& angle, const std::vector<double>& weight) const;
  const std::vector<double>& vertex_areas() const;

 private:
  std::vector<double> solve_load(const std::vector<double>& load) const;  // (M + tL)^-1 load
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Per-face gradient of a piecewise-linear field: (1/2A) Σ u_i (n × e_i).
std::vector<Vec3> face_gradients(const Mesh& mesh, const std::vector<double>& u);

}  // namespace ms::asymmetry
