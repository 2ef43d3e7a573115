// See compare_checks.h.
#include "pipeline/compare_checks.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>

#include "core/error.h"
#include "reference/reference.h"

namespace ms::pipeline::compare_checks {

namespace {

using Value = Json;
using Type = JsonKind;

// Mandible volume ratio (larger / smaller enclosed volume) above which PRE and
// POST are flagged as possibly not the same mandible. Two contours of one bone
// at the inter-observer Dice of CT mandible contours (~0.9, Brouwer et al.
// 2012, Radiother Oncol 104:326; docs/qc.md) differ in volume by at most
// 1/0.9^2 ≈ 1.22 (one nested in the other); orthognathic surgery moves bone
// rather than removing it. Adults span 29-112 cm³ (90 OpenKBP contours,
// docs/qc.md), so a larger ratio is more likely another person (or a
// resection, or a failed segmentation).
constexpr double kMaxVolumeRatio = 1.25;
// RMS (mm) of the ramus landmarks (Co, Cr, Go, both sides) of POST after a
// rigid Kabsch fit onto PRE's, above which the mandibles are flagged. These
// landmarks sit on the proximal segments that a sagittal split osteotomy and
// a genioplasty leave in place; 5 mm is above the worst per-landmark error of
// the detector on a real scan (3.6 mm, Visible Human female, README) and a
// quarter of the adult range of ramus height (Co-Go 50-70 mm, docs/phantom.md).
constexpr double kMaxRamusRmsMm = 5.0;
const char* const kRamusLandmarks[] = {"Co_L", "Co_R", "Cr_L", "Cr_R", "Go_L", "Go_R"};

std::string type_word(Type t) { return std::string(t == Type::Array || t == Type::Object ? "an " : "a ") + json_kind_name(t); }

bool deidentified(const Value& results) {
  const Value* in = find_member(results, "input");
  const Value* p = in && in->is_object() ? find_member(*in, "path") : nullptr;
  return !p || !p->is_string() || p->get<std::string>() == "(removed)";
}

// input.KEY as a string ("" when absent or null); wrong types are refused.
std::string input_string(const Value& results, const char* key, const std::string& file) {
  const Value* in = member(results, "input", Type::Object, file, "input");
  if (!in) return "";
  const Value* v = member(*in, key, Type::String, file, std::string("input.") + key);
  return v ? v->get<std::string>() : "";
}

bool is_date(const std::string& s) {
  return s.size() == 8 && std::all_of(s.begin(), s.end(), [](char c) { return std::isdigit(static_cast<unsigned char>(c)); });
}

void warn(Consistency& c, const std::string& code, const std::string& message, Value evidence) {
  c.warnings.push_back(message);
  Value d = Value::object();
  d["code"] = code;
  d["message"] = message;
  d["evidence"] = std::move(evidence);
  c.details.push_back(std::move(d));
}

void check_identity(const RunView& pre, const RunView& post, Consistency& c) {
  Value id = Value::object();
  if (deidentified(pre.results) || deidentified(post.results)) {
    id["compared"] = false;
    id["reason"] = "a de-identified run records no identifiers";
    c.block["identity"] = id;
    return;
  }
  id["compared"] = true;
  const std::string d1 = input_string(pre.results, "study_date", pre.file);
  const std::string d2 = input_string(post.results, "study_date", post.file);
  id["pre_study_date"] = d1.empty() ? Value() : Value(d1);
  id["post_study_date"] = d2.empty() ? Value() : Value(d2);
  if (is_date(d1) && is_date(d2) && d2 < d1) {
    Value e = Value::object();
    e["pre_study_date"] = d1;
    e["post_study_date"] = d2;
    warn(c, "post_dated_before_pre", "POST's study date " + d2 + " is before PRE's " + d1 + ": PRE and POST may be swapped", e);
  }
  const std::string h1 = input_string(pre.results, "sha256_of_pixel_data", pre.file);
  const std::string h2 = input_string(post.results, "sha256_of_pixel_data", post.file);
  const std::string u1 = input_string(pre.results, "series_uid", pre.file);
  const std::string u2 = input_string(post.results, "series_uid", post.file);
  id["same_pixel_data"] = !h1.empty() && h1 == h2;
  id["same_series_uid"] = !u1.empty() && u1 == u2;
  if ((!h1.empty() && h1 == h2) || (!u1.empty() && u1 == u2)) {
    Value e = Value::object();
    e["same_pixel_data"] = !h1.empty() && h1 == h2;
    e["same_series_uid"] = !u1.empty() && u1 == u2;
    e["series_uid"] = u1 == u2 && !u1.empty() ? Value(u1) : Value();
    warn(c, "same_scan", "PRE and POST are the same scan (same pixel data or series UID): no change can be measured", e);
  }
  c.block["identity"] = id;
}

void check_shape(const RunView& pre, const RunView& post, Consistency& c) {
  Value shape = Value::object();
  const double v1 = enclosed_volume_mm3(pre.mesh), v2 = enclosed_volume_mm3(post.mesh);
  const double ratio = std::max(v1, v2) / std::max(1e-9, std::min(v1, v2));
  shape["pre_volume_cm3"] = v1 / 1000;
  shape["post_volume_cm3"] = v2 / 1000;
  shape["volume_ratio"] = ratio;
  shape["volume_ratio_max"] = kMaxVolumeRatio;
  if (ratio > kMaxVolumeRatio) {
    Value e = Value::object();
    e["pre_volume_cm3"] = v1 / 1000, e["post_volume_cm3"] = v2 / 1000, e["ratio"] = ratio, e["max_ratio"] = kMaxVolumeRatio;
    char b[200];
    std::snprintf(b, sizeof b, "mandible volumes differ %.2f-fold (PRE %.1f cm3, POST %.1f cm3; same-patient limit %.2f): "
                  "different patients, a resection, or a failed segmentation", ratio, v1 / 1000, v2 / 1000, kMaxVolumeRatio);
    warn(c, "mandible_volume_ratio", b, e);
  }
  std::vector<std::pair<Vec3, Vec3>> pairs;
  for (const char* n : kRamusLandmarks)
    if (const Vec3* a = post.landmarks.find(n))
      if (const Vec3* b = pre.landmarks.find(n)) pairs.emplace_back(*a, *b);
  shape["ramus_landmarks"] = static_cast<double>(pairs.size());
  shape["ramus_rms_max_mm"] = kMaxRamusRmsMm;
  if (pairs.size() >= 4) {
    const reference::RigidTransform T = reference::kabsch(pairs);
    double ss = 0;
    for (const auto& [a, b] : pairs) ss += std::pow(distance(T.apply(a), b), 2);
    const double rms = std::sqrt(ss / static_cast<double>(pairs.size()));
    shape["ramus_rms_mm"] = rms;
    if (rms > kMaxRamusRmsMm) {
      Value e = Value::object();
      e["ramus_rms_mm"] = rms, e["landmarks"] = static_cast<double>(pairs.size()), e["max_mm"] = kMaxRamusRmsMm;
      char b[200];
      std::snprintf(b, sizeof b, "the ramus landmarks (Co, Cr, Go) differ by %.1f mm RMS after rigid alignment (same-patient "
                    "limit %.1f mm): different patients, or a misdetection", rms, kMaxRamusRmsMm);
      warn(c, "ramus_configuration", b, e);
    }
  } else {
    shape["ramus_rms_mm"] = Value();
  }
  c.block["shape"] = shape;
}

}  // namespace

void bad_field(const std::string& file, const std::string& field, const std::string& what) {
  throw Error(ExitCode::InputInvalid, file + ": field `" + field + "`: " + what);
}

const Json* member(const Json& obj, const std::string& key, JsonKind type, const std::string& file,
                          const std::string& field) {
  const Value* v = find_member(obj, key);
  if (!v || v->is_null()) return nullptr;
  if (json_kind(*v) != type) bad_field(file, field, "expected " + type_word(type) + ", found " + type_word(json_kind(*v)));
  return v;
}

double coordinate(const Json& v, const std::string& file, const std::string& field) {
  if (!v.is_number()) bad_field(file, field, "expected a number, found " + type_word(json_kind(v)));
  const double x = v.get<double>();
  if (!std::isfinite(x) || std::abs(x) > kMaxCoordinateMm)
  {
    char b[64];
    std::snprintf(b, sizeof b, "%.6g", x);
    bad_field(file, field, std::string("coordinate ") + b + " mm is not finite or beyond 10 m (corrupt)");
  }
  return x;
}

Vec3 point3(const Json& v, const std::string& file, const std::string& field) {
  if (!v.is_array()) bad_field(file, field, "expected an array of 3 numbers, found " + type_word(json_kind(v)));
  if (v.size() != 3) bad_field(file, field, "expected 3 coordinates, found " + std::to_string(v.size()));
  return {coordinate(v[0], file, field + "[0]"), coordinate(v[1], file, field + "[1]"), coordinate(v[2], file, field + "[2]")};
}

LandmarkSet read_landmarks(const Json& results, const std::string& file) {
  LandmarkSet out;
  const Value* lm = member(results, "landmarks", Type::Object, file, "landmarks");
  if (!lm) return out;
  if (lm->size() > kMaxLandmarks)
    bad_field(file, "landmarks", std::to_string(lm->size()) + " landmarks (at most " + std::to_string(kMaxLandmarks) + ")");
  for (const auto& [name, v] : lm->items())
    if (!v.is_null()) out.set(name, point3(v, file, "landmarks." + name));
  return out;
}

Plane read_plane(const Json& results, const std::string& file) {
  const Value* sp = member(results, "symmetry_plane", Type::Object, file, "symmetry_plane");
  if (!sp) bad_field(file, "symmetry_plane", "missing");
  const Value* p = member(*sp, "point", Type::Array, file, "symmetry_plane.point");
  const Value* n = member(*sp, "normal", Type::Array, file, "symmetry_plane.normal");
  if (!p) bad_field(file, "symmetry_plane.point", "missing");
  if (!n) bad_field(file, "symmetry_plane.normal", "missing");
  Plane pl;
  pl.point = point3(*p, file, "symmetry_plane.point");
  pl.normal = point3(*n, file, "symmetry_plane.normal");
  if (norm(pl.normal) < 1e-6) bad_field(file, "symmetry_plane.normal", "zero vector");
  return pl;
}

double score_at(const Json& results, const std::vector<std::string>& path, const std::string& file, bool* ok) {
  *ok = false;
  const Value* cur = &results;
  std::string field;
  for (std::size_t i = 0; i < path.size(); ++i) {
    field += (i ? "." : "") + path[i];
    cur = member(*cur, path[i], i + 1 < path.size() ? Type::Object : Type::Number, file, field);
    if (!cur) return NAN;
  }
  if (!std::isfinite(cur->get<double>())) return NAN;
  *ok = true;
  return cur->get<double>();
}

SrdData read_srd(const Json& j, const std::string& f) {
  SrdData d;
  if (!j.is_object()) bad_field(f, "(top level)", "expected an object");
  const Value* bins = member(j, "bins", Type::Number, f, "bins");
  if (!bins || bins->get<double>() != std::floor(bins->get<double>()) || bins->get<double>() < 1 || bins->get<double>() > kMaxSrdBins)
    bad_field(f, "bins", "expected an integer 1.." + std::to_string(kMaxSrdBins));
  d.bins = static_cast<int>(bins->get<double>());
  const Value* lms = member(j, "landmarks", Type::Object, f, "landmarks");
  if (!lms) return d;
  if (lms->size() > kMaxLandmarks) bad_field(f, "landmarks", "more than " + std::to_string(kMaxLandmarks) + " landmarks");
  for (const auto& [name, blocks] : lms->items()) {
    const std::string field = "landmarks." + name;
    if (!blocks.is_array()) bad_field(f, field, "expected an array");
    asymmetry::Srd x{name, {}};
    for (std::size_t i = 0; i < blocks.size(); ++i) {
      const std::string bf = field + "[" + std::to_string(i) + "]";
      if (!blocks[i].is_object()) bad_field(f, bf, "expected an object");
      const Value* conf = member(blocks[i], "configuration", Type::String, f, bf + ".configuration");
      const Value* mir = member(blocks[i], "mirrored", Type::Bool, f, bf + ".mirrored");
      const Value* h = member(blocks[i], "histogram", Type::Array, f, bf + ".histogram");
      if (!conf || !mir || !h) bad_field(f, bf, "needs configuration, mirrored and histogram");
      if (h->size() % static_cast<std::size_t>(d.bins)) bad_field(f, bf + ".histogram", "length is not a multiple of bins");
      asymmetry::SrdBlock b{conf->get<std::string>(), mir->get<bool>(), {}};
      for (std::size_t k = 0; k < h->size(); ++k) {
        const Value& e = (*h)[k];
        if (!e.is_number() || !std::isfinite(e.get<double>()) || e.get<double>() < 0)
          bad_field(f, bf + ".histogram[" + std::to_string(k) + "]", "expected a finite number >= 0");
        b.histogram.push_back(e.get<double>());
      }
      x.blocks.push_back(std::move(b));
    }
    d.landmarks[name] = std::move(x);
  }
  return d;
}

void check_mesh(const Mesh& m, const std::string& file) {
  if (m.faces.size() < kMinFaces)
    throw Error(ExitCode::InputInvalid, file + ": degenerate surface (" + std::to_string(m.faces.size()) + " faces, at least " +
                                            std::to_string(kMinFaces) + " needed)");
  for (std::size_t i = 0; i < m.vertices.size(); ++i)
    for (double x : m.vertices[i])
      if (!std::isfinite(x) || std::abs(x) > kMaxCoordinateMm)
        throw Error(ExitCode::InputInvalid, file + ": vertex " + std::to_string(i) + " lies beyond 10 m or is not finite (corrupt)");
  const auto n = static_cast<long long>(m.vertices.size());
  for (std::size_t f = 0; f < m.faces.size(); ++f)
    for (int k : m.faces[f])
      if (k < 0 || k >= n) throw Error(ExitCode::InputInvalid, file + ": face " + std::to_string(f) + " names vertex " + std::to_string(k) + " of " + std::to_string(n));
}

double enclosed_volume_mm3(const Mesh& m) {
  double v6 = 0;
  for (const auto& f : m.faces) {
    const Vec3 &a = m.vertices[static_cast<std::size_t>(f[0])], &b = m.vertices[static_cast<std::size_t>(f[1])],
               &c = m.vertices[static_cast<std::size_t>(f[2])];
    v6 += dot(a, cross(b, c));
  }
  return std::abs(v6) / 6.0;
}

Consistency check_consistency(const RunView& pre, const RunView& post) {
  Consistency c;
  check_identity(pre, post, c);
  check_shape(pre, post, c);
  return c;
}

}  // namespace ms::pipeline::compare_checks
