// CGAL side of the surface stage: polygon-soup repair, hole filling,
// self-intersection removal, isotropic remeshing, outward orientation
// (docs/surface.md). No VTK or ITK headers here.
#include "surface/surface.h"
#include "core/error.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/connected_components.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/orientation.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/remesh.h>
#include <CGAL/Polygon_mesh_processing/repair.h>
#include <CGAL/Polygon_mesh_processing/repair_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/repair_self_intersections.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Polygon_mesh_processing/triangulate_hole.h>
#include <CGAL/Surface_mesh.h>

#include <array>
#include <cstdio>
#include <iterator>
#include <cmath>
#include <set>
#include <vector>

#include "core/debug_lap.h"

namespace ms::surface {
namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using SM = CGAL::Surface_mesh<K::Point_3>;
namespace PMP = CGAL::Polygon_mesh_processing;

// Fills every hole (border cycle) with a refined, faired patch.
std::size_t fill_holes(SM& sm) {
  std::vector<SM::Halfedge_index> borders;
  PMP::extract_boundary_cycles(sm, std::back_inserter(borders));
  for (auto h : borders) {
    std::vector<SM::Face_index> patch_faces;
    std::vector<SM::Vertex_index> patch_vertices;
    PMP::triangulate_refine_and_fair_hole(sm, h, std::back_inserter(patch_faces), std::back_inserter(patch_vertices));
  }
  return borders.size();
}

using FacePairs = std::vector<std::pair<SM::Face_index, SM::Face_index>>;

FacePairs self_intersecting_pairs(const SM& sm) {
  FacePairs pairs;
  PMP::self_intersections<CGAL::Parallel_if_available_tag>(faces(sm), sm, std::back_inserter(pairs));
  return pairs;
}

std::size_t count_self_intersections(const SM& sm) { return self_intersecting_pairs(sm).size(); }

// Removes the self-intersections of the given pairs working on their
// neighbourhood only (3 rings of faces around them): CGAL's repair searches
// its whole range for intersections at every step (7 steps at most), which
// on a 70k-face mandible with 3 pairs took 0.8 s. Returns the pairs left in
// the whole mesh; when some remain, the repair runs once more on every face.
// Holes the repair leaves are filled (counted in holes_filled).
FacePairs remove_self_intersections_near(SM& sm, const FacePairs& pairs, std::size_t& holes_filled) {
  std::set<SM::Face_index> region;
  for (const auto& [a, b] : pairs) region.insert({a, b});
  for (int ring = 0; ring < 3; ++ring) {
    const std::vector<SM::Face_index> current(region.begin(), region.end());
    for (SM::Face_index f : current)
      for (SM::Vertex_index v : vertices_around_face(sm.halfedge(f), sm))
        for (SM::Face_index g : faces_around_target(sm.halfedge(v), sm))
          if (g != SM::null_face()) region.insert(g);
  }
  PMP::experimental::remove_self_intersections(region, sm);
  holes_filled += fill_holes(sm);
  FacePairs left = self_intersecting_pairs(sm);
  if (!left.empty()) {
    PMP::experimental::remove_self_intersections(sm);
    holes_filled += fill_holes(sm);
    left = self_intersecting_pairs(sm);
  }
  return left;
}

}  // namespace

// At most this many self-intersecting triangle pairs per triangle before
// repair (1 %): see repair_and_remesh.
constexpr double kMaxIntersectingPairsPerFace = 0.01;
// Patient coordinates beyond 10 m are not a scanner's (mm).
constexpr double kMaxCoordinateMm = 1e4;

RepairReport repair_and_remesh(Mesh& mesh, const RepairOptions& opt) {
  RepairReport rep;
  DebugLap lap("MANDISYM_DEBUG_SURFACE", "surface");
  // CGAL's exact predicates convert every coordinate to a rational: a
  // non-finite one raises SIGFPE inside GMP. Scan geometry is checked at
  // ingest; this keeps the stage safe on its own.
  for (const auto& v : mesh.vertices)
    for (double c : v)
      if (!(std::abs(c) <= kMaxCoordinateMm))
        throw Error(ExitCode::GeometryFailed, "the surface has a vertex at a non-finite or absurd coordinate (beyond 10 m)");
  std::vector<K::Point_3> points;
  points.reserve(mesh.vertices.size());
  for (const auto& v : mesh.vertices) points.emplace_back(v[0], v[1], v[2]);
  std::vector<std::array<std::size_t, 3>> polygons;
  polygons.reserve(mesh.faces.size());
  for (const auto& f : mesh.faces)
    polygons.push_back({static_cast<std::size_t>(f[0]), static_cast<std::size_t>(f[1]), static_cast<std::size_t>(f[2])});

  // Soup repair: duplicate points and polygons, degenerate triangles; a
  // consistent orientation (non-manifold vertices are split apart) unless
  // the soup already is an oriented manifold (flying edges' usually is).
  PMP::repair_polygon_soup(points, polygons);
  const std::size_t before = points.size();
  if (!PMP::is_polygon_soup_a_polygon_mesh(polygons) && !PMP::orient_polygon_soup(points, polygons))
    rep.non_manifold_vertices = points.size() - before;
  SM sm;
  PMP::polygon_soup_to_polygon_mesh(points, polygons, sm);
  rep.non_manifold_vertices += PMP::duplicate_non_manifold_vertices(sm);
  rep.components_removed = PMP::keep_largest_connected_components(sm, 1);
  sm.collect_garbage();
  lap("  soup repair");

  rep.holes_filled = fill_holes(sm);
  rep.self_intersections_before = count_self_intersections(sm);
  if (lap.on()) std::fprintf(stderr, "  surface   %zu self-intersecting pairs in %zu faces before repair\n", rep.self_intersections_before, static_cast<std::size_t>(sm.number_of_faces()));
  // Degenerate input (docs/surface.md, "Repair"): the surface of a voxel
  // mask does not intersect itself (0 pairs on every real scan here); a few
  // pairs come from decimation. Thousands per hundred faces are noise or a
  // corrupt mask, on which CGAL's repair runs for minutes.
  if (static_cast<double>(rep.self_intersections_before) > kMaxIntersectingPairsPerFace * static_cast<double>(sm.number_of_faces()))
    throw Error(ExitCode::GeometryFailed, "the surface intersects itself in " + std::to_string(rep.self_intersections_before) +
                                              " triangle pairs (of " + std::to_string(sm.number_of_faces()) +
                                              " triangles): not the surface of a bone (noise, or a corrupt mask)");
  if (rep.self_intersections_before > 0) CGAL::Polygon_mesh_processing::experimental::remove_self_intersections(sm);
  lap("  holes, intersections");

  if (opt.target_edge_mm > 0) {
    PMP::isotropic_remeshing(faces(sm), opt.target_edge_mm, sm,
                             CGAL::parameters::number_of_iterations(opt.remesh_iterations).number_of_relaxation_steps(1));
    sm.collect_garbage();
    lap("  isotropic remeshing");
    rep.remeshed = true;
    if (!CGAL::is_closed(sm)) rep.holes_filled += fill_holes(sm);
    const FacePairs pairs = self_intersecting_pairs(sm);
    rep.self_intersections_after = pairs.size();
    lap("  remesh check");
    if (lap.on()) std::fprintf(stderr, "  surface   %zu self-intersecting pairs after remeshing\n", pairs.size());
    if (!pairs.empty()) {
      rep.self_intersections_after = remove_self_intersections_near(sm, pairs, rep.holes_filled).size();
      lap("  remesh repairs");
    }
  } else {
    rep.self_intersections_after = count_self_intersections(sm);
    lap("  check");
  }
  if (CGAL::is_closed(sm)) PMP::orient_to_bound_a_volume(sm);  // outward
  lap("  orient");

  Mesh out;
  out.vertices.reserve(sm.number_of_vertices());
  std::vector<int> id(sm.num_vertices(), -1);
  for (auto v : sm.vertices()) {
    id[v.idx()] = static_cast<int>(out.vertices.size());
    const auto& p = sm.point(v);
    out.vertices.push_back({p.x(), p.y(), p.z()});
  }
  out.faces.reserve(sm.number_of_faces());
  for (auto f : sm.faces()) {
    std::array<int, 3> t{};
    int k = 0;
    for (auto v : CGAL::vertices_around_face(sm.halfedge(f), sm)) {
      if (k < 3) t[static_cast<std::size_t>(k)] = id[v.idx()];
      ++k;
    }
    if (k == 3) out.faces.push_back(t);
  }
  mesh = std::move(out);
  return rep;
}

}  // namespace ms::surface
