// Descriptor evaluation of Zhang 2014 (thesis section 3.3, ../shared/seed)
// re-run on phantom mandibles: Spin Image, Improved Spin Image (three radii
// of the neighbour-normal frames) and SHOT (PCL), recall vs 1-precision under
// partial views, clutter, rigid motion and three levels of Gaussian noise.
// Protocol, parameters and results: docs/descriptor-benchmark.md. Run through
// scripts/descriptor-eval.
//
// Outputs (into --out DIR): descriptor_eval_noise{10,20,30}.svg (one per
// noise level) and descriptor_eval_curves.csv; the markdown tables go to
// stdout, progress to stderr.
#include <omp.h>

#include <pcl/features/shot_omp.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/search/kdtree.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "descriptors/matching.h"
#include "descriptors/spin_image.h"
#include "geometry/mesh_geometry.h"
#include "phantom/phantom.h"
#include "surface/surface.h"

namespace {

using ms::Mesh;
using ms::Vec3;
using ms::operator+;
using ms::operator-;
using ms::operator*;
namespace d = ms::descriptors;
using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// ---------------------------------------------------------------- settings

struct Settings {
  std::string out = "docs/figures";
  std::string dump;  // optional CSV of every scene feature's match (diagnostics)
  bool quick = false;
  int models = 5;
  int features = 1000;
  int scenes_per_model = 3;
  std::vector<int> noise_pct = {10, 20, 30};  // Gaussian noise, % of the model's mesh resolution
};

constexpr double kKeepLo = 0.60, kKeepHi = 0.80;  // kept surface-area fraction of a partial view
constexpr double kMinCentreGap = 150;               // mm between the two parts' centroids (at least)
constexpr double kCorrectRes = 2;                   // correct: within 2 x mesh resolution of the truth
constexpr int kGrid = 1000;                         // 1-precision grid of the AUC / recall@x (step 0.001)
constexpr std::uint64_t kFeatureSeed = 20140301, kSceneSeed = 20140302, kNoiseSeed = 20140303;

// ------------------------------------------------------------------ models

struct Model {
  std::string name;
  Mesh mesh;
  double resolution = 0;
  double area = 0;
  std::vector<int> features;       // model vertices (sorted)
  std::vector<char> is_feature;    // per vertex
  ms::Plane plane;                 // symmetry plane of the unmodified anatomy (diagnostics only)
};

Model make_model(int id) {
  ms::phantom::PhantomParams p;
  p.spacing = {1, 1, 1};
  p.fov_mm = {150, 140, 130};
  p.noise_hu = 0;
  p.occlusal_gap_mm = 2;
  p.seed = static_cast<std::uint64_t>(id + 1);
  Model m;
  switch (id) {
    case 0: m.name = "symmetric"; break;
    case 1: m.name = "left ramus +5 mm"; p.side[0].ramus_height_mm = 5; break;
    case 2: m.name = "right body +5 mm"; p.side[1].body_length_mm = 5; break;
    case 3: m.name = "chin deviation 4 mm"; p.chin_deviation_mm = 4; break;
    case 4:
      m.name = "left gonial +8 deg, right condyle +2 mm";
      p.side[0].gonial_angle_deg = 8;
      p.side[1].condyle_size_mm = 2;
      break;
    default: throw std::logic_error("model id");
  }
  const auto ph = ms::phantom::generate(p);
  m.mesh = ms::surface::mesh_from_mask(ph.mandible).mesh;  // default options: 1 mm remeshed edges
  m.plane = ph.plane;
  m.resolution = d::mesh_resolution(m.mesh);
  for (double a : ms::geometry::face_areas(m.mesh)) m.area += a;
  return m;
}

void pick_features(Model& m, int id, int count) {
  const std::size_t n = m.mesh.vertices.size();
  std::vector<int> v(n);
  for (std::size_t i = 0; i < n; ++i) v[i] = static_cast<int>(i);
  std::mt19937_64 rng(kFeatureSeed + static_cast<std::uint64_t>(id));
  std::shuffle(v.begin(), v.end(), rng);
  v.resize(std::min(n, static_cast<std::size_t>(count)));
  std::sort(v.begin(), v.end());
  m.features = v;
  m.is_feature.assign(n, 0);
  for (int i : v) m.is_feature[static_cast<std::size_t>(i)] = 1;
}

// ------------------------------------------------------------------ scenes

Vec3 random_unit(std::mt19937_64& rng) {
  std::normal_distribution<double> g(0, 1);
  for (;;) {
    const Vec3 v{g(rng), g(rng), g(rng)};
    const double n = ms::norm(v);
    if (n > 1e-9) return (1 / n) * v;
  }
}

// Uniform random rotation (row-major 3x3) from a uniform random unit quaternion.
std::array<double, 9> random_rotation(std::mt19937_64& rng) {
  std::normal_distribution<double> g(0, 1);
  double q[4], n = 0;
  do {
    n = 0;
    for (double& c : q) c = g(rng), n += c * c;
  } while (n < 1e-12);
  n = std::sqrt(n);
  const double w = q[0] / n, x = q[1] / n, y = q[2] / n, z = q[3] / n;
  return {1 - 2 * (y * y + z * z), 2 * (x * y - w * z),     2 * (x * z + w * y),
          2 * (x * y + w * z),     1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
          2 * (x * z - w * y),     2 * (y * z + w * x),     1 - 2 * (x * x + y * y)};
}

Vec3 rotate(const std::array<double, 9>& R, const Vec3& v) {
  return {R[0] * v[0] + R[1] * v[1] + R[2] * v[2], R[3] * v[0] + R[4] * v[1] + R[5] * v[2],
          R[6] * v[0] + R[7] * v[1] + R[8] * v[2]};
}

// A partial view of one model: the faces whose centroid lies on the positive
// side of a plane through a random vertex with a uniform random normal,
// redrawn until 60-80 % of the area is kept; unreferenced vertices dropped.
struct Part {
  int model = -1;
  Mesh mesh;                 // cut, then posed (noise is added per noise level)
  std::vector<int> to_model; // part vertex -> model vertex
  double kept_fraction = 0;
  int tries = 0;
};

Part cut_and_pose(const Model& m, int model_id, std::mt19937_64& rng) {
  const auto& V = m.mesh.vertices;
  const auto& F = m.mesh.faces;
  const auto fa = ms::geometry::face_areas(m.mesh);
  std::vector<Vec3> centroid(F.size());
  for (std::size_t f = 0; f < F.size(); ++f)
    centroid[f] = (1.0 / 3) * (V[static_cast<std::size_t>(F[f][0])] + V[static_cast<std::size_t>(F[f][1])] +
                               V[static_cast<std::size_t>(F[f][2])]);
  std::uniform_int_distribution<std::size_t> pick(0, V.size() - 1);
  Part part;
  part.model = model_id;
  Vec3 point, normal;
  for (;;) {
    ++part.tries;
    if (part.tries > 100000) throw std::runtime_error("no plane keeps 60-80 % of the area");
    point = V[pick(rng)];
    normal = random_unit(rng);
    double kept = 0;
    for (std::size_t f = 0; f < F.size(); ++f)
      if (ms::dot(centroid[f] - point, normal) >= 0) kept += fa[f];
    part.kept_fraction = kept / m.area;
    if (part.kept_fraction >= kKeepLo && part.kept_fraction <= kKeepHi) break;
  }
  std::vector<int> remap(V.size(), -1);
  for (std::size_t f = 0; f < F.size(); ++f) {
    if (ms::dot(centroid[f] - point, normal) < 0) continue;
    std::array<int, 3> face{};
    for (int k = 0; k < 3; ++k) {
      const auto v = static_cast<std::size_t>(F[f][static_cast<std::size_t>(k)]);
      if (remap[v] < 0) {
        remap[v] = static_cast<int>(part.to_model.size());
        part.to_model.push_back(static_cast<int>(v));
        part.mesh.vertices.push_back(V[v]);
      }
      face[static_cast<std::size_t>(k)] = remap[v];
    }
    part.mesh.faces.push_back(face);
  }
  // Rotation about the part's centroid; the translation is set by the scene.
  Vec3 c{0, 0, 0};
  for (const auto& v : part.mesh.vertices) c = c + v;
  c = (1.0 / static_cast<double>(part.mesh.vertices.size())) * c;
  const auto R = random_rotation(rng);
  for (auto& v : part.mesh.vertices) v = rotate(R, v - c);
  return part;
}

double bounding_radius(const Mesh& m) {  // about the origin (parts are centred)
  double r = 0;
  for (const auto& v : m.vertices) r = std::max(r, ms::norm(v));
  return r;
}

struct SceneLayout {
  int model = -1, clutter = -1, index = 0;  // index: the model's scene number
  std::array<Part, 2> parts;  // [0] the scene's model, [1] the clutter model; posed, no noise
};

SceneLayout make_layout(const std::vector<Model>& models, int m, int s) {
  const int M = static_cast<int>(models.size());
  SceneLayout L;
  L.model = m;
  L.index = s;
  L.clutter = (m + 1 + s) % M;
  std::mt19937_64 rng(kSceneSeed + 1000 * static_cast<std::uint64_t>(m) + static_cast<std::uint64_t>(s));
  L.parts[0] = cut_and_pose(models[static_cast<std::size_t>(m)], m, rng);
  L.parts[1] = cut_and_pose(models[static_cast<std::size_t>(L.clutter)], L.clutter, rng);
  std::uniform_real_distribution<double> u(-50, 50);
  const Vec3 t0{u(rng), u(rng), u(rng)};
  const double gap = std::max(kMinCentreGap, bounding_radius(L.parts[0].mesh) + bounding_radius(L.parts[1].mesh) + 20);
  const Vec3 t1 = t0 + gap * random_unit(rng);
  for (auto& v : L.parts[0].mesh.vertices) v = v + t0;
  for (auto& v : L.parts[1].mesh.vertices) v = v + t1;
  return L;
}

struct SceneFeature {
  int vertex;       // in the scene mesh
  int model;        // ground truth
  int model_vertex;
};

struct Scene {
  Mesh mesh;
  std::vector<SceneFeature> features;
};

// Both parts in one mesh, isotropic Gaussian noise of sigma = pct % of each
// part's model resolution on every vertex.
Scene make_scene(const std::vector<Model>& models, const SceneLayout& L, int pct) {
  Scene sc;
  std::mt19937_64 rng(kNoiseSeed + 100000 * static_cast<std::uint64_t>(pct) + 1000 * static_cast<std::uint64_t>(L.model) +
                      static_cast<std::uint64_t>(L.index));
  for (const Part& p : L.parts) {
    const Model& mod = models[static_cast<std::size_t>(p.model)];
    std::normal_distribution<double> g(0, pct / 100.0 * mod.resolution);
    const int base = static_cast<int>(sc.mesh.vertices.size());
    for (std::size_t i = 0; i < p.mesh.vertices.size(); ++i) {
      const Vec3& v = p.mesh.vertices[i];
      sc.mesh.vertices.push_back({v[0] + g(rng), v[1] + g(rng), v[2] + g(rng)});
      const int mv = p.to_model[i];
      if (mod.is_feature[static_cast<std::size_t>(mv)]) sc.features.push_back({base + static_cast<int>(i), p.model, mv});
    }
    for (const auto& f : p.mesh.faces) sc.mesh.faces.push_back({f[0] + base, f[1] + base, f[2] + base});
  }
  return sc;
}

// ------------------------------------------------------------- descriptors

enum Variant { kSI, kISI, kISI_R4, kISI_R2, kSHOT, kVariants };
const char* const kName[kVariants] = {"SI", "ISI", "ISI normals R/4", "ISI normals R/2", "SHOT"};
const char* const kKey[kVariants] = {"SI", "ISI", "ISI_R4", "ISI_R2", "SHOT"};

struct Descriptors {
  int len = 0;
  std::vector<float> rows;
  std::vector<char> valid;  // finite and not all zero
  double setup_s = 0;       // per-mesh work, whatever the number of keypoints
  double keypoints_s = 0;   // the rest
};

void mark_valid(Descriptors& D) {
  const std::size_t n = D.rows.size() / static_cast<std::size_t>(D.len);
  D.valid.assign(n, 1);
  for (std::size_t k = 0; k < n; ++k) {
    bool finite = true, nonzero = false;
    for (int i = 0; i < D.len; ++i) {
      const float x = D.rows[k * static_cast<std::size_t>(D.len) + static_cast<std::size_t>(i)];
      finite = finite && std::isfinite(x);
      nonzero = nonzero || x != 0.0f;
    }
    D.valid[k] = finite && nonzero;
  }
}

Descriptors shot(const Mesh& mesh, const std::vector<int>& keypoints, double R, int threads) {
  const auto t0 = Clock::now();
  pcl::PointCloud<pcl::PointXYZ>::Ptr surface(new pcl::PointCloud<pcl::PointXYZ>);
  pcl::PointCloud<pcl::PointXYZ>::Ptr keys(new pcl::PointCloud<pcl::PointXYZ>);
  pcl::PointCloud<pcl::Normal>::Ptr normals(new pcl::PointCloud<pcl::Normal>);
  const auto vn = ms::geometry::vertex_normals(mesh);
  surface->reserve(mesh.vertices.size());
  normals->reserve(mesh.vertices.size());
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    const Vec3& v = mesh.vertices[i];
    surface->push_back(pcl::PointXYZ(static_cast<float>(v[0]), static_cast<float>(v[1]), static_cast<float>(v[2])));
    normals->push_back(pcl::Normal(static_cast<float>(vn[i][0]), static_cast<float>(vn[i][1]), static_cast<float>(vn[i][2])));
  }
  for (int k : keypoints) keys->push_back((*surface)[static_cast<std::size_t>(k)]);
  const double setup_s = seconds_since(t0);
  const auto t1 = Clock::now();
  pcl::SHOTEstimationOMP<pcl::PointXYZ, pcl::Normal, pcl::SHOT352> est(static_cast<unsigned>(threads));
  pcl::search::KdTree<pcl::PointXYZ>::Ptr tree(new pcl::search::KdTree<pcl::PointXYZ>);
  est.setSearchMethod(tree);
  est.setInputCloud(keys);
  est.setSearchSurface(surface);
  est.setInputNormals(normals);
  est.setRadiusSearch(R);
  pcl::PointCloud<pcl::SHOT352> out;
  est.compute(out);  // builds the k-d tree of the surface, then the frames and histograms
  const double keypoints_s = seconds_since(t1);
  if (out.size() != keypoints.size()) throw std::runtime_error("SHOT: output size differs from the keypoints");
  Descriptors D;
  D.len = 352;
  D.rows.resize(out.size() * 352);
  for (std::size_t k = 0; k < out.size(); ++k)
    std::copy(out[k].descriptor, out[k].descriptor + 352, D.rows.begin() + static_cast<long>(k * 352));
  mark_valid(D);
  D.setup_s = setup_s;
  D.keypoints_s = keypoints_s;
  return D;
}

Descriptors describe(Variant v, const Mesh& mesh, const std::vector<int>& keypoints, double R, int threads) {
  if (v == kSHOT) return shot(mesh, keypoints, R, threads);
  d::Options o;
  o.support_radius_mm = R;  // 15 x 15 bins, support angle 90 deg, LRF and normal radius R: the defaults
  if (v == kISI_R4) o.normal_radius_mm = R / 4;
  if (v == kISI_R2) o.normal_radius_mm = R / 2;
  const d::Kind kind = v == kSI ? d::Kind::kSpinImage : d::Kind::kImprovedSpinImage;
  const auto t0 = Clock::now();
  const d::SpinImages si(mesh, o);  // neighbour grid, vertex areas and normals
  // The ISI's neighbour normals (a frame at every vertex) are made on the
  // first ISI request: one throw-away descriptor puts them in the setup time.
  if (kind == d::Kind::kImprovedSpinImage && !keypoints.empty()) (void)si.compute(kind, {keypoints.front()});
  Descriptors D;
  D.setup_s = seconds_since(t0);
  const auto t1 = Clock::now();
  D.len = si.length();
  D.rows = si.compute(kind, keypoints);
  D.keypoints_s = seconds_since(t1);
  mark_valid(D);
  return D;
}

// ---------------------------------------------------------------- curves

// What the nearest model feature is, for a scene feature.
enum Outcome : signed char {
  kUnmatched = -1,  // invalid scene descriptor (or empty base)
  kCorrect = 0,     // right model, within 2 x resolution of the true position (the protocol's "correct")
  kOtherModel = 1,  // false: another model, but within 2 x resolution of the true position in the
                    // common head frame (the five phantoms share all anatomy away from their edits)
  kMirror = 2,      // false: within 2 x resolution of the true position mirrored in the true model's symmetry plane
  kElsewhere = 3,   // false: anywhere else
};

struct Match {
  float distance;  // +inf: unmatched
  Outcome outcome;
  int model = -1, vertex = -1;        // truth
  int nn_model = -1, nn_vertex = -1;  // the nearest model feature
};

struct CurvePoint {
  double threshold;
  long matches, correct, wrong;
  double recall, one_minus_precision;
};

struct Summary {
  long total = 0, invalid = 0;
  double auc = 0, recall_at_01 = 0, recall_at_02 = 0;
  double recall_all = 0, omp_all = 0;  // at the largest threshold (every valid feature matched)
  std::vector<CurvePoint> curve;      // decimated sweep (plots, CSV)
};

// location_only: count kOtherModel as correct (diagnostic, not the protocol).
Summary summarise(std::vector<Match> matches, bool location_only = false) {
  Summary S;
  S.total = static_cast<long>(matches.size());
  std::sort(matches.begin(), matches.end(), [](const Match& a, const Match& b) { return a.distance < b.distance; });
  // Envelope on the 1-precision grid: best[j] = max recall over thresholds with 1-precision <= j / kGrid.
  std::vector<double> best(kGrid + 1, 0.0);
  long c = 0, f = 0;
  const long step = std::max(1L, S.total / 500);
  long next_emit = step;
  for (std::size_t i = 0; i < matches.size();) {
    if (!std::isfinite(matches[i].distance)) break;
    const float t = matches[i].distance;
    for (; i < matches.size() && matches[i].distance == t; ++i) {
      const Outcome o = matches[i].outcome;
      (o == kCorrect || (location_only && o == kOtherModel) ? c : f)++;
    }
    const long n = c + f;
    const double recall = static_cast<double>(c) / static_cast<double>(S.total);
    const long j = (static_cast<long>(kGrid) * f + n - 1) / n;  // smallest grid index with f / n <= j / kGrid
    best[static_cast<std::size_t>(j)] = std::max(best[static_cast<std::size_t>(j)], recall);
    const bool last = i >= matches.size() || !std::isfinite(matches[i].distance);
    if (n >= next_emit || last) {
      S.curve.push_back({t, n, c, f, recall, static_cast<double>(f) / static_cast<double>(n)});
      while (next_emit <= n) next_emit += step;
    }
  }
  S.invalid = S.total - c - f;
  for (std::size_t j = 1; j < best.size(); ++j) best[j] = std::max(best[j], best[j - 1]);
  for (std::size_t j = 0; j + 1 < best.size(); ++j) S.auc += 0.5 * (best[j] + best[j + 1]) / kGrid;
  S.recall_at_01 = best[kGrid / 10];
  S.recall_at_02 = best[kGrid / 5];
  if (S.total > 0) S.recall_all = static_cast<double>(c) / static_cast<double>(S.total);
  if (c + f > 0) S.omp_all = static_cast<double>(f) / static_cast<double>(c + f);
  return S;
}

// ------------------------------------------------------------------- SVG

const char* const kColour[kVariants] = {"#1f77b4", "#d62728", "#ff9896", "#8c564b", "#2ca02c"};
const char* const kDash[kVariants] = {"", "", "6,4", "2,3", ""};
const double kWidth[kVariants] = {2.2, 2.2, 1.6, 1.6, 2.2};

std::string fmt(const char* f, double x) {
  char b[64];
  std::snprintf(b, sizeof b, f, x);
  return b;
}

void write_svg(const std::string& path, int pct, const std::array<Summary, kVariants>& S, double R, long features,
               int scenes, int models) {
  const double W = 640, H = 520, L = 70, Rm = 20, T = 50, B = 60;
  const double pw = W - L - Rm, ph = H - T - B;
  auto X = [&](double x) { return L + x * pw; };
  auto Y = [&](double y) { return T + (1 - y) * ph; };
  std::ostringstream o;
  o << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << W << "\" height=\"" << H << "\" viewBox=\"0 0 " << W << ' '
    << H << "\" font-family=\"DejaVu Sans, Arial, sans-serif\" font-size=\"12\">\n";
  o << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  o << "<text x=\"" << W / 2 << "\" y=\"22\" text-anchor=\"middle\" font-size=\"15\">Recall vs 1-precision, noise σ = " << pct
    << " % of mesh resolution</text>\n";
  o << "<text x=\"" << W / 2 << "\" y=\"40\" text-anchor=\"middle\" font-size=\"11\" fill=\"#555\">" << scenes
    << " scenes, " << features << " scene features, " << models << " phantom mandibles as models, support radius "
    << fmt("%.2f", R) << " mm</text>\n";
  for (int k = 0; k <= 10; ++k) {  // grid and ticks
    const double v = k / 10.0;
    o << "<line x1=\"" << X(v) << "\" y1=\"" << Y(0) << "\" x2=\"" << X(v) << "\" y2=\"" << Y(1)
      << "\" stroke=\"#e6e6e6\"/>\n";
    o << "<line x1=\"" << X(0) << "\" y1=\"" << Y(v) << "\" x2=\"" << X(1) << "\" y2=\"" << Y(v)
      << "\" stroke=\"#e6e6e6\"/>\n";
    o << "<line x1=\"" << X(v) << "\" y1=\"" << Y(0) << "\" x2=\"" << X(v) << "\" y2=\"" << Y(0) + 5
      << "\" stroke=\"black\"/>\n";
    o << "<line x1=\"" << X(0) - 5 << "\" y1=\"" << Y(v) << "\" x2=\"" << X(0) << "\" y2=\"" << Y(v)
      << "\" stroke=\"black\"/>\n";
    o << "<text x=\"" << X(v) << "\" y=\"" << Y(0) + 18 << "\" text-anchor=\"middle\">" << fmt("%.1f", v) << "</text>\n";
    o << "<text x=\"" << X(0) - 8 << "\" y=\"" << Y(v) + 4 << "\" text-anchor=\"end\">" << fmt("%.1f", v) << "</text>\n";
  }
  o << "<rect x=\"" << X(0) << "\" y=\"" << Y(1) << "\" width=\"" << pw << "\" height=\"" << ph
    << "\" fill=\"none\" stroke=\"black\"/>\n";
  o << "<text x=\"" << X(0.5) << "\" y=\"" << H - 15 << "\" text-anchor=\"middle\" font-size=\"13\">1 - precision</text>\n";
  o << "<text transform=\"translate(20," << Y(0.5) << ") rotate(-90)\" text-anchor=\"middle\" font-size=\"13\">recall</text>\n";
  // Curves: the thin ISI variants first, the three descriptors of the thesis on top.
  for (int v : {kISI_R4, kISI_R2, kSI, kSHOT, kISI}) {
    const auto& c = S[static_cast<std::size_t>(v)].curve;
    if (c.empty()) continue;
    o << "<polyline fill=\"none\" stroke=\"" << kColour[v] << "\" stroke-width=\"" << kWidth[v] << "\"";
    if (*kDash[v]) o << " stroke-dasharray=\"" << kDash[v] << "\"";
    o << " points=\"";
    for (const auto& p : c) o << fmt("%.1f", X(p.one_minus_precision)) << ',' << fmt("%.1f", Y(p.recall)) << ' ';
    o << "\"/>\n";
  }
  // Legend (upper right, inside the axes: high recall at high 1-precision
  // cannot happen together), with each curve's AUC.
  const double lx = X(0.97) - 235, ly = Y(0.97);
  o << "<rect x=\"" << lx << "\" y=\"" << ly << "\" width=\"235\" height=\"" << 18 * kVariants + 10
    << "\" fill=\"white\" fill-opacity=\"0.9\" stroke=\"#999\"/>\n";
  for (int v = 0; v < kVariants; ++v) {
    const double y = ly + 15 + 18 * v;
    o << "<line x1=\"" << lx + 8 << "\" y1=\"" << y - 4 << "\" x2=\"" << lx + 38 << "\" y2=\"" << y - 4 << "\" stroke=\""
      << kColour[v] << "\" stroke-width=\"" << kWidth[v] << "\"";
    if (*kDash[v]) o << " stroke-dasharray=\"" << kDash[v] << "\"";
    o << "/>\n<text x=\"" << lx + 45 << "\" y=\"" << y << "\">" << kName[v] << " (AUC "
      << fmt("%.3f", S[static_cast<std::size_t>(v)].auc) << ")</text>\n";
  }
  o << "</svg>\n";
  std::ofstream f(path);
  if (!f) throw std::runtime_error("cannot write " + path);
  f << o.str();
}

// ------------------------------------------------------------------- main

void usage(std::FILE* to) {
  std::fprintf(to,
               "usage: isi_eval [--out DIR] [--quick]\n"
               "  --out DIR  where the SVGs and the CSV go (default docs/figures)\n"
               "  --quick    smoke run: 2 models, 100 features each, 1 scene per model and noise level\n"
               "  --noise L  comma-separated noise levels in %% of mesh resolution (default 10,20,30; 0 = a check)\n"
               "  --dump F   also write every scene feature's nearest neighbour to the CSV file F\n"
               "Markdown tables on stdout, progress on stderr; docs/descriptor-benchmark.md.\n");
}

}  // namespace

int main(int argc, char** argv) try {
  Settings set;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--out" && i + 1 < argc) set.out = argv[++i];
    else if (a.rfind("--out=", 0) == 0) set.out = a.substr(6);
    else if (a == "--quick") set.quick = true;
    else if (a == "--dump" && i + 1 < argc) set.dump = argv[++i];
    else if (a == "--noise" && i + 1 < argc) {
      set.noise_pct.clear();
      std::stringstream list(argv[++i]);
      for (std::string item; std::getline(list, item, ',');) {
        char* end = nullptr;
        const long pct = std::strtol(item.c_str(), &end, 10);
        if (item.empty() || *end || pct < 0 || pct > 1000)
          return std::fprintf(stderr, "isi_eval: bad --noise list '%s'\n", argv[i]), 2;
        set.noise_pct.push_back(static_cast<int>(pct));
      }
    }
    else if (a == "-h" || a == "--help") return usage(stdout), 0;
    else return std::fprintf(stderr, "isi_eval: unknown argument '%s'\n", a.c_str()), usage(stderr), 2;
  }
  if (set.quick) set.models = 2, set.features = 100, set.scenes_per_model = 1;
  std::filesystem::create_directories(set.out);
  const int threads = omp_get_max_threads();
  const auto t_start = Clock::now();

  // Models.
  std::vector<Model> models(static_cast<std::size_t>(set.models));
  for (int m = 0; m < set.models; ++m) {
    const auto t0 = Clock::now();
    models[static_cast<std::size_t>(m)] = make_model(m);
    pick_features(models[static_cast<std::size_t>(m)], m, set.features);
    const Model& md = models[static_cast<std::size_t>(m)];
    std::fprintf(stderr, "isi_eval: model %d (%s): %zu vertices, %zu faces, resolution %.4f mm, area %.0f mm2 (%.1f s)\n",
                 m + 1, md.name.c_str(), md.mesh.vertices.size(), md.mesh.faces.size(), md.resolution, md.area,
                 seconds_since(t0));
  }
  double mean_res = 0;
  for (const auto& m : models) mean_res += m.resolution / static_cast<double>(models.size());
  const double R = 10 * mean_res;  // one absolute support radius for every model and scene
  const double t_models = seconds_since(t_start);
  std::fprintf(stderr, "isi_eval: support radius R = 10 x %.4f = %.3f mm; %d threads\n", mean_res, R, threads);

  // Model descriptors: the matching base.
  std::array<Descriptors, kVariants> base;
  std::array<std::vector<std::pair<int, int>>, kVariants> base_id;  // row -> (model, vertex)
  std::array<double, kVariants> t_desc{}, t_setup{};  // keypoint part, per-mesh part (s)
  std::array<long, kVariants> n_keys{}, base_invalid{}, n_meshes{};
  for (int v = 0; v < kVariants; ++v) {
    auto& B = base[static_cast<std::size_t>(v)];
    for (int m = 0; m < set.models; ++m) {
      const Model& md = models[static_cast<std::size_t>(m)];
      const Descriptors D = describe(static_cast<Variant>(v), md.mesh, md.features, R, threads);
      t_setup[static_cast<std::size_t>(v)] += D.setup_s;
      t_desc[static_cast<std::size_t>(v)] += D.keypoints_s;
      ++n_meshes[static_cast<std::size_t>(v)];
      n_keys[static_cast<std::size_t>(v)] += static_cast<long>(md.features.size());
      B.len = D.len;
      for (std::size_t k = 0; k < md.features.size(); ++k) {
        if (!D.valid[k]) {
          ++base_invalid[static_cast<std::size_t>(v)];
          continue;
        }
        B.rows.insert(B.rows.end(), D.rows.begin() + static_cast<long>(k * static_cast<std::size_t>(D.len)),
                      D.rows.begin() + static_cast<long>((k + 1) * static_cast<std::size_t>(D.len)));
        base_id[static_cast<std::size_t>(v)].push_back({m, md.features[k]});
      }
    }
    std::fprintf(stderr, "isi_eval: model descriptors %-16s %zu rows (%ld invalid)\n", kName[v],
                 base_id[static_cast<std::size_t>(v)].size(), base_invalid[static_cast<std::size_t>(v)]);
  }

  // Scene layouts (cuts and poses), shared by the three noise levels.
  std::vector<SceneLayout> layouts;
  for (int m = 0; m < set.models; ++m)
    for (int s = 0; s < set.scenes_per_model; ++s) {
      layouts.push_back(make_layout(models, m, s));
      const auto& L = layouts.back();
      std::fprintf(stderr, "isi_eval: scene layout model %d + clutter %d: kept %.3f / %.3f of the area (%d / %d planes drawn)\n",
                   L.model + 1, L.clutter + 1, L.parts[0].kept_fraction, L.parts[1].kept_fraction, L.parts[0].tries,
                   L.parts[1].tries);
    }

  // Scenes: descriptors, nearest model feature, correctness.
  const std::vector<int>& kNoisePercent = set.noise_pct;
  std::vector<std::array<std::vector<Match>, kVariants>> results(kNoisePercent.size());
  std::vector<long> scene_features(kNoisePercent.size(), 0);
  double t_match = 0;
  for (std::size_t l = 0; l < kNoisePercent.size(); ++l) {
    const auto t_level = Clock::now();
    for (const auto& L : layouts) {
      const Scene sc = make_scene(models, L, kNoisePercent[l]);
      std::vector<int> keys;
      for (const auto& f : sc.features) keys.push_back(f.vertex);
      scene_features[l] += static_cast<long>(keys.size());
      for (int v = 0; v < kVariants; ++v) {
        const Descriptors D = describe(static_cast<Variant>(v), sc.mesh, keys, R, threads);
        t_setup[static_cast<std::size_t>(v)] += D.setup_s;
        t_desc[static_cast<std::size_t>(v)] += D.keypoints_s;
        ++n_meshes[static_cast<std::size_t>(v)];
        n_keys[static_cast<std::size_t>(v)] += static_cast<long>(keys.size());
        const auto t1 = Clock::now();
        const auto nn = d::nearest(D.rows, base[static_cast<std::size_t>(v)].rows, D.len, 1);
        t_match += seconds_since(t1);
        auto& out = results[l][static_cast<std::size_t>(v)];
        for (std::size_t k = 0; k < keys.size(); ++k) {
          const auto& f = sc.features[k];
          if (!D.valid[k] || nn[k].index < 0) {
            out.push_back({std::numeric_limits<float>::infinity(), kUnmatched, f.model, f.model_vertex, -1, -1});
            continue;
          }
          const auto [bm, bv] = base_id[static_cast<std::size_t>(v)][static_cast<std::size_t>(nn[k].index)];
          const Model& truth = models[static_cast<std::size_t>(f.model)];
          const Vec3& at = models[static_cast<std::size_t>(bm)].mesh.vertices[static_cast<std::size_t>(bv)];
          const Vec3& want = truth.mesh.vertices[static_cast<std::size_t>(f.model_vertex)];
          const double tol = kCorrectRes * truth.resolution;
          Outcome o = kElsewhere;
          if (ms::distance(at, want) <= tol) o = bm == f.model ? kCorrect : kOtherModel;
          else if (ms::distance(at, truth.plane.reflect(want)) <= tol) o = kMirror;
          out.push_back({nn[k].distance, o, f.model, f.model_vertex, bm, bv});
        }
      }
    }
    std::fprintf(stderr, "isi_eval: noise %d %%: %zu scenes, %ld scene features (%.1f s)\n", kNoisePercent[l],
                 layouts.size(), scene_features[l], seconds_since(t_level));
  }

  // Summaries, CSV, SVG, tables.
  std::vector<std::array<Summary, kVariants>> S(kNoisePercent.size());
  const std::string csv_path = set.out + "/descriptor_eval_curves.csv";
  std::ofstream csv(csv_path);
  if (!csv) throw std::runtime_error("cannot write " + csv_path);
  csv << "descriptor,noise_pct,threshold,matches,correct,false,recall,one_minus_precision\n";
  for (std::size_t l = 0; l < kNoisePercent.size(); ++l) {
    for (int v = 0; v < kVariants; ++v) {
      auto& s = S[l][static_cast<std::size_t>(v)];
      s = summarise(results[l][static_cast<std::size_t>(v)]);
      for (const auto& p : s.curve)
        csv << kKey[v] << ',' << kNoisePercent[l] << ',' << fmt("%.6g", p.threshold) << ',' << p.matches << ','
            << p.correct << ',' << p.wrong << ',' << fmt("%.6f", p.recall) << ',' << fmt("%.6f", p.one_minus_precision)
            << '\n';
    }
    write_svg(set.out + "/descriptor_eval_noise" + std::to_string(kNoisePercent[l]) + ".svg", kNoisePercent[l], S[l], R,
              scene_features[l], static_cast<int>(layouts.size()), set.models);
  }
  csv.close();
  if (!set.dump.empty()) {
    std::ofstream dump(set.dump);
    if (!dump) throw std::runtime_error("cannot write " + set.dump);
    dump << "descriptor,noise_pct,distance,outcome,model,vertex,x,y,z,nn_model,nn_vertex,nn_x,nn_y,nn_z\n";
    for (std::size_t l = 0; l < kNoisePercent.size(); ++l)
      for (int v = 0; v < kVariants; ++v)
        for (const auto& m : results[l][static_cast<std::size_t>(v)]) {
          const Vec3& p = models[static_cast<std::size_t>(m.model)].mesh.vertices[static_cast<std::size_t>(m.vertex)];
          dump << kKey[v] << ',' << kNoisePercent[l] << ',' << fmt("%.6g", m.distance) << ',' << static_cast<int>(m.outcome)
               << ',' << m.model << ',' << m.vertex << ',' << fmt("%.3f", p[0]) << ',' << fmt("%.3f", p[1]) << ','
               << fmt("%.3f", p[2]) << ',' << m.nn_model << ',' << m.nn_vertex;
          if (m.nn_model >= 0) {
            const Vec3& q = models[static_cast<std::size_t>(m.nn_model)].mesh.vertices[static_cast<std::size_t>(m.nn_vertex)];
            dump << ',' << fmt("%.3f", q[0]) << ',' << fmt("%.3f", q[1]) << ',' << fmt("%.3f", q[2]) << '\n';
          } else {
            dump << ",,,\n";
          }
        }
  }

  std::printf("| noise σ | descriptor | length | scene features | unmatched (invalid) | AUC | recall @ 1-p ≤ 0.1 "
              "| recall @ 1-p ≤ 0.2 | recall, all matched | 1-p, all matched |\n");
  std::printf("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  for (std::size_t l = 0; l < kNoisePercent.size(); ++l)
    for (int v : {kISI, kSHOT, kSI, kISI_R4, kISI_R2}) {
      const auto& s = S[l][static_cast<std::size_t>(v)];
      std::printf("| %d %% | %s | %d | %ld | %ld | %.3f | %.3f | %.3f | %.3f | %.3f |\n", kNoisePercent[l], kName[v],
                  base[static_cast<std::size_t>(v)].len, s.total, s.invalid, s.auc, s.recall_at_01, s.recall_at_02,
                  s.recall_all, s.omp_all);
    }
  std::printf("\n| descriptor |");
  for (int pct : kNoisePercent) std::printf(" AUC σ %d %% |", pct);
  std::printf(" model features invalid | per keypoint (ms) | setup per mesh (s) | all / keypoint (ms) |\n|---|");
  for (std::size_t l = 0; l < kNoisePercent.size(); ++l) std::printf("---:|");
  std::printf("---:|---:|---:|---:|\n");
  for (int v : {kISI, kSHOT, kSI, kISI_R4, kISI_R2}) {
    std::printf("| %s |", kName[v]);
    for (std::size_t l = 0; l < kNoisePercent.size(); ++l) std::printf(" %.3f |", S[l][static_cast<std::size_t>(v)].auc);
    const auto u = static_cast<std::size_t>(v);
    const double keys = static_cast<double>(n_keys[u]);
    std::printf(" %ld | %.3f | %.3f | %.3f |\n", base_invalid[u], 1000 * t_desc[u] / keys,
                t_setup[u] / static_cast<double>(n_meshes[u]), 1000 * (t_desc[u] + t_setup[u]) / keys);
  }
  std::printf("\nFalse nearest neighbours with every valid scene feature matched (largest threshold), by where they "
              "lie; and, as a diagnostic outside the protocol, the curve with the right place on any model counted as "
              "correct:\n\n");
  std::printf("| noise σ | descriptor | false NN | same place, other model | mirror place | elsewhere "
              "| AUC, location only | recall, all matched, location only |\n");
  std::printf("|---|---|---:|---:|---:|---:|---:|---:|\n");
  for (std::size_t l = 0; l < kNoisePercent.size(); ++l)
    for (int v : {kISI, kSHOT, kSI, kISI_R4, kISI_R2}) {
      const auto& r = results[l][static_cast<std::size_t>(v)];
      long n[4] = {0, 0, 0, 0};
      for (const auto& m : r)
        if (m.outcome >= 0) ++n[m.outcome];
      const long wrong = n[1] + n[2] + n[3];
      const auto pct = [&](long x) { return wrong ? 100.0 * static_cast<double>(x) / static_cast<double>(wrong) : 0.0; };
      const Summary loc = summarise(r, true);
      std::printf("| %d %% | %s | %ld | %.1f %% | %.1f %% | %.1f %% | %.3f | %.3f |\n", kNoisePercent[l], kName[v], wrong,
                  pct(n[1]), pct(n[2]), pct(n[3]), loc.auc, loc.recall_all);
    }
  double t_all_desc = 0;
  for (std::size_t v = 0; v < kVariants; ++v) t_all_desc += t_desc[v] + t_setup[v];
  std::printf("\nModels: %d (%.1f s to generate and mesh), %d features each; support radius %.3f mm (10 x mean "
              "resolution %.4f mm); %zu scenes per noise level; descriptor time %.1f s, matching time %.1f s, total "
              "%.1f s on %d threads.\n",
              set.models, t_models, set.features, R, mean_res, layouts.size(), t_all_desc, t_match,
              seconds_since(t_start), threads);
  std::fprintf(stderr, "isi_eval: wrote %s and descriptor_eval_noise*.svg in %s\n", csv_path.c_str(), set.out.c_str());
  return 0;
} catch (const std::exception& e) {
  std::fprintf(stderr, "isi_eval: %s\n", e.what());
  return 1;
}
