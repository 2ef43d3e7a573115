#include "pipeline/cohort_stats.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <random>

namespace ms::pipeline::cohort {

namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
}  // namespace

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return kNaN;
  std::sort(v.begin(), v.end());
  const double h = q * static_cast<double>(v.size() - 1);
  const auto lo = static_cast<std::size_t>(std::floor(h));
  const std::size_t hi = std::min(lo + 1, v.size() - 1);
  return v[lo] + (h - static_cast<double>(lo)) * (v[hi] - v[lo]);
}

MannWhitney mann_whitney(const std::vector<double>& a, const std::vector<double>& b) {
  MannWhitney r;
  if (a.empty() || b.empty()) {
    r.p = kNaN;
    return r;
  }
  // Ranks of the pooled sample (ties share their mean rank).
  std::vector<std::pair<double, int>> pooled;
  for (double x : a) pooled.emplace_back(x, 0);
  for (double x : b) pooled.emplace_back(x, 1);
  std::sort(pooled.begin(), pooled.end());
  const double n1 = static_cast<double>(a.size()), n2 = static_cast<double>(b.size()), n = n1 + n2;
  double rank_sum_a = 0, tie_term = 0;
  for (std::size_t i = 0; i < pooled.size();) {
    std::size_t j = i;
    while (j < pooled.size() && pooled[j].first == pooled[i].first) ++j;
    const double t = static_cast<double>(j - i), mean_rank = 0.5 * static_cast<double>(i + 1 + j);
    for (std::size_t k = i; k < j; ++k)
      if (pooled[k].second == 0) rank_sum_a += mean_rank;
    tie_term += t * t * t - t;
    i = j;
  }
  r.u = rank_sum_a - n1 * (n1 + 1) / 2;
  const double mean = n1 * n2 / 2;
  const double var = n1 * n2 / 12 * ((n + 1) - tie_term / (n * (n - 1)));
  if (var <= 0) return r;  // every value equal: no evidence either way
  const double d = r.u - mean;
  r.z = (d > 0 ? d - 0.5 : d < 0 ? d + 0.5 : 0) / std::sqrt(var);
  if ((d > 0 && r.z < 0) || (d < 0 && r.z > 0)) r.z = 0;
  r.p = std::erfc(std::abs(r.z) / std::sqrt(2.0));
  return r;
}

double cliffs_delta(const std::vector<double>& a, const std::vector<double>& b) {
  if (a.empty() || b.empty()) return kNaN;
  double more = 0, less = 0;
  for (double x : a)
    for (double y : b) more += x > y, less += x < y;
  return (more - less) / (static_cast<double>(a.size()) * static_cast<double>(b.size()));
}

Interval cliffs_delta_bootstrap(const std::vector<double>& a, const std::vector<double>& b, double level, int resamples,
                                std::uint64_t seed) {
  if (a.empty() || b.empty() || resamples < 1) return {kNaN, kNaN};
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<std::size_t> pick_a(0, a.size() - 1), pick_b(0, b.size() - 1);
  std::vector<double> deltas, ra(a.size()), rb(b.size());
  deltas.reserve(static_cast<std::size_t>(resamples));
  for (int k = 0; k < resamples; ++k) {
    for (auto& x : ra) x = a[pick_a(rng)];
    for (auto& y : rb) y = b[pick_b(rng)];
    deltas.push_back(cliffs_delta(ra, rb));
  }
  return {quantile(deltas, (1 - level) / 2), quantile(deltas, (1 + level) / 2)};
}

}  // namespace ms::pipeline::cohort
