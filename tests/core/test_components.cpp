// core/components.h against a plain breadth-first flood fill on random grids:
// the same components, numbered by decreasing size (ties: first voxel in
// raster order), those under the minimum size dropped.
#include <gtest/gtest.h>

#include <algorithm>
#include <deque>
#include <random>

#include "core/components.h"

namespace {

std::vector<std::uint32_t> flood_fill_labels(const std::vector<std::uint8_t>& m, const ms::Dims3& d, bool full, std::size_t min_voxels) {
  const long nx = static_cast<long>(d[0]), ny = static_cast<long>(d[1]), nz = static_cast<long>(d[2]);
  std::vector<long> comp(m.size(), -1);
  std::vector<std::size_t> sizes;
  for (std::size_t s = 0; s < m.size(); ++s) {
    if (!m[s] || comp[s] >= 0) continue;
    const long c = static_cast<long>(sizes.size());
    sizes.push_back(0);
    std::deque<std::size_t> q{s};
    comp[s] = c;
    while (!q.empty()) {
      const std::size_t v = q.front();
      q.pop_front();
      ++sizes[static_cast<std::size_t>(c)];
      const long i = static_cast<long>(v) % nx, j = static_cast<long>(v) / nx % ny, k = static_cast<long>(v) / (nx * ny);
      for (long dk = -1; dk <= 1; ++dk)
        for (long dj = -1; dj <= 1; ++dj)
          for (long di = -1; di <= 1; ++di) {
            const long steps = (di != 0) + (dj != 0) + (dk != 0);
            if (steps == 0 || (!full && steps > 1)) continue;
            const long a = i + di, b = j + dj, e = k + dk;
            if (a < 0 || b < 0 || e < 0 || a >= nx || b >= ny || e >= nz) continue;
            const std::size_t w = static_cast<std::size_t>(a + nx * (b + ny * e));
            if (m[w] && comp[w] < 0) comp[w] = c, q.push_back(w);
          }
    }
  }
  // Components are found in the raster order of their first voxel.
  std::vector<std::size_t> order;
  for (std::size_t c = 0; c < sizes.size(); ++c)
    if (sizes[c] >= std::max<std::size_t>(min_voxels, 1)) order.push_back(c);
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return sizes[a] > sizes[b]; });
  std::vector<std::uint32_t> label_of(sizes.size(), 0);
  for (std::size_t r = 0; r < order.size(); ++r) label_of[order[r]] = static_cast<std::uint32_t>(r + 1);
  std::vector<std::uint32_t> out(m.size(), 0);
  for (std::size_t v = 0; v < m.size(); ++v)
    if (comp[v] >= 0) out[v] = label_of[static_cast<std::size_t>(comp[v])];
  return out;
}

}  // namespace

TEST(Components, MatchAFloodFillOnRandomGrids) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 24; ++trial) {
    const ms::Dims3 d{5 + rng() % 20, 4 + rng() % 15, 3 + rng() % 12};
    const double fill = 0.2 + 0.1 * (trial % 5);  // around the percolation thresholds of both connectivities
    std::bernoulli_distribution set(fill);
    std::vector<std::uint8_t> m(d[0] * d[1] * d[2]);
    for (auto& v : m) v = set(rng);
    for (bool full : {false, true})
      for (std::size_t min_voxels : {std::size_t{0}, std::size_t{3}}) {
        std::vector<std::uint32_t> got(m.size(), 99);
        const ms::Components c = ms::label_components(m.data(), d, full, min_voxels, got.data());
        const auto want = flood_fill_labels(m, d, full, min_voxels);
        ASSERT_EQ(got, want) << "trial " << trial << (full ? " 26" : " 6") << "-connected, min " << min_voxels;
        std::vector<std::size_t> sizes(c.count + 1, 0);
        for (auto l : got) ++sizes[l];
        sizes[0] = 0;
        EXPECT_EQ(sizes, c.sizes);
        EXPECT_TRUE(std::is_sorted(c.sizes.begin() + 1, c.sizes.end(), std::greater<>()));
      }
  }
}

TEST(Components, EmptyAndFullGrids) {
  const ms::Dims3 d{4, 3, 2};
  std::vector<std::uint8_t> m(24, 0);
  std::vector<std::uint32_t> out(24, 5);
  EXPECT_EQ(ms::label_components(m.data(), d, false, 0, out.data()).count, 0u);
  EXPECT_EQ(std::count(out.begin(), out.end(), 0u), 24);
  std::fill(m.begin(), m.end(), 1);
  const auto c = ms::label_components(m.data(), d, false, 0, out.data());
  EXPECT_EQ(c.count, 1u);
  EXPECT_EQ(c.sizes[1], 24u);
  EXPECT_EQ(std::count(out.begin(), out.end(), 1u), 24);
  EXPECT_EQ(ms::label_components(m.data(), d, true, 25, out.data()).count, 0u);  // under the minimum
}

namespace {

std::size_t count_components(const std::vector<std::uint8_t>& m, const ms::Dims3& d, bool full) {
  std::vector<std::uint32_t> out(m.size());
  return ms::label_components(m.data(), d, full, 0, out.data()).count;
}

}  // namespace

// Pieces that touch only at an edge or a corner are joined by the fewest
// voxels (one per edge contact, two per corner contact), without touching
// what is face-connected already.
TEST(Components, JoinDiagonalContactsLikeTheIsoSurfaceNeedsThem) {
  const ms::Dims3 d{6, 6, 6};
  auto at = [&](long x, long y, long z) { return static_cast<std::size_t>(x + 6 * (y + 6 * z)); };
  std::vector<std::uint8_t> edge(216, 0);
  edge[at(1, 1, 1)] = edge[at(1, 1, 2)] = 1;  // a bar, and a voxel touching its top along an edge
  edge[at(2, 1, 3)] = 1;
  std::vector<std::uint8_t> joined = edge;
  EXPECT_EQ(ms::join_diagonal_contacts(joined.data(), d), 1u);
  EXPECT_EQ(count_components(joined, d, false), 1u);
  // Of the two voxels between them, the one with more set neighbours: (2, 1, 2), beside the bar.
  EXPECT_EQ(joined[at(2, 1, 2)], 1);
  std::vector<std::uint8_t> corner(216, 0);
  corner[at(1, 1, 1)] = corner[at(2, 2, 2)] = 1;
  EXPECT_EQ(ms::join_diagonal_contacts(corner.data(), d), 2u);
  EXPECT_EQ(count_components(corner, d, false), 1u);
  std::vector<std::uint8_t> apart(216, 0);  // one voxel apart: not touching, not joined
  apart[at(1, 1, 1)] = apart[at(3, 1, 1)] = 1;
  EXPECT_EQ(ms::join_diagonal_contacts(apart.data(), d), 0u);
  EXPECT_EQ(count_components(apart, d, false), 2u);
  std::vector<std::uint8_t> solid(216, 0);  // face-connected already: unchanged
  for (long z = 1; z < 5; ++z) solid[at(2, 2, z)] = solid[at(3, 2, z)] = 1;
  const auto before = solid;
  EXPECT_EQ(ms::join_diagonal_contacts(solid.data(), d), 0u);
  EXPECT_EQ(solid, before);
}

// On sparse random grids (many diagonal contacts): afterwards the face-
// connected pieces are the fully connected ones, the mask only grew, and by
// at most two voxels per piece joined.
TEST(Components, JoinDiagonalContactsOnRandomGrids) {
  std::mt19937 rng(11);
  for (int trial = 0; trial < 40; ++trial) {
    const ms::Dims3 d{6 + rng() % 14, 5 + rng() % 12, 4 + rng() % 10};
    const double fill = 0.05 + 0.03 * (trial % 5);
    std::vector<std::uint8_t> m(d[0] * d[1] * d[2]);
    std::bernoulli_distribution b(fill);
    for (auto& v : m) v = b(rng);
    const std::size_t faces = count_components(m, d, false), full = count_components(m, d, true);
    std::vector<std::uint8_t> j = m;
    const std::size_t added = ms::join_diagonal_contacts(j.data(), d);
    const std::size_t full_after = count_components(j, d, true);
    EXPECT_EQ(count_components(j, d, false), full_after) << "trial " << trial;
    EXPECT_LE(full_after, full);
    EXPECT_LE(added, 2 * (faces - full_after)) << "trial " << trial;
    for (std::size_t v = 0; v < m.size(); ++v) EXPECT_LE(m[v], j[v]);
  }
}
