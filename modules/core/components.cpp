#include "core/components.h"

#include <algorithm>
#include <cstdlib>
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

namespace {

// The 26 neighbour offsets, by the number of axes they step along: 1 face, 2 edge, 3 corner.
struct Offset {
  int dx, dy, dz, axes;
};

const std::vector<Offset>& neighbour_offsets() {
  static const std::vector<Offset> o = [] {
    std::vector<Offset> v;
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx)
          if (dx || dy || dz) v.push_back({dx, dy, dz, std::abs(dx) + std::abs(dy) + std::abs(dz)});
    return v;
  }();
  return o;
}

// A grid and its labels, read by voxel and offset (outside the grid: background).
struct LabelGrid {
  const std::uint8_t* mask;
  const std::vector<std::uint32_t>& label;  // face-connected pieces
  const std::vector<std::uint32_t>& whole;  // fully connected components
  long nx, ny, nz;

  long step(long v, const Offset& o) const {
    const long x = v % nx + o.dx, y = (v / nx) % ny + o.dy, z = v / (nx * ny) + o.dz;
    if (x < 0 || y < 0 || z < 0 || x >= nx || y >= ny || z >= nz) return -1;
    return x + nx * (y + ny * z);
  }
  // The labels among v's neighbours of the given kind (axes 1 or 2), other
  // than `except` (voxels set since the labelling have none).
  std::vector<std::uint32_t> labels_around(long v, int axes, std::uint32_t except) const {
    std::vector<std::uint32_t> out;
    for (const Offset& o : neighbour_offsets()) {
      const long w = o.axes == axes ? step(v, o) : -1;
      if (w >= 0 && mask[w] && label[w] != 0 && label[w] != except && std::find(out.begin(), out.end(), label[w]) == out.end())
        out.push_back(label[w]);
    }
    return out;
  }
  // The number of set voxels among v's 26 neighbours, and whether they all
  // belong to one fully connected component (else setting v joins others too).
  std::pair<int, bool> neighbourhood(long v) const {
    int n = 0;
    std::uint32_t component = 0;
    bool one = true;
    for (const Offset& o : neighbour_offsets()) {
      const long w = step(v, o);
      if (w < 0 || !mask[w]) continue;
      if (whole[w] != 0 && component != 0 && whole[w] != component) one = false;
      if (whole[w] != 0) component = whole[w];
      ++n;
    }
    return {n, one};
  }
};

// A background voxel that joins (edge join) or brings closer (corner step) pieces a and b.
struct Join {
  long voxel;
  int neighbours;
  bool one_component;  // it touches no other fully connected component
  std::uint32_t a, b;
  bool edge;
};

// Candidates next to the voxels of every piece but the largest (label 1):
// each join touches at least one smaller piece.
std::vector<Join> candidate_joins(const LabelGrid& g) {
  std::vector<Join> out;
  const long n = g.nx * g.ny * g.nz;
  for (long u = 0; u < n; ++u) {
    if (!g.mask[u] || g.label[u] <= 1) continue;
    for (const Offset& o : neighbour_offsets()) {
      if (o.axes == 3) continue;
      const long v = g.step(u, o);
      if (v < 0 || g.mask[v]) continue;
      const auto [nb, one] = g.neighbourhood(v);
      if (o.axes == 1) {  // v is u's face neighbour: a face neighbour of b joins; an edge neighbour steps
        for (std::uint32_t b : g.labels_around(v, 1, g.label[u])) out.push_back({v, nb, one, g.label[u], b, true});
        for (std::uint32_t b : g.labels_around(v, 2, g.label[u])) out.push_back({v, nb, one, g.label[u], b, false});
      } else {  // v is u's edge neighbour: a face neighbour of b steps
        for (std::uint32_t b : g.labels_around(v, 1, g.label[u])) out.push_back({v, nb, one, b, g.label[u], false});
      }
    }
  }
  // Edge joins first; then voxels touching no third component; then the
  // most enclosed voxel, then storage order.
  std::sort(out.begin(), out.end(), [](const Join& p, const Join& q) {
    if (p.edge != q.edge) return p.edge;
    if (p.one_component != q.one_component) return p.one_component;
    if (p.neighbours != q.neighbours) return p.neighbours > q.neighbours;
    return p.voxel < q.voxel;
  });
  return out;
}

}  // namespace

std::size_t join_diagonal_contacts(std::uint8_t* mask, const Dims3& dims) {
  const long nx = static_cast<long>(dims[0]), ny = static_cast<long>(dims[1]), nz = static_cast<long>(dims[2]);
  std::vector<std::uint32_t> label(dims[0] * dims[1] * dims[2]), whole(label.size());
  std::size_t added = 0;
  // Each round joins every edge contact and turns the remaining corner
  // contacts into edge contacts, which the next round joins.
  constexpr int kMaxRounds = 8;
  for (int round = 0; round < kMaxRounds; ++round) {
    const Components c = label_components(mask, dims, false, 0, label.data());
    if (c.count <= 1) break;
    if (c.count == label_components(mask, dims, true, 0, whole.data()).count) break;
    const LabelGrid g{mask, label, whole, nx, ny, nz};
    const std::vector<Join> joins = candidate_joins(g);
    Forest pieces;
    pieces.parent.resize(c.count + 1);
    std::iota(pieces.parent.begin(), pieces.parent.end(), 0u);
    std::size_t set_now = 0;
    for (const Join& j : joins) {
      if (mask[j.voxel] || pieces.find(j.a) == pieces.find(j.b)) continue;
      // The voxel joins every piece it is a face neighbour of: no two of them
      // may be joined already (a loop), and a step joins only its own.
      const std::vector<std::uint32_t> touched = g.labels_around(j.voxel, 1, 0);
      std::vector<std::uint32_t> roots;
      for (std::uint32_t l : touched) roots.push_back(pieces.find(l));
      std::sort(roots.begin(), roots.end());
      if (std::adjacent_find(roots.begin(), roots.end()) != roots.end()) continue;
      if (!j.edge && touched.size() != 1) continue;
      mask[j.voxel] = 1;
      ++set_now;
      pieces.unite(j.a, j.b);
      for (std::uint32_t l : touched) pieces.unite(j.a, l);
    }
    if (set_now == 0) break;  // what is left does not touch
    added += set_now;
  }
  return added;
}

}  // namespace ms
