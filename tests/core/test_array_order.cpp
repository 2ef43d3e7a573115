// core/array_order.h: the canonical array order keeps every voxel's value at
// its world position, and two storages of one grid become the same arrays.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "core/array_order.h"

namespace {

using ms::Geometry;

// A 5 x 4 x 3 grid with the given direction columns (each +-a unit axis, or oblique).
Geometry grid(const std::array<double, 9>& dir) {
  Geometry g;
  g.size = {5, 4, 3};
  g.spacing = {0.7, 1.1, 2.5};
  g.origin = {-12.5, 40.25, 7.0};
  g.direction = dir;
  return g;
}

std::vector<float> values_of(const Geometry& g) {
  std::vector<float> v(g.voxel_count());
  std::mt19937 rng(7);
  for (auto& x : v) x = static_cast<float>(rng() % 1000);
  return v;
}

void expect_same_world_values(const Geometry& g, const std::vector<float>& v, const Geometry& n, const std::vector<float>& w) {
  ASSERT_EQ(n.voxel_count(), g.voxel_count());
  for (std::size_t k = 0; k < g.size[2]; ++k)
    for (std::size_t j = 0; j < g.size[1]; ++j)
      for (std::size_t i = 0; i < g.size[0]; ++i) {
        const ms::Vec3 p = g.index_to_lps(double(i), double(j), double(k));
        const ms::Vec3 q = n.lps_to_index(p);
        const auto r = [](double x) { return static_cast<std::size_t>(std::lround(x)); };
        for (int a = 0; a < 3; ++a) ASSERT_NEAR(q[a], std::round(q[a]), 1e-9) << "not on the new grid";
        EXPECT_EQ(w[n.linear(r(q[0]), r(q[1]), r(q[2]))], v[g.linear(i, j, k)]);
      }
}

TEST(ArrayOrder, IdentityIsLeftAlone) {
  const Geometry g = grid({1, 0, 0, 0, 1, 0, 0, 0, 1});
  EXPECT_TRUE(ms::canonical_reorder(g).identity());
}

// Calls f with the grid of every signed permutation of the axes (48 storages,
// RAS and LAS among them).
template <class F>
void for_every_signed_permutation(F f) {
  std::array<int, 3> perm{0, 1, 2};
  do {
    for (int signs = 0; signs < 8; ++signs) {
      std::array<double, 9> dir{};
      for (int c = 0; c < 3; ++c) dir[static_cast<std::size_t>(3 * perm[c] + c)] = (signs >> c & 1) ? -1.0 : 1.0;
      f(grid(dir));
    }
  } while (std::next_permutation(perm.begin(), perm.end()));
}

TEST(ArrayOrder, EverySignedPermutationKeepsValuesAtTheirPositionsAndEndsAtIdentity) {
  for_every_signed_permutation([](const Geometry& g) {
    const auto v = values_of(g);
    const ms::AxisReorder r = ms::canonical_reorder(g);
    const Geometry n = ms::reordered(g, r);
    const auto w = ms::reordered_values(v, g, r);
    expect_same_world_values(g, v, n, w);
    for (int a = 0; a < 9; ++a) EXPECT_DOUBLE_EQ(n.direction[a], a % 4 == 0 ? 1.0 : 0.0);
  });
}

// The inverse brings a canonical grid and its values back to the stored order
// exactly (outputs on the input's grid in its array order, io::in_stored_order).
TEST(ArrayOrder, InverseRestoresTheStoredOrder) {
  for_every_signed_permutation([](const Geometry& g) {
    const auto v = values_of(g);
    const ms::AxisReorder r = ms::canonical_reorder(g);
    const Geometry n = ms::reordered(g, r);
    const ms::AxisReorder back = ms::inverse(r);
    const Geometry h = ms::reordered(n, back);
    EXPECT_EQ(ms::reordered_values(ms::reordered_values(v, g, r), n, back), v);
    EXPECT_EQ(h.size, g.size);
    for (int a = 0; a < 3; ++a) {
      EXPECT_DOUBLE_EQ(h.spacing[a], g.spacing[a]);
      EXPECT_NEAR(h.origin[a], g.origin[a], 1e-9);
    }
    for (int a = 0; a < 9; ++a) EXPECT_DOUBLE_EQ(h.direction[a], g.direction[a]);
  });
}

// An oblique (gantry-tilted, rotated) grid: axes go to their nearest L/P/S.
TEST(ArrayOrder, ObliqueGridGoesToTheNearestAxes) {
  const double c = std::cos(0.3), s = std::sin(0.3);
  // old i ~ -S, old j ~ +L (rotated), old k ~ -P
  const Geometry g = grid({0, c, s, 0, s, -c, -1, 0, 0});
  const auto v = values_of(g);
  const ms::AxisReorder r = ms::canonical_reorder(g);
  EXPECT_EQ(r.from, (std::array<int, 3>{1, 2, 0}));
  const Geometry n = ms::reordered(g, r);
  expect_same_world_values(g, v, n, ms::reordered_values(v, g, r));
  for (int a = 0; a < 3; ++a) EXPECT_GT(n.direction[static_cast<std::size_t>(4 * a)], 0.9);
}

}  // namespace
