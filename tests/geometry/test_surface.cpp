// surface::mesh_from_mask and surface::measure on analytic shapes.
//
// The ellipsoid is voxelised on a grid with anisotropic spacing and an oblique
// direction matrix, so a mistake in the index -> LPS mapping (spacing order,
// transposed direction, lost crop offset, ignored handedness) moves the mesh
// away from the analytic surface and fails the distance / volume checks.
#include "surface/surface.h"

#include <gtest/gtest.h>

#include <random>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "core/error.h"
#include "core/types.h"
#include "phantom/phantom.h"

#include <vtkCellArray.h>
#include <vtkNew.h>
#include <vtkPLYReader.h>
#include <vtkPolyData.h>

#include <filesystem>

namespace {

using ms::Vec3;
using ms::operator+;
using ms::operator-;
using ms::operator*;
constexpr double kPi = 3.14159265358979323846;

using Mat3 = std::array<double, 9>;  // row-major

// Rotation by angle about a unit axis (Rodrigues).
Mat3 rotation(const Vec3& axis_in, double angle) {
  const Vec3 k = ms::normalized(axis_in);
  const double c = std::cos(angle), s = std::sin(angle), t = 1 - c;
  return {t * k[0] * k[0] + c,        t * k[0] * k[1] - s * k[2], t * k[0] * k[2] + s * k[1],
          t * k[0] * k[1] + s * k[2], t * k[1] * k[1] + c,        t * k[1] * k[2] - s * k[0],
          t * k[0] * k[2] - s * k[1], t * k[1] * k[2] + s * k[0], t * k[2] * k[2] + c};
}

double det3(const Mat3& m) {
  return m[0] * (m[4] * m[8] - m[5] * m[7]) - m[1] * (m[3] * m[8] - m[5] * m[6]) + m[2] * (m[3] * m[7] - m[4] * m[6]);
}

struct Ellipsoid {
  Vec3 centre{12.5, -7.0, 31.0};  // off-origin on purpose
  Vec3 semi{20.0, 14.0, 10.0};
  double implicit(const Vec3& p) const {  // (x/a)^2 + (y/b)^2 + (z/c)^2 - 1
    double s = 0;
    for (int a = 0; a < 3; ++a) {
      const double t = (p[a] - centre[a]) / semi[a];
      s += t * t;
    }
    return s - 1;
  }
  // Upper bound of the distance from p to the ellipsoid surface: the radial
  // projection centre + (p - centre)/sqrt(F+1) lies on the surface.
  double distance_bound(const Vec3& p) const {
    const Vec3 d = p - centre;
    const double scale = 1.0 / std::sqrt(implicit(p) + 1.0);
    return ms::norm(d) * std::abs(1.0 - scale);
  }
  double volume() const { return 4.0 / 3.0 * kPi * semi[0] * semi[1] * semi[2]; }
};

// A grid of the given spacing and direction covering a ball of radius reach
// about centre (its centre mapped onto centre); a voxel is inside iff its
// centre is, by inside(p) with p in LPS.
template <class Inside>
ms::Mask implicit_mask(const Inside& inside, const Vec3& centre, double reach, const Vec3& spacing,
                       const Mat3& direction) {
  ms::Mask m;
  m.geom.spacing = spacing;
  m.geom.direction = direction;
  Vec3 half{};
  for (int a = 0; a < 3; ++a) {
    m.geom.size[a] = static_cast<std::size_t>(std::ceil(2 * reach / spacing[a])) + 1;
    half[a] = 0.5 * static_cast<double>(m.geom.size[a] - 1) * spacing[a];
  }
  Vec3 rot_half{0, 0, 0};
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) rot_half[r] += direction[3 * r + c] * half[c];
  m.geom.origin = centre - rot_half;
  m.data.assign(m.geom.voxel_count(), 0);
  for (std::size_t k = 0; k < m.geom.size[2]; ++k)
    for (std::size_t j = 0; j < m.geom.size[1]; ++j)
      for (std::size_t i = 0; i < m.geom.size[0]; ++i) {
        const Vec3 p = m.geom.index_to_lps(static_cast<double>(i), static_cast<double>(j), static_cast<double>(k));
        m.data[m.geom.linear(i, j, k)] = inside(p) ? 1 : 0;
      }
  return m;
}

// The ellipsoid on such a grid.
ms::Mask ellipsoid_mask(const Ellipsoid& e, const Vec3& spacing, const Mat3& direction) {
  const double reach = *std::max_element(e.semi.begin(), e.semi.end()) + 4.0;  // covers any rotation
  return implicit_mask([&](const Vec3& p) { return e.implicit(p) <= 0; }, e.centre, reach, spacing, direction);
}

// Area-weighted mean of n_f · (centroid_f - c): positive iff the faces point
// away from c on average (independent of the signed-volume formula).
double mean_outward_component(const ms::Mesh& mesh, const Vec3& c) {
  double num = 0, den = 0;
  for (const auto& f : mesh.faces) {
    const Vec3 &a = mesh.vertices[f[0]], &b = mesh.vertices[f[1]], &d = mesh.vertices[f[2]];
    const Vec3 cr = ms::cross(b - a, d - a);
    const double area2 = ms::norm(cr);
    if (area2 == 0) continue;
    const Vec3 centroid = (1.0 / 3.0) * (a + b + d);
    num += ms::dot(cr, centroid - c);  // = area2 * n·(centroid - c)
    den += area2;
  }
  return num / den;
}

const Vec3 kSpacing{0.7, 0.8, 1.1};
const Vec3 kAxis{1.0, 2.0, 3.0};
const double kAngle = 25.0 * kPi / 180.0;

void check_ellipsoid_mesh(const Ellipsoid& e, const ms::surface::Result& r) {
  const auto& s = r.stats;
  EXPECT_TRUE(s.closed);
  EXPECT_TRUE(s.manifold);
  EXPECT_EQ(s.genus, 0);
  EXPECT_EQ(s.vertices, r.mesh.vertices.size());
  EXPECT_EQ(s.faces, r.mesh.faces.size());
  EXPECT_GT(s.volume_mm3, 0);
  // The reported stats must describe the returned mesh (after any flip).
  const auto again = ms::surface::measure(r.mesh);
  EXPECT_NEAR(again.volume_mm3, s.volume_mm3, 1e-6 * s.volume_mm3);
  EXPECT_NEAR(again.area_mm2, s.area_mm2, 1e-6 * s.area_mm2);
  // Voxelisation at the voxel centres is unbiased for a smooth convex body;
  // 3 % leaves room for the smoothing shrinkage at curvature radius >= 5 mm.
  EXPECT_NEAR(s.volume_mm3, e.volume(), 0.03 * e.volume());

  // Every vertex lies on the analytic surface up to the voxel resolution:
  // the voxel-centre staircase is within half a voxel diagonal (0.77 mm here)
  // of the true surface, so the largest spacing (1.1 mm) is a safe bound.
  const double max_spacing = *std::max_element(kSpacing.begin(), kSpacing.end());
  double worst = 0, sum = 0;
  for (const auto& v : r.mesh.vertices) {
    const double d = e.distance_bound(v);
    worst = std::max(worst, d);
    sum += d;
  }
  EXPECT_LE(worst, max_spacing);
  // ... and on average well inside a voxel (a systematic offset, e.g. a half
  // voxel shift of the crop, would show here first).
  EXPECT_LT(sum / static_cast<double>(r.mesh.vertices.size()), 0.25 * max_spacing);
  // Mesh centroid of the vertices ≈ ellipsoid centre.
  Vec3 c{0, 0, 0};
  for (const auto& v : r.mesh.vertices) c = c + v;
  c = (1.0 / static_cast<double>(r.mesh.vertices.size())) * c;
  EXPECT_LT(ms::distance(c, e.centre), 0.5 * max_spacing);

  // Outward orientation checked without the signed volume.
  EXPECT_GT(mean_outward_component(r.mesh, e.centre), 0.5 * *std::min_element(e.semi.begin(), e.semi.end()));
}

TEST(Surface, ObliqueAnisotropicEllipsoidIsClosedOutwardAndAccurate) {
  const Ellipsoid e;
  const Mat3 d = rotation(kAxis, kAngle);
  ASSERT_NEAR(det3(d), 1.0, 1e-12);
  const auto r = ms::surface::mesh_from_mask(ellipsoid_mask(e, kSpacing, d));
  check_ellipsoid_mesh(e, r);
}

TEST(Surface, MirrorHandedGridStillGivesOutwardMesh) {
  const Ellipsoid e;
  Mat3 d = rotation(kAxis, kAngle);
  for (int r = 0; r < 3; ++r) d[3 * r] = -d[3 * r];  // flip the i axis: det = -1
  ASSERT_NEAR(det3(d), -1.0, 1e-12);
  const auto r = ms::surface::mesh_from_mask(ellipsoid_mask(e, kSpacing, d));
  check_ellipsoid_mesh(e, r);
}

TEST(Surface, DecimationKeepsAClosedOutwardSurface) {
  const Ellipsoid e;
  ms::surface::Options opt;
  opt.target_faces = 3000;
  opt.target_edge_mm = 0;  // decimation alone
  const auto r = ms::surface::mesh_from_mask(ellipsoid_mask(e, kSpacing, rotation(kAxis, kAngle)), opt);
  EXPECT_LE(r.stats.faces, 3000u * 11 / 10);
  EXPECT_TRUE(r.stats.closed);
  EXPECT_TRUE(r.stats.manifold);
  EXPECT_EQ(r.stats.genus, 0);
  EXPECT_NEAR(r.stats.volume_mm3, e.volume(), 0.03 * e.volume());
  EXPECT_GT(mean_outward_component(r.mesh, e.centre), 0);
}

// Mean edge length of a mesh.
double mean_edge(const ms::Mesh& m) {
  double s = 0;
  for (const auto& f : m.faces)
    for (int e = 0; e < 3; ++e) s += ms::distance(m.vertices[f[e]], m.vertices[f[(e + 1) % 3]]);
  return s / (3.0 * static_cast<double>(m.faces.size()));
}

// Largest distance (mm) from a mesh vertex to the mask's boundary, the union
// of the voxel faces between an inside and an outside voxel.
double max_distance_to_mask_boundary(const ms::Mesh& mesh, const ms::Mask& mask) {
  const ms::Geometry& g = mask.geom;
  auto inside = [&](long i, long j, long k) {
    return i >= 0 && j >= 0 && k >= 0 && i < long(g.size[0]) && j < long(g.size[1]) && k < long(g.size[2]) &&
           mask.data[g.linear(std::size_t(i), std::size_t(j), std::size_t(k))] != 0;
  };
  double worst = 0;
  for (const auto& v : mesh.vertices) {
    const Vec3 q = g.lps_to_index(v);  // distances in index space scaled by spacing (the direction is a rotation)
    double best = 1e30;
    const long ci = std::lround(q[0]), cj = std::lround(q[1]), ck = std::lround(q[2]);
    for (long k = ck - 3; k <= ck + 3; ++k)
      for (long j = cj - 3; j <= cj + 3; ++j)
        for (long i = ci - 3; i <= ci + 3; ++i) {
          if (!inside(i, j, k)) continue;
          const long c[3] = {i, j, k};
          for (int a = 0; a < 3; ++a)
            for (int sgn : {-1, 1}) {
              long n[3] = {i, j, k};
              n[a] += sgn;
              if (inside(n[0], n[1], n[2])) continue;
              // Face between voxel c and its neighbour along axis a.
              double d2 = 0;
              for (int b = 0; b < 3; ++b) {
                double t;
                if (b == a) {
                  t = q[b] - (static_cast<double>(c[b]) + 0.5 * sgn);
                } else {
                  const double lo = static_cast<double>(c[b]) - 0.5, hi = static_cast<double>(c[b]) + 0.5;
                  t = q[b] < lo ? lo - q[b] : q[b] > hi ? q[b] - hi : 0.0;
                }
                d2 += t * t * g.spacing[b] * g.spacing[b];
              }
              best = std::min(best, std::sqrt(d2));
            }
        }
    worst = std::max(worst, best);
  }
  return worst;
}

// A CT of a ball with partial volume (a linear ramp one voxel wide across
// its surface, as a scanner's voxel averages it) on the oblique anisotropic
// grid; the mask is the voxels at or above the half-maximum level.
struct BallScan {
  ms::Volume ct;
  ms::Mask mask;
  Vec3 centre;
  double radius = 11.3;
  double level = 40.0 + 0.5 * 1500.0;  // half-maximum: the CT crosses it at the ball's surface
};

BallScan ball_scan() {
  BallScan b;
  Ellipsoid e;
  e.semi = {b.radius, b.radius, b.radius};
  b.centre = e.centre;
  b.mask = ellipsoid_mask(e, kSpacing, rotation(kAxis, kAngle));
  const ms::Geometry& g = b.mask.geom;
  b.ct.geom = g;
  b.ct.hu.resize(g.voxel_count());
  const double w = (kSpacing[0] + kSpacing[1] + kSpacing[2]) / 3.0;
  for (std::size_t k = 0; k < g.size[2]; ++k)
    for (std::size_t j = 0; j < g.size[1]; ++j)
      for (std::size_t i = 0; i < g.size[0]; ++i) {
        const double d = ms::distance(g.index_to_lps(double(i), double(j), double(k)), b.centre) - b.radius;
        const double cover = std::clamp(0.5 - d / w, 0.0, 1.0);
        b.ct.hu[g.linear(i, j, k)] = static_cast<float>(40.0 + 1500.0 * cover);
        b.mask.data[g.linear(i, j, k)] = b.ct.hu[g.linear(i, j, k)] >= b.level ? 1 : 0;
      }
  return b;
}

// Mean and largest |distance to the sphere| of a mesh's vertices.
std::pair<double, double> sphere_error(const ms::Mesh& m, const Vec3& c, double r) {
  double sum = 0, worst = 0;
  for (const auto& v : m.vertices) {
    const double d = std::abs(ms::distance(v, c) - r);
    sum += d;
    worst = std::max(worst, d);
  }
  return {sum / static_cast<double>(m.vertices.size()), worst};
}

TEST(Surface, GuidedByTheCtTheSurfaceLiesBetweenVoxelsWhereTheCtCrossesItsLevel) {
  const BallScan b = ball_scan();
  const auto binary = ms::surface::mesh_from_mask(b.mask);
  ms::surface::Options o;
  o.guide = &b.ct;
  o.guide_level_hu = b.level;
  const auto guided = ms::surface::mesh_from_mask(b.mask, o);
  EXPECT_TRUE(guided.stats.closed);
  EXPECT_EQ(guided.stats.genus, 0);
  const auto [bin_mean, bin_max] = sphere_error(binary.mesh, b.centre, b.radius);
  const auto [gui_mean, gui_max] = sphere_error(guided.mesh, b.centre, b.radius);
  std::printf("distance to the sphere: mask alone mean %.3f max %.3f mm, CT-guided mean %.3f max %.3f mm\n", bin_mean, bin_max,
              gui_mean, gui_max);
  EXPECT_LT(gui_mean, 0.5 * bin_mean);
  EXPECT_LT(gui_max, 0.6 * bin_max);
  // Volume: the Gaussian pre-smoothing (0.6 mm) shrinks a ball of this size
  // by about 1.5 % whatever places the contour.
  const double exact = 4.0 / 3.0 * kPi * b.radius * b.radius * b.radius;
  std::printf("volume: exact %.0f, mask alone %.0f, CT-guided %.0f mm3\n", exact, binary.stats.volume_mm3, guided.stats.volume_mm3);
  EXPECT_NEAR(guided.stats.volume_mm3, exact, 0.02 * exact);
  // The guide moves the contour between voxels, never across them.
  EXPECT_LE(max_distance_to_mask_boundary(guided.mesh, b.mask), *std::max_element(kSpacing.begin(), kSpacing.end()));
}

TEST(Surface, WhereTheCtDisagreesWithTheMaskTheGuideLeavesTheMaskAlone) {
  BallScan b = ball_scan();
  const ms::Geometry& g = b.mask.geom;
  // The mask also holds a slab of dark voxels (a filled cavity, a closed gap)
  // and leaves out a bright one (a neighbouring bone cut off at a contact).
  ms::Mask m = b.mask;
  std::size_t added = 0, dropped = 0;
  for (std::size_t k = 0; k < g.size[2]; ++k)
    for (std::size_t j = 0; j < g.size[1]; ++j)
      for (std::size_t i = 0; i < g.size[0]; ++i) {
        const Vec3 q = g.index_to_lps(double(i), double(j), double(k)) - b.centre;
        const std::size_t c = g.linear(i, j, k);
        if (q[2] > b.radius - 1 && q[2] < b.radius + 4 && std::abs(q[0]) < 4 && std::abs(q[1]) < 4 && !m.data[c]) m.data[c] = 1, ++added;
        if (q[2] < -b.radius + 3 && m.data[c]) m.data[c] = 0, ++dropped;
      }
  ASSERT_GT(added, 50u);
  ASSERT_GT(dropped, 50u);
  ms::surface::Options o;
  o.guide = &b.ct;
  o.guide_level_hu = b.level;
  const auto guided = ms::surface::mesh_from_mask(m, o);
  EXPECT_TRUE(guided.stats.closed);
  EXPECT_LE(max_distance_to_mask_boundary(guided.mesh, m), *std::max_element(kSpacing.begin(), kSpacing.end()));
  const auto binary = ms::surface::mesh_from_mask(m);
  EXPECT_NEAR(guided.stats.volume_mm3, binary.stats.volume_mm3, 0.02 * binary.stats.volume_mm3);
  // A CT on another grid is refused.
  ms::Volume shifted = b.ct;
  shifted.geom.origin[0] += 0.3;
  o.guide = &shifted;
  EXPECT_THROW(ms::surface::mesh_from_mask(m, o), ms::Error);
}

TEST(Surface, RemeshedEllipsoidIsIsotropicAndStaysOnTheMask) {
  const Ellipsoid e;
  const ms::Mask mask = ellipsoid_mask(e, kSpacing, rotation(kAxis, kAngle));
  for (double edge : {0.8, 1.5}) {
    ms::surface::Options opt;
    opt.target_edge_mm = edge;
    const auto r = ms::surface::mesh_from_mask(mask, opt);
    EXPECT_TRUE(r.repair.remeshed);
    EXPECT_EQ(r.repair.self_intersections_after, 0u);
    EXPECT_NEAR(mean_edge(r.mesh), edge, 0.25 * edge);
    EXPECT_TRUE(r.stats.closed);
    EXPECT_EQ(r.stats.genus, 0);
    EXPECT_NEAR(r.stats.volume_mm3, e.volume(), 0.02 * e.volume());
    EXPECT_LE(max_distance_to_mask_boundary(r.mesh, mask), *std::max_element(kSpacing.begin(), kSpacing.end()));
  }
}

// Masks finer than max_contour_spacing_mm are contoured on a bin-averaged grid
// (2 x 2 x 2 here): the same smoothing in total, a quarter of the triangles,
// and the surface where the full-resolution contour puts it.
TEST(Surface, FineMaskIsContouredOnABinnedGridInTheSamePlace) {
  const Ellipsoid e;
  const Vec3 fine{0.35, 0.4, 0.45};
  const ms::Mask mask = ellipsoid_mask(e, fine, rotation(kAxis, kAngle));
  ms::surface::Options raw;  // contours only: no decimation, no remeshing
  raw.target_faces = 0;
  raw.target_edge_mm = 0;
  ms::surface::Options full = raw;
  full.max_contour_spacing_mm = 0;
  const auto rb = ms::surface::mesh_from_mask(mask, raw);
  const auto rf = ms::surface::mesh_from_mask(mask, full);
  std::printf("contour faces: binned %zu, full resolution %zu; volume %.1f / %.1f mm3 (analytic %.1f)\n", rb.stats.faces,
              rf.stats.faces, rb.stats.volume_mm3, rf.stats.volume_mm3, e.volume());
  EXPECT_LT(rb.stats.faces, rf.stats.faces / 3);
  EXPECT_TRUE(rb.stats.closed);
  EXPECT_EQ(rb.stats.genus, 0);
  EXPECT_NEAR(rb.stats.volume_mm3, rf.stats.volume_mm3, 0.005 * rf.stats.volume_mm3);
  // The pipeline's defaults (decimation, remeshing) on the fine mask.
  const auto r = ms::surface::mesh_from_mask(mask);
  EXPECT_TRUE(r.stats.closed);
  EXPECT_EQ(r.stats.genus, 0);
  EXPECT_NEAR(r.stats.volume_mm3, e.volume(), 0.02 * e.volume());
  const double worst = max_distance_to_mask_boundary(r.mesh, mask);
  std::printf("largest vertex distance to the mask boundary: %.3f mm (voxel %.2f mm)\n", worst, fine[2]);
  EXPECT_LE(worst, fine[2]);
}

// A sharp cone (half-angle 14 degrees) on a fine oblique grid: the Gaussian
// pre-smoothing (0.6 mm) rounds its apex and its base rim inwards by more
// than one of these voxels; the surface is held to the mask boundary there.
TEST(Surface, SharpTipsOnAFineGridStayWithinOneVoxelOfTheMask) {
  const Vec3 base{3.0, -2.0, 5.0}, axis = ms::normalized(Vec3{1.0, -0.5, 2.0});
  const double height = 14.0, radius = 3.5;
  const auto inside = [&](const Vec3& p) {
    const double t = ms::dot(p - base, axis);
    return t >= 0 && t <= height && ms::norm(p - base - t * axis) <= radius * (1 - t / height);
  };
  const Vec3 fine{0.3, 0.35, 0.4};
  const ms::Mask mask = implicit_mask(inside, base + (0.5 * height) * axis, 0.5 * height + 3.0, fine, rotation(kAxis, kAngle));
  ms::surface::Options unheld;
  unheld.max_boundary_distance_voxels = 0;
  const auto loose = ms::surface::mesh_from_mask(mask, unheld);
  const auto r = ms::surface::mesh_from_mask(mask);
  const double worst_loose = max_distance_to_mask_boundary(loose.mesh, mask);
  const double worst = max_distance_to_mask_boundary(r.mesh, mask);
  std::printf("largest vertex distance to the mask boundary: %.3f mm unheld, %.3f mm held (%zu vertices pulled, "
              "at most %.3f mm; finest voxel %.2f mm)\n",
              worst_loose, worst, r.vertices_pulled, r.largest_pull_mm, fine[0]);
  EXPECT_GT(worst_loose, fine[0]);  // the case needs the hold
  EXPECT_LE(worst, fine[0] + 1e-6);
  EXPECT_GT(r.vertices_pulled, 0u);
  EXPECT_TRUE(r.stats.closed);
  EXPECT_TRUE(r.stats.manifold);
  EXPECT_EQ(r.stats.genus, 0);
  EXPECT_NEAR(r.stats.volume_mm3, loose.stats.volume_mm3, 0.01 * loose.stats.volume_mm3);
  // Only the outliers move: every other vertex is where it was.
  ASSERT_EQ(r.mesh.vertices.size(), loose.mesh.vertices.size());
  std::size_t moved = 0;
  for (std::size_t i = 0; i < r.mesh.vertices.size(); ++i) moved += r.mesh.vertices[i] != loose.mesh.vertices[i];
  EXPECT_EQ(moved, r.vertices_pulled);
}

TEST(Surface, PhantomMandibleIsWatertightAndOnTheMask) {
  ms::phantom::PhantomParams p;
  p.spacing = {1.0, 1.0, 1.0};
  p.fov_mm = {150, 140, 130};
  p.yaw_deg = 7;
  p.roll_deg = -4;
  p.noise_hu = 0;
  const auto ph = ms::phantom::generate(p);
  const auto r = ms::surface::mesh_from_mask(ph.mandible);
  const double mask_volume = static_cast<double>(ph.mandible.count()) * ph.mandible.geom.voxel_volume_mm3();
  std::printf("mandible: %zu faces, volume %.0f mm3 (mask %.0f), genus %d, mean edge %.2f mm\n", r.stats.faces,
              r.stats.volume_mm3, mask_volume, r.stats.genus, mean_edge(r.mesh));
  EXPECT_TRUE(r.stats.closed);
  EXPECT_TRUE(r.stats.manifold);
  // The ground-truth teeth touch their neighbours: each contact closes a loop
  // through the alveolar bone (a handle), so genus 0 needs --close-handles.
  EXPECT_GE(r.stats.genus, 0);
  EXPECT_EQ(r.repair.self_intersections_after, 0u);
  EXPECT_NEAR(r.stats.volume_mm3, mask_volume, 0.02 * mask_volume);
  EXPECT_NEAR(mean_edge(r.mesh), 1.0, 0.25);
  const double worst = max_distance_to_mask_boundary(r.mesh, ph.mandible);
  std::printf("largest vertex distance to the mask boundary: %.2f mm\n", worst);
  EXPECT_LE(worst, 1.0);  // one voxel

  ms::surface::Options closed_opt;
  closed_opt.close_handles_mm = 2.0;
  const auto c = ms::surface::mesh_from_mask(ph.mandible, closed_opt);
  std::printf("closed 2 mm: genus %d, volume %.0f mm3, largest distance %.2f mm\n", c.stats.genus, c.stats.volume_mm3,
              max_distance_to_mask_boundary(c.mesh, ph.mandible));
  EXPECT_EQ(c.stats.genus, 0);
  EXPECT_NEAR(c.stats.volume_mm3, mask_volume, 0.02 * mask_volume);
}

// A scan stored mirrored (flipped left<->right along the grid) must give the
// mirror image of the same mesh: decimation and CGAL remeshing follow the
// grid's order, so without the canonical orientation the two meshes were
// different triangulations (34 906 vs 34 812 vertices through the pipeline),
// which moved the SAF score by up to 5 % (docs/method.md, "Precision").
TEST(Surface, MirrorImageMaskGivesTheMirrorImageMesh) {
  ms::phantom::PhantomParams p;
  p.spacing = {1.0, 1.0, 1.0};
  p.fov_mm = {150, 140, 130};
  p.yaw_deg = 8;
  p.pitch_deg = 6;
  p.roll_deg = -5;
  p.side[0].ramus_height_mm = 3;  // not symmetric
  const auto a = ms::phantom::generate(p);
  p.mirror = true;
  const auto b = ms::phantom::generate(p);
  {
    // As the pipeline meshes: guided by the CT, closing handles automatically.
    ms::surface::Options o;
    o.close_handles_auto = true;
    o.closing_plugs_only = true;
    o.guide = &a.ct;
    const auto ma = ms::surface::mesh_from_mask(a.mandible, o);
    o.guide = &b.ct;
    const auto mb = ms::surface::mesh_from_mask(b.mandible, o);
    ASSERT_EQ(ma.mesh.vertices.size(), mb.mesh.vertices.size());
    ASSERT_EQ(ma.mesh.faces.size(), mb.mesh.faces.size());
    EXPECT_EQ(ma.closing_mm, mb.closing_mm);
    // The grid's mid-plane across i (the phantom flips along i).
    const auto& g = a.mandible.geom;
    const ms::Plane mid{g.index_to_lps(0.5 * (g.size[0] - 1.0), 0, 0), {g.direction[0], g.direction[3], g.direction[6]}};
    double worst = 0;
    for (std::size_t v = 0; v < ma.mesh.vertices.size(); ++v) {
      const ms::Vec3 r = mid.reflect(ma.mesh.vertices[v]);
      for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(r[c] - mb.mesh.vertices[v][c]));
    }
    EXPECT_LT(worst, 1e-6);
    std::size_t same = 0;
    for (std::size_t f = 0; f < ma.mesh.faces.size(); ++f) {
      const auto& fa = ma.mesh.faces[f];
      const auto& fb = mb.mesh.faces[f];
      same += fa[0] == fb[0] && fa[1] == fb[2] && fa[2] == fb[1];  // reflected: winding reversed
    }
    EXPECT_EQ(same, ma.mesh.faces.size());
    EXPECT_NEAR(ma.stats.volume_mm3, mb.stats.volume_mm3, 1e-6 * ma.stats.volume_mm3);
    EXPECT_GT(mb.stats.volume_mm3, 0);
  }
}

// A coarse mask (4.5 x 4.5 x 3 mm, OpenKBP-like) whose upper part touches
// the lower only across a voxel edge, as a one-voxel condylar neck does:
// the iso-surface alone leaves the two apart and the mesh kept the larger.
// Joined first (docs/surface.md, step 1), the mesh is one piece holding
// both, and the mirror-image mask still gives the mirror-image mesh.
TEST(Surface, PiecesTouchingAcrossAVoxelEdgeAreOneSurface) {
  ms::Mask m;
  m.geom.size = {12, 10, 14};
  m.geom.spacing = {4.5, 4.5, 3.0};
  m.data.assign(m.geom.voxel_count(), 0);
  for (std::size_t k = 2; k < 8; ++k)  // the ramus: 2 x 3 voxels wide
    for (std::size_t j = 3; j < 6; ++j)
      for (std::size_t i = 3; i < 5; ++i) m.data[m.geom.linear(i, j, k)] = 1;
  for (std::size_t k = 8; k < 12; ++k) m.data[m.geom.linear(5, 4, k)] = 1;  // the neck, one edge off the ramus
  ms::Mask mirrored = m;
  for (std::size_t k = 0; k < 14; ++k)
    for (std::size_t j = 0; j < 10; ++j)
      for (std::size_t i = 0; i < 12; ++i) mirrored.data[m.geom.linear(11 - i, j, k)] = m.data[m.geom.linear(i, j, k)];
  const auto a = ms::surface::mesh_from_mask(m);
  const auto b = ms::surface::mesh_from_mask(mirrored);
  EXPECT_GE(a.voxels_joining, 1u);
  EXPECT_EQ(a.voxels_joining, b.voxels_joining);
  // Both pieces: from the ramus's lower face (k 1.5, z 4.5 mm) to the neck's upper one (k 11.5, z 34.5 mm).
  double low = 1e30, high = -1e30;
  for (const auto& v : a.mesh.vertices) low = std::min(low, v[2]), high = std::max(high, v[2]);
  std::printf("z %.1f to %.1f mm, %zu voxel(s) joining\n", low, high, a.voxels_joining);
  EXPECT_NEAR(low, 4.5, 1.5);
  EXPECT_NEAR(high, 34.5, 1.5);
  EXPECT_EQ(a.stats.genus, 0);
  EXPECT_TRUE(a.stats.closed);
  ASSERT_EQ(a.mesh.vertices.size(), b.mesh.vertices.size());
  const ms::Plane mid{m.geom.index_to_lps(5.5, 0, 0), {1, 0, 0}};
  double worst = 0;
  for (std::size_t v = 0; v < a.mesh.vertices.size(); ++v) {
    const ms::Vec3 r = mid.reflect(a.mesh.vertices[v]);
    for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(r[c] - b.mesh.vertices[v][c]));
  }
  EXPECT_LT(worst, 1e-6);
}

TEST(SurfaceRepair, FillsAHoleAndKeepsTheShape) {
  const Ellipsoid e;
  ms::surface::Options opt;
  opt.target_edge_mm = 0;
  auto r = ms::surface::mesh_from_mask(ellipsoid_mask(e, kSpacing, rotation(kAxis, kAngle)), opt);
  const double volume = r.stats.volume_mm3;
  // Punch a hole: drop every face touching the vertices within 3 mm of one.
  const Vec3 centre = r.mesh.vertices[0];
  ms::Mesh holed;
  holed.vertices = r.mesh.vertices;
  for (const auto& f : r.mesh.faces) {
    bool near = false;
    for (int k = 0; k < 3; ++k) near |= ms::distance(r.mesh.vertices[f[k]], centre) < 3.0;
    if (!near) holed.faces.push_back(f);
  }
  ASSERT_LT(holed.faces.size(), r.mesh.faces.size());
  ASSERT_FALSE(ms::surface::measure(holed).closed);
  ms::surface::RepairOptions ro;
  ro.target_edge_mm = 0;
  const auto rep = ms::surface::repair_and_remesh(holed, ro);
  EXPECT_EQ(rep.holes_filled, 1u);
  const auto st = ms::surface::measure(holed);
  EXPECT_TRUE(st.closed);
  EXPECT_EQ(st.genus, 0);
  EXPECT_NEAR(st.volume_mm3, volume, 0.01 * volume);
}

TEST(SurfaceRepair, SplitsANonManifoldVertexAndKeepsTheLargestPart) {
  // Two tetrahedra sharing one vertex (a bow tie): non-manifold at the apex.
  ms::Mesh m;
  m.vertices = {{0, 0, 0}, {4, 0, 0}, {0, 4, 0}, {0, 0, 4}, {-1, 0, 0}, {0, -1, 0}, {0, 0, -1}};
  m.faces = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}, {0, 4, 5}, {0, 6, 4}, {0, 5, 6}, {4, 6, 5}};
  ms::surface::RepairOptions ro;
  ro.target_edge_mm = 0;
  const auto rep = ms::surface::repair_and_remesh(m, ro);
  EXPECT_GE(rep.non_manifold_vertices, 1u);
  EXPECT_EQ(rep.components_removed, 1u);
  const auto st = ms::surface::measure(m);
  EXPECT_TRUE(st.closed);
  EXPECT_TRUE(st.manifold);
  EXPECT_NEAR(st.volume_mm3, 64.0 / 6.0, 1e-9);  // the large tetrahedron, outward
}

TEST(Surface, EmptyMaskThrows) {
  ms::Mask m;
  m.geom.size = {8, 9, 10};
  m.data.assign(m.geom.voxel_count(), 0);
  EXPECT_THROW(ms::surface::mesh_from_mask(m), ms::Error);
  try {
    ms::surface::mesh_from_mask(m);
  } catch (const ms::Error& err) {
    EXPECT_EQ(err.code(), ms::ExitCode::GeometryFailed);
  }
}

TEST(Surface, SingleVoxelMaskGivesAClosedSurface) {
  // A one-voxel mask touching the grid corner: the crop padding must close it.
  ms::Mask m;
  m.geom.size = {4, 4, 4};
  m.data.assign(m.geom.voxel_count(), 0);
  m.data[m.geom.linear(0, 0, 0)] = 1;
  ms::surface::Options opt;
  opt.smoothing_sigma_mm = 0.0;
  const auto r = ms::surface::mesh_from_mask(m, opt);
  EXPECT_TRUE(r.stats.closed);
  EXPECT_EQ(r.stats.genus, 0);
  EXPECT_GT(r.stats.volume_mm3, 0);
  for (const auto& v : r.mesh.vertices)
    for (int a = 0; a < 3; ++a) EXPECT_LE(std::abs(v[a]), 1.0);  // around voxel (0,0,0) at the origin
}

// Unit tetrahedron with outward (counter-clockwise seen from outside) faces.
ms::Mesh unit_tetrahedron(const Vec3& offset) {
  ms::Mesh m;
  m.vertices = {offset + Vec3{0, 0, 0}, offset + Vec3{1, 0, 0}, offset + Vec3{0, 1, 0}, offset + Vec3{0, 0, 1}};
  m.faces = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  return m;
}

TEST(SurfaceMeasure, UnitTetrahedron) {
  for (const Vec3& off : {Vec3{0, 0, 0}, Vec3{-30.0, 12.5, 100.0}}) {  // translation-invariant when closed
    const ms::Mesh m = unit_tetrahedron(off);
    const auto s = ms::surface::measure(m);
    EXPECT_TRUE(s.closed);
    EXPECT_TRUE(s.manifold);
    EXPECT_EQ(s.genus, 0);
    EXPECT_EQ(s.vertices, 4u);
    EXPECT_EQ(s.faces, 4u);
    EXPECT_NEAR(s.volume_mm3, 1.0 / 6.0, 1e-9);
    EXPECT_NEAR(s.area_mm2, 1.5 + std::sqrt(3.0) / 2.0, 1e-12);
    EXPECT_GT(mean_outward_component(m, off + Vec3{0.25, 0.25, 0.25}), 0);

    ms::Mesh flipped = m;
    for (auto& f : flipped.faces) std::swap(f[1], f[2]);
    const auto sf = ms::surface::measure(flipped);
    EXPECT_TRUE(sf.closed);
    EXPECT_EQ(sf.genus, 0);
    EXPECT_NEAR(sf.volume_mm3, -1.0 / 6.0, 1e-9);
    EXPECT_NEAR(sf.area_mm2, s.area_mm2, 1e-12);
  }
}

TEST(SurfaceMeasure, OpenAndNonManifoldMeshes) {
  ms::Mesh open = unit_tetrahedron({0, 0, 0});
  open.faces.pop_back();
  const auto so = ms::surface::measure(open);
  EXPECT_FALSE(so.closed);
  EXPECT_TRUE(so.manifold);
  EXPECT_EQ(so.genus, -1);

  // A third triangle on edge (0,1): not manifold, not closed.
  ms::Mesh fin = unit_tetrahedron({0, 0, 0});
  fin.vertices.push_back({0.5, -1, 0.5});
  fin.faces.push_back({0, 1, 4});
  const auto sn = ms::surface::measure(fin);
  EXPECT_FALSE(sn.manifold);
  EXPECT_FALSE(sn.closed);

  const auto se = ms::surface::measure(ms::Mesh{});
  EXPECT_FALSE(se.closed);
  EXPECT_EQ(se.genus, -1);
}

TEST(SurfaceMeasure, TorusHasGenusOne) {
  // Quad torus (n x m grid of vertices), each quad split into two triangles.
  const int n = 24, m = 12;
  const double R = 10, r = 3;
  ms::Mesh t;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < m; ++j) {
      const double u = 2 * kPi * i / n, v = 2 * kPi * j / m;
      t.vertices.push_back({(R + r * std::cos(v)) * std::cos(u), (R + r * std::cos(v)) * std::sin(u), r * std::sin(v)});
    }
  auto id = [&](int i, int j) { return ((i + n) % n) * m + (j + m) % m; };
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < m; ++j) {
      t.faces.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
      t.faces.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
    }
  const auto s = ms::surface::measure(t);
  EXPECT_TRUE(s.closed);
  EXPECT_TRUE(s.manifold);
  EXPECT_EQ(s.genus, 1);
  // |volume| close to 2π²Rr² (inscribed polyhedron: slightly smaller).
  const double v = 2 * kPi * kPi * R * r * r;
  EXPECT_NEAR(std::abs(s.volume_mm3), v, 0.06 * v);
}

}  // namespace

namespace {
// A 30 x 20 x 20 mm block (1 mm voxels) pierced along y through its middle by
// a square tunnel `width` voxels wide: one handle; optionally a 2 mm groove
// along y in its top face (a crease, no handle).
ms::Mask pierced_block(int width, bool groove = false) {
  ms::Mask m;
  m.geom.size = {40, 30, 30};
  m.data.assign(m.geom.voxel_count(), 0);
  const long k0 = 15 - width / 2, i0 = 20 - width / 2;  // tunnel: [i0, i0 + width) x [k0, k0 + width)
  for (long k = 5; k < 25; ++k)
    for (long j = 5; j < 25; ++j)
      for (long i = 5; i < 35; ++i) {
        const bool tunnel = i >= i0 && i < i0 + width && k >= k0 && k < k0 + width;
        const bool cut = groove && i >= 28 && i < 30 && k >= 21;
        m.data[m.geom.linear(i, j, k)] = !tunnel && !cut;
      }
  return m;
}
}  // namespace

TEST(Surface, AutoClosingRemovesANarrowHandleAndKeepsAWideOne) {
  ms::surface::Options plain;
  const auto open = ms::surface::mesh_from_mask(pierced_block(2), plain);
  ASSERT_EQ(open.stats.genus, 1);
  EXPECT_EQ(open.closing_mm, 0);

  ms::surface::Options o;
  o.close_handles_auto = true;
  const auto closed = ms::surface::mesh_from_mask(pierced_block(2), o);
  EXPECT_EQ(closed.stats.genus, 0);
  EXPECT_GE(closed.closing_mm, 1.0);
  EXPECT_LE(closed.closing_mm, 2.0);
  EXPECT_EQ(closed.genus_before_closing, 1);
  EXPECT_TRUE(closed.closing_plugs_only);  // only the plug in the tunnel was kept
  EXPECT_NEAR(closed.stats.volume_mm3, open.stats.volume_mm3, 0.05 * open.stats.volume_mm3);

  // A 10 mm tunnel is anatomy, not an artefact: no radius up to 3 mm closes it,
  // and the unclosed surface is kept.
  const auto wide = ms::surface::mesh_from_mask(pierced_block(10), o);
  EXPECT_EQ(wide.stats.genus, 1);
  EXPECT_EQ(wide.closing_mm, 0);
  EXPECT_EQ(wide.genus_before_closing, 1);

  // An explicit radius wins over auto.
  ms::surface::Options fixed = o;
  fixed.close_handles_mm = 3;
  EXPECT_EQ(ms::surface::mesh_from_mask(pierced_block(2), fixed).closing_mm, 3.0);
}

TEST(Surface, AutoClosingPlugsTheHandleAndLeavesACreaseOpen) {
  // The whole closing fills the groove as well as the tunnel; the automatic
  // closing keeps only a plug in the tunnel (genus 0 all the same), so the
  // groove's faces stay where the mask has them.
  const ms::Mask m = pierced_block(2, true);
  ms::surface::Options o;
  o.close_handles_auto = true;
  const auto plugged = ms::surface::mesh_from_mask(m, o);
  ms::surface::Options fixed;
  fixed.close_handles_mm = plugged.closing_mm;  // the whole closing at the same radius
  const auto whole = ms::surface::mesh_from_mask(m, fixed);
  const auto open = ms::surface::mesh_from_mask(m, ms::surface::Options{});
  ASSERT_EQ(open.stats.genus, 1);
  EXPECT_EQ(plugged.stats.genus, 0);
  EXPECT_EQ(whole.stats.genus, 0);
  EXPECT_TRUE(plugged.closing_plugs_only);
  EXPECT_FALSE(whole.closing_plugs_only);
  // Material added: a few voxels of plug against the tunnel's 80 and the groove's ~60.
  const double added_plug = plugged.stats.volume_mm3 - open.stats.volume_mm3;
  const double added_whole = whole.stats.volume_mm3 - open.stats.volume_mm3;
  std::printf("added by the closing: plugs %.1f mm3, whole %.1f mm3\n", added_plug, added_whole);
  EXPECT_LT(added_plug, 0.5 * added_whole);
  // The groove's floor (voxel boundary z = 20.5, between its walls) is part
  // of the plugged surface and buried under the whole closing's fill.
  auto on_floor = [&](const ms::surface::Result& r) {
    int n = 0;
    for (const auto& v : r.mesh.vertices) {
      const ms::Vec3 q = m.geom.lps_to_index(v);
      n += q[0] > 28.0 && q[0] < 29.0 && q[2] > 19.5 && q[2] < 21.5 && q[1] > 7 && q[1] < 22;
    }
    return n;
  };
  std::printf("vertices on the groove's floor: plugs %d, whole %d\n", on_floor(plugged), on_floor(whole));
  EXPECT_GE(on_floor(plugged), 10);
  EXPECT_EQ(on_floor(whole), 0);
}

TEST(Surface, ClosingByDistanceTransformsEqualsTheBallClosing) {
  // Random blobs on a small anisotropic grid: the closing through two exact
  // distance transforms equals the brute-force closing by the Euclidean ball
  // (dilation, then erosion, counting only voxels of the grid).
  ms::Mask m;
  m.geom.size = {22, 19, 15};
  m.geom.spacing = {0.7, 0.9, 1.3};
  m.data.assign(m.geom.voxel_count(), 0);
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> ux(0, 21), uy(0, 18), uz(0, 14);
  for (int k = 0; k < 40; ++k) m.data[m.geom.linear(ux(rng), uy(rng), uz(rng))] = 1;
  // Radii off every voxel distance of this grid (no ties at the boundary).
  for (const double r : {1.05, 2.05, 2.75}) {
    const auto fast = ms::surface::closed(m, r);
    const auto& g = m.geom;
    auto mm = [&](std::size_t a, std::size_t b, double s) { return (static_cast<double>(a) - static_cast<double>(b)) * s; };
    auto within = [&](std::size_t i, std::size_t j, std::size_t k, std::size_t x, std::size_t y, std::size_t z) {
      const double dx = mm(i, x, g.spacing[0]), dy = mm(j, y, g.spacing[1]), dz = mm(k, z, g.spacing[2]);
      return dx * dx + dy * dy + dz * dz <= r * r;
    };
    std::vector<std::uint8_t> dil(g.voxel_count(), 0);
    for (std::size_t k = 0; k < g.size[2]; ++k)
      for (std::size_t j = 0; j < g.size[1]; ++j)
        for (std::size_t i = 0; i < g.size[0]; ++i)
          for (std::size_t z = 0; z < g.size[2] && !dil[g.linear(i, j, k)]; ++z)
            for (std::size_t y = 0; y < g.size[1] && !dil[g.linear(i, j, k)]; ++y)
              for (std::size_t x = 0; x < g.size[0]; ++x)
                if (m.data[g.linear(x, y, z)] && within(i, j, k, x, y, z)) {
                  dil[g.linear(i, j, k)] = 1;
                  break;
                }
    std::size_t differ = 0, set = 0;
    for (std::size_t k = 0; k < g.size[2]; ++k)
      for (std::size_t j = 0; j < g.size[1]; ++j)
        for (std::size_t i = 0; i < g.size[0]; ++i) {
          bool keep = true;
          for (std::size_t z = 0; z < g.size[2] && keep; ++z)
            for (std::size_t y = 0; y < g.size[1] && keep; ++y)
              for (std::size_t x = 0; x < g.size[0] && keep; ++x)
                if (!dil[g.linear(x, y, z)] && within(i, j, k, x, y, z)) keep = false;
          differ += keep != (fast.data[g.linear(i, j, k)] != 0);
          set += keep;
        }
    EXPECT_EQ(differ, 0u) << "r " << r;
    if (r > 2.5) EXPECT_GT(set, 40u);  // the closing joined seeds: more voxels than it was given
  }
}

// mandible.ply: a binary PLY that VTK's own reader loads with every vertex
// and triangle as written (VTK 9.1's writer left the file empty).
TEST(Surface, PlyReadsBackThroughVtksReader) {
  ms::Mesh m;
  m.vertices = {{0, 0, 0}, {10.5, 0, 0}, {0, 20.25, 0}, {0, 0, -30.125}};
  m.faces = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  const std::string path = (std::filesystem::temp_directory_path() / "mandisym_test_tetra.ply").string();
  ms::surface::write_ply(m, path);
  vtkNew<vtkPLYReader> r;
  r->SetFileName(path.c_str());
  r->Update();
  vtkPolyData* pd = r->GetOutput();
  ASSERT_EQ(pd->GetNumberOfPoints(), 4);
  ASSERT_EQ(pd->GetNumberOfPolys(), 4);
  for (vtkIdType i = 0; i < 4; ++i)
    for (int k = 0; k < 3; ++k) EXPECT_FLOAT_EQ(pd->GetPoint(i)[k], m.vertices[static_cast<std::size_t>(i)][k]);
  vtkIdType n = 0;
  const vtkIdType* ids = nullptr;
  pd->GetPolys()->InitTraversal();
  for (std::size_t f = 0; pd->GetPolys()->GetNextCell(n, ids); ++f) {
    ASSERT_EQ(n, 3);
    for (int k = 0; k < 3; ++k) EXPECT_EQ(ids[k], m.faces[f][k]);
  }
  std::filesystem::remove(path);
}
