#include "tests/support/dicom_forge.h"

#include <gdcmDataSet.h>
#include <gdcmFileMetaInformation.h>
#include <gdcmImageChangeTransferSyntax.h>
#include <gdcmImageReader.h>
#include <gdcmImageWriter.h>
#include <gdcmItem.h>
#include <gdcmSequenceOfItems.h>
#include <gdcmTrace.h>
#include <gdcmUIDGenerator.h>
#include <gdcmWriter.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <iomanip>
#include <sstream>
#include <stdexcept>

namespace ms::testing {
namespace {

std::string ds_num(double v) {
  std::ostringstream o;
  o << std::setprecision(10) << v;
  return o.str();
}

void put(gdcm::DataSet& ds, std::uint16_t g, std::uint16_t e, const gdcm::VR& vr, std::string v) {
  if (v.size() % 2) v += (vr == gdcm::VR::UI ? '\0' : ' ');
  gdcm::DataElement de(gdcm::Tag(g, e));
  de.SetVR(vr);
  de.SetByteValue(v.data(), static_cast<std::uint32_t>(v.size()));
  ds.Replace(de);
}

void put_us(gdcm::DataSet& ds, std::uint16_t g, std::uint16_t e, std::uint16_t v) {
  gdcm::DataElement de(gdcm::Tag(g, e));
  de.SetVR(gdcm::VR::US);
  de.SetByteValue(reinterpret_cast<const char*>(&v), 2);
  ds.Replace(de);
}

void put_sq(gdcm::DataSet& ds, std::uint16_t g, std::uint16_t e, const std::vector<gdcm::DataSet>& items) {
  gdcm::SmartPointer<gdcm::SequenceOfItems> sq = new gdcm::SequenceOfItems;
  sq->SetLengthToUndefined();
  for (const auto& nested : items) {
    gdcm::Item it;
    it.SetVLToUndefined();
    it.SetNestedDataSet(nested);
    sq->AddItem(it);
  }
  gdcm::DataElement de(gdcm::Tag(g, e));
  de.SetVR(gdcm::VR::SQ);
  de.SetValue(*sq);
  de.SetVLToUndefined();
  ds.Replace(de);
}

std::string vec_str(const Vec3& v) { return ds_num(v[0]) + "\\" + ds_num(v[1]) + "\\" + ds_num(v[2]); }

void common(gdcm::DataSet& ds, const SliceSpec& s, unsigned frames) {
  put(ds, 0x0008, 0x0016, gdcm::VR::UI, s.sop_class);
  put(ds, 0x0008, 0x0018, gdcm::VR::UI, s.sop_uid.empty() ? unique_uid() : s.sop_uid);
  put(ds, 0x0008, 0x0008, gdcm::VR::CS, s.image_type);
  put(ds, 0x0008, 0x0020, gdcm::VR::DA, "20250102");
  put(ds, 0x0008, 0x0060, gdcm::VR::CS, s.modality);
  put(ds, 0x0008, 0x0070, gdcm::VR::LO, "Forge");
  put(ds, 0x0008, 0x103e, gdcm::VR::LO, s.description);
  put(ds, 0x0010, 0x0010, gdcm::VR::PN, "SECRET^PATIENT");
  put(ds, 0x0010, 0x0020, gdcm::VR::LO, "SECRET-ID-123");
  put(ds, 0x0018, 0x1210, gdcm::VR::SH, "BONE");
  put(ds, 0x0020, 0x000d, gdcm::VR::UI, s.study_uid);
  put(ds, 0x0020, 0x000e, gdcm::VR::UI, s.series_uid);
  put(ds, 0x0020, 0x0013, gdcm::VR::IS, std::to_string(s.instance));
  put_us(ds, 0x0028, 0x0002, static_cast<std::uint16_t>(s.samples_per_pixel));
  put(ds, 0x0028, 0x0004, gdcm::VR::CS, s.photometric);
  if (frames > 1) put(ds, 0x0028, 0x0008, gdcm::VR::IS, std::to_string(frames));
  put_us(ds, 0x0028, 0x0010, static_cast<std::uint16_t>(s.rows));
  put_us(ds, 0x0028, 0x0011, static_cast<std::uint16_t>(s.cols));
  put_us(ds, 0x0028, 0x0100, 16);
  put_us(ds, 0x0028, 0x0101, static_cast<std::uint16_t>(s.bits_stored));
  put_us(ds, 0x0028, 0x0102, static_cast<std::uint16_t>(s.bits_stored - 1));
  put_us(ds, 0x0028, 0x0103, s.signed_pixels ? 1 : 0);
  if (s.samples_per_pixel > 1) put_us(ds, 0x0028, 0x0006, 0);
  if (s.padding) put_us(ds, 0x0028, 0x0120, static_cast<std::uint16_t>(static_cast<std::int16_t>(*s.padding)));
}

void put_pixels(gdcm::DataSet& ds, const std::vector<std::int32_t>& values, std::size_t truncate) {
  std::vector<std::uint16_t> buf(values.size());
  for (std::size_t i = 0; i < values.size(); ++i) buf[i] = static_cast<std::uint16_t>(values[i] & 0xffff);
  std::size_t bytes = buf.size() * 2 - std::min(truncate, buf.size() * 2);
  bytes -= bytes % 2;
  gdcm::DataElement de(gdcm::Tag(0x7fe0, 0x0010));
  de.SetVR(gdcm::VR::OW);
  de.SetByteValue(reinterpret_cast<const char*>(buf.data()), static_cast<std::uint32_t>(bytes));
  ds.Replace(de);
}

void write_file(const std::string& path, gdcm::File& file, const std::string& syntax) {
  gdcm::Trace::SetWarning(false);
  gdcm::Trace::SetError(false);
  const bool implicit = syntax == "implicit";
  file.GetHeader().SetDataSetTransferSyntax(implicit ? gdcm::TransferSyntax::ImplicitVRLittleEndian
                                                     : gdcm::TransferSyntax::ExplicitVRLittleEndian);
  gdcm::FileMetaInformation& fmi = file.GetHeader();
  fmi.Clear();
  fmi.SetDataSetTransferSyntax(implicit ? gdcm::TransferSyntax::ImplicitVRLittleEndian : gdcm::TransferSyntax::ExplicitVRLittleEndian);
  std::filesystem::create_directories(std::filesystem::path(path).parent_path());
  if (syntax == "raw" || syntax == "implicit") {
    gdcm::Writer w;
    w.SetFileName(path.c_str());
    w.SetFile(file);
    if (!w.Write()) throw std::runtime_error("forge: cannot write " + path);
    return;
  }
  // Compressed: write raw to a temporary file, re-encode with GDCM's codecs.
  const std::string tmp = path + ".raw.tmp";
  {
    gdcm::Writer w;
    w.SetFileName(tmp.c_str());
    w.SetFile(file);
    if (!w.Write()) throw std::runtime_error("forge: cannot write " + tmp);
  }
  gdcm::ImageReader r;
  r.SetFileName(tmp.c_str());
  if (!r.Read()) throw std::runtime_error("forge: cannot re-read " + tmp);
  gdcm::ImageChangeTransferSyntax change;
  if (syntax == "jpeg-lossless") change.SetTransferSyntax(gdcm::TransferSyntax::JPEGLosslessProcess14_1);
  else if (syntax == "jpeg2000") change.SetTransferSyntax(gdcm::TransferSyntax::JPEG2000Lossless);
  else if (syntax == "rle") change.SetTransferSyntax(gdcm::TransferSyntax::RLELossless);
  else throw std::runtime_error("forge: unknown transfer syntax " + syntax);
  change.SetInput(r.GetImage());
  if (!change.Change()) throw std::runtime_error("forge: cannot encode " + syntax);
  gdcm::ImageWriter w;
  w.SetFileName(path.c_str());
  w.SetFile(r.GetFile());
  w.SetImage(change.GetOutput());
  if (!w.Write()) throw std::runtime_error("forge: cannot write " + path);
  std::filesystem::remove(tmp);
}

}  // namespace

std::string preamble() { return std::string(128, '\0') + "DICM"; }

std::string element(std::uint16_t group, std::uint16_t elem, const char* vr, const std::string& value,
                    std::optional<std::uint32_t> declared_length) {
  const std::uint32_t len = declared_length ? *declared_length : static_cast<std::uint32_t>(value.size());
  std::string h;
  auto put16 = [&](std::uint32_t v) { h += static_cast<char>(v & 0xff), h += static_cast<char>((v >> 8) & 0xff); };
  put16(group);
  put16(elem);
  h += vr[0];
  h += vr[1];
  const std::string v(vr, 2);
  if (v == "OB" || v == "OW" || v == "OF" || v == "SQ" || v == "UN" || v == "UT") {
    put16(0);
    put16(len & 0xffff);
    put16(len >> 16);
  } else {
    put16(len);
  }
  return h + value;
}

std::string unique_uid() {
  static gdcm::UIDGenerator g;
  return g.Generate();
}

std::int32_t stored_for(const SliceSpec& s, double hu) { return static_cast<std::int32_t>(std::lround((hu - s.intercept) / s.slope)); }

void write_slice(const std::string& path, const SliceSpec& s) {
  gdcm::SmartPointer<gdcm::File> file = new gdcm::File;  // GDCM writers keep a counted reference
  gdcm::DataSet& ds = file->GetDataSet();
  common(ds, s, 1);
  if (!s.omit_ipp) put(ds, 0x0020, 0x0032, gdcm::VR::DS, vec_str(s.ipp));
  if (!s.omit_iop) put(ds, 0x0020, 0x0037, gdcm::VR::DS, vec_str(s.row_dir) + "\\" + vec_str(s.col_dir));
  if (!s.omit_spacing) put(ds, 0x0028, 0x0030, gdcm::VR::DS, ds_num(s.spacing_j) + "\\" + ds_num(s.spacing_i));
  put(ds, 0x0028, 0x1052, gdcm::VR::DS, ds_num(s.intercept));
  put(ds, 0x0028, 0x1053, gdcm::VR::DS, ds_num(s.slope));
  if (!s.omit_pixel_data) {
    std::vector<std::int32_t> v = s.stored;
    if (v.empty()) v.assign(static_cast<std::size_t>(s.rows) * s.cols * s.samples_per_pixel, 0);
    put_pixels(ds, v, s.truncate_pixel_bytes);
  }
  write_file(path, *file, s.omit_pixel_data || s.truncate_pixel_bytes ? "raw" : s.transfer_syntax);
}

void write_enhanced(const std::string& path, const EnhancedSpec& e) {
  SliceSpec s = e.base;
  s.sop_class = "1.2.840.10008.5.1.4.1.1.2.1";  // Enhanced CT Image Storage
  gdcm::SmartPointer<gdcm::File> file = new gdcm::File;
  gdcm::DataSet& ds = file->GetDataSet();
  common(ds, s, static_cast<unsigned>(e.ipps.size()));
  // Shared: orientation, pixel measures, rescale.
  gdcm::DataSet shared, ori, meas, pvt;
  put(ori, 0x0020, 0x0037, gdcm::VR::DS, vec_str(s.row_dir) + "\\" + vec_str(s.col_dir));
  put(meas, 0x0028, 0x0030, gdcm::VR::DS, ds_num(s.spacing_j) + "\\" + ds_num(s.spacing_i));
  put(meas, 0x0018, 0x0050, gdcm::VR::DS, "1");
  put(pvt, 0x0028, 0x1052, gdcm::VR::DS, ds_num(s.intercept));
  put(pvt, 0x0028, 0x1053, gdcm::VR::DS, ds_num(s.slope));
  put(pvt, 0x0028, 0x1054, gdcm::VR::LO, "HU");
  put_sq(shared, 0x0020, 0x9116, {ori});
  put_sq(shared, 0x0028, 0x9110, {meas});
  put_sq(shared, 0x0028, 0x9145, {pvt});
  put_sq(ds, 0x5200, 0x9229, {shared});
  std::vector<gdcm::DataSet> per;
  for (const auto& p : e.ipps) {
    gdcm::DataSet item, pos;
    put(pos, 0x0020, 0x0032, gdcm::VR::DS, vec_str(p));
    put_sq(item, 0x0020, 0x9113, {pos});
    per.push_back(item);
  }
  put_sq(ds, 0x5200, 0x9230, per);
  std::vector<std::int32_t> all;
  for (const auto& f : e.frames) all.insert(all.end(), f.begin(), f.end());
  put_pixels(ds, all, 0);
  write_file(path, *file, s.transfer_syntax);
}

std::vector<SliceSpec> write_series(const std::string& dir, SliceSpec base, int n, double z0, double dz,
                                    const std::function<double(const Vec3&)>& hu, const std::string& prefix) {
  std::vector<SliceSpec> out;
  for (int k = 0; k < n; ++k) {
    SliceSpec s = base;
    s.ipp = base.ipp + (z0 + k * dz) * normalized(cross(base.row_dir, base.col_dir));
    s.instance = k + 1;
    s.stored.resize(static_cast<std::size_t>(s.rows) * s.cols);
    for (unsigned j = 0; j < s.rows; ++j)
      for (unsigned i = 0; i < s.cols; ++i) {
        const Vec3 p = s.ipp + (i * s.spacing_i) * s.row_dir + (j * s.spacing_j) * s.col_dir;
        s.stored[static_cast<std::size_t>(j) * s.cols + i] = stored_for(s, hu(p));
      }
    std::ostringstream name;
    name << prefix << "_" << std::setw(3) << std::setfill('0') << k << ".dcm";
    write_slice((std::filesystem::path(dir) / name.str()).string(), s);
    out.push_back(s);
  }
  return out;
}

}  // namespace ms::testing
