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
#include "asymmetry/saf.h"
#include "core/error.h"
#include "core/memory.h"
#include "core/sha256.h"
#include "geometry/mesh_geometry.h"
#include "io/volume_io.h"
#include "landmarks/landmarks.h"
#include "reports/render.h"
#include "pipeline/commands.h"
#include "pipeline/cranial.h"
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
       {"hu-offset", "HU", "added to every voxel after the file's own rescale (e.g. -1024 for HU+1024 data)", "0"},
       {"series", "UID", "series to use when the folder holds several (see mandisym inspect)", "finest CT series covering the scan"},
       {"orientation", "CODE", "volume files: where the i, j, k axes point, e.g. LPS or LAI (for files without orientation)", "from the file"},
       {"max-memory", "SIZE", "memory budget of this run, e.g. 2G or 800M: a scan whose estimated peak (voxels x 4 B x 5) exceeds "
                              "it is refused before it is decoded (docs/security.md)", "75 % of this machine's (or cgroup's) memory"},
       {"allow-external-data", "", "volume headers (.nhdr, .mhd) may name data files outside their own folder", ""},
       {"bone-threshold", "HU", "bone threshold for segmentation", "250"},
       {"mask", "FILE", "use this segmentation instead of the automatic one (label map in any ITK format)", ""},
       {"label", "N", "with --mask: the mandible's label (TotalSegmentator craniofacial_structures: 1)", "the only label"},
       {"target-faces", "N", "decimate the surface above this many triangles", "60000"},
       {"edge-length", "MM", "isotropic remeshing edge length of the surface (0 = no CGAL repair/remeshing); the SAF score is "
                          "computed on a 1 mm remeshing whatever this is", "1"},
       {"close-handles", "MM|auto", "closing radius before meshing, removes handles such as teeth in contact; auto = only "
                                    "when the surface has handles, the smallest of 1, 2, 3 mm that removes them (0 = never)", "auto"},
       {"disk-radius", "MM", "radius of the Dirichlet disks at landmarks for harmonic fields", "2"},
       {"saf-smoothing", "MM", "heat-kernel sigma smoothing each signed angle field before the mirror comparison "
                               "(0 = per face, METHOD.md's literal definition)", "6"},
       {"saf-anchors", "WHICH", "where the Dirichlet disks sit: reference (the symmetric reference configuration) or "
                                "detected (the detected landmarks)", "reference"},
       {"no-figures", "", "do not write QC figures", ""},
       {"no-cranial", "", "do not fit the cranial mid-sagittal plane (bone above the condyles)", ""},
       {"deidentify", "", "leave out of every output the DICOM strings that can identify a study: UIDs, dates, "
                          "descriptions, the input path", ""},
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
  r.read.hu_offset = args.number_in("hu-offset", 0.0, -4096, 4096, "HU");
  r.read.series_uid = args.get("series");
  r.read.orientation = args.get("orientation");
  if (args.has("max-memory")) r.read.max_memory_bytes = parse_memory_size(args.get("max-memory"));
  r.read.allow_external_data_files = args.has("allow-external-data");
  r.segmentation.bone_threshold_hu = args.number_in("bone-threshold", r.segmentation.bone_threshold_hu, -1000, 3000, "HU");
  if (args.has("label") && !args.has("mask")) throw Error(ExitCode::Usage, "--label needs --mask");
  const double label = args.number_in("label", -1, -1, 65535, "");
  if (label != std::floor(label)) throw Error(ExitCode::Usage, "--label: expected a whole number");
  r.label = static_cast<int>(label);
  r.saf.disk_radius_mm = args.number_in("disk-radius", r.saf.disk_radius_mm, 0.1, 10, "mm");
  r.saf.smoothing_mm = args.number_in("saf-smoothing", r.saf.smoothing_mm, 0, 30, "mm");
  r.anchors = args.get("saf-anchors", "reference");
  if (r.anchors != "reference" && r.anchors != "detected")
    throw Error(ExitCode::Usage, "--saf-anchors must be reference or detected, not '" + r.anchors + "'");
  r.surface.target_faces = static_cast<std::size_t>(args.number_in("target-faces", static_cast<double>(r.surface.target_faces), 1000, 2e6, ""));
  r.surface.target_edge_mm = args.number_in("edge-length", r.surface.target_edge_mm, 0, 5, "mm");
  if (r.surface.target_edge_mm > 0 && r.surface.target_edge_mm < 0.25)
    throw Error(ExitCode::Usage, "--edge-length: " + num(r.surface.target_edge_mm) + " mm is below 0.25 mm (0 turns remeshing off)");
  r.surface.close_handles_auto = args.get("close-handles", "auto") == "auto";
  if (!r.surface.close_handles_auto) r.surface.close_handles_mm = args.number_in("close-handles", r.surface.close_handles_mm, 0, 10, "mm");
  return r;
}

}  // namespace

int run_command(const cli::Args& args, const std::string& command_line) {
  const auto t_start = std::chrono::steady_clock::now();
  const std::string input = args.positional.at(0);
  const std::string outdir = args.get("output");
  if (outdir.empty()) throw Error(ExitCode::Usage, "run: -o OUTDIR is required");
  const RunSettings rs = run_settings(args);
  asymmetry::SafOptions sao = rs.saf;
  const std::string& anchor_choice = rs.anchors;
  surface::Options mo = rs.surface;
  const bool quiet = args.has("quiet");
  std::ostringstream log;
  auto say = [&](const std::string& line) {
    log << line << "\n";
    if (!quiet) std::cout << line << std::endl;
  };

  reports::RunSummary S;
  S.tool_version = version();
  const bool deidentify = args.has("deidentify");
  // De-identified runs never record the input path (folder names often carry
  // the patient's name) nor the command line that contains it.
  const std::string logged_command = deidentify ? "mandisym run <input> --deidentify ..." : command_line;
  S.command_line = logged_command;
  Stopwatch sw;
  auto stage = [&](const char* name, int k) {
    const double t = sw.lap();
    S.timings_s.emplace_back(name, t);
    char b[128];
    std::snprintf(b, sizeof b, "[%d/6] %-10s %7.2f s", k, name, t);
    say(b);
  };

  // 1. ingest
  const io::ReadOptions& ro = rs.read;
  io::LoadedScan scan = io::read_scan(input, ro);
  S.scan = scan.info;
  if (deidentify) {
    S.scan.path = "(removed)";
    S.scan.series_uid.clear();
    S.scan.study_date.clear();
    S.scan.series_description.clear();
  }
  S.grid = scan.volume.geom;
  for (const auto& w : scan.info.warnings) S.warnings.push_back("ingest: " + w);
  stage("ingest", 1);
  const bool figures_on = !args.has("no-figures");
  Staging staging(outdir);

  // Stages 2-6: an error names the input it happened on.
  const segmentation::Options& so = rs.segmentation;
  segmentation::Result seg;
  surface::Result surf;
  asymmetry::Regions regions;
  std::vector<double> saf_lateral;  // asymmetry::lateral_map per output vertex (VTP)
  // Work that only writes outputs runs beside the next stages on the second
  // core (the surface stage is mostly one thread); joined before the report.
  // Declared after what they read (`scan`, `seg`, `surf`) and after `staging`:
  // a failing run waits for them before any of those is destroyed.
  std::future<std::vector<std::string>> mask_outputs;  // mask file + QC slices
  std::future<reference::CranialResult> cranial;
  try {
    // 2. segmentation
    if (args.has("mask")) {
      seg = segmentation::from_label_map(scan.volume.geom, io::read_label_map(args.get("mask")), rs.label, args.get("mask"));
    } else {
      seg = segmentation::segment_mandible(scan.volume, so);
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
    S.image_zone_dice = seg.image_zone_dice;
    for (const auto& w : seg.warnings) S.warnings.push_back("segmentation: " + w);
    stage("segment", 2);
    mask_outputs = std::async(std::launch::async, [&scan, &seg, &staging, figures_on] {
      io::write_mask(seg.mask, staging.path("mandible_mask.nii.gz"));
      return figures_on ? reports::write_qc_slices(scan.volume, seg.mask, staging.path("qc")) : std::vector<std::string>{};
    });

    // 3. surface, between voxels where the CT crosses the level the
    //    segmentation placed the mask's boundary at (not for external masks:
    //    their boundary is theirs)
    if (seg.surface_level_hu != 0 && seg.mask.geom.same_grid(scan.volume.geom, 1e-6)) {
      mo.guide = &scan.volume;
      mo.guide_level_hu = seg.surface_level_hu;
      mo.guide_soft_hu = 40.0 + seg.offset_hu;  // the offset is the soft-tissue peak's distance from 40 HU
    }
    surf = surface::mesh_from_mask(seg.mask, mo);
    S.mesh = surf.stats;
    S.surface = surf.mesh;
    S.closing_mm = surf.closing_mm;
    S.genus_before_closing = surf.genus_before_closing;
    S.closing_plugs_only = surf.closing_plugs_only;
    S.vertices_pulled = surf.vertices_pulled;
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
    stage("surface", 3);

    // 4. landmarks, in the head's frame: the mandible's symmetry plane gives
    //    yaw and roll, the palatal plane (nasal floor) gives pitch.
    landmarks::Options lo;
    if (seg.truncated) lo.scan_grid = &seg.scanned_grid;  // landmarks at the cut are missing, not guessed
    landmarks::PalateOptions po;
    po.plate_hu += seg.offset_hu;  // thresholds follow the scan's calibration offset
    po.air_hu += seg.offset_hu;
    if (seg.atlas.found) po.atlas_superior = seg.atlas.pose.superior();
    S.landmarks = landmarks::detect_in_head_frame(scan.volume, surf.mesh, lo, po, &S.palate, &S.head_frame);
    for (const auto& w : S.landmarks.warnings) S.warnings.push_back(w);
    for (const auto& m : S.landmarks.missing) {
      const auto why = S.landmarks.why_missing.find(m);
      S.warnings.push_back("landmarks: " + m + " missing: " + (why != S.landmarks.why_missing.end() ? why->second : "not found"));
    }
    stage("landmarks", 4);

    // 5. symmetry plane + reference configuration
    reference::Options ro_fit;
    ro_fit.superior = S.head_superior();  // asymmetry vectors in the head's frame, like the landmarks
    try {
      S.reference = reference::fit(S.landmarks.landmarks, &surf.mesh, ro_fit);
    } catch (const Error& e) {
      if (e.code() != ExitCode::GeometryFailed || !seg.truncated) throw;
      std::string missing;
      for (const auto& m : S.landmarks.missing) missing += (missing.empty() ? "" : ", ") + m;
      throw Error(ExitCode::GeometryFailed, std::string(e.what()) + ": the mandible is cut by the scan's edge (" + missing +
                                                " missing); nothing to mirror one side onto the other");
    }
    for (const auto& w : S.reference.warnings) S.warnings.push_back("reference: " + w);
    if (!args.has("no-cranial")) {
      // Cranial mid-sagittal plane (optional: a failure costs the plane, not
      // the run), beside the asymmetry stage.
      CranialInputs ci;
      ci.ct = &scan.volume;
      ci.mandible = &seg.mask;
      ci.threshold_hu = seg.threshold_hu > 0 ? seg.threshold_hu : so.bone_threshold_hu;
      ci.mandible_plane = S.reference.plane;
      ci.landmarks = S.landmarks.landmarks;
      ci.mandible_surface = &surf.mesh;
      cranial = std::async(std::launch::async, [ci] { return fit_cranial_plane(ci); });
    }
    stage("reference", 5);

    // 6. asymmetry
    regions = asymmetry::assign_regions(surf.mesh, S.landmarks.landmarks);
    S.mirror = asymmetry::mirror_distance(surf.mesh, S.reference.plane, regions, &S.landmarks.landmarks);
    const auto disks = asymmetry::saf_anchors(S.landmarks.landmarks, S.reference.reference, anchor_choice == "reference");
    sao.keep_fields = true;  // for the SRD descriptors, dropped right after
    // The SAF score is defined at 1 mm edges (asymmetry::kSafEdgeMm): a surface
    // meshed at another --edge-length is scored on a 1 mm remeshing of itself
    // and the map carried back to its vertices.
    Mesh saf_mesh;
    const bool remesh_for_saf = std::abs(mo.target_edge_mm - asymmetry::kSafEdgeMm) > 0.05 * asymmetry::kSafEdgeMm;
    if (remesh_for_saf) {
      saf_mesh = surf.mesh;
      surface::RepairOptions rp;
      rp.target_edge_mm = asymmetry::kSafEdgeMm;
      surface::repair_and_remesh(saf_mesh, rp);
    }
    const Mesh& scored = remesh_for_saf ? saf_mesh : surf.mesh;
    S.saf = asymmetry::compute_saf(scored, disks, S.reference.plane, sao);
    S.srd = asymmetry::compute_srds(scored, S.saf);
    if (remesh_for_saf && !S.saf.per_vertex.empty()) {
      const geometry::ClosestPointIndex index(saf_mesh);
      S.saf.per_vertex = geometry::values_at(saf_mesh, index, S.saf.per_vertex, surf.mesh.vertices);
    }
    S.saf.fields.clear();
    S.saf.fields.shrink_to_fit();
    if (!S.saf.skipped.empty())
      S.warnings.push_back("asymmetry: " + std::to_string(S.saf.skipped.size()) +
                           " SAF configuration(s) skipped for missing landmarks");
    const auto areas = asymmetry::vertex_areas(surf.mesh);
    if (!S.saf.per_vertex.empty()) {
      S.saf_regions = asymmetry::regional_means(S.saf.per_vertex, areas, regions);
      S.saf_sided = asymmetry::sided_map(S.saf.per_vertex, S.mirror);
      S.saf_regions_sided = asymmetry::regional_means(S.saf_sided, areas, regions);
      saf_lateral = asymmetry::lateral_map(S.saf.per_vertex, S.mirror);
      S.saf_regions_lateral = asymmetry::regional_means(saf_lateral, areas, regions);
    }
    S.bilateral = asymmetry::bilateral_measures(S.landmarks.landmarks, S.reference.plane);
    if (S.truncated) S.warnings.push_back("scores: the mandible is truncated; asymmetry scores are not comparable");
    if (cranial.valid()) {
      S.cranial = cranial.get();
      if (!S.cranial.found) S.warnings.push_back("cranial plane: not fitted: " + S.cranial.reason);
    }
    stage("asymmetry", 6);

  } catch (const Error& e) {
    throw Error(e.code(), input + ": " + e.what());
  }

  S.qc = reports::evaluate_qc(S);
  for (const reports::QcCheck* c : S.qc.failed())
    S.warnings.push_back(std::string("quality control: ") + (c->fatal ? "FAILED " : "") + c->name + ": " + c->message);

  S.parameters["hu_offset"] = num(ro.hu_offset);
  S.parameters["bone_threshold_hu"] = num(so.bone_threshold_hu);
  S.parameters["surface_smoothing_sigma_mm"] = num(mo.smoothing_sigma_mm);
  S.parameters["surface_guide_level_hu"] = mo.guide ? num(mo.guide_level_hu) : "none";
  S.parameters["surface_target_faces"] = std::to_string(mo.target_faces);
  S.parameters["surface_max_contour_spacing_mm"] = num(mo.max_contour_spacing_mm);
  S.parameters["saf_disk_radius_mm"] = num(sao.disk_radius_mm);
  S.parameters["saf_smoothing_mm"] = num(sao.smoothing_mm);
  S.parameters["saf_anchors"] = anchor_choice;
  S.parameters["surface_close_handles"] = args.get("close-handles", "auto");
  S.parameters["landmark_method"] = S.landmarks.method;
  if (args.has("mask")) {  // the segmentation given: which file (its content by hash) and label
    S.parameters["mask_path"] = deidentify ? "(removed)" : args.get("mask");
    S.parameters["mask_sha256"] = file_sha256(args.get("mask"));
    S.parameters["mask_label"] = rs.label >= 0 ? std::to_string(rs.label) : "the only label";
  }

  // ---- outputs, staged then moved into place ----
  {
    surface::PointArrays arrays;
    arrays["mirror_distance_mm"] = S.mirror.per_vertex;
    arrays["saf_asymmetry"] = S.saf.per_vertex.empty() ? std::vector<double>(surf.mesh.vertices.size(), 0.0) : S.saf.per_vertex;
    arrays["saf_asymmetry_sided"] = S.saf_sided.empty() ? std::vector<double>(surf.mesh.vertices.size(), 0.0) : S.saf_sided;
    arrays["saf_asymmetry_lateral"] = saf_lateral.empty() ? std::vector<double>(surf.mesh.vertices.size(), 0.0) : saf_lateral;
    std::vector<double> reg(regions.label.begin(), regions.label.end());
    arrays["region"] = reg;
    surface::write_vtp(surf.mesh, arrays, staging.path("mandible.vtp"));
    surface::write_stl(surf.mesh, staging.path("mandible.stl"));
    surface::write_ply(surf.mesh, staging.path("mandible.ply"));
    reports::write_text_atomic(staging.path("landmarks.mrk.json"), reports::landmarks_markup(S.landmarks.landmarks));
    reports::write_text_atomic(staging.path("symmetry_plane.mrk.json"), reports::plane_markup(S.reference.plane, 120.0));
    if (S.cranial.found)
      reports::write_text_atomic(staging.path("cranial_plane.mrk.json"), reports::plane_markup(S.cranial.plane, 160.0, "cranial mid-sagittal plane"));
    std::vector<std::string> figures = mask_outputs.get();
    if (figures_on && reports::write_head_frame_slice(scan.volume, S.landmarks.plane, S.palate, S.landmarks.landmarks,
                                                      staging.path("qc/qc_head_frame.png")))
      figures.push_back(staging.path("qc/qc_head_frame.png"));
    std::vector<std::string> views;
    std::string views_note;
    if (figures_on) {
      // 3D views: mirror distance on a fixed +-3 mm scale (comparable between
      // scans), the sided SAF map on 0..0.25 rad.
      reports::ColourMap mirror_cm{"mirror distance (mm)", -3.0, 3.0, true};
      reports::ColourMap saf_cm{"SAF map, sided (rad)", 0.0, 0.25, false};
      const auto rendered = reports::render_view_sets(
          surf.mesh,
          {{&S.mirror.per_vertex, mirror_cm, staging.path("qc/view_mirror")},
           {&S.saf_sided, saf_cm, staging.path("qc/view_saf")}},
          S.landmarks.landmarks, S.reference.plane, 520, 420, S.head_superior());
      for (const auto& rv : rendered) {
        if (!rv.error.empty()) {
          views_note = rv.error;
          break;
        }
        views.insert(views.end(), rv.files.begin(), rv.files.end());
      }
      if (!views_note.empty()) {
        S.warnings.push_back("report: 3D views not rendered: " + views_note);
        views.clear();
      }
    } else {
      views_note = "--no-figures";
    }
    S.timings_s.emplace_back("report", sw.lap());
    S.total_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
    // region legend for the VTP's integer region array
    {
      std::ostringstream legend;
      for (std::size_t k = 0; k < regions.names.size(); ++k) legend << k << "=" << regions.names[k] << " ";
      S.parameters["vtp_region_labels"] = legend.str();
    }
    if (deidentify)  // warnings may name files under the input folder
      for (auto& w : S.warnings)
        for (std::size_t p = w.find(input); !input.empty() && p != std::string::npos; p = w.find(input, p))
          w.replace(p, input.size(), "<input>");
    reports::write_text_atomic(staging.path("report.html"), reports::report_html(S, figures, views, views_note));
    reports::write_text_atomic(staging.path("results.csv"), reports::csv_header() + reports::csv_row(S, S.qc.status == "fail" ? "qc_failed" : "ok"));
    for (const auto& w : S.warnings) log << "warning: " << w << "\n";
    for (const auto& m : liblog::take_library_messages()) log << "library: " << m << "\n";
    {
      char b[64];
      std::snprintf(b, sizeof b, "total %.2f s", S.total_s);
      say(b);
    }
    reports::write_text_atomic(staging.path("log.txt"), "mandisym " + S.tool_version + "\n" + logged_command + "\n" + log.str());
    reports::write_text_atomic(staging.path("srd.json"), reports::srd_json(S.srd).dump(1) + "\n");
    reports::write_text_atomic(staging.path("results.json"), reports::results_json(S).dump(2) + "\n");
    staging.commit();
  }
  if (!quiet) {
    for (const auto& w : S.warnings) std::cerr << "warning: " << w << "\n";
    std::cout << "report: " << (fs::absolute(fs::path(outdir)) / "report.html").lexically_normal().string() << std::endl;
  }
  if (S.qc.status == "fail") {
    std::string what, first;
    for (const reports::QcCheck* c : S.qc.failed())
      if (c->fatal) {
        what += (what.empty() ? "" : ", ") + c->name;
        if (first.empty()) first = c->message;
      }
    std::cerr << "mandisym: " << input << ": result failed quality control: " << first << " (" << what << "); outputs written to "
              << outdir << "\n";
    return static_cast<int>(ExitCode::QcFailed);
  }
  return 0;
}

}  // namespace ms::pipeline
