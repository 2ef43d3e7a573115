// The DICOM SEG read back with plain dcmdata (not the dcmseg classes that
// wrote it) and compared with the mask voxel for voxel in LPS world
// coordinates, on the real sample series and on a re-oriented copy.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dctk.h>

#include "dicomout/dicomout.h"
#include "io/volume_io.h"
#include "tests/support/dicom_forge.h"
#include "tests/support/dicom_readback.h"

namespace fs = std::filesystem;

namespace {

using ms::operator+;
using ms::operator*;

const fs::path kSample = fs::path(MANDISYM_SOURCE_DIR) / "sample_dicom" / "symmetric" / "dicom";

fs::path scratch(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("mandisym_seg_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

// The run's mask of the sample (made once by the binary).
const ms::Mask& sample_mask() {
  static const ms::Mask mask = [] {
    const fs::path out = scratch("run");
    const std::string cmd = std::string(MANDISYM_BINARY) + " run " + kSample.string() + " -o " + out.string() + " --quiet --no-figures";
    const int rc = std::system(cmd.c_str());
    EXPECT_EQ(rc, 0) << cmd;
    return ms::io::read_mask((out / "mandible_mask.nii.gz").string());
  }();
  return mask;
}

std::string dump(const fs::path& file, const std::string& tool) {
  const std::string out = (file.parent_path() / (tool + ".txt")).string();
  std::system((tool + " " + file.string() + " > " + out + " 2>&1").c_str());
  std::ifstream in(out);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

}  // namespace

TEST(Seg, FramesEqualTheMaskVoxelForVoxelInWorldCoordinates) {
  const ms::Mask& mask = sample_mask();
  const ms::io::LoadedScan scan = ms::io::read_scan(kSample.string());
  ASSERT_TRUE(scan.dicom.has_value());
  const fs::path dir = scratch("world");
  const auto study = ms::dicomout::read_study_context(*scan.dicom, false, "test");
  const auto w = ms::dicomout::write_seg(mask, *scan.dicom, study, false, (dir / "seg.dcm").string());
  EXPECT_EQ(w.sop_class_uid, UID_SegmentationStorage);
  const ms::test::SegComparison c = ms::test::compare_seg_with_mask(w.path, mask);
  EXPECT_GT(c.frames, 10u);
  EXPECT_EQ(c.mismatches, 0u);
  // The frames left out are empty: every mask voxel is in a frame.
  EXPECT_EQ(c.set_pixels, mask.count());
}

TEST(Seg, CarriesTheStudyFrameOfReferenceAndTheMandibleCode) {
  const ms::io::LoadedScan scan = ms::io::read_scan(kSample.string());
  const fs::path dir = scratch("codes");
  const auto study = ms::dicomout::read_study_context(*scan.dicom, false, "test");
  const auto w = ms::dicomout::write_seg(sample_mask(), *scan.dicom, study, false, (dir / "seg.dcm").string());
  DcmFileFormat ff;
  ASSERT_TRUE(ff.loadFile(w.path.c_str()).good());
  DcmDataset& ds = *ff.getDataset();
  OFString v;
  ds.findAndGetOFString(DCM_StudyInstanceUID, v);
  EXPECT_EQ(v.c_str(), scan.dicom->study_uid);
  ds.findAndGetOFString(DCM_FrameOfReferenceUID, v);
  EXPECT_EQ(v.c_str(), scan.dicom->frame_of_reference_uid);
  ds.findAndGetOFString(DCM_SeriesInstanceUID, v);
  EXPECT_NE(v.c_str(), scan.dicom->series_uid);
  DcmItem& type = ms::test::nested(ds, DCM_SegmentSequence, 0, DCM_SegmentedPropertyTypeCodeSequence);
  type.findAndGetOFString(DCM_CodeValue, v);
  EXPECT_EQ(v, "91609006");
  DcmItem* segment = nullptr;
  ds.findAndGetSequenceItem(DCM_SegmentSequence, segment, 0);
  segment->findAndGetOFString(DCM_SegmentAlgorithmType, v);
  EXPECT_EQ(v, "AUTOMATIC");
  // Every frame derives from a CT instance of the source series.
  DcmItem& deriv = ms::test::nested(ds, DCM_PerFrameFunctionalGroupsSequence, 0, DCM_DerivationImageSequence);
  DcmItem* src = nullptr;
  ASSERT_TRUE(deriv.findAndGetSequenceItem(DCM_SourceImageSequence, src, 0).good());
  src->findAndGetOFString(DCM_ReferencedSOPInstanceUID, v);
  bool found = false;
  for (const auto& f : scan.dicom->frames) found = found || f.sop_instance_uid == v.c_str();
  EXPECT_TRUE(found) << v;
}

TEST(Seg, DeidentifiedKeepsTheUidsAndEmptiesThePatient) {
  const ms::io::LoadedScan scan = ms::io::read_scan(kSample.string());
  const fs::path dir = scratch("deid");
  const auto study = ms::dicomout::read_study_context(*scan.dicom, true, "test");
  const auto w = ms::dicomout::write_seg(sample_mask(), *scan.dicom, study, true, (dir / "seg.dcm").string());
  DcmFileFormat ff;
  ASSERT_TRUE(ff.loadFile(w.path.c_str()).good());
  DcmDataset& ds = *ff.getDataset();
  OFString v;
  EXPECT_TRUE(ds.findAndGetOFString(DCM_PatientName, v).good());  // type 2: present, empty
  EXPECT_TRUE(v.empty()) << v;
  ds.findAndGetOFString(DCM_PatientID, v);
  EXPECT_TRUE(v.empty()) << v;
  ds.findAndGetOFString(DCM_StudyDate, v);
  EXPECT_TRUE(v.empty()) << v;
  EXPECT_FALSE(ds.tagExists(DCM_StudyDescription));
  ds.findAndGetOFString(DCM_PatientIdentityRemoved, v);
  EXPECT_EQ(v, "YES");
  ds.findAndGetOFString(DCM_StudyInstanceUID, v);
  EXPECT_EQ(v.c_str(), scan.dicom->study_uid);
  DcmItem* segment = nullptr;
  ds.findAndGetSequenceItem(DCM_SegmentSequence, segment, 0);
  segment->findAndGetOFString(DCM_SegmentAlgorithmType, v);
  EXPECT_EQ(v, "MANUAL");  // mask_from_user
}

TEST(Seg, ParsesAndHasNoIodErrors) {
  const ms::io::LoadedScan scan = ms::io::read_scan(kSample.string());
  const fs::path dir = scratch("iod");
  const auto study = ms::dicomout::read_study_context(*scan.dicom, false, "test");
  const auto w = ms::dicomout::write_seg(sample_mask(), *scan.dicom, study, false, (dir / "seg.dcm").string());
  if (std::system("command -v dcmdump > /dev/null") == 0) EXPECT_NE(dump(w.path, "dcmdump").find("SegmentSequence"), std::string::npos);
  if (std::system("command -v dciodvfy > /dev/null") != 0) GTEST_SKIP() << "dciodvfy (dicom3tools) not installed";
  const std::string report = dump(w.path, "dciodvfy");
  EXPECT_EQ(report.find("Error"), std::string::npos) << report;
}

// The sample stored as sagittal slices (a different ImageOrientationPatient
// and slice axis): the SEG still holds the run's mask exactly.
TEST(Seg, SagittalSeriesGivesTheMaskExactly) {
  const ms::io::LoadedScan axial = ms::io::read_scan(kSample.string());
  const ms::Geometry& g = axial.volume.geom;
  ms::Volume sag;
  const int perm[3] = {1, 2, 0};  // new index axis a is old axis perm[a]
  for (int a = 0; a < 3; ++a) {
    sag.geom.size[a] = g.size[perm[a]];
    sag.geom.spacing[a] = g.spacing[perm[a]];
    for (int r = 0; r < 3; ++r) sag.geom.direction[r * 3 + a] = g.direction[r * 3 + perm[a]];
  }
  sag.geom.origin = g.origin;
  sag.hu.resize(g.voxel_count());
  for (std::size_t k = 0; k < g.size[2]; ++k)
    for (std::size_t j = 0; j < g.size[1]; ++j)
      for (std::size_t i = 0; i < g.size[0]; ++i) sag.hu[sag.geom.linear(j, k, i)] = axial.volume.hu[g.linear(i, j, k)];
  const fs::path dir = scratch("sagittal");
  ms::io::DicomSeriesSpec spec;
  ms::io::write_dicom_series(sag, spec, (dir / "dicom").string());
  const std::string cmd = std::string(MANDISYM_BINARY) + " run " + (dir / "dicom").string() + " -o " + (dir / "out").string() +
                          " --quiet --no-figures --dicom";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  const ms::Mask mask = ms::io::read_mask((dir / "out" / "mandible_mask.nii.gz").string());
  const ms::io::LoadedScan scan = ms::io::read_scan((dir / "dicom").string());
  EXPECT_NE(scan.dicom->frames.front().row_dir, axial.dicom->frames.front().row_dir);
  const ms::test::SegComparison c = ms::test::compare_seg_with_mask((dir / "out" / "dicom" / "seg.dcm").string(), mask);
  EXPECT_GT(c.frames, 10u);
  EXPECT_EQ(c.mismatches, 0u);
  EXPECT_EQ(c.set_pixels, mask.count());
  // The same mandible as the axial run: the mask volumes agree.
  EXPECT_NEAR(static_cast<double>(mask.count()), static_cast<double>(sample_mask().count()), 0.01 * sample_mask().count());
}

// An Enhanced (multi-frame) CT stored top to bottom: every SEG frame points at
// the one CT instance and its own frame number, and holds the mask exactly.
TEST(Seg, EnhancedMultiFrameCtIsReferencedFrameByFrame) {
  const fs::path dir = scratch("enhanced");
  ms::testing::EnhancedSpec e;
  for (int k = 0; k < 12; ++k) {
    e.ipps.push_back({-5, 3, 40.0 - 1.5 * k});
    e.frames.emplace_back(e.base.rows * e.base.cols, ms::testing::stored_for(e.base, 0));
  }
  ms::testing::write_enhanced((dir / "enhanced.dcm").string(), e);
  const ms::io::LoadedScan scan = ms::io::read_scan(dir.string());
  ASSERT_TRUE(scan.dicom.has_value());
  ASSERT_EQ(scan.dicom->frames.size(), 12u);
  ms::Mask mask{scan.volume.geom, std::vector<std::uint8_t>(scan.volume.geom.voxel_count(), 0)};
  const ms::Geometry& g = mask.geom;
  for (std::size_t k = 2; k < 9; ++k)  // a block, off-centre, on 7 of the 12 frames
    for (std::size_t j = 3; j < 11; ++j)
      for (std::size_t i = 5; i < 20; ++i) mask.data[g.linear(i, j, k)] = 1;
  std::string note;  // the forged CT has no Frame of Reference
  const ms::DicomSource source = ms::dicomout::ensure_frame_of_reference(*scan.dicom, &note);
  EXPECT_NE(note.find("no FrameOfReferenceUID"), std::string::npos);
  const auto study = ms::dicomout::read_study_context(source, false, "test");
  const auto w = ms::dicomout::write_seg(mask, source, study, false, (dir / "seg.dcm").string());
  const ms::test::SegComparison c = ms::test::compare_seg_with_mask(w.path, mask);
  EXPECT_EQ(c.frames, 7u);
  EXPECT_EQ(c.mismatches, 0u);
  EXPECT_EQ(c.set_pixels, mask.count());
  DcmFileFormat ff;
  ASSERT_TRUE(ff.loadFile(w.path.c_str()).good());
  DcmDataset& ds = *ff.getDataset();
  std::set<Uint16> frames;
  for (int f = 0; f < 7; ++f) {
    DcmItem& deriv = ms::test::nested(ds, DCM_PerFrameFunctionalGroupsSequence, f, DCM_DerivationImageSequence);
    DcmItem* src = nullptr;
    ASSERT_TRUE(deriv.findAndGetSequenceItem(DCM_SourceImageSequence, src, 0).good());
    OFString uid;
    src->findAndGetOFString(DCM_ReferencedSOPInstanceUID, uid);
    EXPECT_EQ(uid.c_str(), scan.dicom->frames.front().sop_instance_uid);
    Uint16 number = 0;
    EXPECT_TRUE(src->findAndGetUint16(DCM_ReferencedFrameNumber, number).good() ||
                [&] {
                  OFString s;
                  return src->findAndGetOFString(DCM_ReferencedFrameNumber, s).good() && (number = static_cast<Uint16>(std::stoi(s.c_str()))) > 0;
                }());
    frames.insert(number);
  }
  // The frame numbers of the mask's slices, from where each slice lies (frames stored at z = 40 - 1.5 m).
  std::set<Uint16> expected;
  for (std::size_t k = 2; k < 9; ++k) expected.insert(static_cast<Uint16>(std::lround((40.0 - g.index_to_lps(0, 0, k)[2]) / 1.5) + 1));
  EXPECT_EQ(frames, expected);
}
