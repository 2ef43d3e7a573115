#include "core/components.h"

#include <algorithm>
#include <numeric>

namespace ms {

namespace {

// Union-find over provisional labels; a root is the smallest label of its set,
// so it is the set's first label in raster order.
struct Forest {
  std::vector<std::uint32_t> parent;  // parent[0] = 0: background

  std::uint32_t find(std::uint32_t a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];  // path halving
    return a;
  }
  std::uint32_t unite(std::uint32_t a, std::uint32_t b) {
    a = find(a), b = find(b);
    if (a == b) return a;
    if (b < a) std::swap(a, b);
    parent[b] = a;
    return a;
  }
};

}  // namespace

Components label_components(const std::uint8_t* mask, const Dims3& dims, bool fully_connected, std::size_t min_voxels,
                            std::uint32_t* out) {
  const std::size_t nx = dims[0], ny = dims[1], nz = dims[2], n = nx * ny * nz;
  // Runs of set voxels along x, line by line (line = j + ny * k), in raster order.
  struct Run {
    std::uint32_t x0, x1;  // [x0, x1)
  };
  std::vector<Run> runs;
  std::vector<std::size_t> line_start(ny * nz + 1, 0);
  for (std::size_t line = 0; line < ny * nz; ++line) {
    line_start[line] = runs.size();
    const std::uint8_t* row = mask + line * nx;
    for (std::size_t i = 0; i < nx;) {
      if (!row[i]) {
        ++i;
        continue;
      }
      const std::size_t x0 = i;
      while (i < nx && row[i]) ++i;
      runs.push_back({static_cast<std::uint32_t>(x0), static_cast<std::uint32_t>(i)});
    }
  }
  line_start[ny * nz] = runs.size();
  // Pass 1: each run joins the runs it touches in the lines already seen
  // (face neighbours: the previous row and slice, overlapping in x; fully
  // connected: also the diagonal rows of the previous slice, and touching
  // diagonally in x).
  Forest f;
  f.parent.resize(runs.size() + 1);
  std::iota(f.parent.begin(), f.parent.end(), 0u);  // run r is label r + 1
  const long reach = fully_connected ? 1 : 0;
  for (std::size_t k = 0; k < nz; ++k)
    for (std::size_t j = 0; j < ny; ++j) {
      const std::size_t line = j + ny * k;
      auto join_line = [&](long jj, long kk) {
        if (jj < 0 || kk < 0 || jj >= static_cast<long>(ny)) return;
        const std::size_t other = static_cast<std::size_t>(jj) + ny * static_cast<std::size_t>(kk);
        std::size_t q = line_start[other];
        for (std::size_t r = line_start[line]; r < line_start[line + 1]; ++r) {
          const long lo = static_cast<long>(runs[r].x0) - reach, hi = static_cast<long>(runs[r].x1) + reach;  // [lo, hi)
          while (q < line_start[other + 1] && static_cast<long>(runs[q].x1) <= lo) ++q;
          for (std::size_t p = q; p < line_start[other + 1] && static_cast<long>(runs[p].x0) < hi; ++p)
            f.unite(static_cast<std::uint32_t>(r + 1), static_cast<std::uint32_t>(p + 1));
        }
      };
      const long J = static_cast<long>(j), K = static_cast<long>(k);
      join_line(J - 1, K);
      join_line(J, K - 1);
      if (fully_connected) join_line(J - 1, K - 1), join_line(J + 1, K - 1);
    }
  // Roots and their sizes, in the order of their first voxel.
  const std::size_t provisional = f.parent.size();
  std::vector<std::uint32_t> root(provisional);
  for (std::uint32_t l = 0; l < provisional; ++l) root[l] = f.find(l);
  std::vector<std::size_t> size(provisional, 0);
  for (std::size_t r = 0; r < runs.size(); ++r) size[root[r + 1]] += runs[r].x1 - runs[r].x0;
  std::vector<std::uint32_t> big;
  for (std::uint32_t l = 1; l < provisional; ++l)
    if (root[l] == l && size[l] >= std::max<std::size_t>(min_voxels, 1)) big.push_back(l);
  std::stable_sort(big.begin(), big.end(), [&](std::uint32_t a, std::uint32_t b) { return size[a] > size[b]; });
  // Final labels: 1..count by decreasing size; small components 0.
  std::vector<std::uint32_t> final_of_root(provisional, 0);
  Components c;
  c.count = big.size();
  c.sizes.assign(c.count + 1, 0);
  for (std::size_t r = 0; r < big.size(); ++r) {
    final_of_root[big[r]] = static_cast<std::uint32_t>(r + 1);
    c.sizes[r + 1] = size[big[r]];
  }
  std::fill(out, out + n, 0u);
  for (std::size_t line = 0; line < ny * nz; ++line)
    for (std::size_t r = line_start[line]; r < line_start[line + 1]; ++r)
      std::fill(out + line * nx + runs[r].x0, out + line * nx + runs[r].x1, final_of_root[root[r + 1]]);
  return c;
}

}  // namespace ms
