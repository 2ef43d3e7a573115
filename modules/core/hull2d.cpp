#include "core/hull2d.h"

#include <algorithm>
#include <numeric>

namespace ms {

std::vector<std::size_t> convex_hull_2d(const std::vector<std::array<double, 2>>& p) {
  std::vector<std::size_t> order(p.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return p[a] < p[b]; });
  order.erase(std::unique(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return p[a] == p[b]; }), order.end());
  if (order.size() < 3) return order;
  auto turn = [&](std::size_t o, std::size_t a, std::size_t b) {
    return (p[a][0] - p[o][0]) * (p[b][1] - p[o][1]) - (p[a][1] - p[o][1]) * (p[b][0] - p[o][0]);
  };
  std::vector<std::size_t> h(2 * order.size());
  std::size_t k = 0;
  for (std::size_t i : order) {  // lower chain
    while (k >= 2 && turn(h[k - 2], h[k - 1], i) <= 0) --k;
    h[k++] = i;
  }
  for (std::size_t n = order.size() - 1, t = k + 1; n-- > 0;) {  // upper chain
    while (k >= t && turn(h[k - 2], h[k - 1], order[n]) <= 0) --k;
    h[k++] = order[n];
  }
  h.resize(k - 1);
  return h;
}

}  // namespace ms
