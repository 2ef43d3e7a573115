// Everything one `mandisym run` produced, gathered for the writers. Plain
// value types from each stage; the writers never call back into the stages.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "asymmetry/measures.h"
#include "asymmetry/saf.h"
#include "asymmetry/srd.h"
#include "core/types.h"
#include "landmarks/landmarks.h"
#include "landmarks/palate.h"
#include "reports/qc.h"
#include "reference/reference.h"
#include "segmentation/segmentation.h"
#include "surface/surface.h"

namespace ms::reports {

struct RunSummary {
  std::string tool_version;
  std::string command_line;
  ScanInfo scan;
  Geometry grid;
  std::string segmentation_method;
  std::size_t seg_voxels = 0;
  double seg_volume_mm3 = 0;
  bool truncated = false;
  double seg_threshold_hu = 0, seg_offset_hu = 0, seg_separation_mm = 0;
  std::string seg_marker_source;
  // The mandible atlas placed in the scan (docs/atlas.md; ncc < -1: not
  // fitted) and the mask's agreement with it (-1: not computed).
  atlas::Fit atlas;
  double atlas_agreement = -1;
  double atlas_halves_balance = -1;  // segmentation::Result::atlas_halves_balance
  double image_zone_dice = -1;  // segmentation::Result::image_zone_dice
  double taken_image_zone_dice = -1;  // segmentation::Result::taken_image_zone_dice
  double welded_occlusion_mm2 = 0;  // segmentation::Result::welded_occlusion_mm2
  bool occlusion_cut_refused = false;  // segmentation::Result::occlusion_cut_refused
  surface::MeshStats mesh;
  Mesh surface;  // the final mandible surface (LPS mm), for the report's interactive viewer
  double closing_mm = 0;          // closing before meshing (0 = none)
  int genus_before_closing = -1;  // genus of the unclosed surface when automatic closing ran
  bool closing_plugs_only = false;  // the closing was kept only where it removed handles
  std::size_t vertices_pulled = 0;  // vertices held to one voxel of the mask's boundary (surface.md)
  std::size_t voxels_joining = 0;   // voxels joining mask pieces that touch only diagonally (surface.md)
  landmarks::Result landmarks;
  double landmarks_off_surface_mm = 0;  // the largest distance of a landmark from `surface` (QC)
  landmarks::PalatalPlane palate;  // the palatal plane's fit (found = false: not found or rejected, palate.reason)
  landmarks::HeadFrame head_frame;  // the frame used: palatal plane, mandible atlas or scan axes
  Vec3 head_superior() const { return head_frame.superior; }
  reference::Result reference;
  reference::CranialResult cranial;  // found = false when not fitted (reason) or --no-cranial
  asymmetry::SafResult saf;
  std::map<std::string, double> saf_regions;
  // The SAF map with each mirror pair's value on the side that lies beyond its
  // mirror image (asymmetry::sided_map), per output vertex, and its regional means.
  std::vector<double> saf_sided;
  std::map<std::string, double> saf_regions_sided;
  // Its lateral form (asymmetry::lateral_map): regional means, > 0 on the
  // larger side; the largest names the region and side.
  std::map<std::string, double> saf_regions_lateral;
  asymmetry::SrdResult srd;
  asymmetry::MirrorResult mirror;
  std::map<std::string, asymmetry::Bilateral> bilateral;
  std::vector<std::pair<std::string, double>> timings_s;  // in stage order
  double total_s = 0;
  std::vector<std::string> warnings;
  std::map<std::string, std::string> parameters;
  Qc qc;  // evaluate_qc(*this), once everything above is set
};

}  // namespace ms::reports
