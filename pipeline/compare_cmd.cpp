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

}  // namespace

int compare_command(const cli::Args& args) {
  const std::string out_s = args.get("output");
  if (out_s.empty()) throw Error(ExitCode::Usage, "compare: -o DIR is required");
  if (args.positional.size() != 2) throw Error(ExitCode::Usage, "compare: needs PRE and POST");
  const bool quiet = args.has("quiet");
  const std::string transfer_mode = args.get("transfer-landmarks", "auto");
  if (transfer_mode != "auto" && transfer_mode != "always" && transfer_mode != "off")
    throw Error(ExitCode::Usage, "compare: --transfer-landmarks must be auto, always or off");
  const fs::path out = out_s;
  std::error_code ec;
  fs::create_directories(out / "qc", ec);
  if (ec) throw Error(ExitCode::OutputFailed, out.string() + ": cannot create the output folder: " + ec.message());

  const RunData pre = resolve(args.positional[0], out, "pre", quiet);
  const RunData post = resolve(args.positional[1], out, "post", quiet);
  // Same patient, in order? Warnings on stderr (also under --quiet: they say
  // the comparison may be meaningless) and in compare.json.
  const compare_checks::Consistency cons = compare_checks::check_consistency(
      {pre.results, pre.mesh, pre.landmarks, (pre.dir / "results.json").string()},
      {post.results, post.mesh, post.landmarks, (post.dir / "results.json").string()});
  for (const auto& w : cons.warnings) std::cerr << "mandisym: warning: " << w << std::endl;

  // Align POST to PRE and measure the change.
  const auto al = reference::align_rigid(post.mesh, pre.mesh, post.landmarks, pre.landmarks);
  Mesh aligned = post.mesh;
  for (auto& v : aligned.vertices) v = al.transform.apply(v);

  // Landmark transfer PRE -> POST where POST's detection is uncertain.
  std::vector<descriptors::LandmarkTransfer> transfers;
  if (transfer_mode != "off")
    transfers = descriptors::transfer_landmarks(pre.mesh, pre.landmarks, post.mesh, post.landmarks, al.transform.inverse());
  LandmarkSet post_lm = post.landmarks;  // detected, with the transferred ones in their place
  std::vector<std::string> transferred_names;
  for (auto& t : transfers) {
    if (transfer_mode == "always" && t.registered && !t.used) {
      t.used = true;
      t.reason = "--transfer-landmarks always (" + t.reason + ")";
    }
    if (!t.used) continue;
    post_lm.set(t.name, t.transferred);
    transferred_names.push_back(t.name);
  }
  LandmarkSet aligned_lm;
  for (const auto& [name, p] : post_lm.points) aligned_lm.set(name, al.transform.apply(p));
  const geometry::ClosestPointIndex pre_index(pre.mesh);
  const auto pre_normals = geometry::face_normals(pre.mesh);
  std::vector<double> change(aligned.vertices.size());
  for (std::size_t i = 0; i < change.size(); ++i) change[i] = geometry::signed_distance(pre_index, pre_normals, aligned.vertices[i]);
  surface::write_vtp(aligned, {{"change_mm", change}}, (out / "post_aligned.vtp").string());
  // Area-weighted, like the mirror-distance statistics of a run.
  const asymmetry::DistanceStats cs = asymmetry::distance_stats(change, asymmetry::vertex_areas(aligned));
  const double mean_abs = cs.mean_abs, p95 = cs.p95, max_out = cs.max_outward, max_in = cs.max_inward;
  const double angle = std::acos(std::clamp((al.transform.R[0] + al.transform.R[4] + al.transform.R[8] - 1) / 2, -1.0, 1.0)) * 180 / M_PI;

  // Scores side by side.
  Json cj = Json::object();
  cj["schema_version"] = "1.1";  // 1.1: stable `scores` keys, `tool`
  cj["tool"]["name"] = "mandisym";
  cj["tool"]["version"] = version();
  cj["pre"] = pre.dir.string();
  cj["post"] = post.dir.string();
  Json alj = Json::object();
  alj["landmark_pairs"] = static_cast<double>(al.landmark_pairs);
  alj["rms_mm"] = al.rms_mm;
  alj["rotation_deg"] = angle;
  alj["translation_mm"] = norm(al.transform.t);
  cj["alignment"] = alj;
  Json ch = Json::object();
  ch["mean_abs_mm"] = mean_abs;
  ch["p95_mm"] = p95;
  ch["max_outward_mm"] = max_out;
  ch["max_inward_mm"] = max_in;
  cj["change"] = ch;
  const std::vector<ScoreRow> rows = score_rows();
  Json sj = Json::object();
  std::ostringstream table;
  table << "<table><tr><th>score</th><th>pre</th><th>post</th><th>change</th></tr>\n";
  for (const auto& r : rows) {
    bool ok1 = false, ok2 = false;
    const double a = score(pre, r.path, &ok1), b = score(post, r.path, &ok2);
    Json e = Json::object();
    e["pre"] = ok1 ? Json(a) : Json();
    e["post"] = ok2 ? Json(b) : Json();
    e["change"] = ok1 && ok2 ? Json(b - a) : Json();
    e["label"] = r.label;
    sj[r.key] = e;
    table << "<tr><td>" << reports::html_escape(r.label) << "</td><td>" << (ok1 ? fixed(a, r.prec) : "n/a") << "</td><td>"
          << (ok2 ? fixed(b, r.prec) : "n/a") << "</td><td>" << (ok1 && ok2 ? fixed(b - a, r.prec) : "n/a") << "</td></tr>\n";
  }
  table << "</table>\n";
  cj["scores"] = sj;

  // SRD per landmark: how far the descriptor moved (same fields, no mirroring)
  // and each scan's mismatch with the mirror twin.
  Json srdj = Json::object();
  std::ostringstream srd_table;
  if (pre.srd_bins > 0 && pre.srd_bins == post.srd_bins) {
    srd_table << "<table><tr><th>landmark</th><th>descriptor change pre&rarr;post (rad)</th><th>twin mismatch pre</th>"
                 "<th>twin mismatch post</th></tr>\n";
    for (const auto& [name, a] : pre.srd) {
      const auto it = post.srd.find(name);
      if (it == post.srd.end()) continue;
      const double d = asymmetry::srd_distance(a, it->second, pre.srd_bins);
      bool ok1 = false, ok2 = false;
      const double m1 = score(pre, srd_mismatch_path(name), &ok1);
      const double m2 = score(post, srd_mismatch_path(name), &ok2);
      Json e = Json::object();
      e["pre_post_distance_rad"] = d >= 0 ? Json(d) : Json();
      e["mirror_mismatch_pre_rad"] = ok1 ? Json(m1) : Json();
      e["mirror_mismatch_post_rad"] = ok2 ? Json(m2) : Json();
      srdj[name] = e;
      srd_table << "<tr><td>" << reports::html_escape(name) << "</td><td>" << (d >= 0 ? fixed(d, 3) : "n/a") << "</td><td>"
                << (ok1 ? fixed(m1, 3) : "&ndash;") << "</td><td>" << (ok2 ? fixed(m2, 3) : "&ndash;") << "</td></tr>\n";
    }
    srd_table << "</table>\n";
  }
  cj["srd"] = srdj;

  // Transfers, and POST's bilateral measurements on the landmarks used.
  Json tj = Json::object();
  std::ostringstream transfer_table;
  if (!transfers.empty()) {
    transfer_table << "<table><tr><th>landmark</th><th>detected on post</th><th>registered</th><th>overlap</th>"
                      "<th>detected &harr; transferred (mm)</th><th>used</th><th>why</th></tr>\n";
    for (const auto& t : transfers) {
      Json e = Json::object();
      e["detected"] = t.detected;
      e["registered"] = t.registered;
      e["used"] = t.used;
      e["overlap"] = t.overlap;
      e["patch_rms_mm"] = t.rms_mm;
      e["inliers"] = static_cast<double>(t.inliers);
      e["disagreement_mm"] = t.disagreement_mm >= 0 ? Json(t.disagreement_mm) : Json();
      Json pt = Json::array();
      for (double x : t.transferred) pt.push_back(Json(x));
      e["transferred"] = t.registered ? pt : Json();
      e["reason"] = t.reason;
      tj[t.name] = e;
      transfer_table << "<tr><td>" << reports::html_escape(t.name) << "</td><td>" << (t.detected ? "yes" : "no")
                     << "</td><td>" << (t.registered ? "yes" : "no") << "</td><td>" << fixed(100 * t.overlap, 0)
                     << " %</td><td>" << (t.disagreement_mm >= 0 ? fixed(t.disagreement_mm, 1) : "&ndash;") << "</td><td>"
                     << (t.used ? "<b>transferred</b>" : "detected") << "</td><td>" << reports::html_escape(t.reason)
                     << "</td></tr>\n";
    }
    transfer_table << "</table>\n";
  }
  cj["landmark_transfer"] = tj;
  cj["landmarks_transferred"] = Json::array();
  for (const auto& n : transferred_names) cj["landmarks_transferred"].push_back(Json(n));
  std::ostringstream bil_table;
  if (!transferred_names.empty()) {
    // Each run measured itself on its own detections; with landmarks replaced,
    // POST's bilateral numbers are measured again on the landmarks used.
    const auto pre_b = asymmetry::bilateral_measures(pre.landmarks, pre.plane);
    const auto post_b = asymmetry::bilateral_measures(post_lm, post.plane);
    Json bj = Json::object();
    bil_table << "<table><tr><th>L&minus;R</th><th>pre</th><th>post (with transferred landmarks)</th><th>change</th></tr>\n";
    for (const auto& [m, b] : post_b) {
      const auto it = pre_b.find(m);
      Json e = Json::object();
      e["pre"] = it != pre_b.end() ? Json(it->second.diff) : Json();
      e["post"] = b.diff;
      e["change"] = it != pre_b.end() ? Json(b.diff - it->second.diff) : Json();
      bj[m] = e;
      bil_table << "<tr><td>" << reports::html_escape(m) << "</td><td>" << (it != pre_b.end() ? fixed(it->second.diff) : "n/a")
                << "</td><td>" << fixed(b.diff) << "</td><td>" << (it != pre_b.end() ? fixed(b.diff - it->second.diff) : "n/a")
                << "</td></tr>\n";
    }
    bil_table << "</table>\n";
    cj["bilateral_with_transferred_landmarks"] = bj;
  }

  // Figures: the change map on the aligned POST surface, PRE's plane.
  const auto rv = reports::render_views(aligned, change, reports::ColourMap{"change post - pre (mm)", -5.0, 5.0, true},
                                        aligned_lm, pre.plane, (out / "qc" / "view_change").string());
  cj["warnings"] = Json::array();
  if (!rv.error.empty()) cj["warnings"].push_back(Json("3D views not rendered: " + rv.error));
  if (al.landmark_pairs < 3) cj["warnings"].push_back(Json("fewer than 3 common landmarks: alignment started from the centroids"));
  for (const auto& w : cons.warnings) cj["warnings"].push_back(Json(w));
  cj["warning_details"] = cons.details;
  cj["consistency"] = cons.block;

  std::ostringstream h;
  h << "<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>MandiSym pre/post comparison</title>"
       "<style>body{font-family:system-ui,sans-serif;margin:2em auto;max-width:1100px;color:#1d2433;padding:0 1em}"
       "table{border-collapse:collapse;margin:.6em 0}td,th{border:1px solid #dde3ec;padding:.3em .7em;text-align:right}"
       "td:first-child,th:first-child{text-align:left}th{background:#f2f5fa}.muted{color:#5a6475;font-size:.9em}"
       ".views{display:grid;grid-template-columns:repeat(4,1fr);gap:.3em}.views img{width:100%;border:1px solid #dde3ec}"
       ".warn{background:#fff4e5;border-left:4px solid #f0a020;padding:.6em 1em;margin:.6em 0}</style></head><body>\n"
    << "<h1>Pre/post comparison</h1>\n<p class=\"muted\">MandiSym " << reports::html_escape(version())
    << " &middot; pre: " << reports::html_escape(pre.dir.filename().string()) << " &middot; post: "
    << reports::html_escape(post.dir.filename().string()) << "</p>\n";
  for (std::size_t i = 0; i < cj["warnings"].size(); ++i)
    h << "<div class=\"warn\">&#9888; " << reports::html_escape(cj["warnings"][i].get<std::string>()) << "</div>\n";
  h << "<h2>Scores</h2>\n" << table.str()
    << "<p class=\"muted\">change = post &minus; pre. Each scan's scores are measured on its own surface and symmetry "
       "plane; see each run's report.html for details.</p>\n"
    << "<h2>Surface change (post aligned to pre)</h2>\n<p>Mean |change| " << fixed(mean_abs) << " mm, 95th percentile "
    << fixed(p95) << " mm, largest outward " << fixed(max_out) << " mm, inward " << fixed(max_in) << " mm. Alignment: "
    << al.landmark_pairs << " common landmarks, then ICP; rotation " << fixed(angle) << "&deg;, translation "
    << fixed(norm(al.transform.t)) << " mm, residual (closest half) " << fixed(al.rms_mm) << " mm.</p>\n";
  if (!transfer_table.str().empty()) {
    h << "<h2>Landmarks on post</h2>\n<p class=\"muted\">Each landmark's 25 mm neighbourhood on pre registered to post "
         "(Improved Spin Image matching, RANSAC, ICP; docs/descriptors.md). A landmark is transferred when post's own "
         "detection is missing or lies more than 3 mm from where its registered neighbourhood puts it (a plate, an "
         "osteotomy);";
    h << (transferred_names.empty() ? " none was." : " transferred here: ");
    for (std::size_t i = 0; i < transferred_names.size(); ++i) h << (i ? ", " : "") << reports::html_escape(transferred_names[i]);
    h << "</p>\n" << transfer_table.str();
    if (!transferred_names.empty())
      h << "<p>Bilateral differences with post measured on the landmarks used:</p>\n" << bil_table.str()
        << "<p class=\"muted\">The score table above keeps each run's own numbers (post's from its detected "
           "landmarks).</p>\n";
  }
  if (!srd_table.str().empty())
    h << "<h2>Landmark neighbourhoods (SRD)</h2>\n<p class=\"muted\">Signed-angle-field histograms around each landmark "
         "(docs/method.md, SRD): the change between the scans, and each scan's mismatch with the landmark's mirror twin "
         "(0 = locally mirror-symmetric; Me and Pog are compared with themselves).</p>\n"
      << srd_table.str();
  if (rv.files.empty()) {
    h << "<p class=\"muted\">3D views not rendered: " << reports::html_escape(rv.error) << "</p>\n";
  } else {
    h << "<p class=\"muted\">Red: post lies outside pre (bone added or moved outward); blue: inside.</p><div class=\"views\">\n";
    for (const auto& f : rv.files)
      h << "<figure><img alt=\"" << reports::html_escape(fs::path(f).stem().string()) << "\" src=\""
        << reports::png_data_uri(f) << "\"><figcaption class=\"muted\">" << reports::html_escape(fs::path(f).stem().string())
        << "</figcaption></figure>\n";
    h << "</div>\n";
  }
  for (const auto* d : {&pre, &post}) {
    const fs::path front = d->dir / "qc" / "view_mirror_front.png";
    if (!fs::exists(front)) continue;
    h << "<h2>Mirror distance, " << (d == &pre ? "pre" : "post") << "</h2>\n<div class=\"views\">\n";
    for (const char* v : {"front", "below", "left", "right"}) {
      const fs::path f = d->dir / "qc" / (std::string("view_mirror_") + v + ".png");
      if (fs::exists(f)) h << "<figure><img alt=\"" << v << "\" src=\"" << reports::png_data_uri(f.string()) << "\"></figure>\n";
    }
    h << "</div>\n";
  }
  h << "</body></html>\n";
  reports::write_text_atomic((out / "compare.html").string(), h.str());
  reports::write_text_atomic((out / "compare.json").string(), dump_json(cj) + "\n");
  if (!quiet) std::cout << "compare: " << (out / "compare.html").string() << std::endl;
  return 0;
}

}  // namespace ms::pipeline
