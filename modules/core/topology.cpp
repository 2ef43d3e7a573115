#include "core/topology.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <queue>
#include <utility>

#include "core/debug_lap.h"

namespace ms {
namespace {

// The 3 x 3 x 3 neighbourhood as bit positions p = (dx+1) + 3 (dy+1) + 9 (dz+1);
// the centre is 13.
constexpr int kCentre = 13;

struct Neighbourhood {
  std::array<std::uint32_t, 27> adj6{};   // 6-neighbours of each position inside the cube, centre excluded
  std::array<std::uint32_t, 27> adj26{};  // 26-neighbours likewise
  std::uint32_t n26 = 0, n18 = 0, n6 = 0; // the centre's neighbourhoods, centre excluded
  Neighbourhood() {
    auto pos = [](int x, int y, int z) { return (x + 1) + 3 * (y + 1) + 9 * (z + 1); };
    for (int z = -1; z <= 1; ++z)
      for (int y = -1; y <= 1; ++y)
        for (int x = -1; x <= 1; ++x) {
          const int p = pos(x, y, z), l1 = std::abs(x) + std::abs(y) + std::abs(z);
          if (p == kCentre) continue;
          n26 |= 1u << p;
          if (l1 <= 2) n18 |= 1u << p;
          if (l1 == 1) n6 |= 1u << p;
          for (int c = -1; c <= 1; ++c)
            for (int b = -1; b <= 1; ++b)
              for (int a = -1; a <= 1; ++a) {
                const int X = x + a, Y = y + b, Z = z + c;
                if ((a == 0 && b == 0 && c == 0) || std::abs(X) > 1 || std::abs(Y) > 1 || std::abs(Z) > 1) continue;
                const int q = pos(X, Y, Z);
                if (q == kCentre) continue;
                adj26[static_cast<std::size_t>(p)] |= 1u << q;
                if (std::abs(a) + std::abs(b) + std::abs(c) == 1) adj6[static_cast<std::size_t>(p)] |= 1u << q;
              }
        }
  }
};

const Neighbourhood& neighbourhood() {
  static const Neighbourhood n;
  return n;
}

int lowest_bit(std::uint32_t v) { return __builtin_ctz(v); }

// Removes from `set` the component of `seed` under the adjacency `adj`.
void take_component(std::uint32_t& set, int seed, const std::array<std::uint32_t, 27>& adj) {
  std::uint32_t frontier = 1u << seed;
  set &= ~frontier;
  while (frontier) {
    const int p = lowest_bit(frontier);
    frontier &= frontier - 1;
    const std::uint32_t next = adj[static_cast<std::size_t>(p)] & set;
    set &= ~next;
    frontier |= next;
  }
}

// Bits of the 26 neighbours of (i, j, k) that are object; outside the grid is background.
std::uint32_t object_bits(const std::uint8_t* m, const Dims3& d, std::size_t i, std::size_t j, std::size_t k) {
  std::uint32_t bits = 0;
  const bool inner = i > 0 && j > 0 && k > 0 && i + 1 < d[0] && j + 1 < d[1] && k + 1 < d[2];
  for (int z = -1, p = 0; z <= 1; ++z)
    for (int y = -1; y <= 1; ++y)
      for (int x = -1; x <= 1; ++x, ++p) {
        const long X = static_cast<long>(i) + x, Y = static_cast<long>(j) + y, Z = static_cast<long>(k) + z;
        if (!inner && (X < 0 || Y < 0 || Z < 0 || X >= static_cast<long>(d[0]) || Y >= static_cast<long>(d[1]) ||
                       Z >= static_cast<long>(d[2])))
          continue;
        if (m[static_cast<std::size_t>(X) + d[0] * (static_cast<std::size_t>(Y) + d[1] * static_cast<std::size_t>(Z))])
          bits |= 1u << p;
      }
  return bits & ~(1u << kCentre);
}

}  // namespace

bool is_simple_point(const std::uint8_t* mask, const Dims3& dims, std::size_t i, std::size_t j, std::size_t k) {
  const Neighbourhood& N = neighbourhood();
  const std::uint32_t object = object_bits(mask, dims, i, j, k);
  // Object: 6-components in the 18-neighbourhood that touch a face neighbour.
  std::uint32_t rest = object & N.n18;
  int components = 0;
  for (std::uint32_t faces = rest & N.n6; faces; faces = rest & N.n6) {
    take_component(rest, lowest_bit(faces), N.adj6);
    if (++components > 1) return false;
  }
  if (components != 1) return false;
  // Background: 26-components in the 26-neighbourhood.
  std::uint32_t background = ~object & N.n26;
  if (!background) return false;
  take_component(background, lowest_bit(background), N.adj26);
  return background == 0;
}

namespace {

// Offsets of the voxels within radius_mm of a voxel (itself included), nearest first.
struct BallOffset {
  int x, y, z;
  float d2;
};
std::vector<BallOffset> ball_offsets(const std::array<double, 3>& spacing, double radius_mm) {
  std::vector<BallOffset> out;
  int reach[3];
  for (int a = 0; a < 3; ++a) reach[a] = static_cast<int>(std::floor(radius_mm / spacing[static_cast<std::size_t>(a)]));
  const double r2 = radius_mm * radius_mm * 1.0001;  // a hair more: rounding of a distance exactly r
  for (int z = -reach[2]; z <= reach[2]; ++z)
    for (int y = -reach[1]; y <= reach[1]; ++y)
      for (int x = -reach[0]; x <= reach[0]; ++x) {
        const double d2 = x * x * spacing[0] * spacing[0] + y * y * spacing[1] * spacing[1] + z * z * spacing[2] * spacing[2];
        if (d2 <= r2) out.push_back({x, y, z, static_cast<float>(d2)});
      }
  std::stable_sort(out.begin(), out.end(), [](const BallOffset& a, const BallOffset& b) { return a.d2 < b.d2; });
  return out;
}

// Squared distance from voxel (i, j, k) to the nearest voxel with in(u) true
// among the ball's offsets; kNoFeature when none is within it.
template <class In>
float nearest_in_ball(const std::vector<BallOffset>& ball, const Dims3& d, long i, long j, long k, In in) {
  for (const BallOffset& o : ball) {
    const long X = i + o.x, Y = j + o.y, Z = k + o.z;
    if (X < 0 || Y < 0 || Z < 0 || X >= static_cast<long>(d[0]) || Y >= static_cast<long>(d[1]) || Z >= static_cast<long>(d[2]))
      continue;
    if (in(static_cast<std::size_t>(X) + d[0] * (static_cast<std::size_t>(Y) + d[1] * static_cast<std::size_t>(Z)))) return o.d2;
  }
  return kNoFeature;
}

}  // namespace

std::size_t keep_closing_plugs(std::vector<std::uint8_t>& closed, const std::vector<std::uint8_t>& original,
                               const Dims3& dims, const std::array<double, 3>& spacing, double radius_mm,
                               double thicken_mm) {
  DebugLap lap("MANDISYM_DEBUG_SURFACE", "surface   ");
  const std::size_t n = closed.size();
  const std::size_t dx = dims[0], dxy = dims[0] * dims[1];
  auto ijk = [&](std::size_t v) {
    return std::array<long, 3>{static_cast<long>(v % dx), static_cast<long>((v / dx) % dims[1]), static_cast<long>(v / dxy)};
  };
  // The added voxels and their depth: the distance to the nearest original
  // voxel, within the closing's radius by construction (searched in a ball
  // nearest first: a closing of a large crop adds a few thousand voxels, and
  // a distance transform of the whole crop would cost more than all the rest).
  constexpr std::uint8_t kAdded = 1, kQueued = 2;
  std::vector<std::uint8_t> state(n, 0);
  std::vector<std::size_t> added;
  for (std::size_t v = 0; v < n; ++v)
    if (closed[v] && !original[v]) added.push_back(v), state[v] = kAdded | kQueued;
  if (added.empty()) return 0;
  const std::vector<BallOffset> depth_ball = ball_offsets(spacing, radius_mm);
  std::vector<float> depth(added.size());
#pragma omp parallel for schedule(static)
  for (long a = 0; a < static_cast<long>(added.size()); ++a) {
    const auto [i, j, k] = ijk(added[static_cast<std::size_t>(a)]);
    depth[static_cast<std::size_t>(a)] = nearest_in_ball(depth_ball, dims, i, j, k, [&](std::size_t u) { return original[u] != 0; });
  }
  lap("plugs: depth");

  // Homotopic thinning: a voxel that is not simple when its turn comes is
  // queued again when a neighbour goes. Entries are (squared depth, index in
  // `added`, which is in voxel order): deepest first, ties by voxel.
  using Entry = std::pair<float, std::size_t>;
  std::vector<Entry> start(added.size());
  for (std::size_t a = 0; a < added.size(); ++a) start[a] = {depth[a], a};
  std::priority_queue<Entry> queue(std::less<Entry>(), std::move(start));
  while (!queue.empty()) {
    const std::size_t v = added[queue.top().second];
    queue.pop();
    state[v] &= static_cast<std::uint8_t>(~kQueued);
    const auto [i, j, k] = ijk(v);
    if (!is_simple_point(closed.data(), dims, static_cast<std::size_t>(i), static_cast<std::size_t>(j), static_cast<std::size_t>(k)))
      continue;
    closed[v] = 0;
    for (int z = -1; z <= 1; ++z)
      for (int y = -1; y <= 1; ++y)
        for (int x = -1; x <= 1; ++x) {
          const long X = i + x, Y = j + y, Z = k + z;
          if (X < 0 || Y < 0 || Z < 0 || X >= static_cast<long>(dims[0]) || Y >= static_cast<long>(dims[1]) ||
              Z >= static_cast<long>(dims[2]))
            continue;
          const std::size_t u = static_cast<std::size_t>(X) + dx * static_cast<std::size_t>(Y) + dxy * static_cast<std::size_t>(Z);
          if ((state[u] & kAdded) && closed[u] && !(state[u] & kQueued)) {
            state[u] |= kQueued;
            const std::size_t a = static_cast<std::size_t>(std::lower_bound(added.begin(), added.end(), u) - added.begin());
            queue.emplace(depth[a], a);
          }
        }
  }
  lap("plugs: thinning");

  // Thicken: give back the added voxels within thicken_mm of what is left of
  // them, nearest first, each only if it is simple (adding it changes no
  // topology either: a thickened plug could otherwise enclose a cavity).
  std::vector<std::uint8_t> plug(n, 0);
  for (std::size_t v : added) plug[v] = closed[v];
  const std::vector<BallOffset> thick_ball = ball_offsets(spacing, thicken_mm);
  std::vector<Entry> shell;  // (squared distance to the plug, voxel)
  for (std::size_t v : added) {
    if (closed[v]) continue;
    const auto [i, j, k] = ijk(v);
    const float d2 = nearest_in_ball(thick_ball, dims, i, j, k, [&](std::size_t u) { return plug[u] != 0; });
    if (d2 < kNoFeature) shell.emplace_back(d2, v);
  }
  std::sort(shell.begin(), shell.end());
  for (int pass = 0; pass < 2; ++pass)  // a second pass takes what the first made simple
    for (const auto& [d2, v] : shell)
      if (!closed[v] && is_simple_point(closed.data(), dims, v % dx, (v / dx) % dims[1], v / dxy)) closed[v] = 1;
  std::size_t kept = 0;
  for (std::size_t v : added) kept += closed[v];
  lap("plugs: thickening");
  if (lap.on()) std::fprintf(stderr, "  surface     plugs: %zu of %zu added voxels kept\n", kept, added.size());
  return kept;
}

}  // namespace ms
