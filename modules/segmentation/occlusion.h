// Teeth in occlusion welded across the occlusal table (docs/segmentation.md,
// "Teeth in occlusion"): the cause the quality gate names when the image
// separation took other bone.
//
// With the teeth in occlusion on a scan of about 1 mm, the upper crowns can
// be welded to the lower ones across the whole occlusal table: no intensity
// valley and no neck lies between them, the upper teeth join the mandible's
// dense core, and the image separation floods the maxilla. Such a weld shows
// as columns of the dentition (along the head's superior axis) that run in
// dense bone, through enamel, from where most training mandibles lie (the
// atlas's zone) to beyond every one.
#pragma once

#include <functional>

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

struct WeldedOcclusion {
  std::size_t columns = 0;  // welded columns through enamel
  double area_mm2 = 0;      // their area normal to the column axis
  bool welded() const { return area_mm2 >= kWeldedOcclusionMinMm2; }
};

// ct: the scan (HU); mask: the image separation's mask on ct's grid; p: the
// placed atlas's mandible probability at an LPS point; superior: the head's
// superior axis (LPS, unit); midline: the atlas's mid-sagittal plane placed in
// the scan; scale: the atlas's fitted scale. A column (along the grid axis
// nearest the superior axis; none when no axis is within 45 degrees) within
// the cheek teeth's band (kPosteriorTeethMm, times scale, from the midline)
// is welded when a run of mask voxels at least dense_hu holds, going up, a
// voxel of the atlas's zone (p >= kAtlasZoneP), then at least kWeldRiseMm of
// voxels outside it with enamel (kEnamelHu) among them: a crown sitting on a
// lower crown. HU thresholds are before the calibration offset offset_hu.
WeldedOcclusion welded_occlusion(const Volume& ct, const Mask& mask, const std::function<double(const Vec3&)>& p,
                                 const Vec3& superior, const Plane& midline, double scale, double dense_hu, double offset_hu);

}  // namespace ms::segmentation
