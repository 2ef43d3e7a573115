#include "core/distance_transform.h"

#include <algorithm>
#include <cmath>
#include <cstring>

namespace ms {
namespace {

// Longest window (voxels each way) of the windowed minimum below.
constexpr long kWindowMax = 12;

// Per-thread scratch of edt_line: the lower envelope's parabolas (apex
// position, value at the apex, apex value + position^2) and their cuts.
struct Envelope {
  std::vector<float> x, f, g, z;
  void reserve(std::size_t n) {
    x.resize(n);
    f.resize(n);
    g.resize(n);
    z.resize(n + 1);
  }
};

// One line of the squared EDT (lower envelope of parabolas, Felzenszwalb &
// Huttenlocher): d[i] = min_q ((i - q) s)^2 + f[q] over the q with
// f[q] <= max_sq (the others cannot bring any d[i] to max_sq or below).
void edt_line(const float* f, float* d, int n, float s, float max_sq, Envelope& e) {
  e.reserve(static_cast<std::size_t>(n));
  float* vx = e.x.data();
  float* vf = e.f.data();
  float* vg = e.g.data();
  float* z = e.z.data();
  int k = -1;
  for (int q = 0; q < n; ++q) {
    const float fq = f[q];
    if (!(fq < kNoFeature && fq <= max_sq)) continue;
    const float xq = static_cast<float>(q) * s;
    const float gq = fq + xq * xq;
    while (k >= 0) {
      const float cut = (gq - vg[k]) / (2 * (xq - vx[k]));
      if (cut > z[k]) {
        ++k;
        vx[k] = xq, vf[k] = fq, vg[k] = gq;
        z[k] = cut;
        z[k + 1] = kNoFeature;
        break;
      }
      --k;
    }
    if (k < 0) {
      k = 0;
      vx[0] = xq, vf[0] = fq, vg[0] = gq;
      z[0] = -kNoFeature;
      z[1] = kNoFeature;
    }
  }
  if (k < 0) {  // no feature on this line
    std::fill(d, d + n, kNoFeature);
    return;
  }
  int j = 0;
  for (int q = 0; q < n; ++q) {
    const float x = static_cast<float>(q) * s;
    while (z[j + 1] < x) ++j;
    const float dx = x - vx[j];
    d[q] = dx * dx + vf[j];
  }
}

// The first axis of a 0/1 feature grid: squared distance along the line to
// the nearest feature (kNoFeature without one). One pass from feature to
// feature: each gap takes the nearer of its two ends (the same float
// arithmetic as a sweep each way, so the same values), and a line without
// features is filled at once.
void binary_line(const std::uint8_t* f, float* d, long n, float s) {
  const std::uint8_t* first = std::find_if(f, f + n, [](std::uint8_t v) { return v != 0; });
  if (first == f + n) {
    std::fill(d, d + n, kNoFeature);
    return;
  }
  long prev = -1;  // the last feature before the gap (-1: none)
  for (long q = first - f;; ++q) {
    while (q < n && !f[q]) ++q;
    // The gap prev + 1 .. q - 1; q == n: no feature after it.
    const float xp = static_cast<float>(prev) * s, xq = static_cast<float>(q) * s;
    if (prev < 0) {
      for (long i = 0; i < q; ++i) {
        const float dx = xq - static_cast<float>(i) * s;
        d[i] = dx * dx;
      }
    } else if (q == n) {
      for (long i = prev + 1; i < n; ++i) {
        const float dx = static_cast<float>(i) * s - xp;
        d[i] = dx * dx;
      }
    } else {
      for (long i = prev + 1; i < q; ++i) {
        const float x = static_cast<float>(i) * s, a = x - xp, b = xq - x;
        d[i] = std::min(a * a, b * b);
      }
    }
    if (q == n) return;
    d[q] = 0.0f;
    prev = q;
  }
}

// Lines processed side by side along y and z (one 64-byte cache line of floats).
constexpr long kBlock = 16;
using F4 = float __attribute__((vector_size(16)));

// Ball semi-axes in voxels (ITK: the kernel box 2r + 1 wide, its inscribed
// ellipsoid): as a spacing, the ball becomes the unit ball.
std::array<double, 3> ball_spacing(const std::array<int, 3>& radius) {
  return {1.0 / (radius[0] + 0.5), 1.0 / (radius[1] + 0.5), 1.0 / (radius[2] + 0.5)};
}

}  // namespace

std::vector<float> squared_distance_transform(const std::uint8_t* feature, const Dims3& dims,
                                              const std::array<double, 3>& spacing, float max_sq) {
  const std::size_t n = dims[0] * dims[1] * dims[2];
  std::vector<float> d(n);
  const long nx = static_cast<long>(dims[0]), ny = static_cast<long>(dims[1]), nz = static_cast<long>(dims[2]);
  // Along x: lines are contiguous, and the features 0/1.
  {
    const float s = static_cast<float>(spacing[0]);
#pragma omp parallel for schedule(static)
    for (long l = 0; l < ny * nz; ++l) binary_line(feature + l * nx, d.data() + l * nx, nx, s);
  }
  // Along y and z: kBlock neighbouring x-lines at a time, so that every
  // gathered cache line is used whole.
  for (int a = 1; a < 3; ++a) {
    const long len = a == 1 ? ny : nz, other = a == 1 ? nz : ny;
    const long stride = a == 1 ? nx : nx * ny, other_stride = a == 1 ? nx * ny : nx;
    const long xblocks = (nx + kBlock - 1) / kBlock;
    const float s = static_cast<float>(spacing[a]);
    // A truncated transform (morphology of a small ball) needs only the
    // features within `reach` voxels along this axis: a windowed minimum of
    // the same terms, the kBlock lines side by side (it vectorises), instead
    // of the envelope (one division per feature). One voxel more than the
    // radius: a longer window costs time, never exactness.
    const long reach = max_sq < kNoFeature ? static_cast<long>(std::sqrt(max_sq) / s) + 1 : kWindowMax + 1;
    const bool windowed = reach <= kWindowMax;
#pragma omp parallel
    {
      std::vector<float> tile(static_cast<std::size_t>(len * kBlock)), out(static_cast<std::size_t>(windowed ? len * kBlock : len));
      Envelope env;
#pragma omp for schedule(static)
      for (long t = 0; t < xblocks * other; ++t) {
        const long x0 = (t % xblocks) * kBlock, w = std::min(kBlock, nx - x0);
        float* base = d.data() + x0 + (t / xblocks) * other_stride;
        if (windowed) {
          if (w < kBlock) std::fill(tile.begin(), tile.end(), kNoFeature);
          for (long i = 0; i < len; ++i) std::copy_n(base + i * stride, w, tile.data() + i * kBlock);  // row i = position i
          for (long i = 0; i < len; ++i) {
            // The kBlock lanes as four 4-float vectors (GCC / Clang vector
            // extension): the compiler left this scalar (minss), one lane at a time.
            F4 acc[kBlock / 4];
            std::memcpy(acc, tile.data() + i * kBlock, sizeof acc);
            const float x = static_cast<float>(i) * s;
            for (long q = std::max(0L, i - reach); q <= std::min(len - 1, i + reach); ++q) {  // q = i: min(acc, acc + 0)
              const float dx = x - static_cast<float>(q) * s;
              const float w2 = dx * dx;
              const F4 wv = {w2, w2, w2, w2};
              const float* r = tile.data() + q * kBlock;
              for (long m = 0; m < kBlock / 4; ++m) {
                F4 t;
                std::memcpy(&t, r + 4 * m, sizeof t);
                t += wv;
                acc[m] = t < acc[m] ? t : acc[m];  // std::min(acc, t), lane by lane
              }
            }
            std::memcpy(out.data() + i * kBlock, acc, sizeof acc);
          }
          for (long i = 0; i < len; ++i) std::copy_n(out.data() + i * kBlock, w, base + i * stride);
          continue;
        }
        for (long i = 0; i < len; ++i)  // transpose in: column c of the tile is line x0 + c
          for (long c = 0; c < w; ++c) tile[static_cast<std::size_t>(c * len + i)] = base[i * stride + c];
        for (long c = 0; c < w; ++c) {
          float* col = tile.data() + c * len;
          edt_line(col, out.data(), static_cast<int>(len), s, max_sq, env);
          std::copy(out.begin(), out.begin() + len, col);
        }
        for (long i = 0; i < len; ++i)
          for (long c = 0; c < w; ++c) base[i * stride + c] = tile[static_cast<std::size_t>(c * len + i)];
      }
    }
  }
  return d;
}

std::vector<float> depth_inside(const std::uint8_t* mask, const Dims3& dims, const std::array<double, 3>& spacing,
                                float max_depth) {
  const long nx = static_cast<long>(dims[0]), ny = static_cast<long>(dims[1]), nz = static_cast<long>(dims[2]);
  std::vector<std::uint8_t> contour(dims[0] * dims[1] * dims[2], 0);
#pragma omp parallel for schedule(static)
  for (long k = 0; k < nz; ++k)
    for (long j = 0; j < ny; ++j)
      for (long i = 0; i < nx; ++i) {
        const std::size_t c = static_cast<std::size_t>(i + nx * (j + ny * k));
        if (!mask[c]) continue;
        bool edge = false;
        for (long z = std::max(0L, k - 1); z <= std::min(nz - 1, k + 1) && !edge; ++z)
          for (long y = std::max(0L, j - 1); y <= std::min(ny - 1, j + 1) && !edge; ++y)
            for (long x = std::max(0L, i - 1); x <= std::min(nx - 1, i + 1); ++x)
              if (!mask[static_cast<std::size_t>(x + nx * (y + ny * z))]) {
                edge = true;
                break;
              }
        contour[c] = edge;
      }
  std::vector<float> d =
      squared_distance_transform(contour.data(), dims, spacing, max_depth < kNoFeature ? max_depth * max_depth : kNoFeature);
#pragma omp parallel for schedule(static)
  for (long i = 0; i < static_cast<long>(d.size()); ++i) {
    float& v = d[static_cast<std::size_t>(i)];
    v = mask[i] ? std::sqrt(v) : 0.0f;
  }
  return d;
}

void dilate_ball(std::vector<std::uint8_t>& mask, const Dims3& dims, const std::array<int, 3>& radius) {
  const std::vector<float> d = squared_distance_transform(mask.data(), dims, ball_spacing(radius), 1.0f);
  const std::size_t n = mask.size();
#pragma omp parallel for schedule(static)
  for (long i = 0; i < static_cast<long>(n); ++i) mask[static_cast<std::size_t>(i)] = d[static_cast<std::size_t>(i)] <= 1.0f;
}

void erode_ball(std::vector<std::uint8_t>& mask, const Dims3& dims, const std::array<int, 3>& radius) {
  const std::size_t n = mask.size();
  std::vector<std::uint8_t> background(n);
#pragma omp parallel for schedule(static)
  for (long i = 0; i < static_cast<long>(n); ++i) background[static_cast<std::size_t>(i)] = !mask[static_cast<std::size_t>(i)];
  const std::vector<float> d = squared_distance_transform(background.data(), dims, ball_spacing(radius), 1.0f);
#pragma omp parallel for schedule(static)
  for (long i = 0; i < static_cast<long>(n); ++i) mask[static_cast<std::size_t>(i)] = d[static_cast<std::size_t>(i)] > 1.0f;
}

void open_ball(std::vector<std::uint8_t>& mask, const Dims3& dims, const std::array<int, 3>& radius) {
  erode_ball(mask, dims, radius);
  dilate_ball(mask, dims, radius);
}

void close_ball(std::vector<std::uint8_t>& mask, const Dims3& dims, const std::array<int, 3>& radius) {
  // Padded by the radius: the dilation then never reaches the padded grid's
  // edge, so the erosion sees the same background as in an infinite grid.
  Dims3 pd;
  std::array<std::size_t, 3> pad;
  for (int a = 0; a < 3; ++a) pad[a] = static_cast<std::size_t>(radius[a]) + 1, pd[a] = dims[a] + 2 * pad[a];
  std::vector<std::uint8_t> p(pd[0] * pd[1] * pd[2], 0);
  for (std::size_t k = 0; k < dims[2]; ++k)
    for (std::size_t j = 0; j < dims[1]; ++j)
      std::copy_n(mask.data() + dims[0] * (j + dims[1] * k), dims[0],
                  p.data() + pad[0] + pd[0] * ((j + pad[1]) + pd[1] * (k + pad[2])));
  dilate_ball(p, pd, radius);
  erode_ball(p, pd, radius);
  for (std::size_t k = 0; k < dims[2]; ++k)
    for (std::size_t j = 0; j < dims[1]; ++j)
      std::copy_n(p.data() + pad[0] + pd[0] * ((j + pad[1]) + pd[1] * (k + pad[2])), dims[0],
                  mask.data() + dims[0] * (j + dims[1] * k));
}

void close_euclidean(std::vector<std::uint8_t>& mask, const Dims3& dims, const std::array<double, 3>& spacing, double r) {
  const long n = static_cast<long>(mask.size());
  const float r2 = static_cast<float>(r * r);
  const std::vector<float> to_mask = squared_distance_transform(mask.data(), dims, spacing, r2);
#pragma omp parallel for schedule(static)
  for (long i = 0; i < n; ++i) mask[static_cast<std::size_t>(i)] = !(to_mask[static_cast<std::size_t>(i)] <= r2);  // outside the dilation
  const std::vector<float> to_outside = squared_distance_transform(mask.data(), dims, spacing, r2);
#pragma omp parallel for schedule(static)
  for (long i = 0; i < n; ++i) mask[static_cast<std::size_t>(i)] = to_outside[static_cast<std::size_t>(i)] > r2;
}

}  // namespace ms
