// Implicit head anatomy in the head frame H (see phantom.h). Internal to the
// phantom module.
#pragma once

#include <array>
#include <vector>

#include "core/types.h"
#include "phantom/phantom.h"
#include "phantom/sdf.h"

namespace ms::phantom {

struct Tooth {
  Vec3 base;        // centre of the crown's occlusal end (x, y, z_occlusal)
  Vec3 tangent;     // along the arch (unit, horizontal)
  Vec3 normal;      // bucco-lingual (unit, horizontal)
  double half_md;   // crown half width along the arch
  double half_bl;   // crown half width across the arch
  double crown_h;   // crown height
  double root_len;
  double dir;       // z direction from the occlusal end into the tooth: +1 upper, -1 lower
};

// One half of the mandible (ramus, condyle, coronoid), side s = +1 left, -1 right.
struct SideModel {
  double s = 1;
  Vec3 corner;                 // angle corner in H (x = s*|x|)
  double x_at_corner = 45, x_at_top = 50;  // ramus mid-surface |x| at u = 0 and u = ramus_top
  double ramus_top = 60;
  std::vector<sdf::P2> polygon;  // (f = anterior, u = superior) relative to corner
  sdf::P2 head_fu;             // condylar head centre (f, u)
  Vec3 head_center;            // in H
  Vec3 head_axes;              // half-axes: medio-lateral, antero-posterior, supero-inferior
  sdf::P2 coronoid_fu;         // coronoid tip vertex (f, u)
  // (f, u, n) of a point in H: f anterior, u superior, n lateral offset from the ramus mid-surface.
  Vec3 local(const Vec3& p) const;
  Vec3 to_h(double f, double u, double n) const;
  double mid_x(double f, double u) const;
};

class Anatomy {
 public:
  explicit Anatomy(const PhantomParams& p);

  // Signed distances (mm, negative inside) in the head frame.
  double mandible_bone(const Vec3& p) const;   // body, rami, condyles, coronoids, chin
  double lower_teeth(const Vec3& p, bool crown_only) const;
  double upper_teeth(const Vec3& p, bool crown_only) const;
  double mandible(const Vec3& p) const;        // bone ∪ lower teeth: the ground-truth mask

  // HU at a head-frame point; w = voxel size for partial-volume coverage.
  double hu(const Vec3& p, double w) const;

  // Ground-truth landmarks in the head frame (METHOD.md §2 definitions).
  LandmarkSet landmarks() const;

  // Head-frame centres of metal fillings (empty unless metal).
  const std::vector<Vec3>& metal_centers() const { return metal_; }
  // Head-frame box that contains the mandible.
  Vec3 mandible_lo() const { return mand_lo_; }
  Vec3 mandible_hi() const { return mand_hi_; }

 private:
  struct ArchHit {
    double d;  // horizontal distance to the centreline
    double t;  // normalised arc length 0 (symphysis) .. 1 (angle)
  };
  ArchHit arch_distance(double x, double y) const;
  double body(const Vec3& p) const;
  double ramus(const SideModel& m, const Vec3& p) const;
  double teeth(const std::vector<Tooth>& set, const Vec3& p, bool crown_only) const;
  double z_lower(double t) const { return -76.0 + 20.0 * t; }
  double z_crest(double t) const;
  double z_occlusal(double t) const { return -34.0 + 7.0 * t; }
  // Constructor steps: the teeth on both arches; the mandible's bounding box.
  void place_teeth(const std::vector<sdf::P2>& base);
  void set_mandible_box();
  double skull_base(const Vec3& p) const;
  double maxilla(const Vec3& p) const;
  double spine(const Vec3& p, bool cancellous) const;

  PhantomParams p_;
  std::array<SideModel, 2> side_;  // [0] left, [1] right
  // Body centreline per side, from the symphysis (t = 0) to the angle (t = 1).
  std::array<std::vector<sdf::P2>, 2> arch_;
  std::array<std::vector<double>, 2> arch_t_;
  std::vector<sdf::P2> base_arch_;  // unmodified left half
  std::vector<double> base_t_;
  Vec3 chin_center_, chin_axes_;
  std::vector<Tooth> lower_, upper_;
  std::vector<Vec3> metal_;
  Vec3 mand_lo_, mand_hi_;
};

}  // namespace ms::phantom
