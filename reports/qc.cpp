#include "reports/qc.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <utility>

#include "reports/run_summary.h"

namespace ms::reports {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// The scan's lowest value, HU: air reads -1000 HU by the scale's definition
// (water 0), fat about -100; a head CT holds air around the head or in its
// airways (and scanners pad outside the field of view below it). A scan whose
// lowest value is above -500 HU is not in HU: stored as HU + 1024 or HU +
// 1000 without its offset (NRRD, raw NIfTI; headsq, OpenKBP), every
// threshold reads soft tissue as bone (headsq without --hu-offset: a 157 cm3
// "mandible", Dice 0.53 against its reference). NaN (not read) passes.
constexpr double kMaxLowestHu = -500.0;

// Mandible volume, cm3: the 90 clinical contours of the atlas's training
// scans (OpenKBP folds 1-4) span 29-112 cm3 (median 63); the bounds are
// widened for children (a mandible at 0.65 of adult size has 0.27 of the
// volume) and for the difference between a 250 HU bone boundary and a
// clinical outline.
constexpr double kVolumeCm3[2] = {15.0, 150.0};
// Intercondylar distance (Co_L - Co_R), mm: about 90-125 mm in adults, from
// about 75 mm in young children (docs/qc.md); hard bounds well outside.
constexpr double kBicondylarMm[2] = {60.0, 150.0};
// Menton below the condyles along the head's superior axis, mm: the ramus and
// body make 50-70 mm in adults; a skull vault or an upside-down head gives
// a negative height.
constexpr double kCondyleMentonMm[2] = {25.0, 130.0};
// Atlas fit: openkbp-train folds 1-4 fit at NCC 0.70-0.88, upright ahead of
// mirrored (upside-down or front-back) by at least 0.19.
constexpr double kMinAtlasNcc = 0.6;
// Agreement (soft Dice) of the mask with the atlas's mandible probability.
// The mask is taken within the atlas's zone (docs/segmentation.md), so the
// agreement no longer tells another bone from the mandible; a low one says
// that the zone held little bone (a small or atrophic mandible, or parts
// missing). openkbp-train folds 1-4 agree at 0.43-0.66, every mask with
// Dice >= 0.73 against the clinical contour: a warning below 0.4.
constexpr double kMinAgreement = 0.4;
// Two independent segmentations of one scan (the image's core/watershed
// separation and the atlas's zone) that the atlas could not decide between
// must agree as two observers do: inter-observer Dice of mandible contours on
// CT is about 0.9 (radiotherapy organ-at-risk delineation, e.g. Brouwer et
// al. 2012, Radiother Oncol 104:326); below 0.85 one of them is wrong and
// nothing says which. Random phantom anatomy outside the atlas's range
// (docs/phantom.md, member 8): image ~0.98 against the truth, zone 0.72.
constexpr double kMinSeparationsDice = 0.85;
// Bigonial width (Go_L - Go_R), mm: about 85-105 mm between the bony gonia
// of adults (the soft-tissue go-go of Farkas's anthropometry, ~90-105 mm,
// adds the masseters' few millimetres), about 70-75 mm at six years; hard
// bounds well outside.
constexpr double kBigonialMm[2] = {55.0, 140.0};
// Ramus height (Co - Go, each side), mm: 50-70 mm in adults, ~40 mm in young
// children; a severely hypoplastic ramus (hemifacial microsomia) can be half
// of its side's, so the lower bound is low.
constexpr double kRamusHeightMm[2] = {20.0, 100.0};
// Body length (Go - Me, each side), mm: 75-95 mm in adults, ~60 mm in young
// children.
constexpr double kBodyLengthMm[2] = {40.0, 130.0};
// Gonial angle Co-Go-Me (each side, in 3-D), degrees: the cephalometric
// gonial angle (between the border tangents) is 120-130 in adults (Jarabak's
// norm 130 +- 7), rarely under 105 (low-angle faces) and up to ~140 in
// children and edentulous elders; the 3-D angle between the points runs
// 5-10 degrees below it (headsq's reference: 122.5 / 124.6 against 131.6 /
// 128.0). Below 85 or beyond 160 no mandible's.
constexpr double kGonialAngleDeg[2] = {85.0, 160.0};
// Each bilateral landmark on its own side of the symmetry plane, mm: half the
// narrowest width above (bigonial ~70 mm in children) less a 15 mm shift of a
// side towards the midline in marked asymmetry.
constexpr double kMinSideOffsetMm = 20.0;
// The mandible's symmetry plane against the atlas's mid-sagittal plane (the
// pose that identified the mandible), degrees: a chin deviated by 15 mm turns
// the plane by ~10 degrees over the ~90 mm from the condyles; the atlas's
// pose is fitted to a few degrees.
constexpr double kMaxPlaneToAtlasDeg = 15.0;
// The mandible's plane against the cranium's (an independent mirror plane):
// the same bound; a warning, since the cranial fit has its own failures.
constexpr double kMaxPlaneToCraniumDeg = 15.0;

// Landmarks lie on the surface they were found on: Me on it, Co, Cr, Go and
// Pog at the apex of a quadratic fitted over 4 mm around a surface point,
// which on a faceted surface of a 4-5 mm scan lies up to about a millimetre
// off it (openkbp-train: at most 1.08 mm); twice that.
constexpr double kMaxLandmarkOffSurfaceMm = 2.0;

// Left and right process tips mirrored through the symmetry plane: the
// condyle and the coronoid of a side stand ~25-35 mm apart, so one process
// taken for the other puts the pair 20+ mm apart; marked asymmetry
// (hemimandibular elongation, a hyperplastic condyle) moves a process by
// ~10 mm against its own mandible's plane. A warning: the bound is near what
// a real patient can have.
constexpr double kMaxProcessMismatchMm = 20.0;

// The U shape: each half of the mandible reaches out from the mid-sagittal
// plane at least as far as a bilateral landmark must lie from it
// (kMinSideOffsetMm: half the narrowest bigonial width, ~70 mm in children,
// less a 15 mm shift of the midline in marked asymmetry). A whole mandible's
// halves reach to the condyles' and gonia's lateral surfaces, ~45-65 mm in
// adults (bicondylar width ~90-125 mm, lateral poles beyond); a mandible
// resected behind the symphysis on one side (hemimandibulectomy) or one whose
// side the segmentation lost reaches only the few centimetres of body that
// cross the midline.
constexpr double kMinSideReachMm = kMinSideOffsetMm;
// The two halves' atlas evidence (segmentation::Result::atlas_halves_balance:
// the mask's sum of the atlas's probability on the weaker side of the atlas's
// mid-sagittal plane over the stronger's). In hemifacial microsomia the ramus
// is reduced far more than the body (Chen et al. 2023, Front Pediatr
// 11:1157607, 210 unilateral cases), so even a half without a ramus keeps its
// body, the larger share of a half; below half of the other side a half lacks
// part of its body too: resected, or not segmented. openkbp-train (111
// whole or scan-cut mandibles): 0.81-1.00 (docs/qc.md); pt_47, one of whose
// halves lacks its ramus and posterior body in the clinical contour as in the
// mask, 0.34.
constexpr double kMinHalvesBalance = 0.5;

constexpr double kPi = 3.14159265358979323846;

double angle_deg(const Vec3& a, const Vec3& b) {
  return std::acos(std::clamp(dot(a, b) / (norm(a) * norm(b)), -1.0, 1.0)) * 180.0 / kPi;
}

// The angle between two planes' normals, ignoring their signs, degrees.
double plane_angle_deg(const Vec3& n1, const Vec3& n2) { return std::min(angle_deg(n1, n2), angle_deg(n1, -1.0 * n2)); }

// Of per-side values (NaN: side not measured), the one farther from the
// middle of range: the side that decides the check.
double deciding_side(double l, double r, const double range[2]) {
  if (std::isnan(l)) return r;
  if (std::isnan(r)) return l;
  const double mid = 0.5 * (range[0] + range[1]);
  return std::abs(l - mid) >= std::abs(r - mid) ? l : r;
}

const double kInf = std::numeric_limits<double>::infinity();

// Appends checks to a Qc; a NaN value is "not measured" and passes.
struct CheckList {
  Qc& q;
  void add(const std::string& name, double value, const double range[2], const std::string& unit, const std::string& source,
           bool fatal, const std::string& message) {
    QcCheck c;
    c.name = name, c.value = value, c.lo = range[0], c.hi = range[1], c.unit = unit, c.source = source, c.fatal = fatal;
    c.passed = std::isnan(value) || (value >= range[0] && value <= range[1]);
    c.message = message;
    q.checks.push_back(c);
  }
};

// What a disagreement of the two separations means, with its cause when the
// segmentation found one: upper teeth welded to the lower ones
// (segmentation::Result::welded_occlusion_mm2, docs/segmentation.md).
std::string separations_message(const RunSummary& s) {
  std::string m =
      "the image's separation and the atlas's zone disagree and the atlas did not verify the image's: the mandible's "
      "extent is uncertain";
  if (s.welded_occlusion_mm2 <= 0) return m + " (anatomy beyond the atlas's range, or another bone joined in the image)";
  char area[32];
  std::snprintf(area, sizeof area, "%.0f", s.welded_occlusion_mm2);
  if (s.occlusion_cut_refused)
    return m + ": the upper teeth are welded to the lower ones over " + area +
           " mm2 (teeth in occlusion); cut at the occlusal plane, the image's separation still joined other bone (a joint "
           "space or another contact it does not resolve), and the atlas's zone leaves out the lower crowns; an external "
           "mask (--mask) avoids it";
  return m + ": the upper teeth are welded to the lower ones over " + area +
         " mm2 (teeth in occlusion), so the image's separation took the maxilla and the atlas's zone leaves out the lower "
         "crowns; a scan with the teeth apart (a bite block) or an external mask (--mask) avoids it";
}

// 0. The input's values are CT numbers (HU after --hu-offset).
void input_checks(const RunSummary& s, CheckList& out) {
  const double range[2] = {-kInf, kMaxLowestHu};
  char meaning[256];
  std::snprintf(meaning, sizeof meaning,
                "the scan holds no air (its lowest value is %.0f HU; air reads -1000 HU): its values are not HU, so every "
                "threshold is off; if they are stored as HU + 1024 (air at 0), give --hu-offset -1024",
                s.scan.lowest_hu);
  out.add("lowest_value_hu", s.scan.lowest_hu, range, "HU",
          "air reads -1000 HU (the scale's definition); a head CT holds air around the head or in its airways", true, meaning);
}

// 1. Orientation and identification by the atlas (automatic segmentation
//    only). The margin is measured when both an upright and a mirrored
//    placement fit inside the scan; the agreement when the atlas was used.
void atlas_checks(const RunSummary& s, CheckList& out) {
  if (s.segmentation_method != "auto" || s.atlas.ncc < -1) return;
  const double fit_range[2] = {kMinAtlasNcc, 1.0};
  out.add("atlas_fit_ncc", s.atlas.ncc, fit_range, "", "openkbp-train folds 1-4 (90 scans) fit at 0.70-0.88 (docs/atlas.md)", false,
          "the head does not look like the atlas's heads (or too little of it is in the scan): the mandible was identified "
          "with less certainty");
  const bool both = s.atlas.ncc > -1 && s.atlas.mirrored_ncc >= atlas::kMinFitNcc;
  const double margin_range[2] = {0.0, kInf};
  out.add("orientation_margin", both ? s.atlas.ncc - s.atlas.mirrored_ncc : kNaN, margin_range, "",
          "upright fits beat mirrored ones by at least 0.19 on openkbp-train folds 1-4 (docs/atlas.md)", true,
          "the anatomy fits the atlas better upside down or front to back: the scan's orientation is likely wrong "
          "(set it with --orientation)");
  const double agree_range[2] = {kMinAgreement, 1.0};
  out.add("atlas_agreement", s.atlas.found ? s.atlas_agreement : kNaN, agree_range, "",
          "openkbp-train folds 1-4 agree at 0.43-0.66 (all with Dice >= 0.73 against the clinical contour)", false,
          "the mask holds little of the atlas's mandible: a small or atrophic mandible, or parts of it missing");
  const double sep_range[2] = {kMinSeparationsDice, 1.0};
  out.add("separations_agree", s.image_zone_dice >= 0 ? s.image_zone_dice : kNaN, sep_range, "",
          "inter-observer Dice of mandible contours on CT ~0.9 (Brouwer et al. 2012)", true, separations_message(s));
  out.add("image_agrees_with_zone", s.taken_image_zone_dice >= 0 ? s.taken_image_zone_dice : kNaN, sep_range, "",
          "inter-observer Dice of mandible contours on CT ~0.9 (Brouwer et al. 2012); the Visible Human female blurred "
          "by 0.7 mm (a soft kernel) 0.84, phantoms with the mouth open 0.93-0.94",
          false,
          "the image's separation, which was taken, and the atlas's zone disagree beyond observer variation: the mask "
          "may be thinner or shorter than the bone (a soft reconstruction kernel blurs the thin cortex) or the zone "
          "may hold other bone; check the mask and the processes on the report's views");
}

// The mid-sagittal plane the U shape is measured against: the atlas's, which
// does not depend on the mandible's shape; else the mandible's symmetry plane.
Plane midsagittal_plane(const RunSummary& s) {
  if (s.segmentation_method == "auto" && s.atlas.found) return s.atlas.pose.midsagittal();
  return s.reference.plane;
}

// 2. The U shape: two halves reaching out from the mid-sagittal plane, joined
//    across it by the symphysis (a surface triangle straddling the plane),
//    each holding its share of the atlas's mandible.
void u_shape_checks(const RunSummary& s, CheckList& out) {
  const std::vector<Vec3>& V = s.surface.vertices;
  double reach = kNaN, crossing = kNaN;
  const Plane m = midsagittal_plane(s);
  if (!V.empty() && norm(m.normal) > 0) {
    const Plane pl{m.point, normalized(m.normal)};
    std::vector<double> d(V.size());
    double left = 0, right = 0;
    for (std::size_t i = 0; i < V.size(); ++i) {
      d[i] = pl.signed_distance(V[i]);
      left = std::max(left, d[i]), right = std::max(right, -d[i]);
    }
    reach = std::min(left, right);
    crossing = 0;
    for (const auto& f : s.surface.faces) {
      const double lo = std::min({d[f[0]], d[f[1]], d[f[2]]}), hi = std::max({d[f[0]], d[f[1]], d[f[2]]});
      if (lo <= 0 && hi >= 0) {
        crossing = 1;
        break;
      }
    }
  }
  const double balance_range[2] = {kMinHalvesBalance, 1.0};
  const bool atlas = s.segmentation_method == "auto" && s.atlas.found && s.atlas_halves_balance >= 0;
  out.add("halves_balance", atlas ? s.atlas_halves_balance : kNaN, balance_range, "",
          "a half without its ramus (hemifacial microsomia) keeps its body, the larger share of a half (Chen et al. 2023); "
          "openkbp-train's whole mandibles 0.81-1.00",
          true,
          "one half of the mandible holds far less bone than the other where the atlas expects it: part of a half is "
          "missing (resected) or not segmented, so the two sides cannot be compared");
  const double reach_range[2] = {kMinSideReachMm, kInf};
  out.add("side_reach_mm", reach, reach_range, "mm",
          "each half reaches out from the mid-sagittal plane at least half the narrowest bigonial width (~70 mm, "
          "children) less a 15 mm shift of the midline; whole adult halves reach ~45-65 mm",
          true,
          "one half of the mandible is missing: resected (hemimandibulectomy) or not segmented; there is no other side to "
          "compare with");
  const double crossing_range[2] = {1, 1};
  out.add("symphysis_at_midline", crossing, crossing_range, "",
          "a mandible is one bone across the mid-sagittal plane (the symphysis)", true,
          "no bone crosses the mid-sagittal plane: the symphysis is missing (resected) or not segmented, so the mandible "
          "is in two pieces");
}

// 3. Anatomical plausibility of the volume and of the landmarks' distances
//    and angles (adult and child anthropometry, bounds well outside).
void shape_checks(const RunSummary& s, CheckList& out) {
  out.add("mandible_volume_cm3", s.seg_volume_mm3 / 1000.0, kVolumeCm3, "cm3",
          "clinical contours of 90 OpenKBP adults: 29-112 cm3, widened for children", !s.truncated,
          "the segmented volume is not a mandible's");
  const LandmarkSet& L = s.landmarks.landmarks;
  auto dist = [&](const char* a, const char* b) {
    const Vec3 *p = L.find(a), *q = L.find(b);
    return p && q ? distance(*p, *q) : kNaN;
  };
  double drop = kNaN;
  if (const Vec3* me = L.find("Me")) {
    double h = 0, n = 0;
    for (const char* c : {"Co_L", "Co_R"})
      if (const Vec3* co = L.find(c)) h += dot(*co - *me, s.head_superior()), n += 1;
    if (n > 0) drop = h / n;
  }
  out.add("bicondylar_width_mm", dist("Co_L", "Co_R"), kBicondylarMm, "mm",
          "adult intercondylar width ~90-125 mm, young children from ~75 mm", true, "the condyles are not a mandible's width apart");
  out.add("condyles_above_menton_mm", drop, kCondyleMentonMm, "mm", "ramus and body height: 50-70 mm in adults; menton always below the condyles",
          true, "menton is not below the condyles in the head frame: another bone, or the head read upside down");
  out.add("bigonial_width_mm", dist("Go_L", "Go_R"), kBigonialMm, "mm", "bony bigonial width ~85-105 mm in adults, ~70-75 mm in young children", true,
          "the gonia are not a mandible's width apart");
  out.add("ramus_height_mm", deciding_side(dist("Co_L", "Go_L"), dist("Co_R", "Go_R"), kRamusHeightMm), kRamusHeightMm, "mm",
          "Co-Go 50-70 mm in adults, ~40 mm in young children, lower on a hypoplastic ramus", true,
          "a ramus (condylion to gonion) is not a ramus's height: landmarks on the wrong structure");
  out.add("body_length_mm", deciding_side(dist("Go_L", "Me"), dist("Go_R", "Me"), kBodyLengthMm), kBodyLengthMm, "mm",
          "Go-Me 75-95 mm in adults, ~60 mm in young children", true,
          "a body (gonion to menton) is not a mandibular body's length: landmarks on the wrong structure");
  auto gonial = [&](const char* co, const char* go) {
    const Vec3 *c = L.find(co), *g = L.find(go), *m = L.find("Me");
    return c && g && m ? angle_deg(*c - *g, *m - *g) : kNaN;
  };
  const double surface_range[2] = {0.0, kMaxLandmarkOffSurfaceMm};
  out.add("landmarks_off_surface_mm", L.points.empty() ? kNaN : s.landmarks_off_surface_mm, surface_range, "mm",
          "landmarks are surface points; the quadratic apex fit moves them up to ~1 mm off a coarse scan's surface",
          true, "a landmark lies off the mandible's surface");
  out.add("gonial_angle_deg", deciding_side(gonial("Co_L", "Go_L"), gonial("Co_R", "Go_R"), kGonialAngleDeg), kGonialAngleDeg, "deg",
          "cephalometric gonial angle 120-130 deg in adults (rarely under 105), to ~140 in children and edentulous elders; the "
          "3-D angle Co-Go-Me runs 5-10 deg below it", true,
          "the angle condylion-gonion-menton is not a mandible's: landmarks on the wrong structure");
}

// 4. Agreement of the symmetry plane with independent estimates: the sides of
//    the bilateral landmarks, the atlas's pose and the cranium's mirror plane.
void symmetry_checks(const RunSummary& s, CheckList& out) {
  const Plane& plane = s.reference.plane;  // normal to the patient's left
  double side = kNaN;
  for (const char* name : {"Co", "Cr", "Go"})
    for (const auto& [suffix, sign] : {std::pair<const char*, double>{"_L", 1.0}, {"_R", -1.0}})
      if (const Vec3* p = s.landmarks.landmarks.find(std::string(name) + suffix)) {
        const double d = sign * plane.signed_distance(*p);  // + on the landmark's own side
        side = std::isnan(side) ? d : std::min(side, d);
      }
  const double side_range[2] = {kMinSideOffsetMm, kInf};
  out.add("bilateral_side_mm", side, side_range, "mm",
          "each of Co, Cr, Go at least half the narrowest bigonial width (~70 mm, children) less a 15 mm shift from its "
          "side of the symmetry plane",
          true, "a bilateral landmark lies near or beyond the symmetry plane: landmarks or plane on the wrong structure");
  double mismatch = kNaN;
  for (const char* n : {"Co", "Cr"}) {
    const Vec3 *l = s.landmarks.landmarks.find(std::string(n) + "_L"), *r = s.landmarks.landmarks.find(std::string(n) + "_R");
    if (!l || !r) continue;
    const double d = distance(plane.reflect(*r), *l);
    mismatch = std::isnan(mismatch) ? d : std::max(mismatch, d);
  }
  const double mismatch_range[2] = {0.0, kMaxProcessMismatchMm};
  out.add("process_pair_mismatch_mm", mismatch, mismatch_range, "mm",
          "a side's condyle and coronoid stand ~25-35 mm apart; marked asymmetry moves a process ~10 mm", false,
          "a condylion or coronoid tip lies far from its mirrored partner: one process may have been taken for the other "
          "(or the asymmetry is marked); check the landmarks in the report");
  const double plane_range[2] = {0.0, kMaxPlaneToAtlasDeg};
  const bool atlas = s.segmentation_method == "auto" && s.atlas.found;
  out.add("plane_to_atlas_deg", atlas ? plane_angle_deg(plane.normal, s.atlas.pose.lateral()) : kNaN, plane_range, "deg",
          "a chin deviated by 15 mm turns the mandible's plane by ~10 deg; the atlas's pose is fitted to a few degrees", true,
          "the symmetry plane is far from the mid-sagittal plane of the atlas that identified the mandible: the plane or "
          "the landmarks it was fitted to are wrong");
  const double cranial_range[2] = {0.0, kMaxPlaneToCraniumDeg};
  out.add("plane_to_cranium_deg", s.cranial.found ? s.cranial.angle_to_mandible_plane_deg : kNaN, cranial_range, "deg",
          "the mandible's and the cranium's mirror planes: as plane_to_atlas_deg", false,
          "the mandible's symmetry plane and the cranium's disagree: one of the two fits is doubtful");
}

// "the mandible is cut by the scan's edge", with where when the landmarks
// stage found it ("at its top and back": landmarks::Result::cut_at).
std::string cut_by_the_edge(const RunSummary& s) {
  std::string m = "the mandible is cut by the scan's edge";
  const std::vector<std::string>& at = s.landmarks.cut_at;
  for (std::size_t i = 0; i < at.size(); ++i) m += (i == 0 ? " at its " : i + 1 == at.size() ? " and " : ", ") + at[i];
  return m;
}

// The cause of a failure (docs/qc.md): the shape and landmark checks fail as
// symptoms of something upstream. In order: (0) values that are not HU;
// (1) an atlas check that failed
// names its own cause (orientation, teeth in occlusion); (2) an
// identification the atlas does not support: the scan may not hold the
// mandible at all, so no downstream message ("a half resected") is to be
// believed; (3) a mandible cut by the scan's edge, with the first symptom;
// (4) else the first failed check's meaning.
std::string failure_cause(const RunSummary& s, const Qc& q) {
  const QcCheck* first = nullptr;
  for (const QcCheck& c : q.checks)
    if (!c.passed && c.fatal) {
      first = &c;
      break;
    }
  if (!first) return "";
  if (first->name == "lowest_value_hu") return first->message;  // every threshold is off: nothing downstream is to be believed
  const char* beyond =
      ": the scan may not hold the whole mandible (a brain or neck scan, or a partial field of view) or the head is "
      "unlike the atlas's heads, so the bone measured may not be the mandible";
  // A wrong orientation is read from a flipped fit that looks like a head;
  // when neither way up does, the scan itself is in doubt.
  if (first->name == "orientation_margin" && std::max(s.atlas.ncc, s.atlas.mirrored_ncc) < kMinAtlasNcc) {
    char fit[160];
    std::snprintf(fit, sizeof fit, "the head fits the mandible atlas poorly either way up (NCC %.2f upright, %.2f flipped, below %.2f)",
                  s.atlas.ncc, s.atlas.mirrored_ncc, kMinAtlasNcc);
    return fit + std::string(beyond) + "; if it is a whole head, check its orientation (--orientation)";
  }
  if (first->name == "orientation_margin" || first->name == "separations_agree") return first->message;
  // NCC -1: no pose of the pattern search kept enough of the atlas in the
  // scan to be scored; below -1: not even a coarse one (atlas::ncc).
  if (s.segmentation_method == "auto" && s.atlas.ncc <= -1)
    return std::string("the mandible atlas could not be placed in the scan (too little of a head in the field of view)") + beyond;
  if (s.segmentation_method == "auto" && s.atlas.ncc > -1 && s.atlas.ncc < kMinAtlasNcc) {
    char fit[96];
    std::snprintf(fit, sizeof fit, "the head fits the mandible atlas poorly (NCC %.2f, below %.2f)", s.atlas.ncc, kMinAtlasNcc);
    return fit + std::string(beyond);
  }
  if (s.truncated) return cut_by_the_edge(s) + ", and " + first->message;
  return first->message;
}

}  // namespace

Qc evaluate_qc(const RunSummary& s) {
  Qc q;
  CheckList out{q};
  input_checks(s, out);
  atlas_checks(s, out);
  u_shape_checks(s, out);  // before the landmarks' checks: a missing half explains their failures
  shape_checks(s, out);
  symmetry_checks(s, out);
  // 5. Completeness (warnings).
  int missing = 0;
  for (const std::string& n : landmark_names()) missing += !s.landmarks.landmarks.has(n);
  const double none[2] = {0, 0};
  out.add("landmarks_missing", missing, none, "", "all 8 landmarks of METHOD.md are expected on a whole mandible", false,
          s.saf.score >= 0      ? "landmarks are missing; the SAF score uses the configurations that remain"
          : !s.saf.skipped.empty() ? "landmarks are missing; every SAF configuration needs one of them, so there is no SAF score"
                                   : "landmarks are missing");
  out.add("truncated", s.truncated ? 1 : 0, none, "", "the mandible must lie inside the scan", false,
          cut_by_the_edge(s) + ": scores are not comparable");
  bool fail = false, warn = false;
  for (const QcCheck& c : q.checks)
    if (!c.passed) (c.fatal ? fail : warn) = true;
  q.status = fail ? "fail" : warn ? "warn" : "pass";
  if (fail) q.cause = failure_cause(s, q);
  return q;
}

std::vector<const QcCheck*> Qc::failed() const {
  std::vector<const QcCheck*> f;
  for (const QcCheck& c : checks)
    if (!c.passed) f.push_back(&c);
  return f;
}

}  // namespace ms::reports
