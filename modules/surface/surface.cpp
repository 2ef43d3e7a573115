#include "surface/surface.h"
#include "surface/vtk_mesh.h"

#include <vtkCellArray.h>
#include <vtkCleanPolyData.h>
#include <vtkDoubleArray.h>
#include <vtkFlyingEdges3D.h>
#include <vtkImageData.h>
#include <vtkImageGaussianSmooth.h>
#include <vtkIntArray.h>

#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkPolyDataConnectivityFilter.h>
#include <vtkQuadricDecimation.h>
#include <vtkSmartPointer.h>
#include <vtkTriangleFilter.h>
#include <vtkXMLPolyDataReader.h>
#include <vtkXMLPolyDataWriter.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <cmath>
#include <limits>
#include <unordered_map>
#include <vector>

#include "core/components.h"
#include "core/debug_lap.h"
#include "core/distance_transform.h"
#include "core/error.h"
#include "core/files.h"
#include "core/topology.h"

namespace ms::surface {
namespace {

template <class T>
using Ptr = vtkSmartPointer<T>;

// MANDISYM_DEBUG_SURFACE=1: time of each step on stderr (profiling aid).
struct SurfaceLap : DebugLap {
  SurfaceLap() : DebugLap("MANDISYM_DEBUG_SURFACE", "surface") {}
};

Mesh from_vtk(vtkPolyData* pd) {
  Mesh m;
  m.vertices.resize(static_cast<std::size_t>(pd->GetNumberOfPoints()));
  for (vtkIdType i = 0; i < pd->GetNumberOfPoints(); ++i) pd->GetPoint(i, m.vertices[static_cast<std::size_t>(i)].data());
  auto* polys = pd->GetPolys();
  polys->InitTraversal();
  vtkIdType n;
  const vtkIdType* ids;
  while (polys->GetNextCell(n, ids))
    if (n == 3) m.faces.push_back({static_cast<int>(ids[0]), static_cast<int>(ids[1]), static_cast<int>(ids[2])});
  return m;
}

}  // namespace

vtkSmartPointer<vtkPolyData> to_polydata(const Mesh& m) {
  auto pts = Ptr<vtkPoints>::New();
  pts->SetDataTypeToDouble();
  pts->SetNumberOfPoints(static_cast<vtkIdType>(m.vertices.size()));
  for (std::size_t i = 0; i < m.vertices.size(); ++i) pts->SetPoint(static_cast<vtkIdType>(i), m.vertices[i].data());
  auto cells = Ptr<vtkCellArray>::New();
  for (const auto& f : m.faces) {
    const vtkIdType ids[3] = {f[0], f[1], f[2]};
    cells->InsertNextCell(3, ids);
  }
  auto pd = Ptr<vtkPolyData>::New();
  pd->SetPoints(pts);
  pd->SetPolys(cells);
  return pd;
}

MeshStats measure(const Mesh& m) {
  MeshStats s;
  s.vertices = m.vertices.size();
  s.faces = m.faces.size();
  std::unordered_map<std::uint64_t, int> edges;
  edges.reserve(m.faces.size() * 2);
  for (const auto& f : m.faces) {
    const Vec3 &a = m.vertices[f[0]], &b = m.vertices[f[1]], &c = m.vertices[f[2]];
    s.area_mm2 += 0.5 * norm(cross(b - a, c - a));
    s.volume_mm3 += dot(a, cross(b, c)) / 6.0;
    for (int e = 0; e < 3; ++e) {
      std::uint64_t u = static_cast<std::uint32_t>(f[e]), v = static_cast<std::uint32_t>(f[(e + 1) % 3]);
      if (u > v) std::swap(u, v);
      ++edges[(u << 32) | v];
    }
  }
  bool closed = !m.faces.empty(), manifold = true;
  for (const auto& [key, count] : edges) {
    if (count != 2) closed = false;
    if (count > 2) manifold = false;
  }
  s.closed = closed;
  s.manifold = manifold;
  if (closed) {
    const long chi = static_cast<long>(s.vertices) - static_cast<long>(edges.size()) + static_cast<long>(s.faces);
    s.genus = static_cast<int>((2 - chi) / 2);
  }
  return s;
}

// Topology and orientation of a result: measure, flip to outward if needed.
static void measure_outward(Result& r) {
  r.stats = measure(r.mesh);
  if (r.stats.volume_mm3 < 0) {  // mirror-handed grid or inward faces: flip to outward
    for (auto& f : r.mesh.faces) std::swap(f[1], f[2]);
    r.stats.volume_mm3 = -r.stats.volume_mm3;
  }
}

// CGAL repair and isotropic remeshing of a raw surface, then measure again.
static void finish(Result& r, const Options& opt) {
  if (opt.target_edge_mm <= 0) return;
  RepairOptions ro;
  ro.target_edge_mm = opt.target_edge_mm;
  ro.remesh_iterations = opt.remesh_iterations;
  SurfaceLap lap;
  r.repair = repair_and_remesh(r.mesh, ro);
  lap("CGAL repair + remesh");
  if (r.mesh.faces.empty()) throw Error(ExitCode::GeometryFailed, "surface repair left no triangles");
  measure_outward(r);
}

// Closing of a 0/1 float image by a ball of radius r mm (core/distance_transform);
// plugs_only keeps only what changes its topology (core/topology), thickened
// to a millimetre (at least a voxel) so that the smoothing keeps them whole.
// Returns the number of voxels it added.
static std::size_t close_binary(float* buf, const int dims[3], const double spacing[3], double r, bool plugs_only) {
  const Dims3 d{static_cast<std::size_t>(dims[0]), static_cast<std::size_t>(dims[1]), static_cast<std::size_t>(dims[2])};
  const long n = static_cast<long>(d[0] * d[1] * d[2]);
  std::vector<std::uint8_t> m(static_cast<std::size_t>(n));
#pragma omp parallel for schedule(static)
  for (long i = 0; i < n; ++i) m[static_cast<std::size_t>(i)] = buf[i] > 0.5f;
  const auto ones = [&] { return static_cast<std::size_t>(std::count(m.begin(), m.end(), std::uint8_t{1})); };
  const std::size_t before = ones();
  const std::array<double, 3> s{spacing[0], spacing[1], spacing[2]};
  if (plugs_only) {
    const std::vector<std::uint8_t> original = m;
    close_euclidean(m, d, s, r);
    keep_closing_plugs(m, original, d, s, r, std::max({1.0, s[0], s[1], s[2]}));
  } else {
    close_euclidean(m, d, s, r);
  }
#pragma omp parallel for schedule(static)
  for (long i = 0; i < n; ++i) buf[i] = m[static_cast<std::size_t>(i)] ? 1.0f : 0.0f;
  return ones() - before;  // a closing only adds
}

// Bins per axis for contouring (Options::max_contour_spacing_mm): the most
// with f * spacing <= max_contour_spacing_mm whose box blur ((f^2 - 1) / 12
// spacing^2, the variance of f point samples) is at most half the Gaussian's.
static std::array<int, 3> contour_bins(const Vec3& spacing, const Options& opt) {
  std::array<int, 3> f{1, 1, 1};
  if (opt.max_contour_spacing_mm <= 0) return f;
  const double var = opt.smoothing_sigma_mm * opt.smoothing_sigma_mm;
  for (int a = 0; a < 3; ++a)
    while ((f[a] + 1) * spacing[a] <= opt.max_contour_spacing_mm + 1e-9 &&
           ((f[a] + 1) * (f[a] + 1) - 1) / 12.0 * spacing[a] * spacing[a] <= 0.5 * var)
      ++f[a];
  return f;
}

// Mean of each f[0] x f[1] x f[2] block of img (blocks past the end average
// the voxels they hold), on a grid whose voxel I is centred where its block
// is: origin (f - 1) / 2 voxels in, spacing f voxels. (vtkImageShrink3D with
// averaging keeps the block's first voxel as the sample's position: a half
// block, 0.2 mm at 0.45 mm voxels, off.)
static vtkSmartPointer<vtkImageData> binned(vtkImageData* img, const std::array<int, 3>& f) {
  int d[3];
  img->GetDimensions(d);
  double s[3], o[3];
  img->GetSpacing(s);
  img->GetOrigin(o);
  int n[3];
  for (int a = 0; a < 3; ++a) n[a] = (d[a] + f[a] - 1) / f[a];
  auto out = Ptr<vtkImageData>::New();
  out->SetDimensions(n);
  out->SetSpacing(f[0] * s[0], f[1] * s[1], f[2] * s[2]);
  out->SetOrigin(o[0] + 0.5 * (f[0] - 1) * s[0], o[1] + 0.5 * (f[1] - 1) * s[1], o[2] + 0.5 * (f[2] - 1) * s[2]);
  out->AllocateScalars(VTK_FLOAT, 1);
  const auto* in = static_cast<const float*>(img->GetScalarPointer());
  auto* b = static_cast<float*>(out->GetScalarPointer());
  const std::size_t dx = static_cast<std::size_t>(d[0]), dxy = dx * static_cast<std::size_t>(d[1]);
  for (int K = 0; K < n[2]; ++K)
    for (int J = 0; J < n[1]; ++J)
      for (int I = 0; I < n[0]; ++I) {
        float sum = 0;
        int count = 0;
        for (int k = K * f[2]; k < std::min(d[2], (K + 1) * f[2]); ++k)
          for (int j = J * f[1]; j < std::min(d[1], (J + 1) * f[1]); ++j)
            for (int i = I * f[0]; i < std::min(d[0], (I + 1) * f[0]); ++i, ++count)
              sum += in[static_cast<std::size_t>(i) + dx * static_cast<std::size_t>(j) + dxy * static_cast<std::size_t>(k)];
        b[I + static_cast<std::size_t>(n[0]) * (J + static_cast<std::size_t>(n[1]) * K)] = sum / static_cast<float>(count);
      }
  return out;
}

// Flying-edges surface of a mask (after the optional closing), in index-space
// millimetres of a crop starting pad voxels before index lo.
struct Contour {
  vtkSmartPointer<vtkPolyData> pd;  // null when skipped (contour(): unchanged_is_enough)
  std::array<long, 3> lo{0, 0, 0};
  long pad = 0;
  std::array<long, 3> dims{0, 0, 0};
  std::vector<std::uint8_t> solid;  // the 0/1 crop as contoured (after any closing, before guiding)
  std::size_t closing_added = 0;    // voxels the closing added
};

// Index bounding box of a mask's voxels (hi[0] < 0 when empty); slices in
// parallel (a 512 x 512 x 300 mask is 78 M voxels to look at).
using Box = std::pair<std::array<long, 3>, std::array<long, 3>>;
static Box mask_box(const Mask& mask) {
  const Geometry& g = mask.geom;
  const long nx = static_cast<long>(g.size[0]), ny = static_cast<long>(g.size[1]), nz = static_cast<long>(g.size[2]);
  std::vector<std::array<long, 4>> slice(static_cast<std::size_t>(nz), {nx, -1, ny, -1});  // x lo, x hi, y lo, y hi
#pragma omp parallel for schedule(static)
  for (long k = 0; k < nz; ++k) {
    auto& b = slice[static_cast<std::size_t>(k)];
    for (long j = 0; j < ny; ++j) {
      const std::uint8_t* row = mask.data.data() + static_cast<std::size_t>(nx) * static_cast<std::size_t>(j + ny * k);
      long first = 0;
      while (first < nx && !row[first]) ++first;
      if (first == nx) continue;
      long last = nx - 1;
      while (!row[last]) --last;
      b[0] = std::min(b[0], first), b[1] = std::max(b[1], last);
      b[2] = std::min(b[2], j), b[3] = std::max(b[3], j);
    }
  }
  std::array<long, 3> lo{nx, ny, nz}, hi{-1, -1, -1};
  for (long k = 0; k < nz; ++k) {
    const auto& b = slice[static_cast<std::size_t>(k)];
    if (b[1] < 0) continue;
    lo = {std::min(lo[0], b[0]), std::min(lo[1], b[2]), std::min(lo[2], k)};
    hi = {std::max(hi[0], b[1]), std::max(hi[1], b[3]), std::max(hi[2], k)};
  }
  return {lo, hi};
}

// Takes the 0/1 crop of a mask (dims, starting pad voxels before index lo of
// the mask's grid) and a CT on that grid; where the CT agrees with the mask
// (a mask voxel at or above level_hu, a non-mask voxel below it) the voxel's
// value becomes 0.5 + (HU - level) / (2 (level - soft)), held on its own side
// of 0.5 and within [0, 1], so that the 0.5 contour between a mask voxel and
// its neighbour lies where the CT crosses the level (partial volume:
// sub-voxel placement). Soft tissue maps to 0 and bone as far above the level
// to 1: the values on either side are as far from 0.5 as the mask's 0 and 1,
// so the Gaussian pre-smoothing does not push the contour outwards (with a
// wider span, cortex at 0.9 against soft tissue at 0.17 did: +1.8 % volume on
// the phantom mandible). Where they disagree (a cut between touching bones, a
// filled cavity, a closed gap) the voxel keeps its 0/1 value and the contour
// stays near half-way. Every value stays on its side of 0.5: the unsmoothed
// contour has the mask's topology.
static void guide_by_ct(float* buf, const int dims[3], const std::array<long, 3>& lo, long pad, const Volume& ct,
                        const Geometry& g, double level_hu, double soft_hu) {
  constexpr float kGuideMargin = 0.02f;
  const float span = static_cast<float>(2.0 * std::max(level_hu - soft_hu, 100.0));
  if (!ct.geom.same_grid(g, 1e-6)) throw Error(ExitCode::Internal, "surface: the guiding CT is not on the mask's grid");
  const float level = static_cast<float>(level_hu);
#pragma omp parallel for schedule(static)
  for (int k = 0; k < dims[2]; ++k)
    for (int j = 0; j < dims[1]; ++j)
      for (int i = 0; i < dims[0]; ++i) {
        const long x = i + lo[0] - pad, y = j + lo[1] - pad, z = k + lo[2] - pad;
        if (x < 0 || y < 0 || z < 0 || x >= static_cast<long>(g.size[0]) || y >= static_cast<long>(g.size[1]) ||
            z >= static_cast<long>(g.size[2]))
          continue;  // outside the scan: stays 0
        float& v = buf[i + static_cast<std::size_t>(dims[0]) * (j + static_cast<std::size_t>(dims[1]) * k)];
        const float hu = ct.hu[g.linear(x, y, z)];
        const bool inside = v > 0.5f;
        if (inside != (hu >= level)) continue;  // disagreement: 0/1 as the mask says
        const float f = 0.5f + (hu - level) / span;
        v = inside ? std::clamp(f, 0.5f + kGuideMargin, 1.0f) : std::clamp(f, 0.0f, 0.5f - kGuideMargin);
      }
}

// unchanged_is_enough: when the closing added nothing, stop there (pd null):
// the contour would be the unclosed one's.
// box: mask_box(mask), found once for every contour of the mask.
static Contour contour(const Mask& mask, const Box& box, const Options& opt, bool unchanged_is_enough = false) {
  SurfaceLap lap;
  const Geometry& g = mask.geom;
  // Crop to the mask's bounding box plus a margin of empty voxels so the
  // surface closes at the scan border.
  const auto& [lo, hi] = box;
  if (hi[0] < 0) throw Error(ExitCode::GeometryFailed, "mandible mask is empty: no surface to build");
  const std::array<int, 3> f = contour_bins(g.spacing, opt);
  const long pad = 3 * std::max({f[0], f[1], f[2]}) +
                   static_cast<long>(std::ceil(opt.close_handles_mm / std::min({g.spacing[0], g.spacing[1], g.spacing[2]})));
  int dims[3];
  for (int a = 0; a < 3; ++a) dims[a] = static_cast<int>(hi[a] - lo[a] + 1 + 2 * pad);
  auto img = Ptr<vtkImageData>::New();
  img->SetDimensions(dims);
  img->SetSpacing(g.spacing[0], g.spacing[1], g.spacing[2]);  // mm along the index axes
  img->SetOrigin(0, 0, 0);
  img->AllocateScalars(VTK_FLOAT, 1);
  auto* buf = static_cast<float*>(img->GetScalarPointer());
  // Slice by slice in parallel, each slice of the crop written whole (its
  // pad included), so the crop is filled once.
  const std::size_t slice = static_cast<std::size_t>(dims[0]) * static_cast<std::size_t>(dims[1]);
#pragma omp parallel for schedule(static)
  for (long z = 0; z < dims[2]; ++z) {
    float* out = buf + slice * static_cast<std::size_t>(z);
    std::fill(out, out + slice, 0.0f);
    const long k = z - pad + lo[2];
    if (k < lo[2] || k > hi[2]) continue;
    for (long j = lo[1]; j <= hi[1]; ++j) {
      const std::uint8_t* row = mask.data.data() + g.linear(0, static_cast<std::size_t>(j), static_cast<std::size_t>(k));
      float* o = out + static_cast<std::size_t>(dims[0]) * static_cast<std::size_t>(j - lo[1] + pad) + pad - lo[0];
      for (long i = lo[0]; i <= hi[0]; ++i) o[i] = row[i] ? 1.0f : 0.0f;
    }
  }

  // Morphological closing by a ball of this radius (mm): fills the narrow
  // gaps that make handles, e.g. between teeth in contact.
  lap("crop");
  Contour c;
  c.lo = lo;
  c.pad = pad;
  c.dims = {dims[0], dims[1], dims[2]};
  if (opt.close_handles_mm > 0)
    c.closing_added = close_binary(buf, dims, g.spacing.data(), opt.close_handles_mm, opt.closing_plugs_only);
  lap("closing");
  if (unchanged_is_enough && c.closing_added == 0) return c;
  if (opt.max_boundary_distance_voxels > 0) {
    c.solid.resize(static_cast<std::size_t>(dims[0]) * dims[1] * dims[2]);
#pragma omp parallel for schedule(static)
    for (long i = 0; i < static_cast<long>(c.solid.size()); ++i) c.solid[static_cast<std::size_t>(i)] = buf[i] > 0.5f;
  }
  if (opt.guide) guide_by_ct(buf, dims, lo, pad, *opt.guide, mask.geom, opt.guide_level_hu, opt.guide_soft_hu);
  // Fine masks: bin-average, then smooth by what the bins did not.
  std::array<double, 3> sigma_vox{};
  for (int a = 0; a < 3; ++a) {
    const double box_var = (f[a] * f[a] - 1) / 12.0 * g.spacing[a] * g.spacing[a];
    sigma_vox[a] = std::sqrt(std::max(0.0, opt.smoothing_sigma_mm * opt.smoothing_sigma_mm - box_var)) / (f[a] * g.spacing[a]);
  }
  if (f[0] * f[1] * f[2] > 1) img = binned(img, f);
  auto smooth = Ptr<vtkImageGaussianSmooth>::New();
  smooth->SetInputData(img);
  smooth->SetDimensionality(3);
  smooth->SetStandardDeviations(sigma_vox[0], sigma_vox[1], sigma_vox[2]);
  smooth->SetRadiusFactors(3, 3, 3);
  auto fe = Ptr<vtkFlyingEdges3D>::New();
  fe->SetInputConnection(smooth->GetOutputPort());
  fe->SetValue(0, 0.5);
  fe->ComputeNormalsOff();
  fe->ComputeGradientsOff();
  fe->ComputeScalarsOff();
  auto conn = Ptr<vtkPolyDataConnectivityFilter>::New();
  conn->SetInputConnection(fe->GetOutputPort());
  conn->SetExtractionModeToLargestRegion();
  auto clean = Ptr<vtkCleanPolyData>::New();
  clean->SetInputConnection(conn->GetOutputPort());
  clean->PointMergingOn();
  clean->Update();
  vtkSmartPointer<vtkPolyData> pd = clean->GetOutput();
  lap("smooth + flying edges");
  if (pd->GetNumberOfPolys() == 0) throw Error(ExitCode::GeometryFailed, "marching cubes produced no surface");
  c.pd = pd;
  return c;
}

// Nearest point to q (continuous index of the crop) on the boundary of
// c.solid -- the voxel faces between a solid voxel and an empty one, the
// crop's outside counting as empty -- among the solid voxels within r[a]
// indices of q's voxel along each axis; distances in mm (spacing s along the
// index axes: the direction matrix is a rotation). Returns the squared
// distance (infinity when none is in reach) and the point in *nearest.
static double nearest_on_boundary(const Contour& c, const Vec3& q, const Vec3& s, const std::array<long, 3>& r,
                                  Vec3* nearest) {
  auto solid = [&](long i, long j, long k) {
    return i >= 0 && j >= 0 && k >= 0 && i < c.dims[0] && j < c.dims[1] && k < c.dims[2] &&
           c.solid[static_cast<std::size_t>(i + c.dims[0] * (j + c.dims[1] * k))] != 0;
  };
  const long ci = std::lround(q[0]), cj = std::lround(q[1]), ck = std::lround(q[2]);
  double best = std::numeric_limits<double>::infinity();
  for (long k = ck - r[2]; k <= ck + r[2]; ++k)
    for (long j = cj - r[1]; j <= cj + r[1]; ++j)
      for (long i = ci - r[0]; i <= ci + r[0]; ++i) {
        if (!solid(i, j, k)) continue;
        const long v[3] = {i, j, k};
        for (int a = 0; a < 3; ++a)
          for (int sgn : {-1, 1}) {
            long n[3] = {i, j, k};
            n[a] += sgn;
            if (solid(n[0], n[1], n[2])) continue;
            Vec3 p;  // the face's point nearest q: q clamped to the face's square
            for (int b = 0; b < 3; ++b)
              p[b] = b == a ? static_cast<double>(v[b]) + 0.5 * sgn
                            : std::clamp(q[b], static_cast<double>(v[b]) - 0.5, static_cast<double>(v[b]) + 0.5);
            double d2 = 0;
            for (int b = 0; b < 3; ++b) d2 += (q[b] - p[b]) * (q[b] - p[b]) * s[b] * s[b];
            if (d2 < best) best = d2, *nearest = p;
          }
      }
  return best;
}

// Pulls every vertex farther than opt.max_boundary_distance_voxels (x the
// finest spacing) from the boundary of the contoured mask back to that
// distance, straight towards its nearest boundary point. The Gaussian rounds
// a cusp or a thin edge inwards by a fixed number of millimetres, which on a
// fine grid can be more than a voxel (one vertex of 32 898 at 0.496 mm on a
// 0.45 x 0.45 x 0.495 mm phantom mandible). The moves measured are hundredths
// of a millimetre (Result::largest_pull_mm), a few percent of an edge; they
// come after the self-intersection check and are not checked again.
static void hold_to_mask(Result& res, const Contour& c, const Geometry& g, const Options& opt) {
  if (opt.max_boundary_distance_voxels <= 0 || c.solid.empty()) return;
  SurfaceLap lap;
  const Vec3& s = g.spacing;
  const double tol = opt.max_boundary_distance_voxels * std::min({s[0], s[1], s[2]});
  std::array<long, 3> reach{}, wide{};
  for (int a = 0; a < 3; ++a) {
    reach[a] = static_cast<long>(std::floor(tol / s[a])) + 1;  // every face within tol (see nearest_on_boundary)
    wide[a] = reach[a] + static_cast<long>(std::ceil(3.0 / s[a]));  // a vertex up to 3 mm off: the nearest face
  }
  const Vec3 shift{static_cast<double>(c.pad - c.lo[0]), static_cast<double>(c.pad - c.lo[1]),
                   static_cast<double>(c.pad - c.lo[2])};
  std::size_t pulled = 0;
  double largest = 0;
  auto& verts = res.mesh.vertices;
#pragma omp parallel for schedule(dynamic, 1024) reduction(+ : pulled) reduction(max : largest)
  for (long i = 0; i < static_cast<long>(verts.size()); ++i) {
    Vec3& v = verts[static_cast<std::size_t>(i)];
    const Vec3 q = g.lps_to_index(v) + shift;
    Vec3 p;
    double d2 = nearest_on_boundary(c, q, s, reach, &p);
    if (d2 <= tol * tol) continue;
    d2 = nearest_on_boundary(c, q, s, wide, &p);
    if (!std::isfinite(d2)) continue;  // nothing within reach: leave it
    const double d = std::sqrt(d2), keep = tol * (1 - 1e-9) / d;
    const Vec3 moved = p + keep * (q - p);
    v = g.index_to_lps(moved[0] - shift[0], moved[1] - shift[1], moved[2] - shift[2]);
    ++pulled;
    largest = std::max(largest, d - tol);
  }
  res.vertices_pulled = pulled;
  res.largest_pull_mm = largest;
  if (pulled > 0) res.stats = measure(res.mesh);
  lap("hold to the mask");
}

// The contour decimated to opt.target_faces, in LPS, measured (before CGAL repair).
static Result raw_mesh(const Contour& c, const Geometry& g, const Options& opt, bool decimate = true) {
  SurfaceLap lap;
  vtkSmartPointer<vtkPolyData> pd = c.pd;
  const auto& lo = c.lo;
  const long pad = c.pad;
  if (decimate && opt.target_faces > 0 && static_cast<std::size_t>(pd->GetNumberOfPolys()) > opt.target_faces) {
    auto tri = Ptr<vtkTriangleFilter>::New();
    tri->SetInputData(pd);
    auto dec = Ptr<vtkQuadricDecimation>::New();
    dec->SetInputConnection(tri->GetOutputPort());
    dec->SetTargetReduction(1.0 - static_cast<double>(opt.target_faces) / pd->GetNumberOfPolys());
    dec->VolumePreservationOn();
    auto clean2 = Ptr<vtkCleanPolyData>::New();
    clean2->SetInputConnection(dec->GetOutputPort());
    clean2->Update();
    pd = clean2->GetOutput();
  }
  Result r;
  r.mesh = from_vtk(pd);
  // Index-space mm -> LPS: p = origin + D * (lo * spacing + q), q in mm along index axes.
  for (auto& v : r.mesh.vertices) {
    const Vec3 q{v[0] / g.spacing[0] + lo[0] - pad, v[1] / g.spacing[1] + lo[1] - pad, v[2] / g.spacing[2] + lo[2] - pad};
    v = g.index_to_lps(q[0], q[1], q[2]);
  }
  measure_outward(r);
  lap(decimate ? "decimate + measure" : "measure");
  return r;
}

// The surface of a mask as stored (mesh_from_mask canonicalises the
// orientation first); box: mask_box(mask).
static Result mesh_as_stored(const Mask& mask, const Box& box, const Options& opt) {
  const Geometry& g = mask.geom;
  // Automatic closing: the topology is decided on the undecimated contours
  // (the mask's own topology; decimating costs five times the contouring);
  // only the chosen one is decimated, repaired and remeshed.
  if (opt.close_handles_auto && opt.close_handles_mm <= 0) {
    const Contour open = contour(mask, box, opt);
    const int genus = raw_mesh(open, g, opt, false).stats.genus;
    if (genus > 0) {
      const double finest = std::min({g.spacing[0], g.spacing[1], g.spacing[2]});
      // The closing's plugs alone at each radius first, then the whole
      // closing at each radius (plugs at 3 mm change less than a whole 1 mm
      // closing): the first whose surface is genus 0 through repair.
      for (bool plugs_only : {true, false})
        for (double radius : {1.0, 2.0, 3.0}) {
          if (radius < finest) continue;  // the kernel would be a single voxel: no closing
          Options o = opt;
          o.close_handles_mm = radius;
          o.closing_plugs_only = plugs_only;
          const Contour cc = contour(mask, box, o, true);
          if (!cc.pd) continue;  // the closing added nothing: the unclosed surface's genus
          if (raw_mesh(cc, g, o, false).stats.genus != 0) continue;
          Result c = raw_mesh(cc, g, o);
          if (c.stats.genus != 0) continue;  // decimation made a handle: try the next
          finish(c, o);
          if (c.stats.genus != 0) continue;  // repair changed the topology: try the next
          hold_to_mask(c, cc, g, o);
          c.closing_mm = radius;
          c.closing_plugs_only = plugs_only;
          c.genus_before_closing = genus;
          return c;
        }
    }
    Result r = raw_mesh(open, g, opt);
    if (genus > 0) r.genus_before_closing = genus;
    finish(r, opt);
    hold_to_mask(r, open, g, opt);
    return r;
  }
  const Contour c = contour(mask, box, opt);
  Result r = raw_mesh(c, g, opt);
  r.closing_mm = opt.close_handles_mm;
  finish(r, opt);
  hold_to_mask(r, c, g, opt);
  return r;
}

// ---- Orientation: mirror-image masks give mirror-image surfaces.
// Decimation and CGAL's remeshing visit vertices and edges in an order that
// follows the grid, so a scan stored mirrored (flipped left<->right) used to
// mesh to another triangulation of the mirrored surface, and the SAF score of
// the flipped scan differed by 1.2-5.3 % through the pipeline (docs/method.md,
// "Precision"). The surface is therefore built
// from the mask's crop in a canonical orientation: of the crop and its mirror
// along the grid's lateral axis (the index axis nearest LPS x), the one that
// is smaller in storage order (first differing voxel; the guiding CT's on a
// tie). A mirrored crop is meshed in the geometry the unmirrored one would
// have, and the mesh reflected back through the grid's mid-plane, so a mask
// and its mirror image give the same mesh reflected, to rounding.
namespace {

// The crop [lo, hi] of a grid's values, mirrored along axis `flip_axis` when
// >= 0 (index hi - x for lo + x along it); storage order of the crop.
template <typename T>
std::vector<T> crop_values(const std::vector<T>& v, const Geometry& g, const std::array<long, 3>& lo,
                           const std::array<long, 3>& hi, int flip_axis) {
  const long n[3] = {hi[0] - lo[0] + 1, hi[1] - lo[1] + 1, hi[2] - lo[2] + 1};
  std::vector<T> out(static_cast<std::size_t>(n[0] * n[1] * n[2]));
#pragma omp parallel for schedule(static)
  for (long k = 0; k < n[2]; ++k)
    for (long j = 0; j < n[1]; ++j)
      for (long i = 0; i < n[0]; ++i) {
        long x[3] = {i, j, k};
        if (flip_axis >= 0) x[flip_axis] = n[flip_axis] - 1 - x[flip_axis];
        out[static_cast<std::size_t>(i + n[0] * (j + n[1] * k))] =
            v[g.linear(static_cast<std::size_t>(lo[0] + x[0]), static_cast<std::size_t>(lo[1] + x[1]),
                       static_cast<std::size_t>(lo[2] + x[2]))];
      }
  return out;
}

// Sign of the first difference, in storage order, between the crop [lo, hi]
// of a grid's values and its mirror along `axis`: < 0 when the crop comes
// first. Usually decided within the first rows that hold the mask.
template <typename T>
int compare_with_mirror(const std::vector<T>& v, const Geometry& g, const std::array<long, 3>& lo,
                        const std::array<long, 3>& hi, int axis) {
  for (long k = lo[2]; k <= hi[2]; ++k)
    for (long j = lo[1]; j <= hi[1]; ++j)
      for (long i = lo[0]; i <= hi[0]; ++i) {
        long x[3] = {i, j, k};
        x[axis] = lo[axis] + hi[axis] - x[axis];
        const T a = v[g.linear(static_cast<std::size_t>(i), static_cast<std::size_t>(j), static_cast<std::size_t>(k))];
        const T b = v[g.linear(static_cast<std::size_t>(x[0]), static_cast<std::size_t>(x[1]), static_cast<std::size_t>(x[2]))];
        if (a != b) return a < b ? -1 : 1;
      }
  return 0;
}

}  // namespace

Result mesh_from_mask(const Mask& mask, const Options& opt) {
  SurfaceLap lap;
  const Geometry& g = mask.geom;
  if (mask.data.size() != g.voxel_count()) throw Error(ExitCode::Internal, "surface: mask and grid disagree in size");
  const Box box = mask_box(mask);
  if (box.second[0] < 0) throw Error(ExitCode::GeometryFailed, "mandible mask is empty: no surface to build");
  if (opt.guide && !opt.guide->geom.same_grid(g, 1e-6))
    throw Error(ExitCode::Internal, "surface: the guiding CT is not on the mask's grid");
  // Crop: the box plus what the contour reads around it (its pad, with the
  // widest closing the automatic one tries), clamped to the scan.
  const std::array<int, 3> f = contour_bins(g.spacing, opt);
  const double finest = std::min({g.spacing[0], g.spacing[1], g.spacing[2]});
  const double widest_closing = std::max(opt.close_handles_mm, opt.close_handles_auto ? 3.0 : 0.0);
  const long margin = 3 * std::max({f[0], f[1], f[2]}) + static_cast<long>(std::ceil(widest_closing / finest)) + 1;
  std::array<long, 3> lo{}, hi{};
  for (int a = 0; a < 3; ++a) {
    lo[a] = std::max(0L, box.first[a] - margin);
    hi[a] = std::min(static_cast<long>(g.size[a]) - 1, box.second[a] + margin);
  }
  int lateral = 0;  // the index axis nearest LPS x (direction's columns are the axes)
  for (int a = 1; a < 3; ++a)
    if (std::abs(g.direction[a]) > std::abs(g.direction[lateral])) lateral = a;

  int order = compare_with_mirror(mask.data, g, lo, hi, lateral);
  if (order == 0 && opt.guide) order = compare_with_mirror(opt.guide->hu, g, lo, hi, lateral);
  const bool flip = order > 0;
  Mask crop;
  crop.data = crop_values(mask.data, g, lo, hi, flip ? lateral : -1);
  lap(flip ? "orientation: crop, mirrored" : "orientation: crop, as stored");
  // The iso-surface keeps apart what touches only at a voxel edge or corner;
  // the mask's pieces are joined there first (in the canonical crop, so a
  // mirrored mask gains the mirrored voxels).
  const std::size_t joining =
      join_diagonal_contacts(crop.data.data(), Dims3{static_cast<std::size_t>(hi[0] - lo[0] + 1),
                                                     static_cast<std::size_t>(hi[1] - lo[1] + 1),
                                                     static_cast<std::size_t>(hi[2] - lo[2] + 1)});
  lap("join diagonal contacts");
  Volume guide;
  if (opt.guide) guide.hu = crop_values(opt.guide->hu, g, lo, hi, flip ? lateral : -1);
  // The crop's grid; mirrored, the grid the unmirrored crop has in the
  // mirrored scan (its first index along the lateral axis is size - 1 - hi).
  std::array<long, 3> first = lo;
  if (flip) first[lateral] = static_cast<long>(g.size[lateral]) - 1 - hi[lateral];
  crop.geom = g;
  for (int a = 0; a < 3; ++a) crop.geom.size[a] = static_cast<std::size_t>(hi[a] - lo[a] + 1);
  crop.geom.origin = g.index_to_lps(static_cast<double>(first[0]), static_cast<double>(first[1]), static_cast<double>(first[2]));
  guide.geom = crop.geom;
  Options o = opt;
  if (opt.guide) o.guide = &guide;

  // The mask's box in the crop (mirrored: hi - x along the lateral axis).
  Box in_crop;
  for (int a = 0; a < 3; ++a) {
    const bool m = flip && a == lateral;
    in_crop.first[a] = m ? hi[a] - box.second[a] : box.first[a] - lo[a];
    in_crop.second[a] = m ? hi[a] - box.first[a] : box.second[a] - lo[a];
  }
  Result r = mesh_as_stored(crop, in_crop, o);
  r.voxels_joining = joining;
  if (flip) {
    // Back through the grid's mid-plane across the lateral axis.
    const double mid = 0.5 * (static_cast<double>(g.size[lateral]) - 1.0);
    const Vec3 centre = g.index_to_lps(lateral == 0 ? mid : 0.0, lateral == 1 ? mid : 0.0, lateral == 2 ? mid : 0.0);
    const Plane plane{centre, Vec3{g.direction[lateral], g.direction[3 + lateral], g.direction[6 + lateral]}};
    for (auto& v : r.mesh.vertices) v = plane.reflect(v);
    for (auto& t : r.mesh.faces) std::swap(t[1], t[2]);
  }
  return r;
}

Mask closed(const Mask& mask, double radius_mm) {
  const Geometry& g = mask.geom;
  Mask out = mask;
  if (radius_mm > 0 && !out.data.empty()) close_euclidean(out.data, g.size, g.spacing, radius_mm);
  return out;
}

void write_vtp(const Mesh& mesh, const PointArrays& arrays, const std::string& path) {
  auto pd = to_polydata(mesh);
  for (const auto& [name, values] : arrays) {
    if (values.size() != mesh.vertices.size())
      throw Error(ExitCode::Internal, "write_vtp: array " + name + " has the wrong length");
    auto arr = Ptr<vtkDoubleArray>::New();
    arr->SetName(name.c_str());
    arr->SetNumberOfValues(static_cast<vtkIdType>(values.size()));
    for (std::size_t i = 0; i < values.size(); ++i) arr->SetValue(static_cast<vtkIdType>(i), values[i]);
    pd->GetPointData()->AddArray(arr);
  }
  // Written to memory, then to disk by a checked writer: VTK 9.1's XML
  // writer frees an invalid pointer when the disk fills mid-write.
  auto w = Ptr<vtkXMLPolyDataWriter>::New();
  w->WriteToOutputStringOn();
  w->SetInputData(pd);
  w->SetDataModeToBinary();
  if (!w->Write()) throw Error(ExitCode::OutputFailed, path + ": cannot write VTP");
  write_file_atomic(path, w->GetOutputString());
}

// Binary STL (80-byte header, triangle count, then per triangle its unit
// normal, three vertices as float32 and a zero attribute word), little endian.
void write_stl(const Mesh& mesh, const std::string& path) {
  constexpr std::size_t kHeaderBytes = 80, kTriangleBytes = 50;
  if (mesh.faces.size() > 0xffffffffull) throw Error(ExitCode::OutputFailed, path + ": too many triangles for STL");
  std::string out(kHeaderBytes + 4 + kTriangleBytes * mesh.faces.size(), '\0');
  const std::string header = "MandiSym mandible surface, patient LPS, mm";
  out.replace(0, header.size(), header);
  auto put_u32 = [&](std::size_t at, std::uint32_t v) {
    for (int b = 0; b < 4; ++b) out[at + b] = static_cast<char>((v >> (8 * b)) & 0xffu);
  };
  auto put_f32 = [&](std::size_t at, double v) {
    const float f = static_cast<float>(v);
    std::uint32_t u;
    std::memcpy(&u, &f, 4);
    put_u32(at, u);
  };
  put_u32(kHeaderBytes, static_cast<std::uint32_t>(mesh.faces.size()));
  for (std::size_t t = 0; t < mesh.faces.size(); ++t) {
    const auto& f = mesh.faces[t];
    const Vec3 &a = mesh.vertices[f[0]], &b = mesh.vertices[f[1]], &c = mesh.vertices[f[2]];
    Vec3 n = cross(b - a, c - a);
    const double len = norm(n);
    n = len > 0 ? Vec3{n[0] / len, n[1] / len, n[2] / len} : Vec3{0, 0, 0};
    std::size_t at = kHeaderBytes + 4 + kTriangleBytes * t;
    for (const Vec3* v : std::array<const Vec3*, 4>{&n, &a, &b, &c})
      for (int k = 0; k < 3; ++k, at += 4) put_f32(at, (*v)[k]);
  }
  write_file_atomic(path, out);
}

static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "write_ply and write_stl write host-order bytes as little endian");

// Binary little-endian PLY 1.0: float32 x y z per vertex, then per face a
// uchar count (3) and three int32 vertex indices. Written by us: VTK 9.1's
// vtkPLYWriter writes nothing at all into its output string in binary mode.
void write_ply(const Mesh& mesh, const std::string& path) {
  if (mesh.vertices.size() > 0x7fffffffull) throw Error(ExitCode::OutputFailed, path + ": too many vertices for PLY");
  std::string out = "ply\nformat binary_little_endian 1.0\ncomment MandiSym mandible surface, patient LPS, mm\nelement vertex " +
                    std::to_string(mesh.vertices.size()) + "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
                    std::to_string(mesh.faces.size()) + "\nproperty list uchar int vertex_indices\nend_header\n";
  const std::size_t header = out.size();
  out.resize(header + 12 * mesh.vertices.size() + 13 * mesh.faces.size());
  char* at = out.data() + header;
  const auto put = [&at](const void* p, std::size_t n) {  // x86-64 and arm64 are little endian, as the header says
    std::memcpy(at, p, n);
    at += n;
  };
  for (const Vec3& v : mesh.vertices)
    for (int k = 0; k < 3; ++k) {
      const float f = static_cast<float>(v[k]);
      put(&f, 4);
    }
  for (const auto& f : mesh.faces) {
    const unsigned char three = 3;
    put(&three, 1);
    for (int k = 0; k < 3; ++k) {
      const std::int32_t i = static_cast<std::int32_t>(f[k]);
      put(&i, 4);
    }
  }
  write_file_atomic(path, out);
}

Mesh read_vtp(const std::string& path) {
  auto r = Ptr<vtkXMLPolyDataReader>::New();
  r->SetFileName(path.c_str());
  r->Update();
  if (!r->GetOutput() || r->GetOutput()->GetNumberOfPoints() == 0)
    throw Error(ExitCode::InputInvalid, path + ": cannot read VTP mesh");
  return from_vtk(r->GetOutput());
}

}  // namespace ms::surface
