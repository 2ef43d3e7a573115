#include "core/distance_transform.h"

#include <algorithm>
#include <cmath>

namespace ms {
namespace {

// One line of the squared EDT (lower envelope of parabolas, Felzenszwalb &
// Huttenlocher): d[i] = min_q ((i - q) s)^2 + f[q].
void edt_line(const float* f, float* d, int n, float s, std::vector<int>& v, std::vector<float>& z) {
  v.resize(static_cast<std::size_t>(n));
  z.resize(static_cast<std::size_t>(n) + 1);
  int k = -1;
  for (int q = 0; q < n; ++q) {
    if (!(f[q] < kNoFeature)) continue;
    const float xq = static_cast<float>(q) * s;
    while (k >= 0) {
      const float xv = static_cast<float>(v[static_cast<std::size_t>(k)]) * s;
      const float cut = ((f[q] + xq * xq) - (f[v[static_cast<std::size_t>(k)]] + xv * xv)) / (2 * (xq - xv));
      if (cut > z[static_cast<std::size_t>(k)]) {
        ++k;
        v[static_cast<std::size_t>(k)] = q;
        z[static_cast<std::size_t>(k)] = cut;
        z[static_cast<std::size_t>(k) + 1] = kNoFeature;
        break;
      }
      --k;
    }
    if (k < 0) {
      k = 0;
      v[0] = q;
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
    while (z[static_cast<std::size_t>(j) + 1] < x) ++j;
    const float dx = x - static_cast<float>(v[static_cast<std::size_t>(j)]) * s;
    d[q] = dx * dx + f[v[static_cast<std::size_t>(j)]];
  }
}

// Ball semi-axes in voxels (ITK: the kernel box 2r + 1 wide, its inscribed
// ellipsoid): as a spacing, the ball becomes the unit ball.
std::array<double, 3> ball_spacing(const std::array<int, 3>& radius) {
  return {1.0 / (radius[0] + 0.5), 1.0 / (radius[1] + 0.5), 1.0 / (radius[2] + 0.5)};
}

}  // namespace

std::vector<float> squared_distance_transform(const std::uint8_t* feature, const Dims3& dims,
                                              const std::array<double, 3>& spacing) {
  const std::size_t n = dims[0] * dims[1] * dims[2];
  std::vector<float> d(n);
  for (std::size_t i = 0; i < n; ++i) d[i] = feature[i] ? 0.0f : kNoFeature;
  const long nx = static_cast<long>(dims[0]), ny = static_cast<long>(dims[1]), nz = static_cast<long>(dims[2]);
  // Along x: lines are contiguous.
  {
    const float s = static_cast<float>(spacing[0]);
#pragma omp parallel
    {
      std::vector<float> out(dims[0]), z;
      std::vector<int> v;
#pragma omp for schedule(static)
      for (long l = 0; l < ny * nz; ++l) {
        float* p = d.data() + l * nx;
        edt_line(p, out.data(), static_cast<int>(nx), s, v, z);
        std::copy(out.begin(), out.end(), p);
      }
    }
  }
  // Along y and z: kBlock neighbouring x-lines at a time, so that every
  // gathered cache line is used whole.
  constexpr long kBlock = 16;
  for (int a = 1; a < 3; ++a) {
    const long len = a == 1 ? ny : nz, other = a == 1 ? nz : ny;
    const long stride = a == 1 ? nx : nx * ny, other_stride = a == 1 ? nx * ny : nx;
    const long xblocks = (nx + kBlock - 1) / kBlock;
    const float s = static_cast<float>(spacing[a]);
#pragma omp parallel
    {
      std::vector<float> tile(static_cast<std::size_t>(len * kBlock)), out(static_cast<std::size_t>(len)), z;
      std::vector<int> v;
#pragma omp for schedule(static)
      for (long t = 0; t < xblocks * other; ++t) {
        const long x0 = (t % xblocks) * kBlock, w = std::min(kBlock, nx - x0);
        float* base = d.data() + x0 + (t / xblocks) * other_stride;
        for (long i = 0; i < len; ++i)  // transpose in: column c of the tile is line x0 + c
          for (long c = 0; c < w; ++c) tile[static_cast<std::size_t>(c * len + i)] = base[i * stride + c];
        for (long c = 0; c < w; ++c) {
          float* col = tile.data() + c * len;
          edt_line(col, out.data(), static_cast<int>(len), s, v, z);
          std::copy(out.begin(), out.end(), col);
        }
        for (long i = 0; i < len; ++i)
          for (long c = 0; c < w; ++c) base[i * stride + c] = tile[static_cast<std::size_t>(c * len + i)];
      }
    }
  }
  return d;
}

std::vector<float> depth_inside(const std::uint8_t* mask, const Dims3& dims, const std::array<double, 3>& spacing) {
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
  std::vector<float> d = squared_distance_transform(contour.data(), dims, spacing);
#pragma omp parallel for schedule(static)
  for (long i = 0; i < static_cast<long>(d.size()); ++i) {
    float& v = d[static_cast<std::size_t>(i)];
    v = mask[i] ? std::sqrt(v) : 0.0f;
  }
  return d;
}

void dilate_ball(std::vector<std::uint8_t>& mask, const Dims3& dims, const std::array<int, 3>& radius) {
  const std::vector<float> d = squared_distance_transform(mask.data(), dims, ball_spacing(radius));
  const std::size_t n = mask.size();
#pragma omp parallel for schedule(static)
  for (long i = 0; i < static_cast<long>(n); ++i) mask[static_cast<std::size_t>(i)] = d[static_cast<std::size_t>(i)] <= 1.0f;
}

void erode_ball(std::vector<std::uint8_t>& mask, const Dims3& dims, const std::array<int, 3>& radius) {
  const std::size_t n = mask.size();
  std::vector<std::uint8_t> background(n);
  for (std::size_t i = 0; i < n; ++i) background[i] = !mask[i];
  const std::vector<float> d = squared_distance_transform(background.data(), dims, ball_spacing(radius));
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
  const std::size_t n = mask.size();
  const float r2 = static_cast<float>(r * r);
  const std::vector<float> to_mask = squared_distance_transform(mask.data(), dims, spacing);
  for (std::size_t i = 0; i < n; ++i) mask[i] = !(to_mask[i] <= r2);  // outside the dilation
  const std::vector<float> to_outside = squared_distance_transform(mask.data(), dims, spacing);
  for (std::size_t i = 0; i < n; ++i) mask[i] = to_outside[i] > r2;
}

}  // namespace ms
