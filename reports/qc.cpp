#include "reports/qc.h"

#include <cmath>
#include <limits>

#include "reports/run_summary.h"

namespace ms::reports {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

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

}  // namespace

std::vector<const QcCheck*> Qc::failed() const {
  std::vector<const QcCheck*> f;
  for (const QcCheck& c : checks)
    if (!c.passed) f.push_back(&c);
  return f;
}

Qc evaluate_qc(const RunSummary& s) {
  Qc q;
  auto add = [&](const std::string& name, double value, const double range[2], const std::string& unit, const std::string& source,
                 bool fatal, const std::string& message) {
    QcCheck c;
    c.name = name, c.value = value, c.lo = range[0], c.hi = range[1], c.unit = unit, c.source = source, c.fatal = fatal;
    c.passed = std::isnan(value) || (value >= range[0] && value <= range[1]);
    c.message = message;
    q.checks.push_back(c);
  };
  const double inf = std::numeric_limits<double>::infinity();
  // 1. Orientation and identification by the atlas (automatic segmentation
  //    only). The margin is measured when both an upright and a mirrored
  //    placement fit inside the scan; the agreement when the atlas was used.
  if (s.segmentation_method == "auto" && s.atlas.ncc >= -1) {
    const double fit_range[2] = {kMinAtlasNcc, 1.0};
    add("atlas_fit_ncc", s.atlas.ncc, fit_range, "", "openkbp-train folds 1-4 (90 scans) fit at 0.70-0.88 (docs/atlas.md)", false,
        "the head does not look like the atlas's heads (or too little of it is in the scan): the mandible was identified "
        "with less certainty");
    const bool both = s.atlas.ncc > -1 && s.atlas.mirrored_ncc >= atlas::kMinFitNcc;
    const double margin_range[2] = {0.0, inf};
    add("orientation_margin", both ? s.atlas.ncc - s.atlas.mirrored_ncc : kNaN, margin_range, "",
        "upright fits beat mirrored ones by at least 0.19 on openkbp-train folds 1-4 (docs/atlas.md)", true,
        "the anatomy fits the atlas better upside down or front to back: the scan's orientation is likely wrong "
        "(set it with --orientation)");
    const double agree_range[2] = {kMinAgreement, 1.0};
    add("atlas_agreement", s.atlas.found ? s.atlas_agreement : kNaN, agree_range, "",
        "openkbp-train folds 1-4 agree at 0.43-0.66 (all with Dice >= 0.73 against the clinical contour)", false,
        "the mask holds little of the atlas's mandible: a small or atrophic mandible, or parts of it missing");
    const double sep_range[2] = {kMinSeparationsDice, 1.0};
    add("separations_agree", s.image_zone_dice >= 0 ? s.image_zone_dice : kNaN, sep_range, "",
        "inter-observer Dice of mandible contours on CT ~0.9 (Brouwer et al. 2012)", true,
        "the image's separation and the atlas's zone disagree and the atlas did not verify the image's: the mandible's "
        "extent is uncertain (anatomy beyond the atlas's range, or another bone joined in the image)");
  }
  // 2. Anatomical plausibility.
  add("mandible_volume_cm3", s.seg_volume_mm3 / 1000.0, kVolumeCm3, "cm3",
      "clinical contours of 90 OpenKBP adults: 29-112 cm3, widened for children", !s.truncated,
      "the segmented volume is not a mandible's");
  const Vec3* col = s.landmarks.landmarks.find("Co_L");
  const Vec3* cor = s.landmarks.landmarks.find("Co_R");
  const Vec3* me = s.landmarks.landmarks.find("Me");
  double width = kNaN, drop = kNaN;
  if (col && cor) width = distance(*col, *cor);
  if (me && (col || cor)) {
    const Vec3 up = s.head_superior();
    double h = 0, n = 0;
    for (const Vec3* c : {col, cor})
      if (c) h += dot(*c - *me, up), n += 1;
    drop = h / n;
  }
  add("bicondylar_width_mm", width, kBicondylarMm, "mm", "adult intercondylar width ~90-125 mm, young children from ~75 mm", true,
      "the condyles are not a mandible's width apart");
  add("condyles_above_menton_mm", drop, kCondyleMentonMm, "mm",
      "ramus and body height: 50-70 mm in adults; menton always below the condyles", true,
      "menton is not below the condyles in the head frame: another bone, or the head read upside down");
  // 3. Completeness (warnings).
  int missing = 0;
  for (const std::string& n : landmark_names()) missing += !s.landmarks.landmarks.has(n);
  const double none[2] = {0, 0};
  add("landmarks_missing", missing, none, "", "all 8 landmarks of METHOD.md are expected on a whole mandible", false,
      "landmarks are missing; the SAF score uses the configurations that remain");
  add("truncated", s.truncated ? 1 : 0, none, "", "the mandible must lie inside the scan", false,
      "the mandible is cut by the scan's edge: scores are not comparable");
  bool fail = false, warn = false;
  for (const QcCheck& c : q.checks)
    if (!c.passed) (c.fatal ? fail : warn) = true;
  q.status = fail ? "fail" : warn ? "warn" : "pass";
  return q;
}

}  // namespace ms::reports
