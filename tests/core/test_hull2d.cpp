// core::convex_hull_2d against hulls known by construction.
#include "core/hull2d.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

namespace {

using Pts = std::vector<std::array<double, 2>>;

double signed_area(const Pts& p, const std::vector<std::size_t>& h) {
  double a = 0;
  for (std::size_t i = 0; i < h.size(); ++i) {
    const auto &u = p[h[i]], &v = p[h[(i + 1) % h.size()]];
    a += u[0] * v[1] - v[0] * u[1];
  }
  return 0.5 * a;
}

TEST(Hull2d, SquareWithInteriorEdgeAndDuplicatePointsIsItsFourCornersCounterClockwise) {
  Pts p = {{0.5, 0.5}, {1, 1}, {0, 0}, {1, 0}, {0, 1}, {0.5, 0}, {0.2, 0.7}, {1, 1}, {0, 0.3}};
  const auto h = ms::convex_hull_2d(p);
  ASSERT_EQ(h.size(), 4u);  // the edge midpoints (0.5, 0), (0, 0.3) and the duplicate corner are left out
  EXPECT_EQ(p[h[0]], (std::array<double, 2>{0, 0}));
  EXPECT_EQ(p[h[1]], (std::array<double, 2>{1, 0}));
  EXPECT_EQ(p[h[2]], (std::array<double, 2>{1, 1}));
  EXPECT_EQ(p[h[3]], (std::array<double, 2>{0, 1}));
  EXPECT_NEAR(signed_area(p, h), 1.0, 1e-12);  // positive: counter-clockwise
}

TEST(Hull2d, RandomPointsInADiscAreAllInsideAndTheHullIsConvex) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  Pts p;
  while (p.size() < 2000) {
    const double x = u(rng), y = u(rng);
    if (x * x + y * y <= 1) p.push_back({x, y});
  }
  const auto h = ms::convex_hull_2d(p);
  ASSERT_GE(h.size(), 3u);
  for (std::size_t i = 0; i < h.size(); ++i) {
    const auto &a = p[h[i]], &b = p[h[(i + 1) % h.size()]];
    for (const auto& q : p)  // every point on the left of (or on) every edge
      EXPECT_GE((b[0] - a[0]) * (q[1] - a[1]) - (b[1] - a[1]) * (q[0] - a[0]), -1e-12);
  }
  EXPECT_GT(signed_area(p, h), 0.95 * M_PI * 0.95);  // close to the disc's area
}

TEST(Hull2d, FewerThanThreeDistinctPoints) {
  EXPECT_TRUE(ms::convex_hull_2d({}).empty());
  EXPECT_EQ(ms::convex_hull_2d({{2, 3}, {2, 3}}).size(), 1u);
  EXPECT_EQ(ms::convex_hull_2d({{2, 3}, {1, 3}}).size(), 2u);
}

}  // namespace
