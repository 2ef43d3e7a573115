#include "phantom/phantom.h"

#include <cmath>
#include <random>
#include <stdexcept>
#include <string>

#include "phantom/anatomy.h"

namespace ms::phantom {
namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;

using Mat3 = std::array<double, 9>;  // row-major

Mat3 mul(const Mat3& a, const Mat3& b) {
  Mat3 c{};
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k)
      for (int q = 0; q < 3; ++q) c[3 * r + q] += a[3 * r + k] * b[3 * k + q];
  return c;
}
Vec3 apply(const Mat3& m, const Vec3& v) {
  return {m[0] * v[0] + m[1] * v[1] + m[2] * v[2], m[3] * v[0] + m[4] * v[1] + m[5] * v[2],
          m[6] * v[0] + m[7] * v[1] + m[8] * v[2]};
}
Vec3 apply_t(const Mat3& m, const Vec3& v) {
  return {m[0] * v[0] + m[3] * v[1] + m[6] * v[2], m[1] * v[0] + m[4] * v[1] + m[7] * v[2],
          m[2] * v[0] + m[5] * v[1] + m[8] * v[2]};
}

// R = Rz(yaw) Rx(pitch) Ry(roll), angles in degrees, right-handed about LPS axes.
Mat3 rotation(double yaw, double pitch, double roll) {
  const double cy = std::cos(yaw * kDeg), sy = std::sin(yaw * kDeg);
  const double cp = std::cos(pitch * kDeg), sp = std::sin(pitch * kDeg);
  const double cr = std::cos(roll * kDeg), sr = std::sin(roll * kDeg);
  const Mat3 rz{cy, -sy, 0, sy, cy, 0, 0, 0, 1};
  const Mat3 rx{1, 0, 0, 0, cp, -sp, 0, sp, cp};
  const Mat3 ry{cr, 0, sr, 0, 1, 0, -sr, 0, cr};
  return mul(rz, mul(rx, ry));
}

// Centre of the jaw region in the head frame: the pose pivots about it and
// the grid is centred on it.
const Vec3 kPivot{0, -30, -38};

void check(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument("phantom: invalid parameter " + what);
}

// Separable Gaussian blur, sigma in voxels per axis.
void gaussian_blur(std::vector<float>& v, const Geometry& g, const Vec3& sigma_vox) {
  for (int axis = 0; axis < 3; ++axis) {
    const double s = sigma_vox[axis];
    if (s < 0.05) continue;
    const int rad = static_cast<int>(std::ceil(3.0 * s));
    std::vector<double> k(2 * rad + 1);
    double sum = 0;
    for (int i = -rad; i <= rad; ++i) sum += k[i + rad] = std::exp(-0.5 * i * i / (s * s));
    for (auto& x : k) x /= sum;
    const long nx = g.size[0], ny = g.size[1], nz = g.size[2];
    const long n_axis = axis == 0 ? nx : axis == 1 ? ny : nz;
    const long stride = axis == 0 ? 1 : axis == 1 ? nx : nx * ny;
    const long lines = nx * ny * nz / n_axis;
#pragma omp parallel for schedule(static)
    for (long line = 0; line < lines; ++line) {
      long start;
      if (axis == 0) start = line * nx;
      else if (axis == 1) start = (line / nx) * nx * ny + (line % nx);
      else start = line;
      std::vector<double> src(n_axis);
      for (long i = 0; i < n_axis; ++i) src[i] = v[start + i * stride];
      for (long i = 0; i < n_axis; ++i) {
        double acc = 0;
        for (int j = -rad; j <= rad; ++j) {
          const long q = std::min(std::max(i + j, 0L), n_axis - 1);
          acc += k[j + rad] * src[q];
        }
        v[start + i * stride] = static_cast<float>(acc);
      }
    }
  }
}

// Standard normal deviates from a 64-bit Mersenne Twister via Box-Muller: the
// same numbers on every platform (std::normal_distribution is not portable).
class Normal {
 public:
  explicit Normal(std::uint64_t seed) : rng_(seed) {}
  double operator()() {
    if (has_) {
      has_ = false;
      return spare_;
    }
    double u1 = 0;
    do u1 = static_cast<double>(rng_() >> 11) * (1.0 / 9007199254740992.0);
    while (u1 <= 0.0);
    const double u2 = static_cast<double>(rng_() >> 11) * (1.0 / 9007199254740992.0);
    const double r = std::sqrt(-2.0 * std::log(u1));
    spare_ = r * std::sin(2 * 3.14159265358979323846 * u2);
    has_ = true;
    return r * std::cos(2 * 3.14159265358979323846 * u2);
  }

 private:
  std::mt19937_64 rng_;
  double spare_ = 0;
  bool has_ = false;
};

}  // namespace

// The random anatomy family's ranges (uniform; docs/phantom.md, "Random
// anatomy"), as offsets from the adult model. Sources: bicondylar width
// about 90-125 mm in adults (scale 0.88-1.12 of the model's ~100 mm keeps
// the whole family inside that range); ramus height Co-Go 50-70 mm and body length
// Go-Me 75-95 mm, side-to-side differences up to ~3 mm in normal adults;
// gonial angle 115-135 degrees; condylar head 15-25 x 8-10 mm; mandibular
// body cortex 1.5-3.5 mm at 1200-1800 HU over a 200-500 HU cancellous core;
// TMJ space 1.5-3 mm; crown sizes +-10 % (tooth-size anthropometry).
namespace {
struct Range {
  double lo, hi;
};
constexpr Range kScale{0.88, 1.12};
constexpr Range kRamusHeightMm{-6, 6}, kRamusSideMm{-1.5, 1.5};
constexpr Range kBodyLengthMm{-6, 6}, kBodySideMm{-1.5, 1.5};
constexpr Range kGonialAngleDeg{-7, 7}, kGonialSideDeg{-2, 2};
constexpr Range kCondyleSizeMm{-2, 2}, kCondyleSideMm{-0.5, 0.5};
constexpr Range kChinDeviationMm{-1.5, 1.5};
constexpr Range kCortexMm{1.5, 3.0}, kCorticalHu{1200, 1800}, kCancellousHu{200, 500};
constexpr Range kJointSpaceMm{1.5, 3.0}, kOcclusalGapMm{1.0, 2.0}, kCrownScale{0.9, 1.1};
}  // namespace

PhantomParams random_anatomy(std::uint64_t anatomy_seed, PhantomParams base) {
  std::mt19937_64 rng(anatomy_seed * 104729ULL + 3);
  auto draw = [&](const Range& r) { return std::uniform_real_distribution<double>(r.lo, r.hi)(rng); };
  PhantomParams p = base;
  p.scale = draw(kScale);
  // Shared shape (both sides) plus a small per-side difference.
  const double ramus = draw(kRamusHeightMm), body = draw(kBodyLengthMm), gonial = draw(kGonialAngleDeg), condyle = draw(kCondyleSizeMm);
  for (auto& side : p.side) {
    side.ramus_height_mm = ramus + draw(kRamusSideMm);
    side.body_length_mm = body + draw(kBodySideMm);
    side.gonial_angle_deg = gonial + draw(kGonialSideDeg);
    side.condyle_size_mm = condyle + draw(kCondyleSideMm);
  }
  p.chin_deviation_mm = draw(kChinDeviationMm);
  p.cortex_mm = draw(kCortexMm);
  p.cortical_hu = draw(kCorticalHu);
  p.cancellous_hu = draw(kCancellousHu);
  p.joint_space_mm = draw(kJointSpaceMm);
  p.occlusal_gap_mm = draw(kOcclusalGapMm);
  p.crown_scale = draw(kCrownScale);
  return p;
}

namespace {

// The parameters' documented ranges; throws std::invalid_argument naming the first one outside.
void check_params(const PhantomParams& P) {
  for (int a = 0; a < 3; ++a) {
    check(P.spacing[a] >= 0.1 && P.spacing[a] <= 6.0, "spacing (0.1..6 mm)");
    check(P.fov_mm[a] >= 40 && P.fov_mm[a] <= 400, "fov_mm (40..400 mm)");
  }
  check(P.noise_hu >= 0 && P.noise_hu <= 500, "noise_hu (0..500)");
  check(P.blur_mm >= 0 && P.blur_mm <= 5, "blur_mm (0..5)");
  check(P.occlusal_gap_mm >= 0 && P.occlusal_gap_mm <= 10, "occlusal_gap_mm (0..10)");
  check(!(P.metal && P.edentulous), "metal fillings need teeth (not with edentulous)");
  check(P.joint_space_mm >= 0 && P.joint_space_mm <= 8, "joint_space_mm (0..8)");
  for (const auto& s : P.side) {
    check(std::abs(s.ramus_height_mm) <= 15, "ramus height asymmetry (|x| <= 15 mm)");
    check(std::abs(s.body_length_mm) <= 15, "body length asymmetry (|x| <= 15 mm)");
    check(std::abs(s.gonial_angle_deg) <= 15, "gonial angle asymmetry (|x| <= 15 deg)");
    check(s.condyle_size_mm >= -6 && s.condyle_size_mm <= 10, "condyle size asymmetry (-6..10 mm)");
  }
  check(std::abs(P.chin_deviation_mm) <= 15, "chin deviation (|x| <= 15 mm)");
  check(P.scale >= 0.6 && P.scale <= 1.4, "scale (0.6..1.4)");
  check(P.cortex_mm >= 0.5 && P.cortex_mm <= 5, "cortex_mm (0.5..5 mm)");
  check(P.cortical_hu >= 600 && P.cortical_hu <= 2500, "cortical_hu (600..2500)");
  check(P.cancellous_hu >= 0 && P.cancellous_hu <= 900 && P.cancellous_hu < P.cortical_hu, "cancellous_hu (0..900, below cortical_hu)");
  check(P.crown_scale >= 0.7 && P.crown_scale <= 1.3, "crown_scale (0.7..1.3)");
  check(std::abs(P.yaw_deg) <= 45 && std::abs(P.pitch_deg) <= 45 && std::abs(P.roll_deg) <= 45, "pose (|angle| <= 45 deg)");
}

// Pose (docs/phantom.md, "Pose and grid"): p_LPS = R s (p_H - pivot) + shift.
struct Pose {
  Mat3 R;
  double scale;
  Vec3 shift;
  Vec3 to_lps(const Vec3& h) const { return apply(R, scale * (h - kPivot)) + shift; }
  Vec3 to_head(const Vec3& l) const { return (1.0 / scale) * apply_t(R, l - shift) + kPivot; }
};

// The grid: axial (identity direction), centred on LPS 0, size = round(fov / spacing).
Geometry phantom_grid(const PhantomParams& P) {
  Geometry g;
  for (int a = 0; a < 3; ++a) {
    g.size[a] = static_cast<std::size_t>(std::lround(P.fov_mm[a] / P.spacing[a]));
    g.spacing[a] = P.spacing[a];
    g.origin[a] = -0.5 * (g.size[a] - 1) * P.spacing[a];  // grid centred on LPS 0
  }
  return g;
}

// Image formation, partial volume: the model's HU and the ground-truth
// mandible at every voxel centre (w: a voxel in model mm).
void rasterise(const Anatomy& anat, const Pose& pose, double w, Volume& ct, Mask& mandible) {
  const Geometry& g = ct.geom;
  const long nz = static_cast<long>(g.size[2]);
#pragma omp parallel for schedule(dynamic, 1)
  for (long k = 0; k < nz; ++k)
    for (std::size_t j = 0; j < g.size[1]; ++j)
      for (std::size_t i = 0; i < g.size[0]; ++i) {
        const Vec3 h = pose.to_head(g.index_to_lps(i, j, k));
        const std::size_t idx = g.linear(i, j, k);
        ct.hu[idx] = static_cast<float>(anat.hu(h, w));
        mandible.data[idx] = anat.mandible(h) < 0 ? 1 : 0;
      }
}

// Metal streaks at LPS point p from fillings mc: alternating bright/dark rays
// around each filling and a dark band between two fillings (beam hardening /
// photon starvation), decaying with distance, in axial slices through them.
double streaks_at(const Vec3& p, const std::vector<Vec3>& mc, const std::vector<double>& phase) {
  double add = 0;
  for (std::size_t m = 0; m < mc.size(); ++m) {
    const double dz = std::abs(p[2] - mc[m][2]);
    if (dz > 3.0) continue;
    const double fz = 1.0 - dz / 3.0;
    const double dx = p[0] - mc[m][0], dy = p[1] - mc[m][1];
    const double r = std::hypot(dx, dy);
    if (r < 3.0) continue;
    add += fz * 450.0 * std::exp(-r / 35.0) * std::cos(14.0 * std::atan2(dy, dx) + phase[m]);
    for (std::size_t q = m + 1; q < mc.size(); ++q) {
      // distance from p to the segment between the two fillings, in-plane
      const double ex = mc[q][0] - mc[m][0], ey = mc[q][1] - mc[m][1];
      const double t = std::clamp((dx * ex + dy * ey) / (ex * ex + ey * ey), 0.0, 1.0);
      const double d = std::hypot(dx - t * ex, dy - t * ey);
      add -= fz * 700.0 * std::exp(-0.5 * d * d / 9.0);
    }
  }
  return add;
}

// Image formation, metal: the streaks of the fillings at LPS points mc.
void add_metal_streaks(Volume& ct, const std::vector<Vec3>& mc, std::uint64_t seed) {
  const Geometry& g = ct.geom;
  std::mt19937_64 rng(seed * 7919 + 17);
  std::vector<double> phase;
  for (std::size_t m = 0; m < mc.size(); ++m) phase.push_back(static_cast<double>(rng() % 6283) / 1000.0);
  const long nz = static_cast<long>(g.size[2]);
#pragma omp parallel for schedule(dynamic, 1)
  for (long k = 0; k < nz; ++k)
    for (std::size_t j = 0; j < g.size[1]; ++j)
      for (std::size_t i = 0; i < g.size[0]; ++i)
        ct.hu[g.linear(i, j, k)] += static_cast<float>(streaks_at(g.index_to_lps(i, j, k), mc, phase));
}

// Image formation, noise: Gaussian, Box-Muller over a Mersenne Twister
// seeded per slice (independent of the thread count).
void add_noise(Volume& ct, double noise_hu, std::uint64_t seed) {
  const Geometry& g = ct.geom;
  const long nz = static_cast<long>(g.size[2]);
#pragma omp parallel for schedule(static)
  for (long k = 0; k < nz; ++k) {
    Normal normal(seed * 1000003ULL + static_cast<std::uint64_t>(k));
    const std::size_t base = g.linear(0, 0, k);
    for (std::size_t q = 0; q < g.size[0] * g.size[1]; ++q) ct.hu[base + q] += static_cast<float>(noise_hu * normal());
  }
}

// --mirror: the finished volume flipped through the grid's mid-sagittal
// plane (the grid axis i runs along LPS x): voxels flip along i, L/R labels
// swap, the plane and the asymmetry record follow.
void mirror_phantom(Phantom& out) {
  const Geometry& g = out.ct.geom;
  const double xc = g.index_to_lps(0.5 * (g.size[0] - 1), 0, 0)[0];
  for (std::size_t k = 0; k < g.size[2]; ++k)
    for (std::size_t j = 0; j < g.size[1]; ++j) {
      const std::size_t b = g.linear(0, j, k);
      std::reverse(out.ct.hu.begin() + b, out.ct.hu.begin() + b + g.size[0]);
      std::reverse(out.mandible.data.begin() + b, out.mandible.data.begin() + b + g.size[0]);
    }
  const auto refl = [xc](Vec3 p) {
    p[0] = 2 * xc - p[0];
    return p;
  };
  LandmarkSet m;
  for (const auto& [name, p] : out.landmarks.points) m.set(mirror_label(name), refl(p));
  out.landmarks = m;
  out.plane.point = refl(out.plane.point);
  out.plane.normal = {out.plane.normal[0], -out.plane.normal[1], -out.plane.normal[2]};
  out.superior[0] = -out.superior[0];
  std::swap(out.truth.side[0], out.truth.side[1]);
  out.truth.chin_deviation_mm = -out.truth.chin_deviation_mm;
}

double landmark_distance(const LandmarkSet& lm, const char* a, const char* b) {
  const Vec3 *pa = lm.find(a), *pb = lm.find(b);
  return pa && pb ? distance(*pa, *pb) : 0.0;
}

}  // namespace

Phantom generate(const PhantomParams& params) {
  const PhantomParams& P = params;
  check_params(P);
  const Anatomy anat(P);
  const Pose pose{rotation(P.yaw_deg, P.pitch_deg, P.roll_deg), P.scale, P.shift_mm};

  Phantom out;
  out.params = P;
  out.ct.geom = phantom_grid(P);
  const Geometry& g = out.ct.geom;
  const std::size_t n = g.voxel_count();
  out.ct.hu.assign(n, -1000.0f);
  out.mandible.geom = g;
  out.mandible.data.assign(n, 0);
  const double w = (P.spacing[0] + P.spacing[1] + P.spacing[2]) / 3.0 / P.scale;  // a voxel in model mm
  rasterise(anat, pose, w, out.ct, out.mandible);
  if (!anat.metal_centers().empty()) {
    std::vector<Vec3> mc;
    for (const auto& m : anat.metal_centers()) mc.push_back(pose.to_lps(m));
    add_metal_streaks(out.ct, mc, P.seed);
  }
  if (P.blur_mm > 0)
    gaussian_blur(out.ct.hu, g, {P.blur_mm / P.spacing[0], P.blur_mm / P.spacing[1], P.blur_mm / P.spacing[2]});
  if (P.noise_hu > 0) add_noise(out.ct, P.noise_hu, P.seed);

  // Ground truth in LPS.
  for (const auto& [name, p] : anat.landmarks().points) out.landmarks.set(name, pose.to_lps(p));
  out.plane.point = pose.to_lps(Vec3{0, 0, 0});
  out.plane.normal = apply(pose.R, Vec3{1, 0, 0});
  out.superior = apply(pose.R, Vec3{0, 0, 1});
  out.truth.side = P.side;
  out.truth.chin_deviation_mm = P.chin_deviation_mm;
  if (P.mirror) mirror_phantom(out);
  out.truth.ramus_height_L = landmark_distance(out.landmarks, "Co_L", "Go_L");
  out.truth.ramus_height_R = landmark_distance(out.landmarks, "Co_R", "Go_R");
  out.truth.body_length_L = landmark_distance(out.landmarks, "Go_L", "Me");
  out.truth.body_length_R = landmark_distance(out.landmarks, "Go_R", "Me");
  return out;
}

}  // namespace ms::phantom
