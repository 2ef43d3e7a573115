// Simple points and closing plugs (core/topology) against a global count:
// object 6-components, background 26-components and the Euler characteristic
// of the object's 6-complex (voxels, face-adjacent pairs, 2 x 2 squares,
// 2 x 2 x 2 cubes) — a point is simple exactly when flipping it keeps all three.
#include <gtest/gtest.h>

#include <array>
#include <random>
#include <vector>

#include "core/distance_transform.h"
#include "core/topology.h"

namespace {

using ms::Dims3;
using Grid = std::vector<std::uint8_t>;

std::size_t at(const Dims3& d, long i, long j, long k) {
  return static_cast<std::size_t>(i + static_cast<long>(d[0]) * (j + static_cast<long>(d[1]) * k));
}
bool inside(const Dims3& d, long i, long j, long k) {
  return i >= 0 && j >= 0 && k >= 0 && i < long(d[0]) && j < long(d[1]) && k < long(d[2]);
}

// Components of the voxels equal to `value` under 6- or 26-adjacency.
int components(const Grid& m, const Dims3& d, std::uint8_t value, bool c26) {
  std::vector<int> label(m.size(), 0);
  int count = 0;
  for (std::size_t s = 0; s < m.size(); ++s) {
    if (m[s] != value || label[s]) continue;
    ++count;
    std::vector<std::size_t> stack{s};
    label[s] = count;
    while (!stack.empty()) {
      const std::size_t v = stack.back();
      stack.pop_back();
      const long i = long(v % d[0]), j = long((v / d[0]) % d[1]), k = long(v / (d[0] * d[1]));
      for (int z = -1; z <= 1; ++z)
        for (int y = -1; y <= 1; ++y)
          for (int x = -1; x <= 1; ++x) {
            const int l1 = std::abs(x) + std::abs(y) + std::abs(z);
            if (l1 == 0 || (!c26 && l1 > 1) || !inside(d, i + x, j + y, k + z)) continue;
            const std::size_t u = at(d, i + x, j + y, k + z);
            if (m[u] == value && !label[u]) label[u] = count, stack.push_back(u);
          }
    }
  }
  return count;
}

// Euler characteristic of the object's 6-complex.
long euler(const Grid& m, const Dims3& d) {
  auto on = [&](long i, long j, long k) { return inside(d, i, j, k) && m[at(d, i, j, k)]; };
  long v = 0, e = 0, f = 0, c = 0;
  for (long k = 0; k < long(d[2]); ++k)
    for (long j = 0; j < long(d[1]); ++j)
      for (long i = 0; i < long(d[0]); ++i) {
        if (!on(i, j, k)) continue;
        ++v;
        e += on(i + 1, j, k) + on(i, j + 1, k) + on(i, j, k + 1);
        f += (on(i + 1, j, k) && on(i, j + 1, k) && on(i + 1, j + 1, k)) +
             (on(i + 1, j, k) && on(i, j, k + 1) && on(i + 1, j, k + 1)) +
             (on(i, j + 1, k) && on(i, j, k + 1) && on(i, j + 1, k + 1));
        c += on(i + 1, j, k) && on(i, j + 1, k) && on(i, j, k + 1) && on(i + 1, j + 1, k) && on(i + 1, j, k + 1) &&
             on(i, j + 1, k + 1) && on(i + 1, j + 1, k + 1);
      }
  return v - e + f - c;
}

struct Topology {
  int objects, backgrounds;
  long chi;
  bool operator==(const Topology& o) const { return objects == o.objects && backgrounds == o.backgrounds && chi == o.chi; }
};
Topology topology(const Grid& m, const Dims3& d) { return {components(m, d, 1, false), components(m, d, 0, true), euler(m, d)}; }

TEST(Topology, SimplePointsNeverChangeTheGlobalCountOnRandomNeighbourhoods) {
  // A 5 x 5 x 5 grid with an empty border: the 3 x 3 x 3 block around the
  // centre is random, so every configuration the local test can see occurs.
  // A simple point keeps the counts. The converse has exceptions: flipping a
  // point can cut an object loop that closes through a corner of the block
  // and open a background loop at once, keeping every count (the local test,
  // which follows Bertrand & Malandain's geodesic neighbourhoods, sees both).
  const Dims3 d{5, 5, 5};
  std::mt19937 rng(7);
  int simple = 0, not_simple = 0, agree = 0;
  const int trials = 20000;
  for (int trial = 0; trial < trials; ++trial) {
    const double p = 0.15 + 0.7 * (trial % 8) / 7.0;
    Grid m(125, 0);
    for (long k = 1; k <= 3; ++k)
      for (long j = 1; j <= 3; ++j)
        for (long i = 1; i <= 3; ++i) m[at(d, i, j, k)] = std::bernoulli_distribution(p)(rng);
    const std::size_t c = at(d, 2, 2, 2);
    Grid with = m, without = m;
    with[c] = 1;
    without[c] = 0;
    const bool kept = topology(with, d) == topology(without, d);
    const bool is_simple = ms::is_simple_point(m.data(), d, 2, 2, 2);
    if (is_simple) ASSERT_TRUE(kept) << "trial " << trial;
    agree += is_simple == kept;
    (is_simple ? simple : not_simple)++;
  }
  EXPECT_GT(simple, 2000);  // both answers are exercised
  EXPECT_GT(not_simple, 2000);
  EXPECT_GT(agree, 0.97 * trials);  // the exceptions are rare
}

TEST(Topology, TextbookCases) {
  const Dims3 d{5, 5, 5};
  Grid m(125, 0);
  EXPECT_FALSE(ms::is_simple_point(m.data(), d, 2, 2, 2));  // an isolated voxel is a component of its own
  for (long i = 0; i < 5; ++i) m[at(d, i, 2, 2)] = 1;       // a line along x
  EXPECT_FALSE(ms::is_simple_point(m.data(), d, 2, 2, 2));  // its middle cuts it in two
  EXPECT_TRUE(ms::is_simple_point(m.data(), d, 4, 2, 2));   // its end (at the grid's face) is simple
  Grid slab(125, 0);
  for (long j = 1; j <= 3; ++j)
    for (long i = 1; i <= 3; ++i) slab[at(d, i, j, 2)] = 1;
  EXPECT_FALSE(ms::is_simple_point(slab.data(), d, 2, 2, 2));  // the middle of a sheet: a hole through it
  EXPECT_TRUE(ms::is_simple_point(slab.data(), d, 1, 1, 2));   // its corner
  Grid diagonal(125, 0);  // two voxels meeting only at an edge: apart for a 6-connected object
  diagonal[at(d, 1, 1, 2)] = diagonal[at(d, 2, 2, 2)] = 1;
  EXPECT_FALSE(ms::is_simple_point(diagonal.data(), d, 2, 2, 2));
}

// A block pierced by a 2-voxel tunnel along y (a handle) with a 2-voxel wide
// groove cut into its top face (a crease): a closing fills both.
Grid pierced_grooved_block(const Dims3& d) {
  Grid m(d[0] * d[1] * d[2], 0);
  for (long k = 4; k < 20; ++k)
    for (long j = 4; j < 20; ++j)
      for (long i = 4; i < 28; ++i) {
        const bool tunnel = i >= 10 && i < 12 && k >= 10 && k < 12;
        const bool groove = i >= 20 && i < 22 && k >= 16;
        m[at(d, i, j, k)] = !tunnel && !groove;
      }
  return m;
}

TEST(Topology, ClosingPlugsKeepTheClosingsTopologyAndLeaveCreasesOpen) {
  const Dims3 d{32, 24, 24};
  const std::array<double, 3> s{1, 1, 1};
  const Grid original = pierced_grooved_block(d);
  Grid full = original;
  ms::close_euclidean(full, d, s, 2.0);
  Grid plugs = full;
  const std::size_t kept = ms::keep_closing_plugs(plugs, original, d, s, 2.0, 1.0);

  EXPECT_EQ(topology(original, d).chi, 0);  // a solid torus: one handle
  EXPECT_EQ(topology(full, d).chi, 1);      // closed: a solid ball
  EXPECT_EQ(topology(plugs, d), topology(full, d));
  std::size_t added = 0;
  for (std::size_t v = 0; v < original.size(); ++v) {
    ASSERT_TRUE(!original[v] || plugs[v]);  // contains the original
    ASSERT_TRUE(!plugs[v] || full[v]);      // within the closing
    added += full[v] && !original[v];
  }
  EXPECT_GT(added, kept);
  // The groove is left open, where the full closing filled it.
  int groove_full = 0, groove_plugs = 0;
  for (long k = 16; k < 20; ++k)
    for (long j = 4; j < 20; ++j)
      for (long i = 20; i < 22; ++i) groove_full += full[at(d, i, j, k)], groove_plugs += plugs[at(d, i, j, k)];
  EXPECT_GT(groove_full, 60);
  EXPECT_EQ(groove_plugs, 0);
  // The tunnel is plugged across its whole section somewhere along it, and the
  // plug is a few voxels thick, not the tunnel's 16.
  int plugged_rows = 0;
  for (long j = 4; j < 20; ++j) {
    bool all = true;
    for (long k = 10; k < 12; ++k)
      for (long i = 10; i < 12; ++i) all = all && plugs[at(d, i, j, k)];
    plugged_rows += all;
  }
  EXPECT_GE(plugged_rows, 1);
  EXPECT_LE(plugged_rows, 4);
}

TEST(Topology, ClosingPlugsKeepTheTopologyOfRandomClosings) {
  // Random blobs in an anisotropic grid with an empty border: whatever the
  // closing changed (handles, cavities, merged blobs), the plugs change it alike.
  const Dims3 d{30, 26, 22};
  const std::array<double, 3> s{0.8, 1.0, 1.3};
  std::mt19937 rng(11);
  for (int trial = 0; trial < 6; ++trial) {
    Grid original(d[0] * d[1] * d[2], 0);
    for (long k = 3; k < long(d[2]) - 3; ++k)
      for (long j = 3; j < long(d[1]) - 3; ++j)
        for (long i = 3; i < long(d[0]) - 3; ++i) original[at(d, i, j, k)] = std::bernoulli_distribution(0.45)(rng);
    Grid full = original;
    ms::close_euclidean(full, d, s, 1.6);
    Grid plugs = full;
    ms::keep_closing_plugs(plugs, original, d, s, 1.6, 1.0);
    EXPECT_EQ(topology(plugs, d), topology(full, d)) << "trial " << trial;
  }
}

}  // namespace
