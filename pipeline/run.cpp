// `mandisym run`: ingest -> segment -> surface -> landmarks -> reference ->
// asymmetry -> report. Outputs are staged in a hidden folder inside OUTDIR and
// moved into place only when every stage succeeded (results.json last), so a
// failed or killed run never leaves a report that looks complete. Two
// output-only jobs run on a second thread beside the main stages: the mask
// file and QC slices (ITK) beside surface..asymmetry, the cranial plane beside
// asymmetry; no library is used by two threads at once.
#include <chrono>
#include <cmath>
#include <future>
#include <tuple>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <vector>

#include "asymmetry/measures.h"
#include "atlas/atlas.h"
#include "asymmetry/saf.h"
#include "core/error.h"
#include "core/memory.h"
#include "core/digest.h"
#include "geometry/mesh_geometry.h"
#include "io/volume_io.h"
#include "landmarks/landmarks.h"
#include "reports/render.h"
#include "pipeline/commands.h"
#include "pipeline/cranial.h"
#include "pipeline/dicom_export.h"
#include "threads/threads.h"
#include "pipeline/staging.h"
#include "liblog/library_log.h"
#include "reference/reference.h"
#include "reports/figures.h"
#include "reports/writers.h"
#include "segmentation/segmentation.h"
#include "surface/surface.h"

namespace fs = std::filesystem;

namespace ms::pipeline {

const cli::CommandSpec& run_spec() {
  static const cli::CommandSpec s{
      "run",
      "Measure mandibular asymmetry in one head CT and write a report.",
      "INPUT is a folder holding a DICOM CT series (searched recursively) or a volume file (.nii, .nii.gz, .nrrd, "
      ".nhdr, .mha, .mhd) in HU. Writes report.html, results.json, mandible_mask.nii.gz, mandible.vtp/.stl/.ply, "
      "landmarks.mrk.json, symmetry_plane.mrk.json, results.csv, qc/ and log.txt into OUTDIR.",
      {{"INPUT", "DICOM folder or volume file"}},
      {{"output", "OUTDIR", "output folder (created; existing outputs are replaced)", ""},
       {"hu-offset", "HU", "added to every voxel after the file's own rescale (e.g. -1024 for HU+1024 data)", "0", -4096, 4096},
       {"series", "UID", "series to use when the folder holds several (see mandisym inspect)", "finest CT series covering the scan"},
       {"orientation", "CODE", "volume files: where the i, j, k axes point, e.g. LPS or LAI (for files without orientation)", "from the file"},
       {"max-memory", "SIZE", "memory budget of this run, e.g. 2G or 800M: a scan whose estimated peak (voxels x 4 B x 5) exceeds "
                              "it is refused before it is decoded (docs/security.md)", "75 % of this machine's (or cgroup's) memory"},
       {"allow-external-data", "", "volume headers (.nhdr, .mhd) may name data files outside their own folder", ""},
       {"bone-threshold", "HU", "bone threshold for segmentation", "250", -1000, 3000},
       {"mask", "FILE", "use this segmentation instead of the automatic one (label map in any ITK format)", ""},
       {"label", "N", "with --mask: the mandible's label (TotalSegmentator craniofacial_structures: 1)", "the only label", 0, 65535},
       {"target-faces", "N", "decimate the surface above this many triangles", "60000", 1000, 2e6},
       {"edge-length", "MM", "isotropic remeshing edge length of the surface (0 = no CGAL repair/remeshing); the SAF score is "
                          "computed on a 1 mm remeshing whatever this is; 0 or 0.25 to 5", "1", 0, 5},
       {"close-handles", "MM|auto", "closing radius before meshing, removes handles such as teeth in contact; auto = only "
                                    "when the surface has handles, the smallest of 1, 2, 3 mm that removes them (0 = never)", "auto"},
       {"disk-radius", "MM", "radius of the Dirichlet disks at landmarks for harmonic fields", "2", 0.1, 10},
       {"saf-smoothing", "MM", "heat-kernel sigma smoothing each signed angle field before the mirror comparison "
                               "(0 = per face, METHOD.md's literal definition)", "6", 0, 30},
       {"saf-anchors", "WHICH", "where the Dirichlet disks sit: reference (the symmetric reference configuration) or "
                                "detected (the detected landmarks)", "reference"},
       {"no-figures", "", "do not write QC figures", ""},
       {"no-cranial", "", "do not fit the cranial mid-sagittal plane (bone above the condyles)", ""},
       {"deidentify", "", "leave out of every output the DICOM strings that can identify a study: UIDs, dates, "
                          "descriptions, the input path (dicom/ objects keep the UIDs that tie them to the CT; docs/pacs.md)", ""},
       {"dicom", "", "DICOM input: also write dicom/seg.dcm (the mask as DICOM SEG), dicom/sr.dcm (TID 1500 measurement "
                     "report) and dicom/report.dcm (report.pdf encapsulated), new series in the CT's study (docs/pacs.md)", ""},
       {"threads", "N", "threads this run may use (OpenMP, ITK, VTK); `batch` sets it per study; 0 = all", "0 (the cores this process may use)", 0, 1024},
       {"quiet", "", "print nothing but errors", ""},
       {"help", "", "show this help", ""}}};
  return s;
}

namespace {

// Shortest text that reads back as the same number ("250", "0.6").
std::string num(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.10g", v);
  return b;
}

class Stopwatch {
 public:
  double lap() {
    const auto now = std::chrono::steady_clock::now();
    const double s = std::chrono::duration<double>(now - last_).count();
    last_ = now;
    return s;
  }

 private:
  std::chrono::steady_clock::time_point last_ = std::chrono::steady_clock::now();
};

// SHA-256 of a file's bytes (hex).
std::string file_sha256(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  Sha256 h;
  std::vector<char> buf(1 << 20);
  while (f) {
    f.read(buf.data(), static_cast<std::streamsize>(buf.size()));
    h.update(buf.data(), static_cast<std::size_t>(f.gcount()));
  }
  return h.hex_digest();
}

// Every option of `run`, read and checked before the scan is (a bad value
// costs no ingest). Ranges (docs/security.md, "Options"): edge lengths from a
// quarter of the finest CT voxel here (0.25 mm) to the coarsest (5 mm),
// disks and smoothing within a mandible's landmark neighbourhood (a disk
// over 10 mm covers a condylar head, 15-20 mm wide; Dirichlet disks that
// overlap leave no field), HU within the 12-bit CT range plus offsets.
struct RunSettings {
  io::ReadOptions read;
  segmentation::Options segmentation;
  surface::Options surface;
  asymmetry::SafOptions saf;
  std::string anchors;
  int label = -1;
};

RunSettings run_settings(const cli::Args& args) {
  RunSettings r;
  r.read.hu_offset = args.ranged("hu-offset", 0.0, "HU");
  r.read.series_uid = args.get("series");
  r.read.orientation = args.get("orientation");
  if (args.has("max-memory")) r.read.max_memory_bytes = parse_memory_size(args.get("max-memory"));
  r.read.allow_external_data_files = args.has("allow-external-data");
  r.segmentation.bone_threshold_hu = args.ranged("bone-threshold", r.segmentation.bone_threshold_hu, "HU");
  if (args.has("label") && !args.has("mask")) throw Error(ExitCode::Usage, "--label needs --mask");
  const double label = args.has("label") ? args.ranged("label", -1, "") : -1.0;
  if (label != std::floor(label)) throw Error(ExitCode::Usage, "--label: expected a whole number");
  r.label = static_cast<int>(label);
  r.saf.disk_radius_mm = args.ranged("disk-radius", r.saf.disk_radius_mm, "mm");
  r.saf.smoothing_mm = args.ranged("saf-smoothing", r.saf.smoothing_mm, "mm");
  r.anchors = args.get("saf-anchors", "reference");
  if (r.anchors != "reference" && r.anchors != "detected")
    throw Error(ExitCode::Usage, "--saf-anchors must be reference or detected, not '" + r.anchors + "'");
  r.surface.target_faces = static_cast<std::size_t>(args.ranged("target-faces", static_cast<double>(r.surface.target_faces), ""));
  r.surface.target_edge_mm = args.ranged("edge-length", r.surface.target_edge_mm, "mm");
  if (r.surface.target_edge_mm > 0 && r.surface.target_edge_mm < 0.25)
    throw Error(ExitCode::Usage, "--edge-length: " + num(r.surface.target_edge_mm) + " mm is below 0.25 mm (0 turns remeshing off)");
  r.surface.close_handles_auto = args.get("close-handles", "auto") == "auto";
  if (!r.surface.close_handles_auto) r.surface.close_handles_mm = args.number_in("close-handles", r.surface.close_handles_mm, 0, 10, "mm");
  return r;
}

// Progress lines (log.txt, and stdout unless --quiet) and stage timings.
class Progress {
 public:
  Progress(bool quiet, std::vector<std::pair<std::string, double>>& timings) : quiet_(quiet), timings_(timings) {}
  void say(const std::string& line) {
    log_ << line << "\n";
    if (!quiet_) std::cout << line << std::endl;
  }
  void stage(const char* name, int k) {
    const double t = sw_.lap();
    timings_.emplace_back(name, t);
    char b[128];
    std::snprintf(b, sizeof b, "[%d/6] %-10s %7.2f s", k, name, t);
    say(b);
  }
  double lap() { return sw_.lap(); }
  std::string text() const { return log_.str(); }

 private:
  bool quiet_;
  std::vector<std::pair<std::string, double>>& timings_;
  Stopwatch sw_;
  std::ostringstream log_;
};

// 1. Ingest: the scan in HU and LPS (docs/ingest.md); a de-identified run
// keeps none of the strings that can identify the study.
io::LoadedScan ingest_stage(const std::string& input, const RunSettings& rs, bool deidentify, reports::RunSummary& S) {
  io::LoadedScan scan = io::read_scan(input, rs.read);
  S.scan = scan.info;
  if (deidentify) {
    S.scan.path = "(removed)";
    S.scan.series_uid.clear();
    S.scan.study_date.clear();
    S.scan.series_description.clear();
  }
  S.grid = scan.volume.geom;
  for (const auto& w : scan.info.warnings) S.warnings.push_back("ingest: " + w);
  return scan;
}

// 2. Segmentation: the label map given with --mask, or the automatic one.
// An external mask still gets the mandible atlas placed in the CT: the head
// frame checks the palatal plane against its pose and falls back to it
// (docs/landmarks.md, "Head frame order"), as with the automatic one.
segmentation::Result segment_stage(const Volume& ct, const RunSettings& rs, const cli::Args& args, reports::RunSummary& S) {
  segmentation::Result seg;
  if (args.has("mask")) {
    seg = segmentation::from_label_map(ct.geom, io::read_label_map(args.get("mask")), rs.label, args.get("mask"));
    if (rs.segmentation.use_atlas) seg.atlas = atlas::fit_ct(ct, rs.segmentation.bone_threshold_hu);
  } else {
    seg = segmentation::segment_mandible(ct, rs.segmentation);
  }
  S.segmentation_method = seg.method;
  S.seg_voxels = seg.voxels;
  S.seg_volume_mm3 = seg.volume_mm3;
  S.truncated = seg.truncated;
  S.seg_threshold_hu = seg.threshold_hu;
  S.seg_offset_hu = seg.offset_hu;
  S.seg_separation_mm = seg.separation_radius_mm;
  S.seg_marker_source = seg.marker_source;
  S.atlas = seg.atlas;
  S.atlas_agreement = seg.atlas_agreement;
  S.atlas_halves_balance = seg.atlas_halves_balance;
  S.image_zone_dice = seg.image_zone_dice;
  S.taken_image_zone_dice = seg.taken_image_zone_dice;
  S.welded_occlusion_mm2 = seg.welded_occlusion_mm2;
  S.occlusion_cut_refused = seg.occlusion_cut_refused;
  for (const auto& w : seg.warnings) S.warnings.push_back("segmentation: " + w);
  return seg;
}

// 3. Surface, between voxels where the CT crosses the level the segmentation
// placed the mask's boundary at (not for external masks: their boundary is
// theirs), with the warnings its repair earns.
surface::Result surface_stage(const Volume& ct, const segmentation::Result& seg, surface::Options mo, reports::RunSummary& S) {
  if (seg.surface_level_hu != 0 && seg.mask.geom.same_grid(ct.geom, 1e-6)) {
    mo.guide = &ct;
    mo.guide_level_hu = seg.surface_level_hu;
    mo.guide_soft_hu = 40.0 + seg.offset_hu;  // the offset is the soft-tissue peak's distance from 40 HU
  }
  S.parameters["surface_guide_level_hu"] = mo.guide ? num(mo.guide_level_hu) : "none";
  surface::Result surf = surface::mesh_from_mask(seg.mask, mo);
  S.mesh = surf.stats;
  S.surface = surf.mesh;
  S.closing_mm = surf.closing_mm;
  S.genus_before_closing = surf.genus_before_closing;
  S.closing_plugs_only = surf.closing_plugs_only;
  S.vertices_pulled = surf.vertices_pulled;
  S.voxels_joining = surf.voxels_joining;
  if (surf.largest_pull_mm > 0.25 * std::max(mo.target_edge_mm, 1.0))
    S.warnings.push_back("surface: " + std::to_string(surf.vertices_pulled) + " vertices pulled up to " + num(surf.largest_pull_mm) +
                         " mm back to within a voxel of the mask (docs/surface.md); the triangles around them were not re-checked");
  if (surf.genus_before_closing > 0 && surf.closing_mm > 0)
    S.warnings.push_back("surface: " + std::to_string(surf.genus_before_closing) + " handle(s) (e.g. teeth in contact) removed by " +
                         (surf.closing_plugs_only ? "plugs from a " : "a ") + num(surf.closing_mm) +
                         " mm closing before meshing; they would distort the harmonic fields (--close-handles 0 keeps them)");
  if (!surf.stats.closed) S.warnings.push_back("surface: the mesh is not closed; distances near holes are unreliable");
  if (surf.stats.genus > 0)
    S.warnings.push_back("surface: genus " + std::to_string(surf.stats.genus) +
                         " (handles, e.g. teeth in contact or canals) that a 3 mm closing does not remove; geodesic distances and "
                         "harmonic fields may shortcut through them");
  if (surf.repair.self_intersections_after > 0)
    S.warnings.push_back("surface: " + std::to_string(surf.repair.self_intersections_after) + " self-intersecting triangle pairs remain");
  return surf;
}

// 4. Landmarks, in the head's frame: the mandible's symmetry plane gives yaw
// and roll, the palatal plane (nasal floor) gives pitch.
void landmarks_stage(const Volume& ct, const segmentation::Result& seg, const Mesh& mesh, reports::RunSummary& S) {
  landmarks::Options lo;
  if (seg.truncated) lo.scan_grid = &seg.scanned_grid;  // landmarks at the cut are missing, not guessed
  landmarks::PalateOptions po;
  po.plate_hu += seg.offset_hu;  // thresholds follow the scan's calibration offset
  po.air_hu += seg.offset_hu;
  if (seg.atlas.found) {
    po.atlas_superior = seg.atlas.pose.superior();
    static const atlas::ProcessTops tops = atlas::process_tops(atlas::shipped());
    for (double side : {1.0, -1.0}) {
      lo.atlas_condyles.push_back(seg.atlas.pose.apply({side * tops.condyle[0], tops.condyle[1], tops.condyle[2]}));
      lo.atlas_coronoids.push_back(seg.atlas.pose.apply({side * tops.coronoid[0], tops.coronoid[1], tops.coronoid[2]}));
    }
  }
  S.landmarks = landmarks::detect_in_head_frame(ct, mesh, lo, po, &S.palate, &S.head_frame);
  S.landmarks_off_surface_mm = 0;  // eight queries: cheaper than building an index
  for (const auto& [name, p] : S.landmarks.landmarks.points)
    S.landmarks_off_surface_mm = std::max(S.landmarks_off_surface_mm, distance(p, geometry::closest_point_brute_force(mesh, p)));
  for (const auto& w : S.landmarks.warnings) S.warnings.push_back(w);
  for (const auto& m : S.landmarks.missing) {
    const auto why = S.landmarks.why_missing.find(m);
    S.warnings.push_back("landmarks: " + m + " missing: " + (why != S.landmarks.why_missing.end() ? why->second : "not found"));
  }
}

// 5. Symmetry plane and symmetric reference configuration.
void reference_stage(bool truncated, const Mesh& mesh, reports::RunSummary& S) {
  reference::Options ro_fit;
  ro_fit.superior = S.head_superior();  // asymmetry vectors in the head's frame, like the landmarks
  try {
    S.reference = reference::fit(S.landmarks.landmarks, &mesh, ro_fit);
  } catch (const Error& e) {
    if (e.code() != ExitCode::GeometryFailed || !truncated) throw;
    std::string missing;
    for (const auto& m : S.landmarks.missing) missing += (missing.empty() ? "" : ", ") + m;
    throw Error(ExitCode::GeometryFailed, std::string(e.what()) + ": the mandible is cut by the scan's edge (" + missing +
                                              " missing); nothing to mirror one side onto the other");
  }
  for (const auto& w : S.reference.warnings) S.warnings.push_back("reference: " + w);
}

// The cranial mid-sagittal plane (optional: a failure costs the plane, not
// the run), fitted on the second core beside the asymmetry stage. The
// pointers must outlive the future.
std::future<reference::CranialResult> start_cranial(const Volume& ct, const segmentation::Result& seg, const RunSettings& rs,
                                                    const Mesh& mesh, const reports::RunSummary& S) {
  CranialInputs ci;
  ci.ct = &ct;
  ci.mandible = &seg.mask;
  ci.threshold_hu = seg.threshold_hu > 0 ? seg.threshold_hu : rs.segmentation.bone_threshold_hu;
  ci.mandible_plane = S.reference.plane;
  ci.landmarks = S.landmarks.landmarks;
  ci.mandible_surface = &mesh;
  return std::async(threads::side_task_launch(), [ci] { return fit_cranial_plane(ci); });
}

// Per-vertex maps the outputs carry beside the summary.
struct AsymmetryMaps {
  asymmetry::Regions regions;
  std::vector<double> saf_lateral;  // asymmetry::lateral_map per vertex (VTP)
};

// The SAF score is defined at 1 mm edges (asymmetry::kSafEdgeMm): a surface
// meshed at another --edge-length is scored on a 1 mm remeshing of itself
// and the map carried back to its vertices.
void score_saf(const Mesh& mesh, const RunSettings& rs, reports::RunSummary& S) {
  asymmetry::SafOptions sao = rs.saf;
  sao.keep_fields = true;  // for the SRD descriptors, dropped right after
  const auto disks = asymmetry::saf_anchors(S.landmarks.landmarks, S.reference.reference, rs.anchors == "reference");
  Mesh saf_mesh;
  const bool remesh_for_saf = std::abs(rs.surface.target_edge_mm - asymmetry::kSafEdgeMm) > 0.05 * asymmetry::kSafEdgeMm;
  if (remesh_for_saf) {
    saf_mesh = mesh;
    surface::RepairOptions rp;
    rp.target_edge_mm = asymmetry::kSafEdgeMm;
    surface::repair_and_remesh(saf_mesh, rp);
  }
  const Mesh& scored = remesh_for_saf ? saf_mesh : mesh;
  S.saf = asymmetry::compute_saf(scored, disks, S.reference.plane, sao);
  S.srd = asymmetry::compute_srds(scored, S.saf);
  if (remesh_for_saf && !S.saf.per_vertex.empty()) {
    const geometry::ClosestPointIndex index(saf_mesh);
    S.saf.per_vertex = geometry::values_at(saf_mesh, index, S.saf.per_vertex, mesh.vertices);
  }
  S.saf.fields.clear();
  S.saf.fields.shrink_to_fit();
  if (!S.saf.skipped.empty())
    S.warnings.push_back("asymmetry: " + std::to_string(S.saf.skipped.size()) + " SAF configuration(s) skipped for missing landmarks");
}

// 6. Asymmetry: regions, mirror distance, SAF score and maps, bilateral measures.
AsymmetryMaps asymmetry_stage(const Mesh& mesh, const RunSettings& rs, reports::RunSummary& S) {
  AsymmetryMaps maps;
  maps.regions = asymmetry::assign_regions(mesh, S.landmarks.landmarks);
  S.mirror = asymmetry::mirror_distance(mesh, S.reference.plane, maps.regions, &S.landmarks.landmarks);
  score_saf(mesh, rs, S);
  const auto areas = asymmetry::vertex_areas(mesh);
  if (!S.saf.per_vertex.empty()) {
    S.saf_regions = asymmetry::regional_means(S.saf.per_vertex, areas, maps.regions);
    S.saf_sided = asymmetry::sided_map(S.saf.per_vertex, S.mirror);
    S.saf_regions_sided = asymmetry::regional_means(S.saf_sided, areas, maps.regions);
    maps.saf_lateral = asymmetry::lateral_map(S.saf.per_vertex, S.mirror);
    S.saf_regions_lateral = asymmetry::regional_means(maps.saf_lateral, areas, maps.regions);
  }
  S.bilateral = asymmetry::bilateral_measures(S.landmarks.landmarks, S.reference.plane);
  if (S.truncated) S.warnings.push_back("scores: the mandible is truncated; asymmetry scores are not comparable");
  return maps;
}

// results.json `parameters`: the options and settings the run used.
void record_parameters(const RunSettings& rs, const cli::Args& args, bool deidentify, const asymmetry::Regions& regions,
                       reports::RunSummary& S) {
  const surface::Options& mo = rs.surface;
  S.parameters["hu_offset"] = num(rs.read.hu_offset);
  S.parameters["bone_threshold_hu"] = num(rs.segmentation.bone_threshold_hu);
  S.parameters["surface_smoothing_sigma_mm"] = num(mo.smoothing_sigma_mm);
  S.parameters["surface_target_faces"] = std::to_string(mo.target_faces);
  S.parameters["surface_max_contour_spacing_mm"] = num(mo.max_contour_spacing_mm);
  S.parameters["saf_disk_radius_mm"] = num(rs.saf.disk_radius_mm);
  S.parameters["saf_smoothing_mm"] = num(rs.saf.smoothing_mm);
  S.parameters["saf_anchors"] = rs.anchors;
  S.parameters["surface_close_handles"] = args.get("close-handles", "auto");
  S.parameters["landmark_method"] = S.landmarks.method;
  if (args.has("mask")) {  // the segmentation given: which file (its content by hash) and label
    S.parameters["mask_path"] = deidentify ? "(removed)" : args.get("mask");
    S.parameters["mask_sha256"] = file_sha256(args.get("mask"));
    S.parameters["mask_label"] = rs.label >= 0 ? std::to_string(rs.label) : "the only label";
  }
  std::ostringstream legend;  // for the VTP's integer region array
  for (std::size_t k = 0; k < regions.names.size(); ++k) legend << k << "=" << regions.names[k] << " ";
  S.parameters["vtp_region_labels"] = legend.str();
}

// The surface with its per-vertex maps (VTP, STL, PLY) and the Slicer markups.
void write_geometry(const Staging& staging, const Mesh& mesh, const reports::RunSummary& S, const AsymmetryMaps& maps) {
  const std::size_t n = mesh.vertices.size();
  surface::PointArrays arrays;
  arrays["mirror_distance_mm"] = S.mirror.per_vertex;
  arrays["saf_asymmetry"] = S.saf.per_vertex.empty() ? std::vector<double>(n, 0.0) : S.saf.per_vertex;
  arrays["saf_asymmetry_sided"] = S.saf_sided.empty() ? std::vector<double>(n, 0.0) : S.saf_sided;
  arrays["saf_asymmetry_lateral"] = maps.saf_lateral.empty() ? std::vector<double>(n, 0.0) : maps.saf_lateral;
  arrays["region"] = std::vector<double>(maps.regions.label.begin(), maps.regions.label.end());
  surface::write_vtp(mesh, arrays, staging.path("mandible.vtp"));
  surface::write_stl(mesh, staging.path("mandible.stl"));
  surface::write_ply(mesh, staging.path("mandible.ply"));
  reports::write_text_atomic(staging.path("landmarks.mrk.json"), reports::landmarks_markup(S.landmarks.landmarks));
  reports::write_text_atomic(staging.path("symmetry_plane.mrk.json"), reports::plane_markup(S.reference.plane, 120.0));
  if (S.cranial.found)
    reports::write_text_atomic(staging.path("cranial_plane.mrk.json"), reports::plane_markup(S.cranial.plane, 160.0, "cranial mid-sagittal plane"));
}

// The report's figures: the QC slices (already written beside the stages),
// the head-frame slice, and the 3D views (mirror distance on a fixed +-3 mm
// scale, comparable between scans; the sided SAF map on 0..0.25 rad).
struct Figures {
  std::vector<std::string> slices, views;
  std::string views_note;  // why there are no views
};

Figures write_figures(bool on, const Volume& ct, const Mesh& mesh, std::vector<std::string> slices, const Staging& staging,
                      reports::RunSummary& S) {
  Figures f;
  f.slices = std::move(slices);
  if (!on) {
    f.views_note = "--no-figures";
    return f;
  }
  if (reports::write_head_frame_slice(ct, S.landmarks.plane, S.palate, S.landmarks.landmarks, staging.path("qc/qc_head_frame.png")))
    f.slices.push_back(staging.path("qc/qc_head_frame.png"));
  reports::ColourMap mirror_cm{"mirror distance (mm)", -3.0, 3.0, true};
  reports::ColourMap saf_cm{"SAF map, sided (rad)", 0.0, 0.25, false};
  const auto rendered = reports::render_view_sets(
      mesh, {{&S.mirror.per_vertex, mirror_cm, staging.path("qc/view_mirror")}, {&S.saf_sided, saf_cm, staging.path("qc/view_saf")}},
      S.landmarks.landmarks, S.reference.plane, 520, 420, S.head_superior());
  for (const auto& rv : rendered) {
    if (!rv.error.empty()) {
      f.views_note = rv.error;
      break;
    }
    f.views.insert(f.views.end(), rv.files.begin(), rv.files.end());
  }
  if (!f.views_note.empty()) {
    S.warnings.push_back("report: 3D views not rendered: " + f.views_note);
    f.views.clear();
  }
  return f;
}

// The summary files: report.html, results.csv, log.txt, srd.json and,
// last, results.json.
void write_summaries(const Staging& staging, const reports::RunSummary& S, const Figures& fig, const std::string& log) {
  reports::write_text_atomic(staging.path("report.html"), reports::report_html(S, fig.slices, fig.views, fig.views_note));
  reports::write_text_atomic(staging.path("results.csv"),
                             reports::csv_header() + reports::csv_row(S, S.qc.status == "fail" ? "qc_failed" : "ok"));
  reports::write_text_atomic(staging.path("log.txt"), log);
  reports::write_text_atomic(staging.path("srd.json"), dump_json(reports::srd_json(S.srd), 1) + "\n");
  reports::write_text_atomic(staging.path("results.json"), dump_json(reports::results_json(S)) + "\n");
}

// A failed quality control: one line with its cause and the fatal checks; exit code 8.
int qc_exit(const reports::RunSummary& S, const std::string& input, const std::string& outdir) {
  if (S.qc.status != "fail") return 0;
  std::string what;
  for (const reports::QcCheck* c : S.qc.failed())
    if (c->fatal) what += (what.empty() ? "" : ", ") + c->name;
  std::cerr << "mandisym: " << input << ": result failed quality control: " << S.qc.cause << " (" << what << "); outputs written to "
            << outdir << "\n";
  return static_cast<int>(ExitCode::QcFailed);
}

}  // namespace

void check_run_options(const cli::Args& args) {
  (void)run_settings(args);
  (void)args.ranged("threads", 0, "threads");
}

int run_command(const cli::Args& args, const std::string& command_line) {
  const auto t_start = std::chrono::steady_clock::now();
  const std::string input = args.positional.at(0);
  const std::string outdir = args.get("output");
  if (outdir.empty()) throw Error(ExitCode::Usage, "run: -o OUTDIR is required");
  const RunSettings rs = run_settings(args);
  threads::set_budget(static_cast<int>(args.ranged("threads", 0, "threads")));
  const bool quiet = args.has("quiet"), deidentify = args.has("deidentify"), figures_on = !args.has("no-figures");
  reports::RunSummary S;
  S.tool_version = version();
  // De-identified runs never record the input path (folder names often carry
  // the patient's name) nor the command line that contains it.
  const std::string logged_command = deidentify ? "mandisym run <input> --deidentify ..." : command_line;
  S.command_line = logged_command;
  Progress progress(quiet, S.timings_s);

  const io::LoadedScan scan = ingest_stage(input, rs, deidentify, S);
  if (args.has("dicom") && !scan.dicom)
    throw Error(ExitCode::Usage, "--dicom needs a DICOM series as INPUT; " + input + " is a " + scan.info.kind + " file");
  progress.stage("ingest", 1);
  Staging staging(outdir);

  // Stages 2-6: an error names the input it happened on. Work that only
  // writes outputs runs beside the next stages on the second core; the
  // futures are declared after what they read (`scan`, `seg`, `surf`) and
  // after `staging`: a failing run waits for them before those go.
  segmentation::Result seg;
  surface::Result surf;
  AsymmetryMaps maps;
  std::future<std::vector<std::string>> mask_outputs;  // mask file + QC slices
  std::future<reference::CranialResult> cranial;
  try {
    seg = segment_stage(scan.volume, rs, args, S);
    progress.stage("segment", 2);
    mask_outputs = std::async(threads::side_task_launch(), [&scan, &seg, &staging, figures_on] {
      io::write_mask(io::in_stored_order(seg.mask, scan.stored_order), staging.path("mandible_mask.nii.gz"));
      return figures_on ? reports::write_qc_slices(scan.volume, seg.mask, staging.path("qc")) : std::vector<std::string>{};
    });
    surf = surface_stage(scan.volume, seg, rs.surface, S);
    progress.stage("surface", 3);
    landmarks_stage(scan.volume, seg, surf.mesh, S);
    progress.stage("landmarks", 4);
    reference_stage(seg.truncated, surf.mesh, S);
    if (!args.has("no-cranial")) cranial = start_cranial(scan.volume, seg, rs, surf.mesh, S);
    progress.stage("reference", 5);
    maps = asymmetry_stage(surf.mesh, rs, S);
    if (cranial.valid()) {
      S.cranial = cranial.get();
      if (!S.cranial.found) S.warnings.push_back("cranial plane: not fitted: " + S.cranial.reason);
    }
    progress.stage("asymmetry", 6);
  } catch (const Error& e) {
    throw Error(e.code(), input + ": " + e.what());
  }

  S.qc = reports::evaluate_qc(S);
  for (const reports::QcCheck* c : S.qc.failed())
    S.warnings.push_back(std::string("quality control: ") + (c->fatal ? "FAILED " : "") + c->name + ": " + c->message);
  record_parameters(rs, args, deidentify, maps.regions, S);

  // Outputs, staged, then moved into place (results.json last).
  write_geometry(staging, surf.mesh, S, maps);
  const Figures fig = write_figures(figures_on, scan.volume, surf.mesh, mask_outputs.get(), staging, S);
  if (deidentify)  // warnings may name files under the input folder
    for (auto& w : S.warnings)
      for (std::size_t p = w.find(input); !input.empty() && p != std::string::npos; p = w.find(input, p))
        w.replace(p, input.size(), "<input>");
  // report.pdf and the DICOM objects hold no timing, so they are written here and timed with the report.
  const DicomExport dx{args.has("dicom") ? &*scan.dicom : nullptr, deidentify, args.has("mask"), S.tool_version};
  const std::vector<std::string> export_lines = write_pdf_and_dicom(staging.dir().string(), reports::results_json(S), seg.mask, fig.views, dx);
  S.timings_s.emplace_back("report", progress.lap());
  S.total_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  char total[64];
  std::snprintf(total, sizeof total, "total %.2f s", S.total_s);
  std::string log = progress.text();
  for (const auto& w : S.warnings) log += "warning: " + w + "\n";
  for (const auto& m : liblog::take_library_messages()) log += "library: " + m + "\n";
  progress.say(total);
  log += std::string(total) + "\n";
  for (const auto& line : export_lines) log += line + "\n";
  write_summaries(staging, S, fig, "mandisym " + S.tool_version + "\n" + logged_command + "\n" + log);
  staging.commit();
  if (!quiet) {
    for (const auto& w : S.warnings) std::cerr << "warning: " << w << "\n";
    std::cout << "report: " << (fs::absolute(fs::path(outdir)) / "report.html").lexically_normal().string() << std::endl;
  }
  return qc_exit(S, input, outdir);
}

}  // namespace ms::pipeline
