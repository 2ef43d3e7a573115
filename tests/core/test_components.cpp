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
