// Group comparison statistics of `batch` against SciPy 1.10 / NumPy values.
#include "pipeline/cohort_stats.h"

#include <gtest/gtest.h>

#include <cmath>

using namespace ms::pipeline::cohort;

TEST(CohortStats, QuantilesInterpolateLikeNumPy) {
  const std::vector<double> v = {3, 1, 4, 1, 5, 9, 2, 6};
  EXPECT_DOUBLE_EQ(quantile(v, 0.25), 1.75);  // numpy.quantile(v, 0.25)
  EXPECT_DOUBLE_EQ(quantile(v, 0.5), 3.5);
  EXPECT_DOUBLE_EQ(quantile(v, 0.75), 5.25);
  EXPECT_TRUE(std::isnan(quantile({}, 0.5)));
}

TEST(CohortStats, MannWhitneyMatchesScipyAsymptotic) {
  // scipy.stats.mannwhitneyu(a, b, method="asymptotic"): U 27.5, p 0.02810006355731762.
  const auto r = mann_whitney({1.2, 3.4, 2.2, 5.0, 4.1, 3.3}, {0.5, 1.1, 2.2, 0.9, 1.7});
  EXPECT_DOUBLE_EQ(r.u, 27.5);
  EXPECT_NEAR(r.p, 0.02810006355731762, 1e-12);
  // With many ties: U 7.0, p 0.04535219143280889.
  const auto t = mann_whitney({1, 2, 2, 3, 3, 3}, {2, 3, 3, 4, 4, 5, 5});
  EXPECT_DOUBLE_EQ(t.u, 7.0);
  EXPECT_NEAR(t.p, 0.04535219143280889, 1e-12);
  EXPECT_LT(t.z, 0);
  // Identical samples: no evidence.
  EXPECT_DOUBLE_EQ(mann_whitney({2, 2, 2}, {2, 2}).p, 1.0);
  EXPECT_TRUE(std::isnan(mann_whitney({}, {1.0}).p));
}

TEST(CohortStats, CliffsDeltaIsTwoUOverN1N2MinusOne) {
  EXPECT_NEAR(cliffs_delta({1.2, 3.4, 2.2, 5.0, 4.1, 3.3}, {0.5, 1.1, 2.2, 0.9, 1.7}), 2 * 27.5 / 30 - 1, 1e-15);
  EXPECT_NEAR(cliffs_delta({1, 2, 2, 3, 3, 3}, {2, 3, 3, 4, 4, 5, 5}), 2 * 7.0 / 42 - 1, 1e-15);
  EXPECT_DOUBLE_EQ(cliffs_delta({5, 6}, {1, 2}), 1.0);
  EXPECT_DOUBLE_EQ(cliffs_delta({1, 2}, {5, 6}), -1.0);
}

TEST(CohortStats, BootstrapIntervalContainsTheEstimateAndIsReproducible) {
  const std::vector<double> a = {1.2, 3.4, 2.2, 5.0, 4.1, 3.3, 2.9, 3.8}, b = {0.5, 1.1, 2.2, 0.9, 1.7, 2.5, 1.4};
  const double d = cliffs_delta(a, b);
  const Interval ci = cliffs_delta_bootstrap(a, b);
  EXPECT_LE(ci.lo, d);
  EXPECT_GE(ci.hi, d);
  EXPECT_GE(ci.lo, -1.0);
  EXPECT_LE(ci.hi, 1.0);
  EXPECT_LT(ci.lo, ci.hi);
  const Interval again = cliffs_delta_bootstrap(a, b);
  EXPECT_EQ(ci.lo, again.lo);
  EXPECT_EQ(ci.hi, again.hi);
  // Separated groups: the whole interval at 1.
  const Interval sep = cliffs_delta_bootstrap({10, 11, 12}, {1, 2, 3});
  EXPECT_DOUBLE_EQ(sep.lo, 1.0);
  EXPECT_DOUBLE_EQ(sep.hi, 1.0);
}
