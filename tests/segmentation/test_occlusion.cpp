// Teeth in occlusion (docs/segmentation.md, "Teeth in occlusion"): welded
// cheek-teeth columns, the occlusal contact plane fitted to them, and the cut.
// A synthetic dentition: a slab of "mandible" (dentine, in the atlas's zone)
// under rows of lower crowns whose enamel caps touch upper crowns, all welded
// into one dense block; the contact plane is tilted by a known slope.
#include <gtest/gtest.h>

#include <cmath>

#include "segmentation/atlas_zone.h"
#include "segmentation/occlusion.h"

using namespace ms;
using namespace ms::segmentation;

namespace {

constexpr double kSlope = 0.15;  // contact rises 0.15 mm per mm backwards (~8.5 degrees)

struct Dentition {
  Volume ct;
  // Contact height (mm, LPS z) at antero-posterior position y (LPS, posterior positive).
  static double contact_z(double y) { return 40.0 + kSlope * y; }
  explicit Dentition(bool welded) {
    ct.geom.size = {100, 60, 80};  // x: -50..49, y: 0..59, z: 0..79 mm
    ct.geom.origin = {-50, 0, 0};
    ct.hu.assign(ct.geom.voxel_count(), 40.0f);
    for (std::size_t k = 0; k < 80; ++k)
      for (std::size_t j = 0; j < 60; ++j)
        for (std::size_t i = 0; i < 100; ++i) {
          const double x = static_cast<double>(i) - 50, y = static_cast<double>(j), z = static_cast<double>(k);
          const double side = std::abs(x);
          if (side < 18 || side > 30 || y < 10 || y > 50) continue;  // two rows of cheek teeth
          const double c = contact_z(y);
          const double d = z - c;  // above (+) or below (-) the contact
          float hu = 0;
          if (d >= -25 && d < -8) hu = 1500;       // lower roots and the alveolar bone
          else if (d >= -8 && d < -2) hu = 1700;   // lower crown dentine
          else if (d >= -2 && d < 0) hu = 2500;    // lower occlusal enamel
          else if (d >= 0 && d < 2) hu = welded ? 2500.0f : 40.0f;  // upper occlusal enamel (or a gap)
          else if (d >= 2 && d < 8) hu = 1700;     // upper crown dentine
          else if (d >= 8 && d < 22) hu = 1500;    // upper roots
          if (!welded && d >= -0.5 && d < 2.5) hu = 40;  // teeth apart: a 3 mm gap
          if (hu == 0) continue;
          const std::size_t v = ct.geom.linear(i, j, k);
          ct.hu[v] = hu;
        }
  }
};

// The atlas's zone: up to 9 mm below the contact (the lower roots and crown necks).
double zone_p(const Vec3& q) { return q[2] < Dentition::contact_z(q[1]) - 9 ? 0.5 : 0.0; }

const Plane kMidline{{0, 0, 0}, {1, 0, 0}};
const Vec3 kSuperior{0, 0, 1}, kAnterior{0, -1, 0};

}  // namespace

TEST(Occlusion, FindsWeldedCheekTeethAndTheirContactPlane) {
  const Dentition d(true);
  const WeldedOcclusion w = welded_occlusion(d.ct, zone_p, kSuperior, kMidline, 1.0, 1000, 0);
  // Columns 18-30 mm from the midline on both sides, between 15 and 35 mm: 2 x 13 x 41.
  EXPECT_EQ(w.columns, 2u * 13u * 41u);
  EXPECT_TRUE(w.welded());
  const OcclusalPlane p = fit_occlusal_plane(w);
  ASSERT_TRUE(p.found);
  EXPECT_EQ(p.axis, 2);
  EXPECT_NEAR(std::atan(kSlope) * 180 / 3.14159265358979, p.tilt_deg, 1.0);
  // The enamel spans [contact - 2, contact + 2): its middle, half a voxel low on the grid.
  for (double y : {10.0, 30.0, 50.0})
    EXPECT_NEAR(p.c0 + p.c1 * 25.0 + p.c2 * y, Dentition::contact_z(y), 1.0) << y;
}

TEST(Occlusion, TeethApartAreNotWelded) {
  const Dentition d(false);
  const WeldedOcclusion w = welded_occlusion(d.ct, zone_p, kSuperior, kMidline, 1.0, 1000, 0);
  EXPECT_EQ(w.columns, 0u);
  EXPECT_FALSE(w.welded());
  EXPECT_FALSE(fit_occlusal_plane(w).found);
}

TEST(Occlusion, TheCutPartsUpperFromLowerTeeth) {
  Dentition d(true);
  const WeldedOcclusion w = welded_occlusion(d.ct, zone_p, kSuperior, kMidline, 1.0, 1000, 0);
  const OcclusalPlane p = fit_occlusal_plane(w);
  ASSERT_TRUE(p.found);
  EXPECT_GT(cut_at_occlusal_plane(d.ct, p, w, kMidline, kAnterior, 0), 0u);
  // Every column of the teeth now has air between its lower and its upper part.
  for (std::size_t j = 10; j <= 50; ++j)
    for (std::size_t i : {22u, 30u, 70u, 78u}) {
      bool gap = false;
      const auto k0 = static_cast<std::size_t>(std::floor(Dentition::contact_z(static_cast<double>(j)) - 3));
      for (std::size_t k = k0; k < k0 + 6; ++k) gap = gap || d.ct.hu[d.ct.geom.linear(i, j, k)] < 0;
      EXPECT_TRUE(gap) << i << " " << j;
    }
  // Nothing beyond the dentition's reach is cut: the midline, 45 mm out, behind the last tooth.
  const Dentition fresh(true);
  std::size_t changed_far = 0;
  for (std::size_t v = 0; v < d.ct.hu.size(); ++v) {
    if (d.ct.hu[v] == fresh.ct.hu[v]) continue;
    const Vec3 q = d.ct.geom.index_to_lps(static_cast<double>(v % 100), static_cast<double>(v / 100 % 60), static_cast<double>(v / 6000));
    changed_far += std::abs(q[0]) > 30 + kOcclusalCutMarginMm + 1 || q[1] > 50 + kOcclusalCutMarginMm + 1;
  }
  EXPECT_EQ(changed_far, 0u);
}
