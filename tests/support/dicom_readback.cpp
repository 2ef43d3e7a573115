#include "tests/support/dicom_readback.h"

#include <cmath>
#include <functional>
#include <vector>

#include "core/files.h"
#include "core/json_text.h"

#include <gtest/gtest.h>

namespace ms::test {

namespace {

ms::Vec3 triple(DcmItem& item, const DcmTagKey& tag, int first) {
  ms::Vec3 v{};
  for (int a = 0; a < 3; ++a) {
    Float64 x = 0;
    EXPECT_TRUE(item.findAndGetFloat64(tag, x, first + a).good()) << DcmTag(tag).getTagName();
    v[a] = x;
  }
  return v;
}

}  // namespace

DcmItem& nested(DcmItem& item, const DcmTagKey& seq, unsigned index, const DcmTagKey& inner) {
  DcmItem* a = nullptr;
  EXPECT_TRUE(item.findAndGetSequenceItem(seq, a, static_cast<int>(index)).good()) << DcmTag(seq).getTagName();
  DcmItem* b = nullptr;
  EXPECT_TRUE(a && a->findAndGetSequenceItem(inner, b, 0).good()) << DcmTag(inner).getTagName();
  return *b;
}

SegComparison compare_seg_with_mask(const std::string& seg_file, const ms::Mask& mask) {
  SegComparison c;
  DcmFileFormat ff;
  EXPECT_TRUE(ff.loadFile(seg_file.c_str()).good());
  DcmDataset& ds = *ff.getDataset();
  Uint16 rows = 0, cols = 0;
  Sint32 frames = 0;
  ds.findAndGetUint16(DCM_Rows, rows);
  ds.findAndGetUint16(DCM_Columns, cols);
  ds.findAndGetSint32(DCM_NumberOfFrames, frames);
  DcmItem& ori = nested(ds, DCM_SharedFunctionalGroupsSequence, 0, DCM_PlaneOrientationSequence);
  DcmItem& meas = nested(ds, DCM_SharedFunctionalGroupsSequence, 0, DCM_PixelMeasuresSequence);
  const ms::Vec3 row_dir = triple(ori, DCM_ImageOrientationPatient, 0), col_dir = triple(ori, DCM_ImageOrientationPatient, 3);
  Float64 sp_rows = 0, sp_cols = 0;
  meas.findAndGetFloat64(DCM_PixelSpacing, sp_rows, 0);
  meas.findAndGetFloat64(DCM_PixelSpacing, sp_cols, 1);
  const Uint8* bits = nullptr;
  unsigned long nbytes = 0;
  EXPECT_TRUE(ds.findAndGetUint8Array(DCM_PixelData, bits, &nbytes).good());
  const std::size_t plane = static_cast<std::size_t>(rows) * cols;
  EXPECT_GE(nbytes * 8, plane * frames);
  const ms::Geometry& g = mask.geom;
  for (Sint32 f = 0; f < frames; ++f) {
    DcmItem& pos = nested(ds, DCM_PerFrameFunctionalGroupsSequence, f, DCM_PlanePositionSequence);
    const ms::Vec3 ipp = triple(pos, DCM_ImagePositionPatient, 0);
    ++c.frames;
    for (Uint16 r = 0; r < rows; ++r)
      for (Uint16 col = 0; col < cols; ++col) {
        const std::size_t bit = f * plane + static_cast<std::size_t>(r) * cols + col;
        const bool seg_on = (bits[bit / 8] >> (bit % 8)) & 1;  // binary SEG: first pixel in the lowest bit
        const ms::Vec3 p = ipp + (col * sp_cols) * row_dir + (r * sp_rows) * col_dir;
        const ms::Vec3 q = g.lps_to_index(p);
        long idx[3];
        bool inside = true;
        for (int a = 0; a < 3; ++a) {
          idx[a] = std::lround(q[a]);
          inside = inside && idx[a] >= 0 && idx[a] < static_cast<long>(g.size[a]);
        }
        const bool mask_on = inside && mask.data[g.linear(idx[0], idx[1], idx[2])];
        c.set_pixels += seg_on;
        c.mismatches += seg_on != mask_on;
      }
  }
  return c;
}


namespace {

void numbers_in(const Json& v, std::vector<double>& out) {
  if (v.is_number()) out.push_back(v.get<double>());
  if (v.is_structured())
    for (const auto& x : v) numbers_in(x, out);
}

// Every content item of the SR tree, depth first.
void walk(DcmItem& item, const std::function<void(DcmItem&)>& visit) {
  DcmSequenceOfItems* seq = nullptr;
  if (item.findAndGetSequence(DCM_ContentSequence, seq).bad() || !seq) return;
  for (unsigned long k = 0; k < seq->card(); ++k) {
    DcmItem* child = seq->getItem(k);
    visit(*child);
    walk(*child, visit);
  }
}

}  // namespace

std::string sr_numbers_mismatching_results(const std::string& sr_file, const std::string& results_json) {
  const Json results = parse_json(read_file_or_empty(results_json));
  std::vector<double> numbers;
  numbers_in(results, numbers);
  std::vector<Vec3> landmarks;
  for (const auto& [name, p] : results.at("landmarks").items())
    if (p.is_array()) landmarks.push_back({p[0].get<double>(), p[1].get<double>(), p[2].get<double>()});
  DcmFileFormat ff;
  if (ff.loadFile(sr_file.c_str()).bad()) return "cannot read " + sr_file;
  std::string bad;
  std::size_t nums = 0, points = 0;
  walk(*ff.getDataset(), [&](DcmItem& it) {
    OFString type;
    it.findAndGetOFString(DCM_ValueType, type);
    if (type == "NUM") {
      DcmItem* mv = nullptr;
      OFString text;
      if (it.findAndGetSequenceItem(DCM_MeasuredValueSequence, mv, 0).bad() || mv->findAndGetOFString(DCM_NumericValue, text).bad()) return;
      const double x = std::stod(text.c_str());
      ++nums;
      bool hit = false;
      for (double y : numbers) hit = hit || std::abs(x - y) <= 1e-9 + 1e-9 * std::abs(y);
      if (!hit) bad += "NUM " + std::string(text.c_str()) + " is no number of results.json\n";
    } else if (type == "SCOORD3D") {
      Float32 c[3] = {0, 0, 0};
      for (int a = 0; a < 3; ++a) it.findAndGetFloat32(DCM_GraphicData, c[a], a);
      ++points;
      bool hit = false;
      for (const Vec3& l : landmarks) hit = hit || (std::abs(c[0] - l[0]) < 1e-3 && std::abs(c[1] - l[1]) < 1e-3 && std::abs(c[2] - l[2]) < 1e-3);
      if (!hit) bad += "SCOORD3D point (" + std::to_string(c[0]) + ", " + std::to_string(c[1]) + ", " + std::to_string(c[2]) + ") is no landmark\n";
    }
  });
  if (nums < kMinSrNumbers) bad += "only " + std::to_string(nums) + " NUM items\n";
  if (points != landmarks.size()) bad += std::to_string(points) + " SCOORD3D points for " + std::to_string(landmarks.size()) + " landmarks\n";
  return bad;
}

}  // namespace ms::test
