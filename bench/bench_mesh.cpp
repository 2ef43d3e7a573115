// Kernels of the VTK / CGAL / Ceres / Eigen-facing stages (the Eigen side of
// the ITK / Eigen split, ENGINEERING.md): marching cubes and CGAL repair /
// remeshing, edge-graph Dijkstra and landmark detection, the Ceres plane fit
// with mirror-ICP, harmonic solves, heat-kernel smoothing, the full SAF score,
// the SRD descriptors, mirror distance, and the report's 3D views and mesh
// writers. Only the stages' value-type headers are included; nothing here may
// include ITK.
#include <benchmark/benchmark.h>

#include <cstdio>
#include <limits>
#include <string>
#include <vector>

#include "asymmetry/harmonic.h"
#include "asymmetry/measures.h"
#include "asymmetry/saf.h"
#include "asymmetry/srd.h"
#include "bench/fixtures.h"
#include "bench/registry.h"
#include "geometry/mesh_geometry.h"
#include "landmarks/landmarks.h"
#include "reference/reference.h"
#include "reports/display.h"
#include "reports/render.h"
#include "surface/surface.h"

namespace ms::bench {

namespace {

struct MeshSize {
  const char* label;  // nominal vertex count in benchmark names; the "vertices" counter has the real one
  double edge_mm;
};
const MeshSize kMeshSizes[] = {{"mesh35k", kEdgeDefault}, {"mesh50k", kEdgeFor50k}};

void mesh_counters(benchmark::State& state, const Mesh& mesh) {
  state.counters["vertices"] = static_cast<double>(mesh.vertices.size());
  state.counters["faces"] = static_cast<double>(mesh.faces.size());
}

// ---- surface stage -------------------------------------------------------

// Flying edges + decimation only (target_edge_mm = 0: no CGAL).
surface::Options marching_cubes_only() {
  surface::Options o;
  o.target_edge_mm = 0;
  return o;
}

void marching_cubes(benchmark::State& state, double spacing_mm) {
  const Mask& mask = head_phantom(spacing_mm).mandible;
  surface::Result r;
  for (auto _ : state) {
    r = surface::mesh_from_mask(mask, marching_cubes_only());
    benchmark::DoNotOptimize(r.mesh.vertices.data());
  }
  state.counters[kVoxelsCounter] = static_cast<double>(mask.geom.voxel_count());
  mesh_counters(state, r.mesh);
}

void repair_remesh(benchmark::State& state, double spacing_mm) {
  const Mesh raw = surface::mesh_from_mask(head_phantom(spacing_mm).mandible, marching_cubes_only()).mesh;
  Mesh m;
  for (auto _ : state) {
    state.PauseTiming();
    m = raw;
    state.ResumeTiming();
    surface::repair_and_remesh(m);
    benchmark::DoNotOptimize(m.vertices.data());
  }
  state.counters["input_vertices"] = static_cast<double>(raw.vertices.size());
  mesh_counters(state, m);
}

void surface_stage(benchmark::State& state, double spacing_mm) {
  const Mask& mask = head_phantom(spacing_mm).mandible;
  surface::Result r;
  for (auto _ : state) {
    r = surface::mesh_from_mask(mask);
    benchmark::DoNotOptimize(r.mesh.vertices.data());
  }
  state.counters[kVoxelsCounter] = static_cast<double>(mask.geom.voxel_count());
  mesh_counters(state, r.mesh);
}

// ---- landmarks -----------------------------------------------------------

void dijkstra_full(benchmark::State& state, double edge_mm) {
  const Mesh& mesh = mandible_mesh(edge_mm).mesh();
  const geometry::EdgeGraph graph = geometry::edge_graph(mesh);
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<double> dist(mesh.vertices.size());
  for (auto _ : state) {
    std::fill(dist.begin(), dist.end(), inf);
    geometry::dijkstra(graph, {0}, inf, dist);
    benchmark::DoNotOptimize(dist.data());
  }
  mesh_counters(state, mesh);
}

void edge_graph(benchmark::State& state, double edge_mm) {
  const Mesh& mesh = mandible_mesh(edge_mm).mesh();
  for (auto _ : state) {
    auto g = geometry::edge_graph(mesh);
    benchmark::DoNotOptimize(g.nbr.data());
  }
  mesh_counters(state, mesh);
}

void detect_landmarks(benchmark::State& state, double edge_mm) {
  const Mesh& mesh = mandible_mesh(edge_mm).mesh();
  for (auto _ : state) {
    auto r = landmarks::detect(mesh);
    benchmark::DoNotOptimize(r.landmarks.points.data());
  }
  mesh_counters(state, mesh);
}

// ---- reference (Ceres) ---------------------------------------------------

void plane_fit(benchmark::State& state, double edge_mm, bool mirror_icp) {
  const MeshCase& c = mandible_mesh(edge_mm);
  reference::Options o;
  o.refine_on_surface = mirror_icp;
  for (auto _ : state) {
    auto r = reference::fit(c.landmarks.landmarks, &c.mesh(), o);
    benchmark::DoNotOptimize(r.plane.normal.data());
  }
  mesh_counters(state, c.mesh());
}

// ---- asymmetry (Eigen) ---------------------------------------------------

// Disk centres as the pipeline places them (reference configuration).
LandmarkSet anchors(const MeshCase& c) { return asymmetry::saf_anchors(c.landmarks.landmarks, c.reference.reference); }

// The (Co_L, Me) disk centres of the harmonic kernels; skips the benchmark
// when the mesh lacks either.
bool co_me_disks(benchmark::State& state, const LandmarkSet& lm, const Vec3*& a, const Vec3*& b) {
  a = lm.find("Co_L");
  b = lm.find("Me");
  if (a && b) return true;
  state.SkipWithError("Co_L or Me not detected on the benchmark mesh");
  return false;
}

// One harmonic field from scratch: Laplacian assembly, one factorisation of
// the Dirichlet set (Co_L, Me), one solve.
void harmonic_field(benchmark::State& state, double edge_mm) {
  const MeshCase& c = mandible_mesh(edge_mm);
  const LandmarkSet lm = anchors(c);
  const Vec3 *a = nullptr, *b = nullptr;
  if (!co_me_disks(state, lm, a, b)) return;
  for (auto _ : state) {
    asymmetry::HarmonicFieldSolver solver(c.mesh());
    auto u = solver.solve(*a, *b);
    benchmark::DoNotOptimize(u.data());
  }
  mesh_counters(state, c.mesh());
}

// Back-substitution only: the constraint set is factorised before timing.
void harmonic_resolve(benchmark::State& state, double edge_mm) {
  const MeshCase& c = mandible_mesh(edge_mm);
  const LandmarkSet lm = anchors(c);
  const Vec3 *a = nullptr, *b = nullptr;
  if (!co_me_disks(state, lm, a, b)) return;
  asymmetry::HarmonicFieldSolver solver(c.mesh());
  solver.prepare({{*a, *b}});
  for (auto _ : state) {
    auto u = solver.solve(*a, *b);
    benchmark::DoNotOptimize(u.data());
  }
  mesh_counters(state, c.mesh());
}

// Heat-kernel smoother at the SAF's default sigma: factorisation + one smooth.
void heat_smoother(benchmark::State& state, double edge_mm) {
  const Mesh& mesh = mandible_mesh(edge_mm).mesh();
  const double sigma = asymmetry::SafOptions{}.smoothing_mm;
  std::vector<double> r(mesh.vertices.size());
  for (std::size_t i = 0; i < r.size(); ++i) r[i] = mesh.vertices[i][0];
  for (auto _ : state) {
    asymmetry::SurfaceSmoother s(mesh, sigma);
    auto x = s.smooth(r);
    benchmark::DoNotOptimize(x.data());
  }
  mesh_counters(state, mesh);
}

// The full SAF score with every default configuration (issue F's budget).
void saf(benchmark::State& state, double edge_mm) {
  const MeshCase& c = mandible_mesh(edge_mm);
  const LandmarkSet lm = anchors(c);
  asymmetry::SafResult r;
  for (auto _ : state) {
    r = asymmetry::compute_saf(c.mesh(), lm, c.reference.plane);
    benchmark::DoNotOptimize(r.per_vertex.data());
  }
  mesh_counters(state, c.mesh());
  state.counters["configurations"] = static_cast<double>(r.per_configuration.size());
  state.counters["factorisations"] = static_cast<double>(r.factorisations);
}

// SRD descriptors from the angle fields of one SAF run (timed: the SRDs only).
void srd(benchmark::State& state, double edge_mm) {
  const MeshCase& c = mandible_mesh(edge_mm);
  asymmetry::SafOptions o;
  o.keep_fields = true;
  const auto fields = asymmetry::compute_saf(c.mesh(), anchors(c), c.reference.plane, o);
  for (auto _ : state) {
    auto r = asymmetry::compute_srds(c.mesh(), fields);
    benchmark::DoNotOptimize(&r);
  }
  mesh_counters(state, c.mesh());
}

void mirror_distance(benchmark::State& state, double edge_mm) {
  const MeshCase& c = mandible_mesh(edge_mm);
  for (auto _ : state) {
    const auto regions = asymmetry::assign_regions(c.mesh(), c.landmarks.landmarks);
    auto r = asymmetry::mirror_distance(c.mesh(), c.reference.plane, regions, &c.landmarks.landmarks);
    benchmark::DoNotOptimize(r.per_vertex.data());
  }
  mesh_counters(state, c.mesh());
}

// ---- report --------------------------------------------------------------

// Four 3D views (front, below, left, right) of one colour map; the pipeline
// renders two maps.
void render_views(benchmark::State& state, double edge_mm) {
  std::string why;
  if (!reports::ensure_display(&why)) {
    state.SkipWithError(("no display for VTK: " + why).c_str());
    return;
  }
  const MeshCase& c = mandible_mesh(edge_mm);
  std::vector<double> values(c.mesh().vertices.size());
  for (std::size_t i = 0; i < values.size(); ++i) values[i] = c.reference.plane.signed_distance(c.mesh().vertices[i]);
  const std::string prefix = (scratch_dir() / "view").string();
  for (auto _ : state) {
    const auto rv = reports::render_views(c.mesh(), values, {"signed distance to plane (mm)", -60, 60, true},
                                          c.landmarks.landmarks, c.reference.plane, prefix);
    if (!rv.error.empty()) {
      state.SkipWithError(("render_views: " + rv.error).c_str());
      break;
    }
  }
  mesh_counters(state, c.mesh());
}

void write_mesh_files(benchmark::State& state, double edge_mm) {
  const Mesh& mesh = mandible_mesh(edge_mm).mesh();
  const surface::PointArrays arrays{{"values", std::vector<double>(mesh.vertices.size(), 1.0)}};
  const auto base = scratch_dir() / "mandible";
  for (auto _ : state) {
    surface::write_vtp(mesh, arrays, base.string() + ".vtp");
    surface::write_stl(mesh, base.string() + ".stl");
    surface::write_ply(mesh, base.string() + ".ply");
  }
  mesh_counters(state, mesh);
}

std::string spacing_label(double mm) {
  char b[32];
  std::snprintf(b, sizeof b, "%.1fmm", mm);
  return b;
}

template <class F, class... Args>
void reg(const std::string& name, F f, Args... args) {
  benchmark::RegisterBenchmark(name.c_str(), f, args...)->Unit(benchmark::kMillisecond)->UseRealTime();
}

}  // namespace

void register_mesh_kernels() {
  for (double mm : volume_spacings_mm()) {
    reg("surface/marching_cubes/" + spacing_label(mm), marching_cubes, mm);
    reg("surface/repair_remesh/" + spacing_label(mm), repair_remesh, mm);
    reg("surface/mesh_from_mask/" + spacing_label(mm), surface_stage, mm);
  }
  const MeshSize& m35 = kMeshSizes[0];
  reg(std::string("landmarks/edge_graph/") + m35.label, edge_graph, m35.edge_mm);
  reg(std::string("landmarks/dijkstra_full/") + m35.label, dijkstra_full, m35.edge_mm);
  for (const MeshSize& m : kMeshSizes) reg(std::string("landmarks/detect/") + m.label, detect_landmarks, m.edge_mm);
  for (const MeshSize& m : kMeshSizes) {
    reg(std::string("reference/fit_landmarks/") + m.label, plane_fit, m.edge_mm, false);
    reg(std::string("reference/fit_mirror_icp/") + m.label, plane_fit, m.edge_mm, true);
  }
  for (const MeshSize& m : kMeshSizes) {
    reg(std::string("asymmetry/harmonic_field/") + m.label, harmonic_field, m.edge_mm);
    reg(std::string("asymmetry/harmonic_resolve/") + m.label, harmonic_resolve, m.edge_mm);
    reg(std::string("asymmetry/heat_smoother/") + m.label, heat_smoother, m.edge_mm);
    reg(std::string("asymmetry/saf/") + m.label, saf, m.edge_mm);
    reg(std::string("asymmetry/srd/") + m.label, srd, m.edge_mm);
    reg(std::string("asymmetry/mirror_distance/") + m.label, mirror_distance, m.edge_mm);
  }
  reg(std::string("report/render_views/") + m35.label, render_views, m35.edge_mm);
  reg(std::string("report/write_mesh_files/") + m35.label, write_mesh_files, m35.edge_mm);
}

}  // namespace ms::bench
