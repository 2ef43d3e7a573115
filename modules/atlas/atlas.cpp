#include "atlas/atlas.h"

#include <zlib.h>

#include <Eigen/Geometry>
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <future>
#include <limits>
#include <stdexcept>

#include "core/components.h"
#include "core/debug_lap.h"
#include "core/error.h"
#include "threads/threads.h"

// The atlas compiled into the binary (generated from modules/atlas/mandible_atlas.bin).
extern const unsigned char kMandibleAtlasData[];
extern const std::size_t kMandibleAtlasSize;

namespace ms::atlas {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

struct Rot {
  double m[9];
};

Rot rotation(const Pose& p) {
  const double cp = std::cos(p.pitch), sp = std::sin(p.pitch), cy = std::cos(p.yaw), sy = std::sin(p.yaw),
               cr = std::cos(p.roll), sr = std::sin(p.roll);
  // Rz(yaw) * Rx(pitch) * Ry(roll)
  const double rz[9] = {cy, -sy, 0, sy, cy, 0, 0, 0, 1};
  const double rx[9] = {1, 0, 0, 0, cp, -sp, 0, sp, cp};
  const double ry[9] = {cr, 0, sr, 0, 1, 0, -sr, 0, cr};
  double a[9] = {}, out[9] = {};
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      for (int k = 0; k < 3; ++k) a[3 * r + c] += rz[3 * r + k] * rx[3 * k + c];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      for (int k = 0; k < 3; ++k) out[3 * r + c] += a[3 * r + k] * ry[3 * k + c];
  Rot R;
  std::copy(out, out + 9, R.m);
  return R;
}

// Sets the pose's angles from a rotation matrix R = Rz(yaw) Rx(pitch) Ry(roll)
// (row-major): its bottom row is (-cos p sin r, sin p, cos p cos r) and its
// middle column (-sin y cos p, cos y cos p, sin p).
void set_angles(Pose& p, const double R[9]) {
  p.pitch = std::asin(std::clamp(R[7], -1.0, 1.0));
  p.roll = std::atan2(-R[6], R[8]);
  p.yaw = std::atan2(-R[1], R[4]);
}

Eigen::Quaterniond quaternion(const Pose& p) {
  const Rot R = rotation(p);
  Eigen::Matrix3d m;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) m(r, c) = R.m[3 * r + c];
  return Eigen::Quaterniond(m);
}

// The pose as one affine map p = A a + t (A = scale R M).
struct Affine {
  double A[9];
  Vec3 t;
  Vec3 operator()(const Vec3& a) const {
    return {A[0] * a[0] + A[1] * a[1] + A[2] * a[2] + t[0], A[3] * a[0] + A[4] * a[1] + A[5] * a[2] + t[1],
            A[6] * a[0] + A[7] * a[1] + A[8] * a[2] + t[2]};
  }
};

Affine affine(const Pose& p) {
  const Rot R = rotation(p);
  const double M[3] = {1.0, (p.flip & 1) ? -1.0 : 1.0, (p.flip & 2) ? -1.0 : 1.0};
  Affine f;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) f.A[3 * r + c] = p.scale * R.m[3 * r + c] * M[c];
  f.t = p.t;
  return f;
}

Vec3 grid_point(const Grid& g, double i, double j, double k) {
  return {g.origin[0] + g.spacing * i, g.origin[1] + g.spacing * j, g.origin[2] + g.spacing * k};
}

// Separable Gaussian of a field with unknown (NaN) voxels: normalised
// convolution over the known ones; unknown voxels stay unknown.
void blur(Field& f, double sigma_mm) {
  if (sigma_mm <= 0) return;
  const double s = sigma_mm / f.grid.spacing;
  const int rad = std::max(1, static_cast<int>(std::ceil(3 * s)));
  std::vector<double> w(2 * rad + 1);
  for (int d = -rad; d <= rad; ++d) w[d + rad] = std::exp(-0.5 * d * d / (s * s));
  const Grid& g = f.grid;
  std::vector<float> val(g.count()), wt(g.count());
  for (std::size_t i = 0; i < g.count(); ++i) {
    const bool known = !std::isnan(f.v[i]);
    val[i] = known ? f.v[i] : 0.0f;
    wt[i] = known ? 1.0f : 0.0f;
  }
  const int stride[3] = {1, g.n[0], g.n[0] * g.n[1]};
  for (int axis = 0; axis < 3; ++axis) {
    std::vector<float> nv(g.count()), nw(g.count());
    const long nz = g.n[2];
#pragma omp parallel for schedule(static)
    for (long k = 0; k < nz; ++k)
      for (int j = 0; j < g.n[1]; ++j)
        for (int i = 0; i < g.n[0]; ++i) {
          const int idx[3] = {i, j, static_cast<int>(k)};
          const std::size_t at = g.linear(i, j, static_cast<int>(k));
          double sv = 0, sw = 0;
          for (int d = -rad; d <= rad; ++d) {
            const int q = idx[axis] + d;
            if (q < 0 || q >= g.n[axis]) continue;
            const std::size_t o = at + static_cast<std::ptrdiff_t>(d) * stride[axis];
            sv += w[d + rad] * val[o];
            sw += w[d + rad] * wt[o];
          }
          nv[at] = static_cast<float>(sv);
          nw[at] = static_cast<float>(sw);
        }
    val.swap(nv);
    wt.swap(nw);
  }
  for (std::size_t i = 0; i < g.count(); ++i)
    if (!std::isnan(f.v[i])) f.v[i] = wt[i] > 1e-6f ? val[i] / wt[i] : 0.0f;
}

// Template points: the atlas grid sampled every `stride` voxels, each point
// the mean of its stride^3 block (position at the block's centre).
struct Points {
  std::vector<Vec3> a;
  std::vector<float> v;
};

Points points_of(const Grid& g, const std::vector<float>& values, int stride) {
  Points p;
  for (int k = 0; k + stride <= g.n[2]; k += stride)
    for (int j = 0; j + stride <= g.n[1]; j += stride)
      for (int i = 0; i + stride <= g.n[0]; i += stride) {
        double s = 0;
        for (int c = 0; c < stride; ++c)
          for (int b = 0; b < stride; ++b)
            for (int a = 0; a < stride; ++a) s += values[g.linear(i + a, j + b, k + c)];
        const double h = 0.5 * (stride - 1);
        p.a.push_back(grid_point(g, i + h, j + h, k + h));
        p.v.push_back(static_cast<float>(s / (stride * stride * stride)));
      }
  return p;
}

// Pearson correlation of the template points with the field under a pose;
// -1 when less than kMinCoverage of the points fall in the scanned field.
double ncc(const Points& pts, const Pose& pose, const Field& f, double* coverage = nullptr) {
  const Affine A = affine(pose);
  double n = 0, st = 0, sf = 0, stt = 0, sff = 0, stf = 0;
  const long np = static_cast<long>(pts.a.size());
#pragma omp parallel for schedule(static) reduction(+ : n, st, sf, stt, sff, stf) if (np > 50000)
  for (long i = 0; i < np; ++i) {
    const float x = f.at(A(pts.a[i]));
    if (std::isnan(x)) continue;
    const double t = pts.v[i];
    n += 1, st += t, sf += x, stt += t * t, sff += double(x) * x, stf += t * x;
  }
  if (coverage) *coverage = np ? n / np : 0.0;
  if (n < kMinCoverage * np || n < 8) return -1;
  const double vt = stt - st * st / n, vf = sff - sf * sf / n;
  if (vt <= 1e-12 || vf <= 1e-12) return -1;
  return (stf - st * sf / n) / std::sqrt(vt * vf);
}

// Field averaged over blocks of `factor` voxels (unknown when under half known).
Field downsample(const Field& f, int factor) {
  Field o;
  o.grid.spacing = f.grid.spacing * factor;
  for (int a = 0; a < 3; ++a) o.grid.n[a] = std::max(1, f.grid.n[a] / factor);
  const double h = 0.5 * (factor - 1) * f.grid.spacing;
  o.grid.origin = {f.grid.origin[0] + h, f.grid.origin[1] + h, f.grid.origin[2] + h};
  o.v.assign(o.grid.count(), kNaN);
  for (int K = 0; K < o.grid.n[2]; ++K)
    for (int J = 0; J < o.grid.n[1]; ++J)
      for (int I = 0; I < o.grid.n[0]; ++I) {
        double s = 0;
        int known = 0;
        for (int c = 0; c < factor; ++c)
          for (int b = 0; b < factor; ++b)
            for (int a = 0; a < factor; ++a) {
              const float x = f.v[f.grid.linear(I * factor + a, J * factor + b, K * factor + c)];
              if (!std::isnan(x)) s += x, ++known;
            }
        if (2 * known >= factor * factor * factor) o.v[o.grid.linear(I, J, K)] = static_cast<float>(s / known);
      }
  return o;
}

// Scan voxel sampling: bone (value >= level) fraction per grid voxel, of
// the scan or, with `flip`, of its mirror (the array flipped, the geometry
// kept), on a grid of the given spacing whose voxel centres lie on multiples
// of spacing (a scan cropped or padded keeps its bins). g places the voxels
// ct.hu: ct.geom, or the scan seen in its own frame (ScanFrame).
Field fraction_field(const Volume& ct, const Geometry& g, double spacing, double level, const ScanMirror* flip) {
  Vec3 lo{1e30, 1e30, 1e30}, hi{-1e30, -1e30, -1e30};
  for (int c = 0; c < 8; ++c) {
    const Vec3 p = g.index_to_lps((c & 1) ? g.size[0] - 0.5 : -0.5, (c & 2) ? g.size[1] - 0.5 : -0.5, (c & 4) ? g.size[2] - 0.5 : -0.5);
    for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], p[a]), hi[a] = std::max(hi[a], p[a]);
  }
  Field f;
  f.grid.spacing = spacing;
  for (int a = 0; a < 3; ++a) {
    f.grid.origin[a] = std::floor(lo[a] / spacing) * spacing;
    f.grid.n[a] = static_cast<int>(std::ceil((hi[a] - f.grid.origin[a]) / spacing)) + 1;
  }
  f.v.assign(f.grid.count(), kNaN);
  const double max_sp = std::max({g.spacing[0], g.spacing[1], g.spacing[2]});
  if (max_sp <= 0.5 * spacing) {
    // Scatter scan voxels (sampled about every millimetre) into grid voxels.
    std::array<std::size_t, 3> step{};
    for (int a = 0; a < 3; ++a) step[a] = std::max<std::size_t>(1, static_cast<std::size_t>(std::floor(1.0 / g.spacing[a] + 1e-6)));
    std::vector<std::uint32_t> all(f.grid.count(), 0), bone(f.grid.count(), 0);
    const Vec3 o = g.index_to_lps(0, 0, 0);
    Vec3 di = g.index_to_lps(1, 0, 0) - o, dj = g.index_to_lps(0, 1, 0) - o, dk = g.index_to_lps(0, 0, 1) - o;
    const int fa = flip ? flip->axis : -1;
    for (std::size_t k = 0; k < g.size[2]; k += step[2])
      for (std::size_t j = 0; j < g.size[1]; j += step[1]) {
        Vec3 p = o + static_cast<double>(j) * dj + static_cast<double>(k) * dk;
        const std::size_t sj = fa == 1 ? g.size[1] - 1 - j : j, sk = fa == 2 ? g.size[2] - 1 - k : k;
        const float* row = ct.hu.data() + g.linear(0, sj, sk);
        for (std::size_t i = 0; i < g.size[0]; i += step[0]) {
          const std::size_t si = fa == 0 ? g.size[0] - 1 - i : i;
          const Vec3 q = p + static_cast<double>(i) * di;
          const int I = static_cast<int>(std::lround((q[0] - f.grid.origin[0]) / spacing));
          const int J = static_cast<int>(std::lround((q[1] - f.grid.origin[1]) / spacing));
          const int K = static_cast<int>(std::lround((q[2] - f.grid.origin[2]) / spacing));
          if (I < 0 || J < 0 || K < 0 || I >= f.grid.n[0] || J >= f.grid.n[1] || K >= f.grid.n[2]) continue;
          const std::size_t at = f.grid.linear(I, J, K);
          ++all[at];
          bone[at] += row[si] >= level;
        }
      }
    for (std::size_t i = 0; i < f.v.size(); ++i)
      if (all[i]) f.v[i] = static_cast<float>(bone[i]) / static_cast<float>(all[i]);
  } else {
    // Gather: the scan (trilinear) at each grid voxel's centre, 0 or 1; the
    // blur that follows makes it a fraction (the scan is as coarse as the grid).
    const long nz = f.grid.n[2];
#pragma omp parallel for schedule(static)
    for (long K = 0; K < nz; ++K)
      for (int J = 0; J < f.grid.n[1]; ++J)
        for (int I = 0; I < f.grid.n[0]; ++I) {
          const Vec3 q = grid_point(f.grid, I, J, static_cast<double>(K));
          const double h = interpolate(g, ct.hu.data(), flip ? flip->apply(q) : q);
          if (!std::isnan(h)) f.v[f.grid.linear(I, J, static_cast<int>(K))] = h >= level ? 1.0f : 0.0f;
        }
  }
  return f;
}

// Coarse exhaustive search of translations on the field's grid for one
// rotation: the template points rounded to integer offsets (nearest voxel).
struct Candidate {
  double score = -2;
  Pose pose;
};

void coarse_search(const Points& pts, const Pose& rot, const Field& f, const std::vector<std::uint8_t>& near_bone,
                   std::vector<Candidate>* out) {
  Pose r0 = rot;
  r0.t = {0, 0, 0};
  const Affine A = affine(r0);
  const double s = f.grid.spacing;
  std::vector<std::array<int, 3>> off(pts.a.size());
  for (std::size_t i = 0; i < pts.a.size(); ++i) {
    const Vec3 q = A(pts.a[i]);
    off[i] = {static_cast<int>(std::lround(q[0] / s)), static_cast<int>(std::lround(q[1] / s)), static_cast<int>(std::lround(q[2] / s))};
  }
  const Grid& g = f.grid;
  const long ncell = static_cast<long>(g.count());
  std::vector<double> score(ncell, -2);
#pragma omp parallel for schedule(dynamic, 64)
  for (long c = 0; c < ncell; ++c) {
    if (std::isnan(f.v[c]) || !near_bone[c]) continue;
    const int i = static_cast<int>(c % g.n[0]), j = static_cast<int>((c / g.n[0]) % g.n[1]), k = static_cast<int>(c / (static_cast<long>(g.n[0]) * g.n[1]));
    double n = 0, st = 0, sf = 0, stt = 0, sff = 0, stf = 0;
    for (std::size_t p = 0; p < off.size(); ++p) {
      const int x = i + off[p][0], y = j + off[p][1], z = k + off[p][2];
      if (x < 0 || y < 0 || z < 0 || x >= g.n[0] || y >= g.n[1] || z >= g.n[2]) continue;
      const float v = f.v[g.linear(x, y, z)];
      if (std::isnan(v)) continue;
      const double t = pts.v[p];
      n += 1, st += t, sf += v, stt += t * t, sff += double(v) * v, stf += t * v;
    }
    if (n < kMinCoverage * off.size()) continue;
    const double vt = stt - st * st / n, vf = sff - sf * sf / n;
    if (vt <= 1e-12 || vf <= 1e-12) continue;
    score[c] = (stf - st * sf / n) / std::sqrt(vt * vf);
  }
  // Local maxima (26-neighbourhood) become candidates.
  for (long c = 0; c < ncell; ++c) {
    if (score[c] <= -1) continue;
    const int i = static_cast<int>(c % g.n[0]), j = static_cast<int>((c / g.n[0]) % g.n[1]), k = static_cast<int>(c / (static_cast<long>(g.n[0]) * g.n[1]));
    bool peak = true;
    for (int dz = -1; dz <= 1 && peak; ++dz)
      for (int dy = -1; dy <= 1 && peak; ++dy)
        for (int dx = -1; dx <= 1 && peak; ++dx) {
          const int x = i + dx, y = j + dy, z = k + dz;
          if ((dx || dy || dz) && x >= 0 && y >= 0 && z >= 0 && x < g.n[0] && y < g.n[1] && z < g.n[2] && score[g.linear(x, y, z)] > score[c])
            peak = false;
        }
    if (!peak) continue;
    Candidate cand;
    cand.score = score[c];
    cand.pose = rot;
    cand.pose.t = grid_point(g, i, j, k);
    out->push_back(cand);
  }
}

// Cells of a coarse field within `reach` cells of bone (fraction above
// kNearBoneFraction): the mandible's centroid lies within ~25 mm of its bone,
// so the coarse search skips the air around the head and the far body.
constexpr float kNearBoneFraction = 0.02f;

std::vector<std::uint8_t> near_bone(const Field& f, int reach) {
  const Grid& g = f.grid;
  std::vector<std::uint8_t> bone(g.count()), out(g.count(), 0);
  for (std::size_t i = 0; i < g.count(); ++i) bone[i] = f.v[i] > kNearBoneFraction;
  for (int k = 0; k < g.n[2]; ++k)
    for (int j = 0; j < g.n[1]; ++j)
      for (int i = 0; i < g.n[0]; ++i) {
        if (!bone[g.linear(i, j, k)]) continue;
        for (int z = std::max(0, k - reach); z <= std::min(g.n[2] - 1, k + reach); ++z)
          for (int y = std::max(0, j - reach); y <= std::min(g.n[1] - 1, j + reach); ++y)
            for (int x = std::max(0, i - reach); x <= std::min(g.n[0] - 1, i + reach); ++x) out[g.linear(x, y, z)] = 1;
      }
  return out;
}

// The best `keep` candidates at least min_dist apart.
std::vector<Candidate> best_distinct(std::vector<Candidate> c, std::size_t keep, double min_dist) {
  std::sort(c.begin(), c.end(), [](const Candidate& a, const Candidate& b) { return a.score > b.score; });
  std::vector<Candidate> out;
  for (const Candidate& x : c) {
    bool near = false;
    for (const Candidate& y : out) {
      near = near || (distance(x.pose.t, y.pose.t) < min_dist && x.pose.flip == y.pose.flip);
    }
    if (!near) out.push_back(x);
    if (out.size() == keep) break;
  }
  return out;
}

// Pattern search over (t, pitch, yaw, roll, log scale) at one template resolution.
Pose pattern_search(const Points& pts, const Field& f, Pose p, double t_step, double t_min, double* best) {
  const double lim_scale[2] = {0.65, 1.5};
  *best = ncc(pts, p, f);
  double step = t_step;
  while (step >= t_min) {
    const double ang = step * 1.0 * kDeg, ls = step * 0.01;  // 6 mm <-> 6 degrees <-> 6 % scale
    bool improved = false;
    Pose winner = p;
    double wscore = *best;
    for (int param = 0; param < 7; ++param)
      for (int sign = -1; sign <= 1; sign += 2) {
        Pose q = p;
        switch (param) {
          case 0: case 1: case 2: q.t[param] += sign * step; break;
          case 3: q.pitch += sign * ang; break;
          case 4: q.yaw += sign * ang; break;
          case 5: q.roll += sign * ang; break;
          default: q.scale *= std::exp(sign * ls); break;
        }
        if (q.scale < lim_scale[0] || q.scale > lim_scale[1]) continue;
        const double s = ncc(pts, q, f);
        if (s > wscore + 1e-6) wscore = s, winner = q, improved = true;
      }
    if (improved) p = winner, *best = wscore;
    else step *= 0.5;
  }
  return p;
}

}  // namespace

float Field::at(const Vec3& p) const {
  const double q[3] = {(p[0] - grid.origin[0]) / grid.spacing, (p[1] - grid.origin[1]) / grid.spacing, (p[2] - grid.origin[2]) / grid.spacing};
  int i0[3];
  double w[3];
  bool interior = true;  // all 8 corners inside the grid
  for (int a = 0; a < 3; ++a) {
    if (!(q[a] >= 0) || q[a] > grid.n[a] - 1) return kNaN;
    i0[a] = std::min(static_cast<int>(q[a]), std::max(0, grid.n[a] - 2));
    w[a] = grid.n[a] > 1 ? q[a] - i0[a] : 0.0;
    interior = interior && i0[a] + 1 < grid.n[a];
  }
  if (interior) {  // the common case, without per-corner clamps; NaN corners below
    const std::size_t sx = 1, sy = static_cast<std::size_t>(grid.n[0]), sz = sy * static_cast<std::size_t>(grid.n[1]);
    const float* c = v.data() + grid.linear(i0[0], i0[1], i0[2]);
    const float c000 = c[0], c100 = c[sx], c010 = c[sy], c110 = c[sx + sy], c001 = c[sz], c101 = c[sx + sz], c011 = c[sy + sz],
                c111 = c[sx + sy + sz];
    if (!std::isnan(c000 + c100 + c010 + c110 + c001 + c101 + c011 + c111)) {
      // The same sum, in the same order, as the general case below.
      const double u[2] = {1 - w[0], w[0]}, vy[2] = {1 - w[1], w[1]}, vz[2] = {1 - w[2], w[2]};
      const float x[8] = {c000, c100, c010, c110, c001, c101, c011, c111};
      double acc = 0;
      for (int k = 0; k < 8; ++k) acc += u[k & 1] * vy[(k >> 1) & 1] * vz[(k >> 2) & 1] * x[k];
      return static_cast<float>(acc);
    }
  }
  // Corners of zero weight do not count (an unknown voxel there is no neighbour).
  double acc = 0;
  for (int c = 0; c < 8; ++c) {
    const int dx = c & 1, dy = (c >> 1) & 1, dz = (c >> 2) & 1;
    const double wt = (dx ? w[0] : 1 - w[0]) * (dy ? w[1] : 1 - w[1]) * (dz ? w[2] : 1 - w[2]);
    if (wt == 0) continue;
    const float x = v[grid.linear(std::min(i0[0] + dx, grid.n[0] - 1), std::min(i0[1] + dy, grid.n[1] - 1), std::min(i0[2] + dz, grid.n[2] - 1))];
    if (std::isnan(x)) return kNaN;
    acc += wt * x;
  }
  return static_cast<float>(acc);
}

Vec3 Pose::apply(const Vec3& a) const { return affine(*this)(a); }

Vec3 Pose::superior() const {
  const Affine A = affine(*this);
  return normalized(Vec3{A.A[2], A.A[5], A.A[8]});
}

Vec3 Pose::lateral() const {
  const Affine A = affine(*this);
  return normalized(Vec3{A.A[0], A.A[3], A.A[6]});
}

Plane Pose::midsagittal() const { return Plane{t, lateral()}; }

Vec3 Pose::inverse(const Vec3& p) const {
  // A = scale R M has orthogonal columns of length scale: A^-1 = A^T / scale^2.
  const Affine A = affine(*this);
  const Vec3 d = p - t;
  Vec3 a{0, 0, 0};
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) a[c] += A.A[3 * r + c] * d[r];
  return (1.0 / (scale * scale)) * a;
}

// Pieces (8-connected) of one level k of the atlas's mean mandible (p >= 0.5)
// on the x > 0 half.
static std::size_t pieces_at_level(const Atlas& a, int k) {
  const Grid& g = a.grid;
  std::vector<std::uint8_t> in(static_cast<std::size_t>(g.n[0]) * g.n[1], 0);
  for (int j = 0; j < g.n[1]; ++j)
    for (int i = 0; i < g.n[0]; ++i)
      in[i + std::size_t(g.n[0]) * j] = g.origin[0] + g.spacing * i > 0 && a.mandible[g.linear(i, j, k)] >= 0.5f;
  std::vector<std::uint32_t> label(in.size());
  return label_components(in.data(), {std::size_t(g.n[0]), std::size_t(g.n[1]), 1}, /*fully_connected=*/true, 0, label.data()).count;
}

double sigmoid_notch_height(const Atlas& a) {
  int k = a.grid.n[2] - 1;
  while (k >= 0 && pieces_at_level(a, k) == 0) --k;  // above the mandible
  while (k >= 0 && pieces_at_level(a, k) == 1) --k;  // the condyle alone
  if (k < 0) return std::numeric_limits<double>::quiet_NaN();
  while (k > 0 && pieces_at_level(a, k - 1) >= 2) --k;  // both processes
  return a.grid.origin[2] + a.grid.spacing * k;
}

ProcessTops process_tops(const Atlas& a) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  ProcessTops out{{nan, nan, nan}, {nan, nan, nan}};
  const double notch = sigmoid_notch_height(a);
  if (std::isnan(notch)) return out;
  // 1. The mean mandible's x > 0 half above the notch, and its pieces.
  const Grid& g = a.grid;
  std::vector<std::uint8_t> in(g.count(), 0);
  for (int k = 0; k < g.n[2]; ++k)
    for (int j = 0; j < g.n[1]; ++j)
      for (int i = 0; i < g.n[0]; ++i)
        in[g.linear(i, j, k)] = g.origin[0] + g.spacing * i > 0 && g.origin[2] + g.spacing * k >= notch - 1e-9 &&
                                a.mandible[g.linear(i, j, k)] >= 0.5f;
  std::vector<std::uint32_t> label(in.size());
  const Components pieces = label_components(in.data(), {std::size_t(g.n[0]), std::size_t(g.n[1]), std::size_t(g.n[2])},
                                             /*fully_connected=*/true, 0, label.data());
  if (pieces.count < 2) return out;
  // 2. Each of the two largest pieces' top: the centroid of its highest level.
  Vec3 top[2];
  for (std::uint32_t l = 1; l <= 2; ++l) {
    int highest = -1;
    for (std::size_t v = 0; v < label.size(); ++v)
      if (label[v] == l) highest = std::max(highest, static_cast<int>(v / (std::size_t(g.n[0]) * g.n[1])));
    Vec3 sum{0, 0, 0};
    double n = 0;
    for (int j = 0; j < g.n[1]; ++j)
      for (int i = 0; i < g.n[0]; ++i)
        if (label[g.linear(i, j, highest)] == l) sum = sum + Vec3{g.origin[0] + g.spacing * i, g.origin[1] + g.spacing * j, 0.0}, n += 1;
    top[l - 1] = {sum[0] / n, sum[1] / n, g.origin[2] + g.spacing * highest};
  }
  // 3. The posterior one (+y) is the condyle.
  const bool first_behind = top[0][1] > top[1][1];
  out.condyle = first_behind ? top[0] : top[1];
  out.coronoid = first_behind ? top[1] : top[0];
  return out;
}

Vec3 ScanMirror::apply(const Vec3& p) const {
  return {m[0] * p[0] + m[1] * p[1] + m[2] * p[2] + b[0], m[3] * p[0] + m[4] * p[1] + m[5] * p[2] + b[1],
          m[6] * p[0] + m[7] * p[1] + m[8] * p[2] + b[2]};
}

ScanMirror lr_mirror(const Geometry& g) {
  ScanMirror s;
  // The array axis whose direction has the largest L-R (x) component.
  for (int a = 1; a < 3; ++a)
    if (std::abs(g.direction[a]) > std::abs(g.direction[s.axis])) s.axis = a;
  auto flipped = [&](const Vec3& p) {
    Vec3 q = g.lps_to_index(p);
    q[s.axis] = static_cast<double>(g.size[s.axis]) - 1 - q[s.axis];
    return g.index_to_lps(q[0], q[1], q[2]);
  };
  s.b = flipped({0, 0, 0});
  for (int c = 0; c < 3; ++c) {
    Vec3 e{0, 0, 0};
    e[c] = 1;
    const Vec3 col = flipped(e) - s.b;
    for (int r = 0; r < 3; ++r) s.m[3 * r + c] = col[r];
  }
  return s;
}

// The pose p carried by the linear map m (row-major) of the scan's space,
// its centre moved to t: A' = m A X, with X = diag(-1, 1, 1) (the atlas
// frame's own mirror) when m is a reflection, so that A' = scale R' M with R'
// a rotation and M (p's flips) unchanged.
static Pose carried(const Pose& p, const double m[9], const Vec3& t, bool reflection) {
  const Affine A = affine(p);
  double R[9];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) {
      double acc = 0;
      for (int k = 0; k < 3; ++k) acc += m[3 * r + k] * A.A[3 * k + c];
      const double M = c == 0 ? (reflection ? -1.0 : 1.0) : (c == 1 ? ((p.flip & 1) ? -1.0 : 1.0) : ((p.flip & 2) ? -1.0 : 1.0));
      R[3 * r + c] = acc * M / p.scale;
    }
  Pose q = p;
  q.t = t;
  set_angles(q, R);
  return q;
}

Pose mirror(const Pose& p, const ScanMirror& s) { return carried(p, s.m, s.apply(p.t), true); }

Field bone_fraction(const Volume& ct, double spacing_mm, double bone_hu, double blur_mm) {
  Field f = fraction_field(ct, ct.geom, spacing_mm, bone_hu, nullptr);
  blur(f, blur_mm);
  return f;
}

Field mask_fraction(const Mask& m, double spacing_mm, double blur_mm) {
  Volume v;
  v.geom = m.geom;
  v.hu.resize(m.data.size());
  for (std::size_t i = 0; i < m.data.size(); ++i) v.hu[i] = m.data[i] ? 1.0f : 0.0f;
  return bone_fraction(v, spacing_mm, 0.5, blur_mm);
}

Pose refine(const Grid& grid, const std::vector<float>& values, const Field& field, Pose start, double* ncc_out) {
  const Points coarse = points_of(grid, values, 2);
  double s = 0;
  Pose p = pattern_search(coarse, field, start, 2 * grid.spacing, 0.5 * grid.spacing, &s);
  const Points fine = points_of(grid, values, 1);
  p = pattern_search(fine, field, p, 0.5 * grid.spacing, 0.25 * grid.spacing, &s);
  if (ncc_out) *ncc_out = s;
  return p;
}

Fit fit(const Atlas& atlas, const Field& scan) {
  Fit out;
  if (atlas.cases == 0 || scan.v.empty()) return out;
  // 1. Coarse search: translations on a 4x coarser grid (12 mm), the atlas
  //    upright pitched by 0 and +-25 degrees (head flexion), and mirrored.
  const Field f4 = downsample(scan, 4);
  const Points p4 = points_of(atlas.grid, atlas.context, 4);
  const std::vector<std::uint8_t> near = near_bone(f4, 2);
  DebugLap lap("MANDISYM_DEBUG_ATLAS", "atlas");
  std::vector<Candidate> upright, mirrored;
  for (int flip = 0; flip < 4; ++flip)
    for (double pitch : {-25.0, 0.0, 25.0}) {
      if (flip && pitch != 0.0) continue;  // mirrored: the orientation check needs no flexion
      Pose r;
      r.flip = flip;
      r.pitch = pitch * kDeg;
      coarse_search(p4, r, f4, near, flip ? &mirrored : &upright);
    }
  lap("coarse search");
  // 2. Pattern search from the best distinct candidates: first on 12 mm
  //    template points, then the best upright and mirrored on 6 mm points.
  const Points p2 = points_of(atlas.grid, atlas.context, 2);
  auto best_of = [&](std::vector<Candidate>& cands, std::size_t keep, double* score) {
    Pose best;
    *score = -2;
    for (const Candidate& c : best_distinct(cands, keep, 30.0)) {
      double s = 0;
      const Pose q = pattern_search(p4, scan, c.pose, 8.0, 3.0, &s);
      if (s > *score) *score = s, best = q;
    }
    if (*score > -1) best = pattern_search(p2, scan, best, 3.0, 0.75, score);
    return best;
  };
  double su = -2, sm = -2;
  out.pose = best_of(upright, 6, &su);
  out.mirrored = best_of(mirrored, 3, &sm);
  out.ncc = su;
  out.mirrored_ncc = sm;
  if (su > -1) ncc(p2, out.pose, scan, &out.coverage);
  out.found = su >= kMinFitNcc;
  return out;
}

namespace {

// Midpoint of two upright poses: mean translation, geometric-mean scale and
// the rotation halfway along the geodesic between the two.
Pose midpoint(const Pose& a, const Pose& b) {
  Pose m = a;
  for (int d = 0; d < 3; ++d) m.t[d] = 0.5 * (a.t[d] + b.t[d]);
  m.scale = std::sqrt(a.scale * b.scale);
  const Eigen::Quaterniond q = quaternion(a).slerp(0.5, quaternion(b));
  const Eigen::Matrix3d R = q.toRotationMatrix();
  double r[9];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r[3 * i + j] = R(i, j);
  set_angles(m, r);
  return m;
}

bool agree(const Pose& a, const Pose& b) {
  return a.flip == b.flip && distance(a.t, b.t) < kPoseAgreementMm &&
         quaternion(a).angularDistance(quaternion(b)) < kPoseAgreementDeg * kDeg;
}

}  // namespace

Fit combine_mirror_fits(const Fit& a, const Fit& b_mirrored, const ScanMirror& s) {
  Fit b = b_mirrored;
  b.pose = mirror(b_mirrored.pose, s);
  b.mirrored = mirror(b_mirrored.mirrored, s);
  Fit out = a.ncc >= b.ncc ? a : b;
  if (a.ncc > -1 && b.ncc > -1 && agree(a.pose, b.pose)) {
    out.pose = midpoint(a.pose, b.pose);
    out.ncc = 0.5 * (a.ncc + b.ncc);
    out.coverage = 0.5 * (a.coverage + b.coverage);
  }
  // The orientation check's best flipped pose: the better of the two.
  const Fit& m = a.mirrored_ncc >= b.mirrored_ncc ? a : b;
  out.mirrored = m.mirrored;
  out.mirrored_ncc = m.mirrored_ncc;
  out.found = out.ncc >= kMinFitNcc;
  return out;
}

ScanFrame scan_frame(const Geometry& g) {
  ScanFrame f;
  f.geom = g;
  f.centre = g.index_to_lps(0.5 * (static_cast<double>(g.size[0]) - 1), 0.5 * (static_cast<double>(g.size[1]) - 1),
                            0.5 * (static_cast<double>(g.size[2]) - 1));
  // P: each array axis along the LPS axis it is nearest to, with its sign.
  double P[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
  bool used[3] = {false, false, false};
  for (int c = 0; c < 3; ++c) {
    int r = 0;
    for (int k = 1; k < 3; ++k)
      if (std::abs(g.direction[3 * k + c]) > std::abs(g.direction[3 * r + c])) r = k;
    if (used[r]) return f;  // no distinct nearest axes (a turn near 45 degrees): the LPS frame
    used[r] = true;
    P[3 * r + c] = g.direction[3 * r + c] < 0 ? -1.0 : 1.0;
  }
  // q = D P^T turns the frame onto the scan: world = q (x - centre) + centre.
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k) {
      double acc = 0;
      for (int c = 0; c < 3; ++c) acc += g.direction[3 * r + c] * P[3 * k + c];
      f.q[3 * r + k] = acc;
    }
  bool turned = false;
  for (int i = 0; i < 9; ++i) turned = turned || f.q[i] != (i % 4 == 0 ? 1.0 : 0.0);
  if (!turned) return f;  // stored along the axes: the scan's geometry as it is
  for (int i = 0; i < 9; ++i) f.geom.direction[i] = P[i];
  f.geom.origin = f.from_world(g.origin);
  return f;
}

Vec3 ScanFrame::to_world(const Vec3& x) const {
  const Vec3 d = x - centre;
  return {q[0] * d[0] + q[1] * d[1] + q[2] * d[2] + centre[0], q[3] * d[0] + q[4] * d[1] + q[5] * d[2] + centre[1],
          q[6] * d[0] + q[7] * d[1] + q[8] * d[2] + centre[2]};
}

Vec3 ScanFrame::from_world(const Vec3& p) const {
  const Vec3 d = p - centre;
  return {q[0] * d[0] + q[3] * d[1] + q[6] * d[2] + centre[0], q[1] * d[0] + q[4] * d[1] + q[7] * d[2] + centre[1],
          q[2] * d[0] + q[5] * d[1] + q[8] * d[2] + centre[2]};
}

Pose ScanFrame::to_world(const Pose& p) const { return carried(p, q, to_world(p.t), false); }

Fit fit_ct(const Volume& ct, double bone_hu) {
  const Atlas& a = shipped();
  if (a.cases == 0) return {};
  const auto t0 = std::chrono::steady_clock::now();
  DebugLap lap("MANDISYM_DEBUG_ATLAS", "atlas");
  // Fitted in the scan's own frame: the same voxels turned in their file
  // about their centre give the same fit, turned (docs/atlas.md, "The scan's
  // frame").
  const ScanFrame frame = scan_frame(ct.geom);
  // The scan and its mirror fitted side by side (the search is mostly serial).
  const ScanMirror s = lr_mirror(frame.geom);
  // Each fit gets half of the OpenMP threads (two teams of all of them
  // oversubscribe the cores: 0.70 s against 0.45 s at 512^2 x 300 on 2 cores).
  const int threads = std::max(1, omp_get_max_threads() / 2);
  auto fit_field = [&](const ScanMirror* flip) {
    const int before = omp_get_max_threads();
    omp_set_num_threads(threads);
    Field f = fraction_field(ct, frame.geom, a.grid.spacing, bone_hu, flip);
    blur(f, kFieldBlurMm);
    Fit out = fit(a, f);
    omp_set_num_threads(before);
    return out;
  };
  std::future<Fit> of_mirror = std::async(threads::side_task_launch(), fit_field, &s);
  const Fit direct = fit_field(nullptr);
  Fit r = combine_mirror_fits(direct, of_mirror.get(), s);
  r.pose = frame.to_world(r.pose);
  r.mirrored = frame.to_world(r.mirrored);
  lap("bone fraction and fit, scan and mirror");
  if (lap.on())
    std::fprintf(stderr, "  atlas: ncc %.3f (mirrored %.3f), coverage %.2f, scale %.2f, centre %.1f %.1f %.1f\n", r.ncc, r.mirrored_ncc,
                 r.coverage, r.pose.scale, r.pose.t[0], r.pose.t[1], r.pose.t[2]);
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

MandiblePrior::MandiblePrior(const Atlas& atlas, const Pose& pose) {
  p_.grid = atlas.grid;
  p_.v = atlas.mandible;
  // a = A^-1 (p - t) with A = scale R M: A^-1 = M R^T / scale.
  const Affine A = affine(pose);
  const double s2 = pose.scale * pose.scale;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) inv_[3 * r + c] = A.A[3 * c + r] / s2;
  t_ = pose.t;
  double sum = 0;
  for (float v : atlas.mandible) sum += v;
  mass_mm3_ = sum * std::pow(atlas.grid.spacing * pose.scale, 3);
}

double MandiblePrior::at(const Vec3& lps) const {
  const Vec3 d = lps - t_;
  const Vec3 a{inv_[0] * d[0] + inv_[1] * d[1] + inv_[2] * d[2], inv_[3] * d[0] + inv_[4] * d[1] + inv_[5] * d[2],
               inv_[6] * d[0] + inv_[7] * d[1] + inv_[8] * d[2]};
  const float v = p_.at(a);
  return std::isnan(v) ? 0.0 : v;
}

// Serialised layout, before compression: "MSATLAS1", int32 n[3], float64
// spacing, float64 origin[3], int32 cases, uint32 source length, source
// bytes, uint8 context[N], uint8 mandible[N] (value * 255, rounded).
std::vector<std::uint8_t> serialise(const Atlas& a) {
  std::vector<std::uint8_t> raw;
  auto put = [&](const void* p, std::size_t n) {
    const auto* b = static_cast<const std::uint8_t*>(p);
    raw.insert(raw.end(), b, b + n);
  };
  put("MSATLAS1", 8);
  const std::int32_t n[3] = {a.grid.n[0], a.grid.n[1], a.grid.n[2]};
  put(n, sizeof n);
  put(&a.grid.spacing, 8);
  put(a.grid.origin.data(), 24);
  const std::int32_t cases = a.cases;
  put(&cases, 4);
  const std::uint32_t len = static_cast<std::uint32_t>(a.source.size());
  put(&len, 4);
  put(a.source.data(), a.source.size());
  for (const auto* v : {&a.context, &a.mandible})
    for (float x : *v) raw.push_back(static_cast<std::uint8_t>(std::lround(std::clamp(x, 0.0f, 1.0f) * 255.0f)));
  uLongf csize = compressBound(raw.size());
  std::vector<std::uint8_t> out(8 + csize);
  const std::uint64_t rsize = raw.size();
  std::memcpy(out.data(), &rsize, 8);
  if (compress2(out.data() + 8, &csize, raw.data(), raw.size(), 9) != Z_OK) throw std::runtime_error("atlas: compression failed");
  out.resize(8 + csize);
  return out;
}

Atlas deserialise(const std::uint8_t* data, std::size_t size) {
  auto bad = [] { return Error(ExitCode::Internal, "mandible atlas: corrupt data"); };
  if (size < 8) throw bad();
  std::uint64_t rsize = 0;
  std::memcpy(&rsize, data, 8);
  if (rsize > (std::uint64_t(1) << 30)) throw bad();
  std::vector<std::uint8_t> raw(rsize);
  uLongf got = rsize;
  if (uncompress(raw.data(), &got, data + 8, size - 8) != Z_OK || got != rsize) throw bad();
  std::size_t at = 0;
  auto take = [&](void* p, std::size_t n) {
    if (at + n > raw.size()) throw bad();
    std::memcpy(p, raw.data() + at, n);
    at += n;
  };
  char magic[8];
  take(magic, 8);
  if (std::memcmp(magic, "MSATLAS1", 8) != 0) throw bad();
  Atlas a;
  std::int32_t n[3], cases;
  take(n, sizeof n);
  take(&a.grid.spacing, 8);
  take(a.grid.origin.data(), 24);
  take(&cases, 4);
  std::uint32_t len = 0;
  take(&len, 4);
  if (len > 4096) throw bad();
  a.source.resize(len);
  take(a.source.data(), len);
  for (int k = 0; k < 3; ++k) {
    if (n[k] < 2 || n[k] > 1024) throw bad();
    a.grid.n[k] = n[k];
  }
  a.cases = cases;
  const std::size_t N = a.grid.count();
  if (at + 2 * N != raw.size()) throw bad();
  a.context.resize(N);
  a.mandible.resize(N);
  for (std::size_t i = 0; i < N; ++i) a.context[i] = raw[at + i] / 255.0f;
  for (std::size_t i = 0; i < N; ++i) a.mandible[i] = raw[at + N + i] / 255.0f;
  return a;
}

const Atlas& shipped() {
  static const Atlas a = kMandibleAtlasSize ? deserialise(kMandibleAtlasData, kMandibleAtlasSize) : Atlas{};
  return a;
}

}  // namespace ms::atlas
