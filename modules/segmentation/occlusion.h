// Teeth in occlusion welded across the occlusal table (docs/segmentation.md,
// "Teeth in occlusion: cut at the occlusal plane"): finding the weld, the
// occlusal contact plane, and the cut that parts the upper teeth from the
// lower ones before the image separation runs again.
//
// With the teeth in occlusion on a scan of about 1 mm, the upper crowns can
// be welded to the lower ones across the whole occlusal table: no intensity
// valley and no neck lies between them, the upper teeth join the mandible's
// dense core, and the image separation floods the maxilla. Such a weld shows
// as cheek-teeth columns (along the head's superior axis) that run in dense
// bone, through enamel, from the atlas's zone to well above it.
#pragma once

#include <functional>
#include <vector>

#include "core/types.h"

namespace ms::segmentation {

// Enamel is the densest tissue of the head: 2500-3000 HU against dentine's
// 1600-2000 and cortical bone's 1200-2000 (HU of dental hard tissues on CT:
// enamel ~2500+, dentine ~1600; e.g. the phantom family of another design,
// docs/phantom-independent.md: enamel 2500, dentine 1700, cortex 1550).
// HU before the calibration offset.
constexpr double kEnamelHu = 2000.0;
// A weld is named when its columns cover at least one molar's occlusal
// table: ~10 x 10 mm (first molar crown 11 mm mesio-distal, 10-11 mm
// bucco-lingual; Wheeler's Dental Anatomy, Nelson 2015).
constexpr double kWeldedOcclusionMinMm2 = 100.0;

// Premolars and molars lie 15-35 mm from the mid-sagittal plane (inter-first-
// premolar width ~34 mm, inter-molar width across the buccal cusps ~55-60 mm;
// Bishara, Jakobsen, Treder & Nowak 1997, Am J Orthod Dentofacial Orthop
// 111:401); the incisors and canines lie nearer, where an overbite joins the
// upper incisors to the lower ones with the teeth apart, and the rami and
// coronoids farther. mm at the atlas's scale 1.
constexpr double kPosteriorTeethMm[2] = {15.0, 35.0};

// A lower cheek tooth's crown rises at most ~8.5 mm above its cervical line
// (mandibular first premolar 8.5 mm, molars 7.5-7.7 mm; Wheeler's Dental
// Anatomy, Nelson 2015), and the atlas's zone reaches at least to the
// alveolar crest. A dense run that goes on this far above the zone has
// passed through the lower crown into an upper one (maxillary molar crowns
// ~7 mm): 3.5 mm into it, more than a closing or a partial-volume bridge
// across an occlusal gap adds. mm.
constexpr double kWeldRiseMm = 12.0;

// Where a welded column's upper and lower crowns meet: the middle between its
// lowest and highest enamel voxels (the lower crown's occlusal cap and the
// upper one's, or, through the crowns' side walls, the two cervical lines:
// lower and upper cheek-teeth crowns are of about one height, 7-8.5 mm,
// Wheeler's Dental Anatomy). In the grid's index frame, mm:
// a_mm, b_mm along the two in-plane axes, s_mm along the column axis.
struct OcclusalContact {
  double a_mm = 0, b_mm = 0, s_mm = 0;
};

struct WeldedOcclusion {
  int axis = -1, up = 1;    // the columns' grid axis; +1 when its index grows superiorly
  std::size_t columns = 0;  // welded columns through enamel
  double area_mm2 = 0;      // their area normal to the column axis
  std::vector<OcclusalContact> contacts;  // one per welded column
  bool welded() const { return area_mm2 >= kWeldedOcclusionMinMm2; }
};

// The occlusal contact plane s = c0 + c1 a + c2 b (mm, the grid's index
// frame of WeldedOcclusion), fitted to the welded columns' contacts by
// Huber-weighted least squares (threshold two robust standard deviations):
// single contacts scatter by several mm (a column through a crown's side
// walls, a cusp against a fossa), the plane through ~200 of them lies within
// ~1 mm of the design's contact (the phantom family of another design, `sym`:
// tilt 10 against 8.5 degrees, 0.3 to 1.1 mm above the top of the design's
// lower crowns over the middle half of the columns).
struct OcclusalPlane {
  bool found = false;
  int axis = -1, up = 1;
  double c0 = 0, c1 = 0, c2 = 0;
  double tilt_deg = 0;   // from the grid plane normal to the axis
  double spread_mm = 0;  // robust scale of the contacts about it (1.4826 MAD)
};

// A plane tilted more than this from the grid plane is not an occlusal plane:
// the occlusal plane lies ~9 degrees to the Frankfort plane (Downs 1948), a
// head in the scanner is pitched or rolled by up to ~20 degrees, and the
// columns' axis is within 45 degrees of the head's superior axis.
constexpr double kOcclusalMaxTiltDeg = 35.0;

OcclusalPlane fit_occlusal_plane(const WeldedOcclusion& weld);

// The cut reaches this far (mm) beyond the welded contacts, sideways and
// backwards: a column through a crown's edge may not qualify as welded, and a
// molar crown is ~10-11 mm both mesio-distally and bucco-lingually (Wheeler's
// Dental Anatomy), so it overhangs its outermost welded column by up to half
// that. The ramus's anterior border rises behind the last molar's
// retromolar area; a cut voxel layer there notches it, but cannot part it.
constexpr double kOcclusalCutMarginMm = 5.0;

// Cuts the weld: sets to air (-1000 HU + offset_hu) the voxel just above the
// plane (its centre within one voxel above it) in every column of the
// dentition: within kOcclusalCutMarginMm of the welded contacts' lateral
// extent from the midline, and not more than that behind the rearmost
// welded contact (anterior: the head's anterior axis). Returns the voxels
// changed.
std::size_t cut_at_occlusal_plane(Volume& ct, const OcclusalPlane& plane, const WeldedOcclusion& weld, const Plane& midline,
                                  const Vec3& anterior, double offset_hu);

// ct: the scan (HU); p: the placed atlas's mandible probability at an LPS
// point; superior: the head's superior axis (LPS, unit); midline: the atlas's
// mid-sagittal plane placed in the scan; scale: the atlas's fitted scale. The
// weld is read from the scan, not from a segmentation: whether the teeth
// touch does not depend on what a separation took. A column (along the grid
// axis nearest the superior axis; none when no axis is within 45 degrees)
// within the cheek teeth's band (kPosteriorTeethMm, times scale, from the
// midline) is welded when a run of voxels at least dense_hu holds, going up,
// a voxel of the atlas's zone (p >= kAtlasZoneP), then at least kWeldRiseMm
// of voxels outside it with enamel (kEnamelHu) among them: a crown sitting on
// a lower crown. HU thresholds are before the calibration offset offset_hu.
WeldedOcclusion welded_occlusion(const Volume& ct, const std::function<double(const Vec3&)>& p, const Vec3& superior,
                                 const Plane& midline, double scale, double dense_hu, double offset_hu);

}  // namespace ms::segmentation
