#include "reports/writers.h"

#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <vtkBase64Utilities.h>

#include "core/error.h"
#include "core/files.h"
#include "reports/html_page.h"
#include "reports/interpretation.h"
#include "reports/viewer.h"
#include "surface/surface.h"

namespace ms::reports {
namespace {

Json vec(const Vec3& v) { return json_numbers(v); }

Json num_or_null(double v, bool valid = true) { return valid && std::isfinite(v) ? Json(v) : Json(); }

}  // namespace

std::string fixed(double v, int prec) {
  if (!std::isfinite(v)) return "n/a";
  char b[64];
  std::snprintf(b, sizeof b, "%.*f", prec, v);
  return b;
}

std::string base64_encode(const std::string& in) {
  std::string out((in.size() + 2) / 3 * 4, '\0');
  const unsigned long n = vtkBase64Utilities::Encode(reinterpret_cast<const unsigned char*>(in.data()), in.size(),
                                                     reinterpret_cast<unsigned char*>(out.data()));
  out.resize(n);
  return out;
}

namespace {

Json stats_json(const asymmetry::DistanceStats& s, bool full) {
  auto o = Json::object();
  o["mean_mm"] = s.mean_abs;
  if (full) o["signed_mean_mm"] = s.signed_mean;
  o["rms_mm"] = s.rms;
  o["p95_mm"] = s.p95;
  o["max_mm"] = s.max;
  o["max_outward_mm"] = s.max_outward;
  o["max_inward_mm"] = s.max_inward;
  if (full) {
    o["pct_area_over_1mm"] = s.pct_area_over_1mm;
    o["pct_area_over_2mm"] = s.pct_area_over_2mm;
  }
  return o;
}

// Slicer markups file skeleton and node header (LPS, mm).
Json markup_root() {
  auto root = Json::object();
  root["@schema"] =
      "https://raw.githubusercontent.com/slicer/slicer/master/Modules/Loadable/Markups/Resources/Schema/"
      "markups-schema-v1.0.3.json#";
  return root;
}
Json markup_node(const char* type) {
  auto m = Json::object();
  m["type"] = type;
  m["coordinateSystem"] = "LPS";
  m["coordinateUnits"] = "mm";
  return m;
}

}  // namespace

std::string png_data_uri(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return "";
  std::stringstream buf;
  buf << in.rdbuf();
  return "data:image/png;base64," + base64_encode(buf.str());
}

std::string html_escape(const std::string& s) {
  std::string o;
  o.reserve(s.size());
  for (char c : s) switch (c) {
      case '&': o += "&amp;"; break;
      case '<': o += "&lt;"; break;
      case '>': o += "&gt;"; break;
      case '"': o += "&quot;"; break;
      case '\'': o += "&#39;"; break;
      default: o += c;
    }
  return o;
}

void write_text_atomic(const std::string& path, const std::string& text) {
  write_file_atomic(path, text);
}

namespace {

using Value = Json;

// results.json segmentation.atlas: the atlas's placement (docs/atlas.md).
Value atlas_json(const RunSummary& s) {
  constexpr double kDegPerRad = 57.29577951308232;
  const atlas::Fit& f = s.atlas;
  Value at = Value::object();
  at["found"] = f.found;
  at["ncc"] = f.ncc;
  at["mirrored_ncc"] = f.mirrored_ncc;
  at["coverage"] = f.coverage;
  at["agreement"] = s.atlas_agreement >= 0 ? Value(s.atlas_agreement) : Value();
  at["halves_balance"] = s.atlas_halves_balance >= 0 ? Value(s.atlas_halves_balance) : Value();
  at["centre_lps_mm"] = json_numbers(f.pose.t);
  at["scale"] = f.pose.scale;
  at["pitch_deg"] = f.pose.pitch * kDegPerRad;
  at["yaw_deg"] = f.pose.yaw * kDegPerRad;
  at["roll_deg"] = f.pose.roll * kDegPerRad;
  at["seconds"] = f.seconds;
  return at;
}

// results.json qc: status and every check (docs/qc.md).
Value qc_json(const RunSummary& s) {
  Value qc = Value::object();
  qc["status"] = s.qc.status;
  qc["cause"] = s.qc.cause.empty() ? Json() : Json(s.qc.cause);
  Value checks = Value::array();
  for (const QcCheck& c : s.qc.checks) {
    Value v = Value::object();
    v["name"] = c.name;
    v["value"] = std::isnan(c.value) ? Value() : Value(c.value);
    v["allowed"] = json_numbers(std::array<double, 2>{c.lo, c.hi});
    if (!c.unit.empty()) v["unit"] = c.unit;
    v["source"] = c.source;
    v["passed"] = c.passed;
    v["severity"] = c.fatal ? "fail" : "warn";
    if (!c.passed) v["meaning"] = c.message;
    checks.push_back(v);
  }
  qc["checks"] = checks;
  qc["head_frame"] = s.head_frame.source;
  return qc;
}

// The report's quality-control section: a failed run opens with a red banner
// listing its failures (docs/qc.md), then the table of every check.
void qc_html(std::ostringstream& h, const RunSummary& s) {
  const auto E = html_escape;
  auto value = [](double v) { return std::isnan(v) ? std::string("n/a") : fixed(v); };
  // The allowed range in words: an open upper end is "at least", an open
  // lower end "at most", a single value is itself.
  auto allowed = [](const QcCheck& c) {
    if (std::isinf(c.hi)) return "at least " + fixed(c.lo);
    if (std::isinf(c.lo)) return "at most " + fixed(c.hi);
    return c.lo == c.hi ? fixed(c.lo) : fixed(c.lo) + " to " + fixed(c.hi);
  };
  if (s.qc.status == "fail") {
    h << "<div class=\"qcfail\" role=\"alert\"><strong>Result failed quality control &mdash; do not use these numbers.</strong>\n"
      << "<p>Likely cause: " << E(s.qc.cause) << ".</p><ul>\n";
    for (const QcCheck* c : s.qc.failed())
      if (c->fatal)
        h << "<li><b>" << E(c->name) << "</b> = " << value(c->value) << " (allowed " << allowed(*c) << "): " << E(c->message)
          << ". <span class=\"muted\">" << E(c->source) << "</span></li>\n";
    h << "</ul></div>\n";
  }
  h << "<h2>Quality control: " << E(s.qc.status) << "</h2>\n<table><tr><th>check</th><th>value</th><th>allowed</th><th>result</th><th>source</th></tr>\n";
  for (const QcCheck& c : s.qc.checks)
    h << "<tr><td>" << E(c.name) << "</td><td>" << value(c.value) << "</td><td>" << allowed(c) << "</td><td>"
      << (c.passed ? "pass" : c.fatal ? "FAIL" : "warn") << "</td><td>" << E(c.source) << "</td></tr>\n";
  h << "</table>\n";
}

}  // namespace

// results.json `input`: the scan as read.
static Json input_json(const RunSummary& s) {
  using Value = Json;
  auto in = Value::object();
  in["path"] = s.scan.path;
  in["kind"] = s.scan.kind;
  in["series_uid"] = s.scan.series_uid.empty() ? Value() : Value(s.scan.series_uid);
  in["modality"] = s.scan.modality.empty() ? Value() : Value(s.scan.modality);
  in["size_voxels"] = json_numbers(s.grid.size);
  in["spacing_mm"] = vec(s.grid.spacing);
  in["origin_mm"] = vec(s.grid.origin);
  in["direction"] = json_numbers(s.grid.direction);
  in["sha256_of_pixel_data"] = s.scan.pixel_sha256;
  in["study_date"] = s.scan.study_date.empty() ? Value() : Value(s.scan.study_date);
  in["manufacturer"] = s.scan.manufacturer.empty() ? Value() : Value(s.scan.manufacturer);
  in["kernel"] = s.scan.kernel.empty() ? Value() : Value(s.scan.kernel);
  return in;
}

// results.json `segmentation`.
static Json segmentation_json(const RunSummary& s) {
  using Value = Json;
  auto seg = Value::object();
  seg["method"] = s.segmentation_method;
  seg["voxels"] = s.seg_voxels;
  seg["volume_mm3"] = s.seg_volume_mm3;
  seg["truncated"] = s.truncated;
  seg["truncated_at"] = Json::array();  // where the scan cuts it, in the head's frame (docs/landmarks.md, step 6)
  for (const std::string& at : s.landmarks.cut_at) seg["truncated_at"].push_back(at);
  if (s.segmentation_method == "auto") {
    seg["bone_threshold_hu"] = s.seg_threshold_hu;
    seg["calibration_offset_hu"] = s.seg_offset_hu;
    seg["separation_depth_mm"] = s.seg_separation_mm > 0 ? Value(s.seg_separation_mm) : Value();
    seg["marker_source"] = s.seg_marker_source.empty() ? Value() : Value(s.seg_marker_source);
  }
  if (s.atlas.ncc >= -1) seg["atlas"] = atlas_json(s);  // external masks: placed for the head frame only
  return seg;
}

// results.json `mesh`.
static Json mesh_json(const RunSummary& s) {
  using Value = Json;
  auto mesh = Value::object();
  mesh["vertices"] = s.mesh.vertices;
  mesh["faces"] = s.mesh.faces;
  mesh["area_mm2"] = s.mesh.area_mm2;
  mesh["volume_mm3"] = s.mesh.volume_mm3;
  mesh["genus"] = s.mesh.genus >= 0 ? Value(s.mesh.genus) : Value();
  mesh["closed"] = s.mesh.closed;
  mesh["manifold"] = s.mesh.manifold;
  mesh["closing_mm"] = s.closing_mm;
  mesh["closing_scope"] = s.closing_mm <= 0 ? "none" : s.closing_plugs_only ? "handles" : "everywhere";
  mesh["genus_before_closing"] = s.genus_before_closing >= 0 ? Value(s.genus_before_closing) : Value();
  mesh["vertices_pulled_to_mask"] = s.vertices_pulled;
  mesh["voxels_joining_pieces"] = s.voxels_joining;
  return mesh;
}

// results.json `landmark_detection`: the method, and each missing landmark with its reason.
static Json landmark_detection_json(const RunSummary& s) {
  using Value = Json;
  auto d = Value::object();
  d["method"] = s.landmarks.method;
  auto& missing = d["missing"];
  missing = Value::array();
  for (const auto& m : s.landmarks.missing) missing.push_back(m);
  auto& why = d["why_missing"];
  why = Value::object();
  for (const auto& [name, reason] : s.landmarks.why_missing) why[name] = reason;
  return d;
}

// results.json `head_frame`: the superior axis used and where it came from.
static Json head_frame_json(const RunSummary& s) {
  using Value = Json;
  auto hf = Value::object();
  hf["superior"] = vec(s.head_superior());
  hf["source"] = s.head_frame.source == "palatal" ? "palatal plane" : s.head_frame.source == "mandible" ? "mandible atlas" : "scan axes";
  if (s.palate.found) {
    hf["palatal_tilt_deg"] = s.palate.tilt_deg;
    hf["palatal_samples"] = s.palate.samples;
    hf["palatal_floor"] = s.palate.floor;
    hf["palatal_length_mm"] = s.palate.length_mm;
    hf["palatal_rms_mm"] = s.palate.rms_mm;
    hf["palatal_line"] = Value::array();
    hf["palatal_line"].push_back(vec(s.palate.anterior));
    hf["palatal_line"].push_back(vec(s.palate.posterior));
  } else {
    hf["palatal_tilt_deg"] = Value();
    hf["reason"] = s.palate.reason;
  }
  return hf;
}

// results.json `scores.saf`: the SAF score, its regions and the SRD.
static Json saf_json(const RunSummary& s) {
  using Value = Json;
  auto saf = Value::object();
  saf["score"] = num_or_null(s.saf.score, s.saf.score >= 0);
  saf["unit"] = "rad";
  saf["per_configuration"] = Value::object();
  for (const auto& [n, v] : s.saf.per_configuration) saf["per_configuration"][n] = v;
  saf["regions"] = Value::object();
  for (const auto& [n, v] : s.saf_regions) saf["regions"][n] = v;
  saf["regions_sided"] = Value::object();
  for (const auto& [n, v] : s.saf_regions_sided) saf["regions_sided"][n] = v;
  saf["regions_lateral"] = Value::object();
  for (const auto& [n, v] : s.saf_regions_lateral) saf["regions_lateral"][n] = v;
  if (!s.saf_regions_lateral.empty()) saf["largest_region_sided"] = asymmetry::largest_region(s.saf_regions_lateral);
  saf["correspondence_free"] = num_or_null(s.saf.correspondence_free, s.saf.correspondence_free >= 0);
  saf["skipped_configurations"] = Value::array();
  for (const auto& n : s.saf.skipped) saf["skipped_configurations"].push_back(n);
  auto& srd = saf["srd"];
  srd = Value::object();
  for (const auto& t : s.srd.twins) {
    auto& e = srd[t.landmark];
    e["twin"] = t.twin;
    e["mirror_mismatch_rad"] = num_or_null(t.mirror_mismatch, t.mirror_mismatch >= 0);
    e["handedness_rad"] = num_or_null(t.handedness, t.handedness >= 0);
  }
  return saf;
}

// results.json `tool`.
static Json tool_json(const RunSummary& s) {
  auto tool = Json::object();
  tool["name"] = "mandisym";
  tool["version"] = s.tool_version;
  return tool;
}

// results.json `landmarks`: every METHOD.md landmark, null when missing.
static Json landmarks_json(const RunSummary& s) {
  auto lm = Json::object();
  for (const auto& n : landmark_names()) {
    const Vec3* p = s.landmarks.landmarks.find(n);
    lm[n] = p ? vec(*p) : Json();
  }
  return lm;
}

// results.json `symmetry_plane`: the mandible's fitted plane.
static Json symmetry_plane_json(const RunSummary& s) {
  auto pl = Json::object();
  pl["point"] = vec(s.reference.plane.point);
  pl["normal"] = vec(s.reference.plane.normal);
  pl["rms_landmark_residual_mm"] = s.reference.rms_landmark_residual_mm;
  pl["surface_rms_mm"] = num_or_null(s.reference.surface_rms_mm, s.reference.surface_rms_mm >= 0);
  return pl;
}

// results.json `cranial_plane`: the skull's mid-sagittal plane, null when not fitted.
static Json cranial_plane_json(const RunSummary& s) {
  if (!s.cranial.found) return Json();
  auto cp = Json::object();
  cp["point"] = vec(s.cranial.plane.point);
  cp["normal"] = vec(s.cranial.plane.normal);
  cp["surface_rms_mm"] = num_or_null(s.cranial.surface_rms_mm, s.cranial.surface_rms_mm >= 0);
  cp["bone_volume_cm3"] = s.cranial.bone_volume_cm3;
  cp["angle_to_mandible_plane_deg"] = s.cranial.angle_to_mandible_plane_deg;
  cp["to_cranial_plane_mm"] = Json::object();
  for (const auto& [n, d] : s.cranial.to_cranial_mm) cp["to_cranial_plane_mm"][n] = d;
  cp["to_mandible_plane_mm"] = Json::object();
  for (const auto& [n, d] : s.cranial.to_mandible_mm) cp["to_mandible_plane_mm"][n] = d;
  return cp;
}

// results.json `reference_configuration`: the symmetric reference landmarks.
static Json reference_configuration_json(const RunSummary& s) {
  auto ref = Json::object();
  for (const auto& [n, p] : s.reference.reference.points) ref[n] = vec(p);
  return ref;
}

// results.json `landmark_asymmetry_mm`: detected minus reference, in the plane's frame.
static Json landmark_asymmetry_json(const RunSummary& s) {
  auto av = Json::object();
  for (const auto& [n, v] : s.reference.asymmetry_vectors) {
    av[n]["medio_lateral"] = v[0];
    av[n]["antero_posterior"] = v[1];
    av[n]["supero_inferior"] = v[2];
  }
  return av;
}

// results.json `scores.mirror`: the mirror surface distance, overall, per region, at the landmarks.
static Json mirror_json(const RunSummary& s) {
  Json mir = stats_json(s.mirror.overall, true);
  mir["regions"] = Json::object();
  for (const auto& [n, st] : s.mirror.regions) mir["regions"][n] = stats_json(st, false);
  mir["at_landmarks_mm"] = Json::object();
  for (const auto& [n, v] : s.mirror.at_landmarks) mir["at_landmarks_mm"][n] = v;
  return mir;
}

// results.json `scores.bilateral`: left, right, L−R and L/R per measure.
static Json bilateral_json(const RunSummary& s) {
  auto bil = Json::object();
  for (const auto& [n, b] : s.bilateral) {
    bil[n]["L"] = b.L;
    bil[n]["R"] = b.R;
    bil[n]["diff"] = b.diff;
    bil[n]["ratio"] = b.ratio;
  }
  return bil;
}

// results.json `scores`: SAF, mirror distance, bilateral measures.
static Json scores_json(const RunSummary& s) {
  auto scores = Json::object();
  scores["saf"] = saf_json(s);
  scores["mirror"] = mirror_json(s);
  scores["bilateral"] = bilateral_json(s);
  return scores;
}

// results.json `interpretation`: the headline numbers' bands (docs/report.md: thresholds and sources).
static Json interpretation_json(const RunSummary& s) {
  auto bands = Json::object();
  for (const auto& it : interpret(interpretation_inputs(s))) {
    auto& e = bands[it.key];
    e["band"] = band_name(it.band);
    e["value"] = num_or_null(it.banded_value);
    e["thresholds"] = it.thresholds;
    e["provisional"] = it.provisional;
    if (!it.measured_from.empty()) e["measured_from"] = it.measured_from;
    e["sources"] = Json::array();
    for (const auto& id : it.sources) e["sources"].push_back(id);
  }
  return bands;
}

// results.json `timings_s`: seconds per stage, in stage order, and the total.
static Json timings_json(const RunSummary& s) {
  auto t = Json::object();
  for (const auto& [n, v] : s.timings_s) t[n] = v;
  t["total"] = s.total_s;
  return t;
}

// results.json `warnings`.
static Json warnings_json(const RunSummary& s) {
  auto w = Json::array();
  for (const auto& x : s.warnings) w.push_back(x);
  return w;
}

// results.json `parameters`: a value that reads back whole as a finite number
// is written as one, the others as strings.
static Json parameters_json(const RunSummary& s) {
  auto p = Json::object();
  for (const auto& [k, v] : s.parameters) {
    char* end = nullptr;
    const double x = std::strtod(v.c_str(), &end);
    if (!v.empty() && end == v.c_str() + v.size() && std::isfinite(x) && !std::isspace(static_cast<unsigned char>(v[0])))
      p[k] = x;
    else
      p[k] = v;
  }
  return p;
}

// One function per top-level block, in the file's order.
Json results_json(const RunSummary& s) {
  auto root = Json::object();
  root["schema_version"] = kSchemaVersion;
  root["tool"] = tool_json(s);
  root["coordinate_system"] = "LPS";  // every position in this file: patient LPS, mm
  root["units"] = "mm";
  root["input"] = input_json(s);
  root["segmentation"] = segmentation_json(s);
  root["qc"] = qc_json(s);
  root["mesh"] = mesh_json(s);
  root["landmarks"] = landmarks_json(s);
  root["landmark_detection"] = landmark_detection_json(s);
  root["head_frame"] = head_frame_json(s);
  root["symmetry_plane"] = symmetry_plane_json(s);
  root["cranial_plane"] = cranial_plane_json(s);
  root["reference_configuration"] = reference_configuration_json(s);
  root["landmark_asymmetry_mm"] = landmark_asymmetry_json(s);
  root["scores"] = scores_json(s);
  root["interpretation"] = interpretation_json(s);
  root["timings_s"] = timings_json(s);
  root["warnings"] = warnings_json(s);
  root["parameters"] = parameters_json(s);
  return root;
}

Json srd_json(const asymmetry::SrdResult& srd) {
  using Value = Json;
  Value root = Value::object();
  root["schema_version"] = "1.0";
  root["rings"] = srd.options.rings;
  root["ring_width_mm"] = srd.options.ring_width_mm;
  root["bins"] = srd.options.bins;
  root["layout"] = "each block: rings x bins area fractions, ring-major; bin b covers theta in [-pi + b*2pi/bins, -pi + (b+1)*2pi/bins)";
  auto& d = root["landmarks"];
  d = Value::object();
  for (const auto& [name, desc] : srd.descriptors) {
    auto& blocks = d[name];
    blocks = Value::array();
    for (const auto& b : desc.blocks) {
      Value e = Value::object();
      e["configuration"] = b.configuration;
      e["mirrored"] = b.mirrored;
      e["histogram"] = Value::array();
      for (double h : b.histogram) e["histogram"].push_back(std::round(h * 1e6) / 1e6);
      blocks.push_back(e);
    }
  }
  return root;
}

std::string landmarks_markup(const LandmarkSet& lms) {
  using Value = Json;
  Value root = markup_root();
  Value m = markup_node("Fiducial");
  m["controlPoints"] = Value::array();
  int id = 1;
  for (const auto& n : landmark_names()) {
    const Vec3* p = lms.find(n);
    auto cp = Value::object();
    cp["id"] = std::to_string(id++);
    cp["label"] = n;
    cp["position"] = p ? vec(*p) : json_numbers(std::array<double, 3>{0, 0, 0});
    cp["positionStatus"] = p ? "defined" : "undefined";
    m["controlPoints"].push_back(cp);
  }
  root["markups"] = Value::array();
  root["markups"].push_back(m);
  return dump_json(root) + "\n";
}

// A plane as Slicer's plane markups read it (Markups JSON schema v1.0.3;
// vtkMRMLMarkupsPlaneJsonStorageNode, vtkMRMLMarkupsPlaneNode): for a
// pointNormal plane with one control point Slicer keeps the rotation of
// `baseToNode` and moves its origin to the control point, so the normal is
// baseToNode's z axis; `center` and `normal` are not read. In an LPS file the
// reader negates the first two rows (first 8 numbers) of both matrices
// (LPS -> RAS), so the LPS axes are written as they are: baseToNode = [x y n p]
// in LPS, objectToBase = diag(-1, -1, 1, 1) (identity once read).
std::string plane_markup(const Plane& plane, double size_mm, const std::string& label) {
  using Value = Json;
  const Vec3 n = normalized(plane.normal);
  // In-plane axes: x from the scan axis least aligned with the normal.
  Vec3 helper{0, 0, 0};
  int least = 0;
  for (int a = 1; a < 3; ++a)
    if (std::abs(n[a]) < std::abs(n[least])) least = a;
  helper[least] = 1;
  const Vec3 x = normalized(helper - dot(helper, n) * n), y = cross(n, x);
  Value root = markup_root();
  Value m = markup_node("Plane");
  m["planeType"] = "pointNormal";
  m["sizeMode"] = "absolute";
  m["autoScalingFactor"] = 1.0;
  m["center"] = vec(plane.point);
  m["normal"] = vec(n);
  const Vec3& p = plane.point;
  m["baseToNode"] = json_numbers(std::array<double, 16>{x[0], y[0], n[0], p[0], x[1], y[1], n[1], p[1], x[2], y[2], n[2], p[2], 0, 0, 0, 1});
  m["objectToBase"] = json_numbers(std::array<double, 16>{-1, 0, 0, 0, 0, -1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1});
  m["orientation"] = json_numbers(std::array<double, 9>{x[0], y[0], n[0], x[1], y[1], n[1], x[2], y[2], n[2]});
  m["size"] = json_numbers(std::array<double, 3>{size_mm, size_mm, 0.0});
  m["planeBounds"] = json_numbers(std::array<double, 4>{-size_mm / 2, size_mm / 2, -size_mm / 2, size_mm / 2});
  auto cp = Value::object();
  cp["id"] = "1";
  cp["label"] = label;
  cp["position"] = vec(plane.point);
  cp["positionStatus"] = "defined";
  m["controlPoints"] = Value::array();
  m["controlPoints"].push_back(cp);
  root["markups"] = Value::array();
  root["markups"].push_back(m);
  return dump_json(root) + "\n";
}

std::string csv_quote(const std::string& x) {
  std::string o = "\"";
  for (char c : x) o += c == '"' ? std::string("\"\"") : std::string(1, c);
  return o + "\"";
}

std::string csv_header() {
  return "study,status,saf_score,saf_correspondence_free,mirror_mean_mm,mirror_rms_mm,mirror_p95_mm,mirror_max_mm,"
         "ramus_height_diff_mm,body_length_diff_mm,gonial_angle_diff_deg,truncated,warnings,saf_largest_region_sided\n";
}

std::string csv_row(const RunSummary& s, const std::string& status) {
  const auto q = csv_quote;
  auto b = [&](const char* n) {
    auto it = s.bilateral.find(n);
    return it == s.bilateral.end() ? std::string() : fixed(it->second.diff, 3);
  };
  std::ostringstream o;
  o << q(s.scan.path) << ',' << status << ',' << (s.saf.score >= 0 ? fixed(s.saf.score, 5) : "") << ','
    << (s.saf.correspondence_free >= 0 ? fixed(s.saf.correspondence_free, 5) : "") << ',' << fixed(s.mirror.overall.mean_abs, 3)
    << ',' << fixed(s.mirror.overall.rms, 3) << ',' << fixed(s.mirror.overall.p95, 3) << ',' << fixed(s.mirror.overall.max, 3)
    << ',' << b("ramus_height_mm") << ',' << b("body_length_mm") << ',' << b("gonial_angle_deg") << ','
    << (s.truncated ? "true" : "false") << ',' << s.warnings.size() << ',';
  // Where the SAF map is larger on one side than on the other: the region and
  // side the asymmetry concentrates on (docs/method.md, "A side for the SAF map").
  o << q(asymmetry::largest_region(s.saf_regions_lateral)) << '\n';
  return o.str();
}

namespace {

// The headline: one card per number with its interpretation band, then the
// sources the bands cite (reports/interpretation.h, docs/report.md).
void headline_html(std::ostringstream& h, const RunSummary& s) {
  const auto E = html_escape;
  const auto items = interpret(interpretation_inputs(s));
  const auto& refs = interpretation_references();
  std::vector<std::string> cited;  // reference ids in order of first citation
  auto ref_number = [&](const std::string& id) {
    for (std::size_t i = 0; i < cited.size(); ++i)
      if (cited[i] == id) return i + 1;
    cited.push_back(id);
    return cited.size();
  };
  h << "<div class=\"cards\">\n";
  for (const auto& x : items) {
    h << "<div class=\"card band-" << band_name(x.band) << "\" data-key=\"" << E(x.key) << "\" data-band=\""
      << band_name(x.band) << "\"><div class=\"k\">" << E(x.title) << "</div><div class=\"v\">" << E(x.value_text)
      << "</div><div class=\"pill\">" << E(band_label(x.band));
    if (x.provisional && (x.band == Band::Typical || x.band == Band::Mild || x.band == Band::Marked))
      h << " &middot; provisional";
    h << "</div>";
    if (!x.detail.empty()) h << "<div class=\"k\">" << E(x.detail) << "</div>";
    h << "<div class=\"m\">" << E(x.meaning) << "</div><div class=\"t\">Bands: " << E(x.thresholds);
    for (const auto& id : x.sources) h << " <a href=\"#ref-" << E(id) << "\">[" << ref_number(id) << "]</a>";
    h << "</div></div>\n";
  }
  h << "</div>\n<p class=\"muted\">The bands place each number against published cut-offs where they exist (menton "
       "deviation, ramus-height asymmetry index), a common convention (mirror distance) or MandiSym's own phantom "
       "measurements (SAF score: provisional, phantom-derived, not clinically validated). They describe size, not a "
       "diagnosis; none has been validated for MandiSym's automatic landmarks and plane. The published cut-offs were "
       "set on radiographs or CBCT against a facial or cranial midline, not against the mandible's own symmetry "
       "plane. Compare against a cohort or a pre-operative scan.</p>\n";
  h << "<ol class=\"refs\">\n";
  for (const auto& id : cited)
    for (const auto& r : refs)
      if (r.id == id) h << "<li id=\"ref-" << E(r.id) << "\">" << E(r.citation) << "</li>\n";
  h << "</ol>\n";
}

// The interactive viewer of the run's surface. Returns the section, or a line
// saying why there is none.
std::string viewer_html(const RunSummary& s) {
  if (s.surface.vertices.empty() || s.surface.vertices.size() != s.mirror.per_vertex.size())
    return "<p class=\"muted\">Interactive 3D view not embedded: no surface with per-vertex results.</p>\n";
  try {
    const PlaneFrame frame = plane_frame(s.surface, s.reference.plane, s.head_superior());
    const ViewerMesh vm = viewer_mesh(s.surface, s.mirror.per_vertex, s.saf_sided, frame);
    return viewer_section_html(vm, frame, s.reference.plane, s.landmarks.landmarks);
  } catch (const std::exception& e) {
    return "<p class=\"muted\">Interactive 3D view not embedded: " + html_escape(e.what()) + "</p>\n";
  }
}

// Identity of the input: kind, series UID, study date, series description,
// scanner and kernel (every DICOM string escaped), grid and pixel hash.
void identity_html(std::ostringstream& h, const RunSummary& s) {
  const auto E = html_escape;
  h << "<h1>Mandibular asymmetry report</h1>\n<p class=\"muted\">MandiSym " << E(s.tool_version) << " &middot; input "
    << E(s.scan.kind) << " &middot; series " << E(s.scan.series_uid.empty() ? "-" : s.scan.series_uid)
    << " &middot; study date " << E(s.scan.study_date.empty() ? "-" : s.scan.study_date) << "</p>\n";
  if (!s.scan.series_description.empty() || !s.scan.manufacturer.empty())
    h << "<p class=\"muted\">Series &ldquo;" << E(s.scan.series_description.empty() ? "-" : s.scan.series_description)
      << "&rdquo; &middot; scanner " << E(s.scan.manufacturer.empty() ? "-" : s.scan.manufacturer) << ' '
      << E(s.scan.model) << " &middot; kernel " << E(s.scan.kernel.empty() ? "-" : s.scan.kernel) << "</p>\n";
  h << "<p class=\"muted\">Grid " << s.grid.size[0] << " &times; " << s.grid.size[1] << " &times; " << s.grid.size[2]
    << " voxels, spacing " << fixed(s.grid.spacing[0]) << " &times; " << fixed(s.grid.spacing[1]) << " &times; "
    << fixed(s.grid.spacing[2]) << " mm. Pixel data SHA-256 <code>" << E(s.scan.pixel_sha256.substr(0, 16))
    << "&hellip;</code></p>\n";
}

// The run's warnings, up front.
void warnings_html(std::ostringstream& h, const RunSummary& s) {
  for (const auto& w : s.warnings) h << "<div class=\"warn\">&#9888; " << html_escape(w) << "</div>\n";
}

// A PNG embedded as a data URI, with its caption.
std::string figure_html(const std::string& file, const std::string& caption) {
  std::ifstream in(file, std::ios::binary);
  std::stringstream buf;
  buf << in.rdbuf();
  return "<figure><img alt=\"" + html_escape(caption) + "\" src=\"data:image/png;base64," + base64_encode(buf.str()) +
         "\"><figcaption>" + html_escape(caption) + "</figcaption></figure>\n";
}

// The static 3D views, one grid per set (files named <set>_<view>.png), or why there are none.
void views_html(std::ostringstream& h, const std::vector<std::string>& views, const std::string& views_note) {
  h << "<h2>3D views</h2>\n";
  if (views.empty()) {
    h << "<p class=\"muted\">3D views not rendered: " << html_escape(views_note.empty() ? "disabled" : views_note)
      << "</p>\n";
    return;
  }
  h << "<p class=\"muted\">In the frame of the fitted symmetry plane (translucent sheet); landmarks in green. Mirror "
       "distance: red where this side bulges beyond its mirror image, blue where it lies inside it.</p>\n";
  std::string set;
  for (const auto& f : views) {
    const std::string stem = std::filesystem::path(f).stem().string();  // e.g. view_mirror_front
    const std::string this_set = stem.substr(0, stem.rfind('_'));
    if (this_set != set) {
      if (!set.empty()) h << "</div>\n";
      h << "<div class=\"views\">\n";
      set = this_set;
    }
    h << figure_html(f, stem);
  }
  h << "</div>\n";
}

// The QC figures: segmentation slices, and the head-frame slice shown with the landmarks.
struct QcFigures {
  bool drawn = false;  // figures were drawn (not --no-figures)
  std::vector<std::string> slices;
  std::string head_frame;  // empty when absent
};

QcFigures sort_qc_figures(const std::vector<std::string>& figures) {
  QcFigures q;
  q.drawn = !figures.empty();
  for (const auto& f : figures) {
    if (std::filesystem::path(f).stem().string() == "qc_head_frame")
      q.head_frame = f;
    else
      q.slices.push_back(f);
  }
  return q;
}

// Segmentation QC slices (nothing when figures were not drawn).
void qc_slices_html(std::ostringstream& h, const QcFigures& qc) {
  if (!qc.drawn) return;
  h << "<h2>Segmentation QC</h2>\n";
  for (const auto& f : qc.slices) h << figure_html(f, std::filesystem::path(f).stem().string());
}

// Landmarks in LPS with their asymmetry vectors (a missing one with its reason).
void landmarks_html(std::ostringstream& h, const RunSummary& s) {
  const auto E = html_escape;
  h << "<h2>Landmarks (LPS mm)</h2>\n<table><tr><th>landmark</th><th>x (L)</th><th>y (P)</th><th>z (S)</th>"
       "<th>medio-lateral</th><th>antero-posterior</th><th>supero-inferior</th></tr>\n";
  for (const auto& n : landmark_names()) {
    const Vec3* p = s.landmarks.landmarks.find(n);
    h << "<tr><td>" << E(n) << "</td>";
    if (!p) {
      const auto why = s.landmarks.why_missing.find(n);
      h << "<td colspan=6>missing" << (why != s.landmarks.why_missing.end() ? ": " + E(why->second) : std::string()) << "</td></tr>\n";
      continue;
    }
    h << "<td>" << fixed((*p)[0]) << "</td><td>" << fixed((*p)[1]) << "</td><td>" << fixed((*p)[2]) << "</td>";
    auto it = s.reference.asymmetry_vectors.find(n);
    for (int a = 0; a < 3; ++a) h << "<td>" << (it != s.reference.asymmetry_vectors.end() ? fixed(it->second[a]) : "") << "</td>";
    h << "</tr>\n";
  }
  h << "</table>\n<p class=\"muted\">Last three columns: detected minus symmetric reference configuration, in the "
       "symmetry plane's frame (mm).</p>\n";
}

// The head frame the landmarks were labelled in (palatal plane, mandible atlas
// or scan axes), with its QC slice.
void head_frame_html(std::ostringstream& h, const RunSummary& s, const std::string& head_frame_figure) {
  if (s.palate.found)
    h << "<p>Head frame: left/right from the mandible's symmetry plane; superior is the normal of the palatal plane, fitted to "
         "the nasal floor (" << s.palate.samples << " samples over " << fixed(s.palate.length_mm, 0) << " mm, residual "
      << fixed(s.palate.rms_mm) << " mm), which is tilted " << fixed(s.palate.tilt_deg, 1)
      << "&deg; to the scan's axial plane (+: posterior end higher, head flexed). Co and Cr are the most superior points, "
         "Me the lowest and Pog the most anterior in this frame, whatever the head's pitch in the scanner.</p>\n";
  else if (s.head_frame.source == "mandible")
    h << "<p>Head frame: palatal plane not used (" << html_escape(s.palate.reason) << "); superior is the head's axis given by the "
         "mandible atlas's pose (placed on the mandible and the bone around it; within about 15&deg; of the palatal "
         "normal on the training scans).</p>\n";
  else
    h << "<p>Head frame: palatal plane not found (" << html_escape(s.palate.reason) << "); superior is the scan's axis, so a head "
         "pitched in the scanner moves Me, Pog and Cr along their borders.</p>\n";
  if (!head_frame_figure.empty())
    h << figure_html(head_frame_figure, "qc_head_frame: mid-sagittal slice, anterior left; palatal line (cyan), Me and Pog (green)");
}

// Bilateral measures: left, right, L−R, L/R.
void bilateral_html(std::ostringstream& h, const RunSummary& s) {
  h << "<h2>Bilateral measures</h2>\n<table><tr><th>measure</th><th>left</th><th>right</th><th>L&minus;R</th>"
       "<th>L/R</th></tr>\n";
  for (const auto& [n, b] : s.bilateral)
    h << "<tr><td>" << html_escape(n) << "</td><td>" << fixed(b.L) << "</td><td>" << fixed(b.R) << "</td><td>" << fixed(b.diff)
      << "</td><td>" << fixed(b.ratio, 3) << "</td></tr>\n";
  h << "</table>\n";
}

// Positional versus shape asymmetry (METHOD.md §5): the chin against the
// skull's plane and against the mandible's own. Nothing without a cranial plane.
void cranial_html(std::ostringstream& h, const RunSummary& s) {
  if (!s.cranial.found) return;
  const auto& c = s.cranial;
  h << "<h2>Mandible against the skull</h2>\n<p>Cranial mid-sagittal plane (mirror plane of the bone above the condyles, "
    << fixed(c.bone_volume_cm3, 0) << " cm&sup3;, residual " << fixed(c.surface_rms_mm) << " mm): "
    << fixed(c.angle_to_mandible_plane_deg, 1) << "&deg; from the mandible's own plane.</p>\n"
    << "<table><tr><th>point</th><th>to the cranial plane (mm)</th><th>to the mandible's plane (mm)</th></tr>\n";
  for (const auto& [n, d] : c.to_cranial_mm) {
    const auto it = c.to_mandible_mm.find(n);
    h << "<tr><td>" << html_escape(n == "condylar_midpoint" ? std::string("midpoint of the condylions") : n) << "</td><td>"
      << fixed(d) << "</td><td>" << (it != c.to_mandible_mm.end() ? fixed(it->second) : "") << "</td></tr>\n";
  }
  h << "</table>\n<p class=\"muted\">Signed, + towards the patient's left. The chin's distance to the cranial plane is "
       "its total deviation; the mandible's own plane leans with a deformed mandible and absorbs much of it (on "
       "phantoms a 4 mm chin deviation reads 4.0 mm against the skull and 0.1 mm against the mandible's plane). "
       "Condyles off the cranial plane with a symmetric mandible suggest a positional shift rather than a "
       "deformity. Plane: cranial_plane.mrk.json.</p>\n";
}

// A regional SAF value with 3 decimals, empty when the region has none.
std::string saf_cell(const std::map<std::string, double>& m, const std::string& n) {
  const auto it = m.find(n);
  return it != m.end() ? fixed(it->second, 3) : std::string();
}

// Regional tables: mirror distance, SAF map, sided and lateral SAF map; the
// lateral map's largest region named under the table.
void regional_html(std::ostringstream& h, const RunSummary& s) {
  h << "<h2>Regional asymmetry</h2>\n<table><tr><th>region</th><th>mirror mean |d| (mm)</th><th>RMS</th><th>p95</th>"
       "<th>max</th><th>SAF map mean (rad)</th><th>SAF map, sided (rad)</th><th>lateral (rad)</th></tr>\n";
  for (const auto& [n, st] : s.mirror.regions)
    h << "<tr><td>" << html_escape(n) << "</td><td>" << fixed(st.mean_abs) << "</td><td>" << fixed(st.rms) << "</td><td>"
      << fixed(st.p95) << "</td><td>" << fixed(st.max) << "</td><td>" << saf_cell(s.saf_regions, n) << "</td><td>"
      << saf_cell(s.saf_regions_sided, n) << "</td><td>" << saf_cell(s.saf_regions_lateral, n) << "</td></tr>\n";
  h << "</table>\n<p class=\"muted\">The SAF map compares each point with its mirror point, so a left/right pair of "
       "regions carries the same value: it marks <em>where</em> the sides differ. The sided map (the 3D views) puts each "
       "pair's value on the member that lies beyond its mirror image (signed mirror distance &gt; 0; shared where the "
       "sides agree within 1 mm): the larger side, which is the abnormal one in an overgrowth and the normal one in an "
       "underdevelopment. Lateral: the sided value minus its mirror region's (positive on the larger side); its largest "
       "region is where the asymmetry concentrates";
  if (!s.saf_regions_lateral.empty()) {
    const std::string top = asymmetry::largest_region(s.saf_regions_lateral);
    h << ": " << html_escape(top) << " (" << fixed(s.saf_regions_lateral.at(top), 3)
      << " rad; symmetric phantoms stay at or below 0.001)";
  }
  h << ".</p>\n";
}

// SAF per configuration and the correspondence-free SAF.
void saf_configurations_html(std::ostringstream& h, const RunSummary& s) {
  h << "<h2>SAF per configuration</h2>\n<table><tr><th>configuration</th><th>score (rad)</th></tr>\n";
  for (const auto& [n, v] : s.saf.per_configuration)
    h << "<tr><td>" << html_escape(n) << "</td><td>" << fixed(v, 4) << "</td></tr>\n";
  h << "</table>\n<p class=\"muted\">Correspondence-free SAF (secondary): "
    << (s.saf.correspondence_free >= 0 ? fixed(s.saf.correspondence_free, 4) : "n/a") << " rad.</p>\n";
}

// SRD at the landmarks: twin mismatch and handedness (nothing without descriptors).
void srd_html(std::ostringstream& h, const RunSummary& s) {
  if (s.srd.twins.empty()) return;
  h << "<h2>Landmark neighbourhoods (SRD)</h2>\n<table><tr><th>landmark</th><th>twin</th><th>twin mismatch (rad)</th>"
       "<th>handedness (rad)</th></tr>\n";
  for (const auto& t : s.srd.twins)
    h << "<tr><td>" << html_escape(t.landmark) << "</td><td>" << html_escape(t.twin) << "</td><td>"
      << (t.mirror_mismatch >= 0 ? fixed(t.mirror_mismatch, 3) : "n/a") << "</td><td>"
      << (t.handedness >= 0 ? fixed(t.handedness, 3) : "n/a") << "</td></tr>\n";
  h << "</table>\n<p class=\"muted\">Signed-angle-field histograms over 5 mm rings around each landmark "
       "(METHOD.md &sect;6). Twin mismatch compares a landmark with its mirror twin after negating the angles "
       "(0 = locally mirror-symmetric; Me and Pog with themselves); handedness is the same comparison without "
       "negating, i.e. how far the descriptor tells the twins apart. It localises asymmetry, it does not grade it "
       "(on phantoms: symmetric 0.01&ndash;0.03 rad, a modified ramus or body 0.04&ndash;0.18 at its condyle or "
       "coronoid). Descriptors: srd.json.</p>\n";
}

// Segmentation volume, mesh statistics and the symmetry plane.
void surface_and_plane_html(std::ostringstream& h, const RunSummary& s) {
  const Plane& pl = s.reference.plane;
  h << "<h2>Surface and plane</h2>\n<table><tr><th>quantity</th><th>value</th></tr>\n"
    << "<tr><td>segmentation volume (mm&sup3;)</td><td>" << fixed(s.seg_volume_mm3, 0) << "</td></tr>\n"
    << "<tr><td>mesh vertices / faces</td><td>" << s.mesh.vertices << " / " << s.mesh.faces << "</td></tr>\n"
    << "<tr><td>mesh area (mm&sup2;) / volume (mm&sup3;)</td><td>" << fixed(s.mesh.area_mm2, 0) << " / "
    << fixed(s.mesh.volume_mm3, 0) << "</td></tr>\n"
    << "<tr><td>closed / genus</td><td>" << (s.mesh.closed ? "yes" : "no") << " / " << s.mesh.genus << "</td></tr>\n"
    << "<tr><td>plane point (LPS mm)</td><td>" << fixed(pl.point[0]) << ", " << fixed(pl.point[1]) << ", "
    << fixed(pl.point[2]) << "</td></tr>\n"
    << "<tr><td>plane normal</td><td>" << fixed(pl.normal[0], 4) << ", " << fixed(pl.normal[1], 4) << ", "
    << fixed(pl.normal[2], 4) << "</td></tr>\n"
    << "<tr><td>landmark residual RMS (mm)</td><td>" << fixed(s.reference.rms_landmark_residual_mm) << "</td></tr>\n"
    << "</table>\n";
}

// The method in one paragraph (details: docs/).
void methods_html(std::ostringstream& h) {
  h << "<h2>Methods</h2>\n<p>The mandible (lower teeth included) is separated from skull, upper teeth and spine by "
       "a marker-based watershed on the bone's depth and intensity, markers being the deep cores of dense bone, and "
       "identified anatomically (ITK; coarse scans are segmented on interpolated working grids that vote). Its "
       "surface comes from VTK flying edges, repaired and isotropically remeshed with CGAL, in patient LPS "
       "millimetres. Landmarks (METHOD.md &sect;2) are geodesic extremities labelled in the frame of the mandible's "
       "own symmetry plane, refined to sub-voxel apices. A Ceres robust fit gives the symmetry plane and a "
       "symmetric reference configuration, refined by mirror-ICP on the surface (Huber, then Cauchy loss). The "
       "mirror surface distance follows Cevidanes et&nbsp;al. 2011 (reflection through the plane, signed "
       "closest-point distance). The SAF score compares, through the mirror correspondence, the signed angle "
       "between gradients of harmonic fields (cotangent Laplacian, Dirichlet disks of 2 mm at landmarks) with its "
       "mirror configuration; the SAF and SRD definitions reconstruct Zhang (NUS, 2014). Details and measured "
       "accuracy: the project's docs/ folder.</p>\n";
}

// Provenance: command, parameters, timings.
void provenance_html(std::ostringstream& h, const RunSummary& s) {
  const auto E = html_escape;
  h << "<h2>Provenance</h2>\n<table><tr><th>item</th><th>value</th></tr>\n";
  h << "<tr><td>command</td><td>" << E(s.command_line) << "</td></tr>\n";
  for (const auto& [k, v] : s.parameters) h << "<tr><td>" << E(k) << "</td><td>" << E(v) << "</td></tr>\n";
  for (const auto& [n, t] : s.timings_s) h << "<tr><td>time: " << E(n) << "</td><td>" << fixed(t, 3) << " s</td></tr>\n";
  h << "<tr><td>time: total</td><td>" << fixed(s.total_s, 3) << " s</td></tr>\n</table>\n";
}

}  // namespace

// The sections in the order of docs/report.md; a failed run has no headline.
std::string report_html(const RunSummary& s, const std::vector<std::string>& figures, const std::vector<std::string>& views,
                        const std::string& views_note) {
  std::ostringstream h;
  identity_html(h, s);
  qc_html(h, s);
  warnings_html(h, s);
  if (s.qc.status != "fail") {
    h << "<h2>Headline</h2>\n";
    headline_html(h, s);
  }
  h << viewer_html(s);
  views_html(h, views, views_note);
  const QcFigures qc_figures = sort_qc_figures(figures);
  qc_slices_html(h, qc_figures);
  landmarks_html(h, s);
  head_frame_html(h, s, qc_figures.head_frame);
  bilateral_html(h, s);
  cranial_html(h, s);
  regional_html(h, s);
  saf_configurations_html(h, s);
  srd_html(h, s);
  surface_and_plane_html(h, s);
  methods_html(h);
  provenance_html(h, s);
  return html_page("MandiSym mandibular asymmetry report", h.str());
}

}  // namespace ms::reports
