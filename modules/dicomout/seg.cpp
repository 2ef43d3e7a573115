// The mandible mask as a binary DICOM Segmentation on the source CT's frames.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>

#include <dcmtk/dcmfg/fgderimg.h>
#include <dcmtk/dcmfg/fgfracon.h>
#include <dcmtk/dcmfg/fgpixmsr.h>
#include <dcmtk/dcmfg/fgplanor.h>
#include <dcmtk/dcmfg/fgplanpo.h>
#include <dcmtk/dcmseg/segdoc.h>
#include <dcmtk/dcmseg/segment.h>

#include "core/error.h"
#include "dicomout/common.h"

namespace ms::dicomout {

namespace {

// A decimal string value (VR DS: at most 16 characters), as precise as fits.
std::string ds(double v) {
  char b[40];
  for (int digits = 12; digits >= 4; --digits) {
    std::snprintf(b, sizeof b, "%.*g", digits, std::abs(v) < 1e-9 ? 0.0 : v);
    if (std::string(b).size() <= 16) break;
  }
  return b;
}

// The mask's set voxels' index bounding box, [lo, hi] per axis; empty() when none.
struct IndexBox {
  long lo[3] = {0, 0, 0}, hi[3] = {-1, -1, -1};
  bool empty() const { return hi[0] < lo[0]; }
};

IndexBox bounding_box(const Mask& mask) {
  IndexBox b;
  const Geometry& g = mask.geom;
  bool first = true;
  for (std::size_t k = 0; k < g.size[2]; ++k)
    for (std::size_t j = 0; j < g.size[1]; ++j)
      for (std::size_t i = 0; i < g.size[0]; ++i) {
        if (!mask.data[g.linear(i, j, k)]) continue;
        const long v[3] = {static_cast<long>(i), static_cast<long>(j), static_cast<long>(k)};
        for (int a = 0; a < 3; ++a) {
          b.lo[a] = first ? v[a] : std::min(b.lo[a], v[a]);
          b.hi[a] = first ? v[a] : std::max(b.hi[a], v[a]);
        }
        first = false;
      }
  return b;
}

// The columns c of a row where a + c * s rounds into [lo, hi] (one column of
// margin each side; the caller still checks every pixel), clipped to [0, n).
void column_range(double a, double s, long lo, long hi, long n, long* c0, long* c1) {
  if (std::abs(s) < 1e-12) {
    const long v = std::lround(a);
    if (v < lo || v > hi) *c0 = 0, *c1 = -1;
    return;
  }
  double x0 = (lo - 0.5 - a) / s, x1 = (hi + 0.5 - a) / s;
  if (x0 > x1) std::swap(x0, x1);
  *c0 = std::max(*c0, static_cast<long>(std::floor(x0)) - 1);
  *c1 = std::min(*c1, std::min(n - 1, static_cast<long>(std::ceil(x1)) + 1));
}

// The mask sampled on one source frame's pixel grid (row-major, 0/1 bytes),
// nearest neighbour in LPS; returns whether any pixel is set. Only the
// columns of each row that can reach the mask's bounding box are visited.
bool sample_frame(const Mask& mask, const IndexBox& box, const DicomSourceFrame& f, std::vector<Uint8>& pixels) {
  pixels.assign(static_cast<std::size_t>(f.rows) * f.cols, 0);
  const Geometry& g = mask.geom;
  const Vec3 o = g.lps_to_index(f.ipp);
  const Vec3 step_c = g.lps_to_index(f.ipp + f.spacing_i * f.row_dir) - o;  // one column along the row
  const Vec3 step_r = g.lps_to_index(f.ipp + f.spacing_j * f.col_dir) - o;  // one row down
  bool any = false;
  for (unsigned r = 0; r < f.rows && !box.empty(); ++r) {
    long c0 = 0, c1 = static_cast<long>(f.cols) - 1;
    for (int a = 0; a < 3; ++a) column_range(o[a] + r * step_r[a], step_c[a], box.lo[a], box.hi[a], f.cols, &c0, &c1);
    for (long c = std::max(0L, c0); c <= c1; ++c) {
      long idx[3];
      bool inside = true;
      for (int a = 0; a < 3 && inside; ++a) {
        idx[a] = std::lround(o[a] + c * step_c[a] + r * step_r[a]);
        inside = idx[a] >= 0 && idx[a] < static_cast<long>(g.size[a]);
      }
      if (!inside || !mask.data[g.linear(idx[0], idx[1], idx[2])]) continue;
      pixels[static_cast<std::size_t>(r) * f.cols + c] = 1;
      any = true;
    }
  }
  return any;
}

// Segment 1: the mandible (SCT 91609006), category anatomical structure (SCT 91723000).
Uint16 add_mandible_segment(DcmSegmentation& seg, bool mask_from_user, const std::string& version) {
  DcmSegment* segment = nullptr;
  const CodeSequenceMacro category("91723000", "SCT", "Anatomical Structure");
  const CodeSequenceMacro type("91609006", "SCT", "Mandible");
  check(DcmSegment::create(segment, "Mandible", category, type, mask_from_user ? DcmSegTypes::SAT_MANUAL : DcmSegTypes::SAT_AUTOMATIC,
                           mask_from_user ? "" : ("MandiSym " + version).c_str()),
        "segment");
  if (mask_from_user) segment->setSegmentDescription("mask given with --mask");
  Uint16 number = 0;
  check(seg.addSegment(segment, number), "addSegment");
  return number;
}

// Orientation and pixel measures shared by every frame, from the CT's first frame.
void add_shared_groups(DcmSegmentation& seg, const DicomSource& source) {
  const DicomSourceFrame& f = source.frames.front();
  std::unique_ptr<FGPlaneOrientationPatient> ori(FGPlaneOrientationPatient::createMinimal(
      ds(f.row_dir[0]).c_str(), ds(f.row_dir[1]).c_str(), ds(f.row_dir[2]).c_str(), ds(f.col_dir[0]).c_str(),
      ds(f.col_dir[1]).c_str(), ds(f.col_dir[2]).c_str()));
  check(seg.addForAllFrames(*ori), "PlaneOrientationSequence");
  double thickness = 1.0;
  if (source.frames.size() > 1) {
    const Vec3 n = normalized(cross(f.row_dir, f.col_dir));
    thickness = std::abs(dot(n, source.frames[1].ipp - f.ipp));
  }
  FGPixelMeasures pm;
  check(pm.setPixelSpacing((ds(f.spacing_j) + "\\" + ds(f.spacing_i)).c_str()), "PixelSpacing");
  check(pm.setSliceThickness(ds(thickness).c_str()), "SliceThickness");
  check(seg.addForAllFrames(pm), "PixelMeasuresSequence");
  const std::string dims = new_uid();
  IODMultiframeDimensionModule& dm = seg.getDimensions();
  check(dm.addDimensionIndex(DCM_ReferencedSegmentNumber, dims.c_str(), DCM_SegmentIdentificationSequence, "ReferencedSegmentNumber"),
        "dimension index");
  check(dm.addDimensionIndex(DCM_ImagePositionPatient, dims.c_str(), DCM_PlanePositionSequence, "ImagePositionPatient"), "dimension index");
}

// One frame: its position, its position in the stack, and the CT instance it was derived from.
void add_seg_frame(DcmSegmentation& seg, Uint16 segment, const DicomSource& source, std::size_t k, std::vector<Uint8>& pixels) {
  const DicomSourceFrame& f = source.frames[k];
  FGPlanePosPatient* pos = FGPlanePosPatient::createMinimal(ds(f.ipp[0]).c_str(), ds(f.ipp[1]).c_str(), ds(f.ipp[2]).c_str());
  FGFrameContent* content = new FGFrameContent();
  check(content->setDimensionIndexValues(segment, 0), "DimensionIndexValues");
  check(content->setDimensionIndexValues(static_cast<Uint32>(k + 1), 1), "DimensionIndexValues");
  ImageSOPInstanceReferenceMacro ref;
  check(ref.setReferencedSOPClassUID(source.sop_class_uid.c_str()), "ReferencedSOPClassUID");
  check(ref.setReferencedSOPInstanceUID(f.sop_instance_uid.c_str()), "ReferencedSOPInstanceUID");
  if (f.frame > 0 || (source.frames.size() > 1 && source.frames[0].file == source.frames[1].file))  // a multi-frame CT
    check(ref.addReferencedFrameNumber(static_cast<Uint16>(f.frame + 1)), "ReferencedFrameNumber");
  FGDerivationImage* derivation = DcmSegmentation::createDerivationImageFG({ref}, "MandiSym mandible segmentation");
  if (!derivation) throw Error(ExitCode::Internal, "DICOM SEG: derivation image group for frame " + std::to_string(k + 1));
  OFVector<FGBase*> groups{pos, content, derivation};
  const OFCondition c = seg.addFrame(pixels.data(), segment, groups);
  for (FGBase* g : groups) delete g;
  check(c, "frame " + std::to_string(k + 1));
}

}  // namespace

Written write_seg(const Mask& mask, const DicomSource& source, const StudyContext& study, bool mask_from_user, const std::string& path) {
  if (source.frames.empty()) throw Error(ExitCode::Internal, "DICOM SEG: the source series has no frames");
  const DicomSourceFrame& first = source.frames.front();
  const IODGeneralEquipmentModule::EquipmentInfo equipment("MandiSym", "MandiSym", "mandisym", study.tool_version.c_str());
  ContentIdentificationMacro content("1", "MANDIBLE", "Mandible segmentation", "MandiSym^Software");
  DcmSegmentation* raw = nullptr;
  check(DcmSegmentation::createBinarySegmentation(raw, static_cast<Uint16>(first.rows), static_cast<Uint16>(first.cols), equipment, content),
        "createBinarySegmentation");
  std::unique_ptr<DcmSegmentation> seg(raw);
  check(seg->importFromSourceImage(source.first_file.c_str()), "import patient, study and frame of reference from " + source.first_file);
  check(seg->getFrameOfReference().setFrameOfReferenceUID(source.frame_of_reference_uid.c_str()), "FrameOfReferenceUID");
  check(seg->getSeries().setSeriesNumber("9701"), "SeriesNumber");
  const Uint16 segment = add_mandible_segment(*seg, mask_from_user, study.tool_version);
  add_shared_groups(*seg, source);
  std::vector<Uint8> pixels;
  std::size_t frames = 0;
  const IndexBox box = bounding_box(mask);
  for (std::size_t k = 0; k < source.frames.size(); ++k)
    if (sample_frame(mask, box, source.frames[k], pixels)) {
      add_seg_frame(*seg, segment, source, k, pixels);
      ++frames;
    }
  if (frames == 0) throw Error(ExitCode::Internal, "DICOM SEG: the mask touches none of the CT's frames");
  DcmFileFormat file;
  check(seg->writeDataset(*file.getDataset()), "SEG dataset");
  DcmDataset& dataset = *file.getDataset();
  apply_output_series(dataset, study, source, "SEG", 9701, "MandiSym mandible segmentation");
  reference_source_series(dataset, source);
  return save(file, path, "SEG");
}

}  // namespace ms::dicomout
