// libFuzzer entry for what `mandisym compare PRE POST` does with the JSON of
// two run folders (pipeline/compare_cmd.cpp, load_run and compare_command).
//
// Input format: up to four texts separated by a 0x00 byte,
//     PRE results.json \0 POST results.json \0 PRE srd.json \0 POST srd.json
// split at the first three 0x00 bytes (the last text keeps any further ones).
// A missing POST results.json is PRE's (the same run twice); a missing or
// empty srd.json is absent (runs before 0.1 have none).
//
// Each run, as load_run: Json::parse (a parse error is compare's exit
// 4), the top-level object check, compare_checks::read_landmarks and
// read_plane, check_mesh, compare_checks::read_srd, and score_at over every
// score path compare reads (the table's rows and each srd landmark's
// mirror_mismatch_rad). Then, as compare_command: check_consistency on the
// pair, reference::align_rigid of POST's surface onto PRE's with their
// landmarks, and asymmetry::srd_distance per common srd landmark. The surfaces
// are fixed (mandible.vtp is not part of the input): a closed ellipsoid of a
// mandible's size (100 x 90 x 70 mm, 66 vertices), POST's turned by 3 degrees
// and moved by a few mm. An ms::Error is an accepted outcome; a crash, a
// sanitizer report, any other exception, a hang or an allocation beyond
// libFuzzer's limit is a finding. FUZZ_COMPARE_VERBOSE=1 prints each refusal
// (which check said no), for triage.

#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <string>
#include <vector>

#include "asymmetry/srd.h"
#include "core/error.h"
#include "core/json_text.h"
#include "pipeline/compare_checks.h"
#include "reference/reference.h"

namespace cc = ms::pipeline::compare_checks;
using ms::Mesh;
using ms::Vec3;

namespace {

// The score paths compare_cmd.cpp reads (score_rows, srd_mismatch_path).
// Keep in step with compare_cmd.cpp.
std::vector<std::vector<std::string>> score_paths() {
  std::vector<std::vector<std::string>> p = {
      {"scores", "saf", "score"}, {"scores", "mirror", "rms_mm"}, {"scores", "mirror", "p95_mm"}};
  for (const char* m : {"ramus_height_mm", "body_length_mm", "gonial_angle_deg", "condyle_to_plane_mm", "gonion_to_plane_mm"})
    p.push_back({"scores", "bilateral", m, "diff"});
  return p;
}

// Octahedron subdivided twice, projected onto an ellipsoid with semi-axes
// 50 x 45 x 35 mm (a mandible's bounding box), outward faces.
Mesh ellipsoid() {
  Mesh m;
  m.vertices = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  m.faces = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4}, {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
  for (int level = 0; level < 2; ++level) {
    std::map<std::pair<int, int>, int> mid;
    auto midpoint = [&](int a, int b) {
      const auto key = std::make_pair(std::min(a, b), std::max(a, b));
      const auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      const Vec3 &u = m.vertices[static_cast<std::size_t>(a)], &w = m.vertices[static_cast<std::size_t>(b)];
      const Vec3 p{u[0] + w[0], u[1] + w[1], u[2] + w[2]};
      const double n = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
      m.vertices.push_back({p[0] / n, p[1] / n, p[2] / n});
      return mid[key] = static_cast<int>(m.vertices.size() - 1);
    };
    std::vector<std::array<int, 3>> faces;
    for (const auto& f : m.faces) {
      const int ab = midpoint(f[0], f[1]), bc = midpoint(f[1], f[2]), ca = midpoint(f[2], f[0]);
      faces.push_back({f[0], ab, ca});
      faces.push_back({ab, f[1], bc});
      faces.push_back({ca, bc, f[2]});
      faces.push_back({ab, bc, ca});
    }
    m.faces = faces;
  }
  for (auto& v : m.vertices) v = {50 * v[0], 45 * v[1], 35 * v[2]};
  return m;
}

const Mesh& pre_mesh() {
  static const Mesh m = ellipsoid();
  return m;
}

const Mesh& post_mesh() {
  static const Mesh m = [] {
    Mesh p = ellipsoid();
    const double a = 3 * M_PI / 180, c = std::cos(a), s = std::sin(a);
    for (auto& v : p.vertices) v = {c * v[0] - s * v[1] + 1.5, s * v[0] + c * v[1] - 2.0, v[2] + 0.5};
    return p;
  }();
  return m;
}

struct Run {
  ms::Json results;
  ms::LandmarkSet landmarks;
  ms::Plane plane;
  cc::SrdData srd;
  std::string file;
};

// What compare_checks promises the code after it (compare_checks.h): every
// coordinate it hands on is finite and within kMaxCoordinateMm. Landmarks at
// 1e300 passed the reading before 80fc225 and kept align_rigid busy for 290 s
// on a real surface (each closest-point query from 1e300 mm visits the whole
// tree); on this harness's 128-face surface that costs nothing, so the promise
// is checked here instead of waiting for a timeout. A breach is a finding.
void require_sane(const Vec3& p, const std::string& what) {
  for (double x : p)
    if (!std::isfinite(x) || std::abs(x) > cc::kMaxCoordinateMm) {
      std::fprintf(stderr, "fuzz_compare: INVARIANT: %s has coordinate %g past the checks\n", what.c_str(), x);
      std::abort();
    }
}

void require_finite(double x, const char* what) {
  if (!std::isfinite(x)) {
    std::fprintf(stderr, "fuzz_compare: INVARIANT: %s is %g\n", what, x);
    std::abort();
  }
}

// load_run without the file system; throws ms::Error where compare exits 4.
Run load(const std::string& results_text, const std::string& srd_text, const std::string& dir, const Mesh& mesh) {
  Run r;
  r.file = dir + "/results.json";
  try {
    r.results = ms::parse_json(results_text);
  } catch (const std::exception& e) {  // as load_run: any parse failure is exit 4
    throw ms::Error(ms::ExitCode::InputInvalid, r.file + ": " + e.what());
  }
  if (!r.results.is_object()) cc::bad_field(r.file, "(top level)", "expected an object");
  r.landmarks = cc::read_landmarks(r.results, r.file);
  r.plane = cc::read_plane(r.results, r.file);
  for (const auto& [name, p] : r.landmarks.points) require_sane(p, r.file + " landmark " + name);
  require_sane(r.plane.point, r.file + " symmetry_plane.point");
  require_sane(r.plane.normal, r.file + " symmetry_plane.normal");
  cc::check_mesh(mesh, dir + "/mandible.vtp");
  if (!srd_text.empty()) {
    const std::string sf = dir + "/srd.json";
    ms::Json j;
    try {
      j = ms::parse_json(srd_text);
    } catch (const std::exception& e) {
      throw ms::Error(ms::ExitCode::InputInvalid, sf + ": " + e.what());
    }
    r.srd = cc::read_srd(j, sf);
  }
  bool ok = false;
  for (const auto& p : score_paths()) cc::score_at(r.results, p, r.file, &ok);
  for (const auto& [name, srd] : r.srd.landmarks)
    cc::score_at(r.results, {"scores", "saf", "srd", name, "mirror_mismatch_rad"}, r.file, &ok);
  return r;
}

// FUZZ_COMPARE_VERBOSE set: print refusals and warnings (triage).
bool verbose() {
  static const bool v = std::getenv("FUZZ_COMPARE_VERBOSE") != nullptr;
  return v;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string in(reinterpret_cast<const char*>(data), size);
  std::vector<std::string> part;
  std::size_t from = 0;
  while (part.size() < 3) {
    const std::size_t sep = in.find('\0', from);
    if (sep == std::string::npos) break;
    part.push_back(in.substr(from, sep - from));
    from = sep + 1;
  }
  part.push_back(in.substr(from));
  if (part.size() == 1) part.push_back(part[0]);  // no separator: the same run twice
  part.resize(4);
  try {
    const Run pre = load(part[0], part[2], "pre", pre_mesh());
    const Run post = load(part[1], part[3], "post", post_mesh());
    const cc::Consistency cons = cc::check_consistency({pre.results, pre_mesh(), pre.landmarks, pre.file},
                                                       {post.results, post_mesh(), post.landmarks, post.file});
    (void)ms::dump_json(cons.block);
    if (verbose())
      for (const auto& w : cons.warnings) std::fprintf(stderr, "fuzz_compare: warning: %s\n", w.c_str());
    const auto al = ms::reference::align_rigid(post_mesh(), pre_mesh(), post.landmarks, pre.landmarks);
    // A finite transform and residual, or compare.json carries NaN.
    for (double x : al.transform.R) require_finite(x, "align_rigid rotation");
    for (double x : al.transform.t) require_finite(x, "align_rigid translation");
    require_finite(al.rms_mm, "align_rigid rms_mm");
    if (pre.srd.bins > 0 && pre.srd.bins == post.srd.bins)
      for (const auto& [name, a] : pre.srd.landmarks) {
        const auto it = post.srd.landmarks.find(name);
        if (it != post.srd.landmarks.end()) (void)ms::asymmetry::srd_distance(a, it->second, pre.srd.bins);
      }
  } catch (const ms::Error& e) {
    if (verbose()) std::fprintf(stderr, "fuzz_compare: exit %d: %s\n", static_cast<int>(e.code()), e.what());
  }
  return 0;
}
