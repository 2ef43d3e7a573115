#include <gtest/gtest.h>

#include <cmath>

#include "core/types.h"

using namespace ms;

TEST(Geometry, IndexToLpsRoundTripOblique) {
  Geometry g;
  g.size = {10, 12, 14};
  g.spacing = {0.7, 0.9, 1.3};
  g.origin = {-12.5, 40.0, 3.25};
  const double c = std::cos(0.4), s = std::sin(0.4);
  g.direction = {c, -s, 0, s, c, 0, 0, 0, 1};  // columns: rotated i and j axes
  const Vec3 p = g.index_to_lps(3.5, 7.25, 11.0);
  const Vec3 idx = g.lps_to_index(p);
  EXPECT_NEAR(idx[0], 3.5, 1e-12);
  EXPECT_NEAR(idx[1], 7.25, 1e-12);
  EXPECT_NEAR(idx[2], 11.0, 1e-12);
  // Moving one index along i moves by spacing[0] along the first column.
  const Vec3 d = g.index_to_lps(4.5, 7.25, 11.0) - p;
  EXPECT_NEAR(d[0], 0.7 * c, 1e-12);
  EXPECT_NEAR(d[1], 0.7 * s, 1e-12);
  EXPECT_NEAR(d[2], 0.0, 1e-12);
}

TEST(Plane, ReflectIsAnInvolutionAndFixesThePlane) {
  Plane pl{{1, 2, 3}, normalized(Vec3{1, 0.2, -0.1})};
  const Vec3 p{7, -3, 5};
  const Vec3 r = pl.reflect(p);
  EXPECT_NEAR(pl.signed_distance(r), -pl.signed_distance(p), 1e-12);
  const Vec3 rr = pl.reflect(r);
  for (int a = 0; a < 3; ++a) EXPECT_NEAR(rr[a], p[a], 1e-12);
  const Vec3 on = pl.reflect(pl.point);
  for (int a = 0; a < 3; ++a) EXPECT_NEAR(on[a], pl.point[a], 1e-12);
}

TEST(Landmarks, MirrorLabelSwapsSidesAndKeepsMidline) {
  EXPECT_EQ(mirror_label("Co_L"), "Co_R");
  EXPECT_EQ(mirror_label("Go_R"), "Go_L");
  EXPECT_EQ(mirror_label("Me"), "Me");
  EXPECT_EQ(mirror_label("Pog"), "Pog");
  for (const auto& n : landmark_names()) EXPECT_EQ(mirror_label(mirror_label(n)), n);
}

TEST(Landmarks, SetReplacesAndFindReportsMissing) {
  LandmarkSet s;
  s.set("Me", {1, 2, 3});
  s.set("Me", {4, 5, 6});
  ASSERT_NE(s.find("Me"), nullptr);
  EXPECT_EQ((*s.find("Me"))[0], 4);
  EXPECT_EQ(s.points.size(), 1u);
  EXPECT_EQ(s.find("Pog"), nullptr);
}
