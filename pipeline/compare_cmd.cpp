// `mandisym compare PRE POST -o DIR`: pre/post surgery comparison.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>

#include "asymmetry/measures.h"
#include "asymmetry/srd.h"
#include "core/error.h"
#include "core/json_text.h"
#include "descriptors/matching.h"
#include "geometry/mesh_geometry.h"
#include "pipeline/commands.h"
#include "pipeline/compare_checks.h"
#include "reference/reference.h"
#include "reports/html_page.h"
#include "reports/render.h"
#include "reports/writers.h"
#include "surface/surface.h"

namespace fs = std::filesystem;

namespace ms::pipeline {

const cli::CommandSpec& compare_spec() {
  static const cli::CommandSpec s{
      "compare",
      "Compare two scans of one patient (pre/post surgery): scores side by side, post aligned to pre, change map.",
      "PRE and POST are completed `mandisym run` folders (with results.json and mandible.vtp) or inputs that `run` "
      "accepts; inputs are run first into DIR/pre and DIR/post. POST's surface is aligned rigidly to PRE's (Kabsch "
      "on common landmarks, then point-to-plane ICP with a Cauchy loss, so that what surgery changed does not drag "
      "the fit). Writes compare.json, compare.html (self-contained), post_aligned.vtp with the per-vertex "
      "`change_mm` (signed distance of aligned POST to PRE, + where POST lies outside PRE) and qc/ figures. "
      "Landmarks POST's detector missed or misplaced are transferred from PRE (--transfer-landmarks; compare.json "
      "`landmark_transfer`), and POST's bilateral measurements are recomputed with them. Run folders are read field by "
      "field: a wrong type, a non-finite or absurd (beyond 10 m) coordinate or a degenerate surface is exit 4 naming the "
      "file and field. POST dated before PRE, the same scan twice, or mandibles unlike one patient's (volume ratio > "
      "1.25, ramus landmarks > 5 mm RMS after rigid alignment) are warned on stderr and in compare.json `warnings`, "
      "`warning_details` and `consistency` (docs/batch.md).",
      {{"PRE", "the earlier scan or run folder"}, {"POST", "the later scan or run folder"}},
      {{"output", "DIR", "output folder (created)", ""},
       {"transfer-landmarks", "WHEN", "move PRE's landmarks onto POST by local ISI matching + RANSAC + ICP: auto = where "
        "POST's detection is missing or disagrees with the registered neighbourhood (plates, osteotomies); always = "
        "wherever the neighbourhood registers; off = never", "auto"},
       {"quiet", "", "print nothing but errors", ""},
       {"help", "", "show this help", ""}}};
  return s;
}

namespace {

struct RunData {
  fs::path dir;
  Json results;
  std::map<std::string, asymmetry::Srd> srd;  // from srd.json (runs before 0.1 have none)
  int srd_bins = 0;
  Mesh mesh;
  LandmarkSet landmarks;
  Plane plane;
};

std::string slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

bool is_run_folder(const fs::path& p) {
  return fs::is_directory(p) && fs::exists(p / "results.json") && fs::exists(p / "mandible.vtp");
}

struct ScoreRow {
  std::string key;    // compare.json `scores` key: stable, ASCII (e.g. "ramus_height_mm_diff")
  std::string label;  // compare.html
  std::vector<std::string> path;
  int prec;
};

// The scores compare puts side by side (results.json paths).
std::vector<ScoreRow> score_rows() {
  std::vector<ScoreRow> rows = {{"saf_score", "SAF score (rad)", {"scores", "saf", "score"}, 4},
                                {"mirror_rms_mm", "mirror distance RMS (mm)", {"scores", "mirror", "rms_mm"}, 2},
                                {"mirror_p95_mm", "mirror distance p95 (mm)", {"scores", "mirror", "p95_mm"}, 2}};
  for (const char* m : {"ramus_height_mm", "body_length_mm", "gonial_angle_deg", "condyle_to_plane_mm", "gonion_to_plane_mm"})
    rows.push_back({std::string(m) + "_diff", std::string(m) + " L−R", {"scores", "bilateral", m, "diff"}, 2});
  return rows;
}

std::vector<std::string> srd_mismatch_path(const std::string& landmark) {
  return {"scores", "saf", "srd", landmark, "mirror_mismatch_rad"};
}

double score(const RunData& d, const std::vector<std::string>& path, bool* ok) {
  return compare_checks::score_at(d.results, path, (d.dir / "results.json").string(), ok);
}

// Every score compare reads, type-checked before any work (exit 4 naming the field).
void check_scores(const RunData& d) {
  bool ok = false;
  for (const auto& r : score_rows()) score(d, r.path, &ok);
  for (const auto& [name, srd] : d.srd) score(d, srd_mismatch_path(name), &ok);
}

// srd.json, checked field by field (exit 4 naming the field; compare_checks::read_srd).
void load_srd(const fs::path& file, RunData& d) {
  const std::string f = file.string();
  Json j;
  try {
    j = parse_json(slurp(file));
  } catch (const std::exception& e) {
    throw Error(ExitCode::InputInvalid, f + ": " + e.what());
  }
  compare_checks::SrdData s = compare_checks::read_srd(j, f);
  d.srd_bins = s.bins;
  d.srd = std::move(s.landmarks);
}

// A run folder, every field compare uses checked: wrong types, non-finite or
// absurd coordinates (beyond 10 m) and degenerate surfaces are exit 4 with
// one line naming the file and the field (compare_checks.h).
RunData load_run(const fs::path& dir) {
  RunData d;
  d.dir = dir;
  const std::string rf = (dir / "results.json").string();
  try {
    d.results = parse_json(slurp(dir / "results.json"));
  } catch (const std::exception& e) {
    throw Error(ExitCode::InputInvalid, rf + ": " + e.what());
  }
  if (!d.results.is_object()) compare_checks::bad_field(rf, "(top level)", "expected an object");
  d.landmarks = compare_checks::read_landmarks(d.results, rf);
  d.plane = compare_checks::read_plane(d.results, rf);
  d.mesh = surface::read_vtp((dir / "mandible.vtp").string());
  compare_checks::check_mesh(d.mesh, (dir / "mandible.vtp").string());
  if (fs::exists(dir / "srd.json")) load_srd(dir / "srd.json", d);
  check_scores(d);
  return d;
}

// Resolves PRE / POST: a run folder, or an input run into out/name.
RunData resolve(const std::string& input, const fs::path& out, const std::string& name, bool quiet) {
  if (is_run_folder(input)) return load_run(input);
  if (!fs::exists(input)) throw Error(ExitCode::InputNotFound, input + ": no such file or folder");
  const fs::path dir = out / name;
  if (!quiet) std::cout << "compare: running " << name << " (" << input << ")" << std::endl;
  const cli::Args a = cli::parse(run_spec(), {input, "-o", dir.string(), "-q"});
  run_command(a, "mandisym run " + input + " -o " + dir.string());
  return load_run(dir);
}

using reports::fixed;
using reports::html_escape;

// ---- Read inputs ----------------------------------------------------------

struct CompareOptions {
  fs::path out;
  bool quiet = false;
  std::string transfer_mode;  // auto | always | off
};

// The options, checked, and the output folder (with qc/) created.
CompareOptions compare_options(const cli::Args& args) {
  const std::string out_s = args.get("output");
  if (out_s.empty()) throw Error(ExitCode::Usage, "compare: -o DIR is required");
  if (args.positional.size() != 2) throw Error(ExitCode::Usage, "compare: needs PRE and POST");
  CompareOptions o{out_s, args.has("quiet"), args.get("transfer-landmarks", "auto")};
  if (o.transfer_mode != "auto" && o.transfer_mode != "always" && o.transfer_mode != "off")
    throw Error(ExitCode::Usage, "compare: --transfer-landmarks must be auto, always or off");
  std::error_code ec;
  fs::create_directories(o.out / "qc", ec);
  if (ec) throw Error(ExitCode::OutputFailed, o.out.string() + ": cannot create the output folder: " + ec.message());
  return o;
}

// ---- Checks ---------------------------------------------------------------

// Same patient, in order? Warnings on stderr (also under --quiet: they say
// the comparison may be meaningless); compare.json carries them too.
compare_checks::Consistency check_pair(const RunData& pre, const RunData& post) {
  compare_checks::Consistency cons = compare_checks::check_consistency(
      {pre.results, pre.mesh, pre.landmarks, (pre.dir / "results.json").string()},
      {post.results, post.mesh, post.landmarks, (post.dir / "results.json").string()});
  for (const auto& w : cons.warnings) std::cerr << "mandisym: warning: " << w << std::endl;
  return cons;
}

// ---- Align ----------------------------------------------------------------

// POST aligned to PRE, and the change: signed distance of each aligned POST
// vertex to PRE's surface (+ outside), with area-weighted statistics like the
// mirror distance of a run.
struct Alignment {
  reference::AlignResult fit;
  double rotation_deg = 0;
  Mesh aligned;
  std::vector<double> change_mm;
  asymmetry::DistanceStats change;
};

Alignment align_post(const RunData& pre, const RunData& post) {
  Alignment a;
  a.fit = reference::align_rigid(post.mesh, pre.mesh, post.landmarks, pre.landmarks);
  const auto& R = a.fit.transform.R;
  a.rotation_deg = std::acos(std::clamp((R[0] + R[4] + R[8] - 1) / 2, -1.0, 1.0)) * 180 / M_PI;
  a.aligned = post.mesh;
  for (auto& v : a.aligned.vertices) v = a.fit.transform.apply(v);
  const geometry::ClosestPointIndex pre_index(pre.mesh);
  const auto pre_normals = geometry::face_normals(pre.mesh);
  a.change_mm.resize(a.aligned.vertices.size());
  for (std::size_t i = 0; i < a.change_mm.size(); ++i)
    a.change_mm[i] = geometry::signed_distance(pre_index, pre_normals, a.aligned.vertices[i]);
  a.change = asymmetry::distance_stats(a.change_mm, asymmetry::vertex_areas(a.aligned));
  return a;
}

// PRE's landmarks carried onto POST where POST's detection is uncertain
// (--transfer-landmarks), and POST's landmarks with the used ones in place.
struct Transfer {
  std::vector<descriptors::LandmarkTransfer> landmarks;  // one per PRE landmark (none when off)
  LandmarkSet post_landmarks;                           // detected, transferred ones in their place
  std::vector<std::string> used;                        // names transferred
};

Transfer transfer_from_pre(const RunData& pre, const RunData& post, const reference::RigidTransform& post_to_pre,
                          const std::string& mode) {
  Transfer t;
  if (mode != "off")
    t.landmarks = descriptors::transfer_landmarks(pre.mesh, pre.landmarks, post.mesh, post.landmarks, post_to_pre.inverse());
  t.post_landmarks = post.landmarks;
  for (auto& x : t.landmarks) {
    if (mode == "always" && x.registered && !x.used) {
      x.used = true;
      x.reason = "--transfer-landmarks always (" + x.reason + ")";
    }
    if (!x.used) continue;
    t.post_landmarks.set(x.name, x.transferred);
    t.used.push_back(x.name);
  }
  return t;
}

// ---- Score table ----------------------------------------------------------

// A value read from PRE and POST; ok = false where a run has none.
struct PrePost {
  bool pre_ok = false, post_ok = false;
  double pre = 0, post = 0;
};

PrePost pre_post(const RunData& pre, const RunData& post, const std::vector<std::string>& path) {
  PrePost v;
  v.pre = score(pre, path, &v.pre_ok);
  v.post = score(post, path, &v.post_ok);
  return v;
}

struct ScoreLine {
  ScoreRow row;
  PrePost value;
};

// SRD per landmark: how far the descriptor moved (same fields, no mirroring)
// and each scan's mismatch with the mirror twin.
struct SrdLine {
  std::string landmark;
  double distance_rad = -1;  // < 0: not computable
  PrePost mismatch;
};
struct SrdComparison {
  bool comparable = false;  // both runs have SRD with the same number of bins
  std::vector<SrdLine> lines;
};

// The bilateral L−R differences with POST measured on the landmarks used.
struct BilateralLine {
  std::string measure;
  bool has_pre = false;
  double pre = 0, post = 0;
};

// What compare puts side by side.
struct Tables {
  std::vector<ScoreLine> scores;
  SrdComparison srd;
  std::vector<BilateralLine> bilateral;  // only when landmarks were transferred
};

SrdComparison srd_comparison(const RunData& pre, const RunData& post) {
  SrdComparison c;
  c.comparable = pre.srd_bins > 0 && pre.srd_bins == post.srd_bins;
  if (!c.comparable) return c;
  for (const auto& [name, a] : pre.srd) {
    const auto it = post.srd.find(name);
    if (it == post.srd.end()) continue;
    c.lines.push_back({name, asymmetry::srd_distance(a, it->second, pre.srd_bins), pre_post(pre, post, srd_mismatch_path(name))});
  }
  return c;
}

// Each run measured itself on its own detections; with landmarks replaced,
// POST's bilateral numbers are measured again on the landmarks used.
std::vector<BilateralLine> bilateral_with_transfers(const RunData& pre, const RunData& post, const Transfer& t) {
  std::vector<BilateralLine> lines;
  if (t.used.empty()) return lines;
  const auto pre_b = asymmetry::bilateral_measures(pre.landmarks, pre.plane);
  for (const auto& [m, b] : asymmetry::bilateral_measures(t.post_landmarks, post.plane)) {
    const auto it = pre_b.find(m);
    lines.push_back({m, it != pre_b.end(), it != pre_b.end() ? it->second.diff : 0.0, b.diff});
  }
  return lines;
}

Tables score_tables(const RunData& pre, const RunData& post, const Transfer& t) {
  Tables tables;
  for (const auto& r : score_rows()) tables.scores.push_back({r, pre_post(pre, post, r.path)});
  tables.srd = srd_comparison(pre, post);
  tables.bilateral = bilateral_with_transfers(pre, post, t);
  return tables;
}

// ---- Write outputs --------------------------------------------------------

// post_aligned.vtp and the change views (aligned POST, PRE's plane, the landmarks used).
reports::RenderedViews write_change_surface(const fs::path& out, const Alignment& a, const Transfer& t, const Plane& pre_plane) {
  surface::write_vtp(a.aligned, {{"change_mm", a.change_mm}}, (out / "post_aligned.vtp").string());
  LandmarkSet aligned_lm;
  for (const auto& [name, p] : t.post_landmarks.points) aligned_lm.set(name, a.fit.transform.apply(p));
  return reports::render_views(a.aligned, a.change_mm, reports::ColourMap{"change post - pre (mm)", -5.0, 5.0, true},
                               aligned_lm, pre_plane, (out / "qc" / "view_change").string());
}

std::vector<std::string> compare_warnings(const reports::RenderedViews& rv, const Alignment& a,
                                          const compare_checks::Consistency& cons) {
  std::vector<std::string> w;
  if (!rv.error.empty()) w.push_back("3D views not rendered: " + rv.error);
  if (a.fit.landmark_pairs < 3) w.push_back("fewer than 3 common landmarks: alignment started from the centroids");
  w.insert(w.end(), cons.warnings.begin(), cons.warnings.end());
  return w;
}

Json value_or_null(bool ok, double v) { return ok ? Json(v) : Json(); }

// compare.json `alignment` and `change`.
Json alignment_json(const Alignment& a) {
  Json j = Json::object();
  j["landmark_pairs"] = static_cast<double>(a.fit.landmark_pairs);
  j["rms_mm"] = a.fit.rms_mm;
  j["rotation_deg"] = a.rotation_deg;
  j["translation_mm"] = norm(a.fit.transform.t);
  return j;
}
Json change_json(const Alignment& a) {
  Json j = Json::object();
  j["mean_abs_mm"] = a.change.mean_abs;
  j["p95_mm"] = a.change.p95;
  j["max_outward_mm"] = a.change.max_outward;
  j["max_inward_mm"] = a.change.max_inward;
  return j;
}

// compare.json `scores`: stable keys, each with pre, post, change and the display label.
Json scores_json(const std::vector<ScoreLine>& lines) {
  Json j = Json::object();
  for (const auto& [r, v] : lines) {
    Json e = Json::object();
    e["pre"] = value_or_null(v.pre_ok, v.pre);
    e["post"] = value_or_null(v.post_ok, v.post);
    e["change"] = value_or_null(v.pre_ok && v.post_ok, v.post - v.pre);
    e["label"] = r.label;
    j[r.key] = e;
  }
  return j;
}

// compare.json `srd`.
Json srd_json(const SrdComparison& srd) {
  Json j = Json::object();
  for (const auto& l : srd.lines) {
    Json e = Json::object();
    e["pre_post_distance_rad"] = value_or_null(l.distance_rad >= 0, l.distance_rad);
    e["mirror_mismatch_pre_rad"] = value_or_null(l.mismatch.pre_ok, l.mismatch.pre);
    e["mirror_mismatch_post_rad"] = value_or_null(l.mismatch.post_ok, l.mismatch.post);
    j[l.landmark] = e;
  }
  return j;
}

// compare.json `landmark_transfer`.
Json transfer_json(const Transfer& t) {
  Json j = Json::object();
  for (const auto& x : t.landmarks) {
    Json e = Json::object();
    e["detected"] = x.detected;
    e["registered"] = x.registered;
    e["used"] = x.used;
    e["overlap"] = x.overlap;
    e["patch_rms_mm"] = x.rms_mm;
    e["inliers"] = static_cast<double>(x.inliers);
    e["disagreement_mm"] = value_or_null(x.disagreement_mm >= 0, x.disagreement_mm);
    Json pt = Json::array();
    for (double c : x.transferred) pt.push_back(Json(c));
    e["transferred"] = x.registered ? pt : Json();
    e["reason"] = x.reason;
    j[x.name] = e;
  }
  return j;
}

// compare.json `bilateral_with_transferred_landmarks`.
Json bilateral_json(const std::vector<BilateralLine>& lines) {
  Json j = Json::object();
  for (const auto& l : lines) {
    Json e = Json::object();
    e["pre"] = value_or_null(l.has_pre, l.pre);
    e["post"] = l.post;
    e["change"] = value_or_null(l.has_pre, l.post - l.pre);
    j[l.measure] = e;
  }
  return j;
}

Json compare_json(const RunData& pre, const RunData& post, const Alignment& a, const Transfer& t, const Tables& tables,
                  const std::vector<std::string>& warnings, const compare_checks::Consistency& cons) {
  Json cj = Json::object();
  cj["schema_version"] = "1.1";  // 1.1: stable `scores` keys, `tool`
  cj["tool"]["name"] = "mandisym";
  cj["tool"]["version"] = version();
  cj["pre"] = pre.dir.string();
  cj["post"] = post.dir.string();
  cj["alignment"] = alignment_json(a);
  cj["change"] = change_json(a);
  cj["scores"] = scores_json(tables.scores);
  cj["srd"] = srd_json(tables.srd);
  cj["landmark_transfer"] = transfer_json(t);
  cj["landmarks_transferred"] = Json::array();
  for (const auto& n : t.used) cj["landmarks_transferred"].push_back(Json(n));
  if (!t.used.empty()) cj["bilateral_with_transferred_landmarks"] = bilateral_json(tables.bilateral);
  cj["warnings"] = Json::array();
  for (const auto& w : warnings) cj["warnings"].push_back(Json(w));
  cj["warning_details"] = cons.details;
  cj["consistency"] = cons.block;
  return cj;
}

// A table cell: the value with prec decimals, or `missing`.
std::string cell(bool ok, double v, int prec, const char* missing = "n/a") { return ok ? fixed(v, prec) : missing; }

void scores_html(std::ostringstream& h, const std::vector<ScoreLine>& lines) {
  h << "<h2>Scores</h2>\n<table><tr><th>score</th><th>pre</th><th>post</th><th>change</th></tr>\n";
  for (const auto& [r, v] : lines)
    h << "<tr><td>" << html_escape(r.label) << "</td><td>" << cell(v.pre_ok, v.pre, r.prec) << "</td><td>"
      << cell(v.post_ok, v.post, r.prec) << "</td><td>" << cell(v.pre_ok && v.post_ok, v.post - v.pre, r.prec)
      << "</td></tr>\n";
  h << "</table>\n<p class=\"muted\">change = post &minus; pre. Each scan's scores are measured on its own surface and "
       "symmetry plane; see each run's report.html for details.</p>\n";
}

void change_html(std::ostringstream& h, const Alignment& a) {
  h << "<h2>Surface change (post aligned to pre)</h2>\n<p>Mean |change| " << fixed(a.change.mean_abs)
    << " mm, 95th percentile " << fixed(a.change.p95) << " mm, largest outward " << fixed(a.change.max_outward)
    << " mm, inward " << fixed(a.change.max_inward) << " mm. Alignment: " << a.fit.landmark_pairs
    << " common landmarks, then ICP; rotation " << fixed(a.rotation_deg) << "&deg;, translation "
    << fixed(norm(a.fit.transform.t)) << " mm, residual (closest half) " << fixed(a.fit.rms_mm) << " mm.</p>\n";
}

void transfer_table_html(std::ostringstream& h, const Transfer& t) {
  h << "<table><tr><th>landmark</th><th>detected on post</th><th>registered</th><th>overlap</th>"
       "<th>detected &harr; transferred (mm)</th><th>used</th><th>why</th></tr>\n";
  for (const auto& x : t.landmarks)
    h << "<tr><td>" << html_escape(x.name) << "</td><td>" << (x.detected ? "yes" : "no") << "</td><td>"
      << (x.registered ? "yes" : "no") << "</td><td>" << fixed(100 * x.overlap, 0) << " %</td><td>"
      << cell(x.disagreement_mm >= 0, x.disagreement_mm, 1, "&ndash;") << "</td><td>"
      << (x.used ? "<b>transferred</b>" : "detected") << "</td><td>" << html_escape(x.reason) << "</td></tr>\n";
  h << "</table>\n";
}

void bilateral_table_html(std::ostringstream& h, const std::vector<BilateralLine>& lines) {
  h << "<table><tr><th>L&minus;R</th><th>pre</th><th>post (with transferred landmarks)</th><th>change</th></tr>\n";
  for (const auto& l : lines)
    h << "<tr><td>" << html_escape(l.measure) << "</td><td>" << cell(l.has_pre, l.pre, 2) << "</td><td>" << fixed(l.post)
      << "</td><td>" << cell(l.has_pre, l.post - l.pre, 2) << "</td></tr>\n";
  h << "</table>\n";
}

// Landmarks on POST: the transfer table and, when any was used, the
// bilateral differences measured on them (nothing when transfer was off).
void landmarks_html(std::ostringstream& h, const Transfer& t, const std::vector<BilateralLine>& bilateral) {
  if (t.landmarks.empty()) return;
  h << "<h2>Landmarks on post</h2>\n<p class=\"muted\">Each landmark's 25 mm neighbourhood on pre registered to post "
       "(Improved Spin Image matching, RANSAC, ICP; docs/descriptors.md). A landmark is transferred when post's own "
       "detection is missing or lies more than 3 mm from where its registered neighbourhood puts it (a plate, an "
       "osteotomy);";
  h << (t.used.empty() ? " none was." : " transferred here: ");
  for (std::size_t i = 0; i < t.used.size(); ++i) h << (i ? ", " : "") << html_escape(t.used[i]);
  h << "</p>\n";
  transfer_table_html(h, t);
  if (t.used.empty()) return;
  h << "<p>Bilateral differences with post measured on the landmarks used:</p>\n";
  bilateral_table_html(h, bilateral);
  h << "<p class=\"muted\">The score table above keeps each run's own numbers (post's from its detected "
       "landmarks).</p>\n";
}

void srd_html(std::ostringstream& h, const SrdComparison& srd) {
  if (!srd.comparable) return;
  h << "<h2>Landmark neighbourhoods (SRD)</h2>\n<p class=\"muted\">Signed-angle-field histograms around each landmark "
       "(docs/method.md, SRD): the change between the scans, and each scan's mismatch with the landmark's mirror twin "
       "(0 = locally mirror-symmetric; Me and Pog are compared with themselves).</p>\n"
    << "<table><tr><th>landmark</th><th>descriptor change pre&rarr;post (rad)</th><th>twin mismatch pre</th>"
       "<th>twin mismatch post</th></tr>\n";
  for (const auto& l : srd.lines)
    h << "<tr><td>" << html_escape(l.landmark) << "</td><td>" << cell(l.distance_rad >= 0, l.distance_rad, 3) << "</td><td>"
      << cell(l.mismatch.pre_ok, l.mismatch.pre, 3, "&ndash;") << "</td><td>"
      << cell(l.mismatch.post_ok, l.mismatch.post, 3, "&ndash;") << "</td></tr>\n";
  h << "</table>\n";
}

// The change views, then each run's own mirror-distance views.
void views_html(std::ostringstream& h, const reports::RenderedViews& rv, const RunData& pre, const RunData& post) {
  if (rv.files.empty()) {
    h << "<p class=\"muted\">3D views not rendered: " << html_escape(rv.error) << "</p>\n";
  } else {
    h << "<p class=\"muted\">Red: post lies outside pre (bone added or moved outward); blue: inside.</p><div class=\"views\">\n";
    for (const auto& f : rv.files)
      h << "<figure><img alt=\"" << html_escape(fs::path(f).stem().string()) << "\" src=\"" << reports::png_data_uri(f)
        << "\"><figcaption class=\"muted\">" << html_escape(fs::path(f).stem().string()) << "</figcaption></figure>\n";
    h << "</div>\n";
  }
  for (const auto* d : {&pre, &post}) {
    if (!fs::exists(d->dir / "qc" / "view_mirror_front.png")) continue;
    h << "<h2>Mirror distance, " << (d == &pre ? "pre" : "post") << "</h2>\n<div class=\"views\">\n";
    for (const char* v : {"front", "below", "left", "right"}) {
      const fs::path f = d->dir / "qc" / (std::string("view_mirror_") + v + ".png");
      if (fs::exists(f)) h << "<figure><img alt=\"" << v << "\" src=\"" << reports::png_data_uri(f.string()) << "\"></figure>\n";
    }
    h << "</div>\n";
  }
}

std::string compare_html(const RunData& pre, const RunData& post, const Alignment& a, const Transfer& t,
                         const Tables& tables, const std::vector<std::string>& warnings, const reports::RenderedViews& rv) {
  std::ostringstream h;
  h << "<h1>Pre/post comparison</h1>\n<p class=\"muted\">MandiSym " << html_escape(version()) << " &middot; pre: "
    << html_escape(pre.dir.filename().string()) << " &middot; post: " << html_escape(post.dir.filename().string())
    << "</p>\n";
  for (const auto& w : warnings) h << "<div class=\"warn\">&#9888; " << html_escape(w) << "</div>\n";
  scores_html(h, tables.scores);
  change_html(h, a);
  landmarks_html(h, t, tables.bilateral);
  srd_html(h, tables.srd);
  views_html(h, rv, pre, post);
  return reports::html_page("MandiSym pre/post comparison", h.str());
}

}  // namespace

// The stages of docs/report.md's compare: read inputs, checks, align (and
// transfer landmarks), score table, write outputs.
int compare_command(const cli::Args& args) {
  const CompareOptions o = compare_options(args);
  const RunData pre = resolve(args.positional[0], o.out, "pre", o.quiet);
  const RunData post = resolve(args.positional[1], o.out, "post", o.quiet);
  const compare_checks::Consistency cons = check_pair(pre, post);
  const Alignment a = align_post(pre, post);
  const Transfer t = transfer_from_pre(pre, post, a.fit.transform, o.transfer_mode);
  const Tables tables = score_tables(pre, post, t);
  const reports::RenderedViews rv = write_change_surface(o.out, a, t, pre.plane);
  const std::vector<std::string> warnings = compare_warnings(rv, a, cons);
  reports::write_text_atomic((o.out / "compare.html").string(), compare_html(pre, post, a, t, tables, warnings, rv));
  reports::write_text_atomic((o.out / "compare.json").string(),
                             dump_json(compare_json(pre, post, a, t, tables, warnings, cons)) + "\n");
  if (!o.quiet) std::cout << "compare: " << (o.out / "compare.html").string() << std::endl;
  return 0;
}

}  // namespace ms::pipeline
