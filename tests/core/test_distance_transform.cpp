// Distance transforms and ball morphology (core/distance_transform) against
// brute force on random blobs in anisotropic grids, including objects cut by
// the grid's faces (where the boundary conventions matter), and against ITK's
// signed Maurer distance map, which the header says they equal.
#include <gtest/gtest.h>
#include <itkImage.h>
#include <itkSignedMaurerDistanceMapImageFilter.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <random>
#include <string>

#include "core/distance_transform.h"

namespace {

using ms::Dims3;

std::size_t at(const Dims3& d, long i, long j, long k) { return static_cast<std::size_t>(i + static_cast<long>(d[0]) * (j + static_cast<long>(d[1]) * k)); }

// Smoothed noise thresholded: blobs of a few voxels, touching the faces.
std::vector<std::uint8_t> blobs(const Dims3& d, unsigned seed, float level) {
  std::mt19937 rng(seed);
  std::vector<float> f(d[0] * d[1] * d[2]);
  for (float& x : f) x = std::uniform_real_distribution<float>(0, 1)(rng);
  for (int it = 0; it < 3; ++it) {
    std::vector<float> g = f;
    for (long k = 1; k + 1 < long(d[2]); ++k)
      for (long j = 1; j + 1 < long(d[1]); ++j)
        for (long i = 1; i + 1 < long(d[0]); ++i)
          g[at(d, i, j, k)] = (f[at(d, i, j, k)] + f[at(d, i - 1, j, k)] + f[at(d, i + 1, j, k)] + f[at(d, i, j - 1, k)] +
                               f[at(d, i, j + 1, k)] + f[at(d, i, j, k - 1)] + f[at(d, i, j, k + 1)]) / 7;
    f = g;
  }
  std::vector<std::uint8_t> m(f.size());
  for (std::size_t i = 0; i < f.size(); ++i) m[i] = f[i] > level;
  return m;
}

// Applies f(i, j, k, index) to every voxel.
template <class F>
void each(const Dims3& d, F f) {
  for (long k = 0; k < long(d[2]); ++k)
    for (long j = 0; j < long(d[1]); ++j)
      for (long i = 0; i < long(d[0]); ++i) f(i, j, k, at(d, i, j, k));
}

const Dims3 kDims{19, 15, 13};
const std::array<double, 3> kSpacing{0.45, 0.6, 1.25};

// Squared distance from every voxel to the nearest voxel of m, by brute force.
std::vector<double> brute_squared_distance(const std::vector<std::uint8_t>& m) {
  std::vector<double> out(m.size());
  each(kDims, [&](long i, long j, long k, std::size_t c) {
    double best = ms::kNoFeature;
    each(kDims, [&](long x, long y, long z, std::size_t q) {
      if (!m[q]) return;
      const double dx = (x - i) * kSpacing[0], dy = (y - j) * kSpacing[1], dz = (z - k) * kSpacing[2];
      best = std::min(best, dx * dx + dy * dy + dz * dz);
    });
    out[c] = best;
  });
  return out;
}

TEST(DistanceTransform, SquaredDistanceIsExact) {
  for (unsigned seed : {1u, 2u}) {
    const auto m = blobs(kDims, seed, 0.52f);
    const auto d2 = ms::squared_distance_transform(m.data(), kDims, kSpacing);
    const auto exact = brute_squared_distance(m);
    each(kDims, [&](long i, long j, long k, std::size_t c) {
      ASSERT_NEAR(d2[c], exact[c], 1e-4 * (1 + exact[c])) << i << " " << j << " " << k;
    });
  }
  const std::vector<std::uint8_t> none(kDims[0] * kDims[1] * kDims[2], 0);
  EXPECT_EQ(ms::squared_distance_transform(none.data(), kDims, kSpacing)[7], ms::kNoFeature);
}

// With max_sq, distances up to it are exact and the others exceed it: both
// the windowed minimum (a small max_sq) and the truncated envelope (a large
// one) against brute force, and close_euclidean built on them.
TEST(DistanceTransform, TruncatedDistanceIsExactUpToItsBound) {
  const auto m = blobs(kDims, 3, 0.53f);
  const auto exact = brute_squared_distance(m);
  for (float max_sq : {0.2f, 1.0f, 2.9f, 9.0f, 60.0f}) {  // 60: reach beyond the window on every axis
    const auto d2 = ms::squared_distance_transform(m.data(), kDims, kSpacing, max_sq);
    std::size_t within = 0, beyond = 0;
    each(kDims, [&](long i, long j, long k, std::size_t c) {
      if (exact[c] <= max_sq) {
        ++within;
        ASSERT_NEAR(d2[c], exact[c], 1e-4 * (1 + exact[c])) << max_sq << ": " << i << " " << j << " " << k;
      } else {
        ++beyond;
        ASSERT_GT(d2[c], max_sq * (1 - 1e-5)) << max_sq << ": " << i << " " << j << " " << k;
      }
    });
    EXPECT_GT(within, 0u);
    if (max_sq < 2) EXPECT_GT(beyond, 0u) << max_sq;  // the blobs leave no voxel farther than ~1.7 mm
  }
  // The closing by a Euclidean ball = brute-force dilation then erosion.
  for (double r : {0.7, 1.3}) {
    auto c = m;
    ms::close_euclidean(c, kDims, kSpacing, r);
    std::vector<std::uint8_t> dil(m.size());
    for (std::size_t i = 0; i < m.size(); ++i) dil[i] = exact[i] <= r * r;
    std::vector<std::uint8_t> want(m.size());
    each(kDims, [&](long i, long j, long k, std::size_t q0) {
      bool keep = true;  // no voxel outside the dilation within r
      each(kDims, [&](long x, long y, long z, std::size_t q) {
        if (!keep || dil[q]) return;
        const double dx = (x - i) * kSpacing[0], dy = (y - j) * kSpacing[1], dz = (z - k) * kSpacing[2];
        if (dx * dx + dy * dy + dz * dz <= r * r) keep = false;
      });
      want[q0] = keep;
    });
    EXPECT_EQ(c, want) << r;
    EXPECT_NE(c, m) << r;
  }
}

// Blobs and an ellipsoid (semi-axes 7 x 6 x 5 voxels) centred at voxel
// (9, 7, zc): at zc = 10 the grid's top face cuts it.
std::vector<std::uint8_t> blobs_and_ellipsoid(double zc) {
  auto m = blobs(kDims, 3, 0.5f);
  each(kDims, [&](long i, long j, long k, std::size_t c) {
    const double x = (i - 9) / 7.0, y = (j - 7) / 6.0, z = (k - zc) / 5.0;
    if (x * x + y * y + z * z <= 1) m[c] = 1;
  });
  return m;
}

TEST(DistanceTransform, DepthInsideIsTheDistanceToTheContour) {
  const auto m = blobs_and_ellipsoid(10);  // cut by the top face
  const auto depth = ms::depth_inside(m.data(), kDims, kSpacing);
  auto contour = [&](long i, long j, long k) {
    for (long z = k - 1; z <= k + 1; ++z)
      for (long y = j - 1; y <= j + 1; ++y)
        for (long x = i - 1; x <= i + 1; ++x)
          if (x >= 0 && y >= 0 && z >= 0 && x < long(kDims[0]) && y < long(kDims[1]) && z < long(kDims[2]) && !m[at(kDims, x, y, z)])
            return true;
    return false;  // the grid's faces are not a contour
  };
  std::size_t deep = 0;
  each(kDims, [&](long i, long j, long k, std::size_t c) {
    if (!m[c]) {
      ASSERT_EQ(depth[c], 0.0f);
      return;
    }
    double best = 1e30;
    each(kDims, [&](long x, long y, long z, std::size_t q) {
      if (!m[q] || !contour(x, y, z)) return;
      const double dx = (x - i) * kSpacing[0], dy = (y - j) * kSpacing[1], dz = (z - k) * kSpacing[2];
      best = std::min(best, std::sqrt(dx * dx + dy * dy + dz * dz));
    });
    ASSERT_NEAR(depth[c], best, 1e-4) << i << " " << j << " " << k;
    deep += best > 1.0;
  });
  EXPECT_GT(deep, 50u);  // the blobs have an interior: the test measures something
}

// ITK's ball for radius r: offsets with sum (o_a / (r_a + 0.5))^2 <= 1.
bool in_ball(long dx, long dy, long dz, const std::array<int, 3>& r) {
  const double a = dx / (r[0] + 0.5), b = dy / (r[1] + 0.5), c = dz / (r[2] + 0.5);
  return a * a + b * b + c * c <= 1.0;
}

// Brute-force dilation (outside the grid is background) or erosion (outside
// the grid is foreground).
std::vector<std::uint8_t> brute(const std::vector<std::uint8_t>& m, const Dims3& d, const std::array<int, 3>& r, bool dilate) {
  std::vector<std::uint8_t> out(m.size());
  each(d, [&](long i, long j, long k, std::size_t c) {
    bool hit = false;  // dilation: a set voxel in the ball; erosion: a clear one
    for (long z = -r[2]; z <= r[2] && !hit; ++z)
      for (long y = -r[1]; y <= r[1] && !hit; ++y)
        for (long x = -r[0]; x <= r[0] && !hit; ++x) {
          if (!in_ball(x, y, z, r)) continue;
          const long X = i + x, Y = j + y, Z = k + z;
          if (X < 0 || Y < 0 || Z < 0 || X >= long(d[0]) || Y >= long(d[1]) || Z >= long(d[2])) continue;
          hit = dilate ? m[at(d, X, Y, Z)] != 0 : m[at(d, X, Y, Z)] == 0;
        }
    out[c] = dilate ? hit : !hit;
  });
  return out;
}

TEST(DistanceTransform, BallMorphologyEqualsBruteForce) {
  for (const std::array<int, 3>& r : {std::array<int, 3>{1, 1, 1}, std::array<int, 3>{2, 2, 1}, std::array<int, 3>{2, 1, 3}}) {
    const auto m = blobs(kDims, 4, 0.5f);
    auto d = m, e = m, o = m, c = m;
    ms::dilate_ball(d, kDims, r);
    ms::erode_ball(e, kDims, r);
    ms::open_ball(o, kDims, r);
    ms::close_ball(c, kDims, r);
    EXPECT_EQ(d, brute(m, kDims, r, true));
    EXPECT_EQ(e, brute(m, kDims, r, false));
    EXPECT_EQ(o, brute(brute(m, kDims, r, false), kDims, r, true));
    // Closing as if embedded in background: pad, close, crop.
    Dims3 pd;
    for (int a = 0; a < 3; ++a) pd[a] = kDims[a] + 2 * static_cast<std::size_t>(r[a]);
    std::vector<std::uint8_t> p(pd[0] * pd[1] * pd[2], 0);
    each(kDims, [&](long i, long j, long k, std::size_t q) { p[at(pd, i + r[0], j + r[1], k + r[2])] = m[q]; });
    const auto pc = brute(brute(p, pd, r, true), pd, r, false);
    std::vector<std::uint8_t> want(m.size());
    each(kDims, [&](long i, long j, long k, std::size_t q) { want[q] = pc[at(pd, i + r[0], j + r[1], k + r[2])]; });
    EXPECT_EQ(c, want);
    // The operations did something on this mask.
    EXPECT_NE(o, m);
    EXPECT_NE(c, m);
  }
}

// Truncated: exact up to max_depth, deeper than max_depth beyond it (the
// segmentation compares a cavity's depth with one threshold below its cap).
TEST(DistanceTransform, TruncatedDepthIsExactUpToItsCap) {
  const auto m = blobs_and_ellipsoid(6);
  const auto full = ms::depth_inside(m.data(), kDims, kSpacing);
  for (float cap : {0.7f, 1.3f, 2.0f}) {
    const auto cut = ms::depth_inside(m.data(), kDims, kSpacing, cap);
    std::size_t beyond = 0;
    for (std::size_t c = 0; c < full.size(); ++c) {
      if (full[c] <= cap) {
        ASSERT_NEAR(cut[c], full[c], 1e-5f) << c << " cap " << cap;  // the two paths round differently
      } else {
        ASSERT_GT(cut[c], cap) << c << " cap " << cap;
        ++beyond;
      }
    }
    EXPECT_GT(beyond, 0u) << cap;  // some voxels lie deeper than the cap: the test measures something
  }
}

}  // namespace

// ---------------------------------------------------------------- against ITK's signed Maurer map
//
// The header's contract in ITK's terms, with itk::SignedMaurerDistanceMapImageFilter
// (background 0, image spacing, inside negative) giving S, or S2 with SquaredDistance:
//   squared_distance_transform(mask) = max(S2, 0)   (0 on the object; outside, the
//                                                    nearest object voxel is a contour voxel)
//   depth_inside(mask)               = max(-S, 0)   (26-neighbour contour, grid faces no contour)
// and their truncated forms equal those wherever the value is within the bound.

namespace {

// ITK's signed Maurer map of a 0/1 mask (x-fastest, as ITK stores it).
std::vector<float> itk_maurer(const std::vector<std::uint8_t>& m, const Dims3& d, const std::array<double, 3>& spacing,
                              bool squared) {
  using In = itk::Image<unsigned char, 3>;
  using Out = itk::Image<float, 3>;
  auto image = In::New();
  In::SizeType size;
  In::SpacingType sp;
  for (unsigned a = 0; a < 3; ++a) size[a] = d[a], sp[a] = spacing[a];
  image->SetRegions(In::RegionType(size));
  image->SetSpacing(sp);
  image->Allocate();
  std::copy(m.begin(), m.end(), image->GetBufferPointer());
  auto f = itk::SignedMaurerDistanceMapImageFilter<In, Out>::New();
  f->SetInput(image);
  f->SetBackgroundValue(0);
  f->SetInsideIsPositive(false);
  f->SetUseImageSpacing(true);
  f->SetSquaredDistance(squared);
  f->Update();
  const float* p = f->GetOutput()->GetBufferPointer();
  return {p, p + m.size()};
}

// A test grid: a mask, its dimensions and spacing.
struct Grid {
  std::string name;
  Dims3 dims;
  std::array<double, 3> spacing;
  std::vector<std::uint8_t> mask;
};

Grid grid(const std::string& name, const Dims3& d, const std::array<double, 3>& spacing,
          const std::function<bool(long, long, long)>& inside) {
  Grid g{name, d, spacing, std::vector<std::uint8_t>(d[0] * d[1] * d[2])};
  each(d, [&](long i, long j, long k, std::size_t c) { g.mask[c] = inside(i, j, k); });
  return g;
}

std::vector<Grid> itk_test_grids() {
  std::vector<Grid> g;
  // Hand-built.
  g.push_back(grid("one voxel", {21, 17, 13}, {0.7, 1.0, 2.5}, [](long i, long j, long k) { return i == 10 && j == 8 && k == 6; }));
  g.push_back(grid("two corners", {16, 12, 9}, {0.4, 0.9, 1.7},
                   [](long i, long j, long k) { return (i == 0 && j == 0 && k == 0) || (i == 15 && j == 11 && k == 8); }));
  g.push_back(grid("box, isotropic", {20, 18, 14}, {1, 1, 1},
                   [](long i, long j, long k) { return i >= 5 && i < 14 && j >= 4 && j < 11 && k >= 4 && k < 9; }));
  g.push_back(grid("box, anisotropic", {20, 18, 14}, {0.5, 0.8, 3.0},
                   [](long i, long j, long k) { return i >= 3 && i < 17 && j >= 2 && j < 15 && k >= 3 && k < 11; }));
  g.push_back(grid("slab through five faces", {15, 13, 11}, {0.6, 0.75, 1.5}, [](long, long, long k) { return k >= 3; }));
  g.push_back(grid("ellipsoid cut by a face", {24, 20, 16}, {0.5, 0.6, 1.25}, [](long i, long j, long k) {
    const double x = (i - 11.5) / 10.0, y = (j - 9.5) / 8.0, z = (k - 13.0) / 6.0;
    return x * x + y * y + z * z <= 1;
  }));
  g.push_back(grid("hollow sphere", {23, 23, 23}, {0.8, 0.8, 0.8}, [](long i, long j, long k) {
    const double r2 = (i - 11.0) * (i - 11.0) + (j - 11.0) * (j - 11.0) + (k - 11.0) * (k - 11.0);
    return r2 <= 100 && r2 >= 16;
  }));
  // Random: blobs touching the faces, and sparse points far apart.
  for (unsigned seed : {1u, 2u, 3u})
    g.push_back({"blobs " + std::to_string(seed), kDims, kSpacing, blobs(kDims, seed, 0.5f + 0.01f * seed)});
  g.push_back({"large blobs", {48, 40, 30}, {0.35, 0.9, 2.0}, blobs({48, 40, 30}, 7, 0.5f)});
  std::mt19937 rng(11);
  g.push_back(grid("sparse points", {40, 33, 27}, {0.45, 1.1, 2.3},
                   [&](long, long, long) { return std::uniform_real_distribution<double>(0, 1)(rng) < 0.004; }));
  return g;
}

// Largest differences of `got` from `want` over the voxels where `use`.
struct Diff {
  double abs = 0, rel = 0;  // rel: |got - want| / max(1, |want|)
  std::size_t n = 0;
  void add(double got, double want) {
    const double e = std::abs(got - want);
    abs = std::max(abs, e);
    rel = std::max(rel, e / std::max(1.0, std::abs(want)));
    ++n;
  }
};

}  // namespace

TEST(DistanceTransform, EqualsItkSignedMaurerMap) {
  Diff squared, depth, distance;
  for (const Grid& g : itk_test_grids()) {
    SCOPED_TRACE(g.name);
    const auto s = itk_maurer(g.mask, g.dims, g.spacing, false);
    const auto s2 = itk_maurer(g.mask, g.dims, g.spacing, true);
    const auto d2 = ms::squared_distance_transform(g.mask.data(), g.dims, g.spacing);
    const auto depth_in = ms::depth_inside(g.mask.data(), g.dims, g.spacing);
    std::size_t inside = 0, deep = 0;
    each(g.dims, [&](long i, long j, long k, std::size_t c) {
      const double want_d2 = std::max(0.0f, s2[c]), want_depth = std::max(0.0f, -s[c]);
      ASSERT_LE(std::abs(d2[c] - want_d2), 1e-4 * std::max(1.0, want_d2)) << "squared distance at " << i << " " << j << " " << k;
      ASSERT_LE(std::abs(depth_in[c] - want_depth), 1e-4 * std::max(1.0, want_depth)) << "depth at " << i << " " << j << " " << k;
      // Outside, the unsigned distance is ITK's too (and the square root of the squared one).
      if (!g.mask[c]) ASSERT_LE(std::abs(std::sqrt(d2[c]) - s[c]), 1e-4 * std::max(1.0f, s[c])) << i << " " << j << " " << k;
      squared.add(d2[c], want_d2);
      depth.add(depth_in[c], want_depth);
      if (!g.mask[c]) distance.add(std::sqrt(d2[c]), s[c]);
      inside += g.mask[c] != 0;
      deep += want_depth > 0;
    });
    EXPECT_GT(inside, 0u);
    if (g.name != "one voxel" && g.name != "two corners" && g.name != "sparse points")
      EXPECT_GT(deep, 0u) << "no voxel inside the contour: the depth is not tested on this grid";
  }
  std::printf("vs ITK SignedMaurerDistanceMap: squared distance max |diff| %.3g (rel %.3g, %zu voxels); "
              "depth max |diff| %.3g (rel %.3g); distance outside max |diff| %.3g (rel %.3g)\n",
              squared.abs, squared.rel, squared.n, depth.abs, depth.rel, distance.abs, distance.rel);
}

// The truncated forms (max_sq, max_depth) equal ITK's map within their bound
// and exceed the bound beyond it (values within float rounding of the bound,
// e.g. a depth of 6 x 0.5 mm against 3 mm, may fall on either side).
TEST(DistanceTransform, TruncatedFormsEqualItkWithinTheirBound) {
  auto check = [](float got, double want, double bound, const char* what, long i, long j, long k) {
    if (want <= bound * (1 - 1e-5))
      EXPECT_LE(std::abs(got - want), 1e-4 * std::max(1.0, want)) << what << " within the bound at " << i << " " << j << " " << k;
    else if (want >= bound * (1 + 1e-5))
      EXPECT_GT(got, bound * (1 - 1e-5)) << what << " beyond the bound at " << i << " " << j << " " << k;
  };
  for (const Grid& g : itk_test_grids()) {
    SCOPED_TRACE(g.name);
    const auto s = itk_maurer(g.mask, g.dims, g.spacing, false);
    const auto s2 = itk_maurer(g.mask, g.dims, g.spacing, true);
    for (float bound : {0.5f, 1.2f, 3.0f}) {
      SCOPED_TRACE("bound " + std::to_string(bound));
      const auto d2 = ms::squared_distance_transform(g.mask.data(), g.dims, g.spacing, bound * bound);
      const auto depth_in = ms::depth_inside(g.mask.data(), g.dims, g.spacing, bound);
      each(g.dims, [&](long i, long j, long k, std::size_t c) {
        check(d2[c], std::max(0.0f, s2[c]), bound * bound, "squared distance", i, j, k);
        check(depth_in[c], std::max(0.0f, -s[c]), bound, "depth", i, j, k);
        ASSERT_FALSE(HasFailure());
      });
    }
  }
}
