// Group comparison statistics of `mandisym batch` (cohort_groups.csv; docs/
// batch.md, "Group comparison"): per-group median and quartiles, the
// Mann-Whitney U test and Cliff's delta with a bootstrap confidence interval.
#pragma once

#include <cstdint>
#include <vector>

namespace ms::pipeline::cohort {

// Quartiles by linear interpolation between order statistics (Hyndman & Fan
// type 7, R's and NumPy's default). Empty input: NaN.
double quantile(std::vector<double> v, double q);

struct MannWhitney {
  double u = 0;  // U of the first sample: pairs (a, b) with a > b, ties counted 1/2
  double z = 0;  // normal approximation with tie and continuity correction
  double p = 1;  // two-sided p-value of z (NaN when either sample is empty)
};
// Mann & Whitney (1947); normal approximation with the tie-corrected variance
// n1 n2 / 12 ((n + 1) - sum(t^3 - t) / (n (n - 1))) and a 0.5 continuity
// correction, as scipy.stats.mannwhitneyu(method="asymptotic").
MannWhitney mann_whitney(const std::vector<double>& a, const std::vector<double>& b);

// Cliff's delta, P(a > b) - P(a < b), in [-1, 1] (Cliff 1993). NaN when
// either sample is empty.
double cliffs_delta(const std::vector<double>& a, const std::vector<double>& b);

struct Interval {
  double lo = 0, hi = 0;
};
// Percentile bootstrap confidence interval of Cliff's delta: `resamples`
// resamplings of each group with replacement (seeded: the same cohort gives
// the same interval), the (1 - level) / 2 and (1 + level) / 2 quantiles.
Interval cliffs_delta_bootstrap(const std::vector<double>& a, const std::vector<double>& b, double level = 0.95,
                                int resamples = 2000, std::uint64_t seed = 20261205);

}  // namespace ms::pipeline::cohort
