// ITK-facing translation unit: no system Eigen here (ENGINEERING.md).
#include "io/volume_io.h"

#include <itkGDCMImageIO.h>
#include <itkGDCMImageIOFactory.h>
#include <itkImage.h>
#include <itkImageFileReader.h>
#include <itkImageFileWriter.h>
#include <itkImageIOFactory.h>
#include <itkImageSeriesWriter.h>
#include <itkMetaDataObject.h>
#include <itkMetaImageIO.h>
#include <itkMetaImageIOFactory.h>
#include <itkNiftiImageIO.h>
#include <itkNiftiImageIOFactory.h>
#include <itkNrrdImageIO.h>
#include <itkNrrdImageIOFactory.h>

#include <gdcmTrace.h>
#include <gdcmUIDGenerator.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <limits>
#include <mutex>
#include <optional>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <zlib.h>
#include <sstream>
#include <cerrno>
#include <sys/stat.h>
#include <unistd.h>

#include "core/array_order.h"
#include "core/error.h"
#include "core/memory.h"
#include "core/digest.h"
#include "io/dicom.h"
#include "io/itk_geometry.h"
#include "io/volume_checks.h"

namespace fs = std::filesystem;

namespace ms::io {
namespace {

using FloatImage = itk::Image<float, 3>;
using MaskImage = itk::Image<unsigned char, 3>;

void register_factories() {
  static std::once_flag once;
  std::call_once(once, [] {
    // Our own one-line messages replace GDCM/ITK console chatter.
    gdcm::Trace::SetWarning(false);
    gdcm::Trace::SetDebug(false);
    itk::Object::GlobalWarningDisplayOff();
    itk::GDCMImageIOFactory::RegisterOneFactory();
    itk::NiftiImageIOFactory::RegisterOneFactory();
    itk::NrrdImageIOFactory::RegisterOneFactory();
    itk::MetaImageIOFactory::RegisterOneFactory();
  });
}

std::string first_line(const std::string& s) {
  std::string t = s.substr(0, s.find('\n'));
  // ITK messages start with "file:line:\n" noise; keep the description part.
  const auto pos = t.rfind(": ");
  return pos == std::string::npos ? t : t.substr(pos + 2);
}

std::string trim(std::string s) {
  while (!s.empty() && (s.back() == ' ' || s.back() == '\0')) s.pop_back();
  while (!s.empty() && s.front() == ' ') s.erase(s.begin());
  return s;
}

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}



// ITK's volume readers (MetaIO, the NIfTI and NRRD libraries) print their own
// diagnostics on stderr, several lines per failure; the product's contract is
// one error line. While a reader runs, file descriptor 2 goes to a temporary
// file; the first line it caught can then explain a terse ITK exception.
// Ingest runs on one thread; nothing else writes to stderr meanwhile.
class StderrCapture {
 public:
  StderrCapture() {
#ifndef MANDISYM_FUZZING  // under libFuzzer its own reports must reach stderr
    std::fflush(stderr);
    file_ = std::tmpfile();
    if (!file_) return;
    saved_ = ::dup(2);
    if (saved_ < 0 || ::dup2(::fileno(file_), 2) < 0) restore();
#endif
  }
  ~StderrCapture() {
    restore();
    if (file_) std::fclose(file_);
  }
  StderrCapture(const StderrCapture&) = delete;
  StderrCapture& operator=(const StderrCapture&) = delete;
  // First non-empty line the libraries printed ("" if none).
  std::string first() {
    restore();
    if (!file_) return "";
    std::rewind(file_);
    char line[512];
    while (std::fgets(line, sizeof line, file_)) {
      std::string l = line;
      while (!l.empty() && (l.back() == '\n' || l.back() == '\r' || l.back() == ' ')) l.pop_back();
      const auto start = l.find_first_not_of(" *");
      if (start != std::string::npos) return l.substr(start);
    }
    return "";
  }

 private:
  void restore() {
    if (saved_ < 0) return;
    std::fflush(stderr);
    ::dup2(saved_, 2);
    ::close(saved_);
    saved_ = -1;
  }
  std::FILE* file_ = nullptr;
  int saved_ = -1;
};

// One line for a failed ITK read: the deepest cause in a NRRD library chain
// ("[nrrd] _nrrdEncodingRaw_read: fread got only ..."), else what the library
// printed on stderr (MetaIO: "DimSize required and not defined."), else ITK's
// own first line.
std::string describe_read_failure(const std::string& description, const std::string& printed) {
  std::istringstream in(description);
  std::string line, deepest;
  while (std::getline(in, line)) {
    if (line.rfind("[nrrd]", 0) != 0) continue;
    const auto p = line.rfind(": ");
    if (p != std::string::npos && !trim(line.substr(p + 2)).empty()) deepest = trim(line.substr(p + 2));
  }
  if (!deepest.empty()) return deepest;
  if (!printed.empty()) return printed;
  if (description.find("Could not create IO object") != std::string::npos)
    return "no reader recognises the file (not NIfTI, NRRD or MetaImage)";
  return first_line(description);
}

// Runs reader->Update() with the libraries' stderr captured. Returns "" on
// success, else describe_read_failure's line. With `into`, the voxels are
// read straight into it (sized from the header): the output's pixel
// container imports its buffer and the reader keeps it (no release before
// the update), so they are not copied out of ITK's buffer afterwards (a
// 512 x 512 x 450 NIfTI: 0.8 s and 470 MB less); cleared on failure.
template <class Reader>
std::string try_update(Reader& reader, std::vector<float>* into = nullptr) {
  StderrCapture capture;
  try {
    if (into) {
      reader->UpdateOutputInformation();
      auto* img = reader->GetOutput();
      const std::size_t n = img->GetLargestPossibleRegion().GetNumberOfPixels();
      into->resize(n);
      img->GetPixelContainer()->SetImportPointer(into->data(), n, false);
      reader->ReleaseDataBeforeUpdateFlagOff();
    }
    reader->Update();
    if (into && reader->GetOutput()->GetBufferPointer() != into->data()) {  // ITK allocated after all
      const float* buf = reader->GetOutput()->GetBufferPointer();
      into->assign(buf, buf + into->size());
    }
    return "";
  } catch (const itk::ExceptionObject& e) {
    if (into) into->clear();
    return describe_read_failure(e.GetDescription(), capture.first());
  } catch (const std::exception& e) {  // e.g. std::length_error from a malformed header (found by fuzzing)
    if (into) into->clear();
    const std::string printed = capture.first();
    return printed.empty() ? std::string("the reader failed (") + e.what() + ")" : printed;
  }
}

std::string volume_kind(const std::string& path) {
  const std::string l = lower(path);
  auto ends = [&](const char* s) {
    const std::string suf(s);
    return l.size() >= suf.size() && l.compare(l.size() - suf.size(), suf.size(), suf) == 0;
  };
  if (ends(".nii") || ends(".nii.gz")) return "nifti";
  if (ends(".nrrd") || ends(".nhdr")) return "nrrd";
  if (ends(".mha") || ends(".mhd")) return "meta";
  return "";
}

// Non-finite or absurd geometry went on to crash the mesh stage (an origin of
// 1e300 mm: SIGFPE in CGAL's exact arithmetic) or to read as "no bone" (a
// spacing of 1e30 mm). Limits in checks:: (docs/ingest.md, "Geometry").
void check_geometry(const Geometry& g, const std::string& path) {
  auto fmt = [](double v) {
    char b[32];
    std::snprintf(b, sizeof b, "%g", v);
    return std::string(b);
  };
  for (int a = 0; a < 3; ++a) {
    if (!(std::abs(g.origin[a]) <= checks::kMaxPositionMm))
      throw Error(ExitCode::InputInvalid, path + ": origin " + fmt(g.origin[a]) + " mm is not finite or beyond 10 m");
    if (!(g.spacing[a] >= checks::kMinSpacingMm && g.spacing[a] <= checks::kMaxSpacingMm))
      throw Error(ExitCode::InputInvalid, path + ": voxel spacing " + fmt(g.spacing[a]) + " mm is outside 0.001 to 100 mm");
  }
  const auto& d = g.direction;
  bool ok = true;
  for (double v : d) ok &= std::isfinite(v);
  for (int c = 0; c < 3 && ok; ++c)
    ok &= std::abs(std::sqrt(d[c] * d[c] + d[3 + c] * d[3 + c] + d[6 + c] * d[6 + c]) - 1) <= checks::kDirectionTolerance;
  const double det = d[0] * (d[4] * d[8] - d[5] * d[7]) - d[1] * (d[3] * d[8] - d[5] * d[6]) + d[2] * (d[3] * d[7] - d[4] * d[6]);
  if (!ok || !(std::abs(std::abs(det) - 1) <= checks::kDirectionTolerance))
    throw Error(ExitCode::InputInvalid, path + ": direction (orientation) matrix is not finite or not orthonormal");
}

void finish(LoadedScan& scan, double hu_offset) {
  auto& hu = scan.volume.hu;
  std::size_t bad = 0;
  float mn = std::numeric_limits<float>::max(), mx = std::numeric_limits<float>::lowest();
  const long n = static_cast<long>(hu.size());
  const float off = static_cast<float>(hu_offset);
#pragma omp parallel for schedule(static) reduction(+ : bad) reduction(min : mn) reduction(max : mx)
  for (long i = 0; i < n; ++i) {
    float& v = hu[static_cast<std::size_t>(i)];
    if (!std::isfinite(v)) ++bad;
    v += off;
    mn = std::min(mn, v);
    mx = std::max(mx, v);
  }
  if (bad)
    throw Error(ExitCode::InputInvalid,
                scan.info.path + ": " + std::to_string(bad) + " voxels are NaN or infinite");
  const auto& g = scan.volume.geom;
  for (int a = 0; a < 3; ++a) {
    if (g.size[a] < 4)
      throw Error(ExitCode::InputInvalid, scan.info.path + ": volume is " + std::to_string(g.size[0]) + " x " +
                                              std::to_string(g.size[1]) + " x " + std::to_string(g.size[2]) +
                                              " voxels, too small to hold a mandible");
    if (!(g.spacing[a] > 0) || !std::isfinite(g.spacing[a]))
      throw Error(ExitCode::InputInvalid, scan.info.path + ": voxel spacing is not positive");
  }
  check_geometry(g, scan.info.path);
  // Provenance hash: SHA-256 over the per-slice SHA-256 digests (hex) of the
  // float32 HU slices, x fastest; slices hash in parallel (docs/ingest.md).
  {
    const std::size_t plane = g.size[0] * g.size[1];
    const long nz = static_cast<long>(g.size[2]);
    std::vector<std::string> digests(static_cast<std::size_t>(nz));
#pragma omp parallel for schedule(static)
    for (long k = 0; k < nz; ++k)
      digests[static_cast<std::size_t>(k)] = sha256_hex(hu.data() + static_cast<std::size_t>(k) * plane, plane * sizeof(float));
    Sha256 top;
    for (const auto& d : digests) top.update(d.data(), d.size());
    scan.info.pixel_sha256 = top.hex_digest();
  }
  scan.info.lowest_hu = static_cast<double>(mn);
  // A CT in HU has air near -1000 and nothing far below it.
  if (mn > -500 || mn < -3100) {
    char range[96];  // %.0f: any finite float prints (an int cast of 1e30 would be undefined)
    std::snprintf(range, sizeof range, "[%.0f, %.0f]", static_cast<double>(mn), static_cast<double>(mx));
    scan.info.warnings.push_back(std::string("value range ") + range +
                                 " does not look like CT in HU (air should be near -1000); check --hu-offset");
  }
}

LoadedScan read_dicom(const std::string& path, const ReadOptions& opt) {
  const dicom::ScanResult sc = dicom::scan(path);
  if (sc.files_seen == 0) throw Error(ExitCode::InputInvalid, path + ": folder is empty");
  if (sc.unreadable_files == sc.files_seen)
    throw Error(ExitCode::InputNotFound, path + ": no file can be read (permission denied), e.g. " + sc.first_unreadable);
  if (sc.dicom_files == 0)
    throw Error(ExitCode::InputInvalid, path + ": no DICOM files (" + std::to_string(sc.files_seen) + " file(s), e.g. " +
                                            sc.first_non_dicom + " is not DICOM)");
  if (sc.series.empty())
    throw Error(ExitCode::InputInvalid, path + ": DICOM files but no images (" + std::to_string(sc.non_image_files) +
                                            " non-image object(s))");
  std::vector<dicom::Layout> layouts;
  for (const auto& s : sc.series) layouts.push_back(dicom::analyse(s));
  int chosen = -1;
  std::string why;
  if (!opt.series_uid.empty()) {
    for (std::size_t i = 0; i < sc.series.size(); ++i)
      if (sc.series[i].uid == opt.series_uid || sc.series[i].label == opt.series_uid) {
        if (!layouts[i].usable) throw Error(ExitCode::InputInvalid, path + ": series " + sc.series[i].label + ": " + layouts[i].problem);
        if (chosen < 0 || layouts[i].order.size() > layouts[chosen].order.size()) chosen = static_cast<int>(i);
      }
    if (chosen < 0) throw Error(ExitCode::InputInvalid, path + ": series " + opt.series_uid + " not found (see mandisym inspect)");
    if (sc.series[chosen].modality != "CT")
      throw Error(ExitCode::InputInvalid, path + ": series " + opt.series_uid + " is " + sc.series[chosen].modality + ", not CT");
  } else {
    chosen = dicom::choose(sc, layouts, &why);
    if (chosen < 0) throw Error(ExitCode::InputInvalid, path + ": " + why);
  }
  const dicom::Series& s = sc.series[chosen];
  const std::uint64_t budget = checks::effective_budget(opt.max_memory_bytes);
  checks::check_budget(path, "DICOM series " + s.label + " (" + std::to_string(s.frames.front().rows) + " x " +
                                 std::to_string(s.frames.front().cols) + " x " + std::to_string(s.frames.size()) + ")",
                       static_cast<std::uint64_t>(s.frames.front().rows) * s.frames.front().cols * s.frames.size(), budget);
  LoadedScan scan;
  scan.info.path = path;
  scan.info.kind = "dicom";
  scan.info.file_count = s.files.size();
  scan.info.series_uid = s.uid;
  scan.info.modality = s.modality;
  scan.info.study_date = s.study_date;
  scan.info.manufacturer = s.manufacturer;
  scan.info.model = s.model;
  scan.info.kernel = s.kernel;
  scan.info.series_description = s.description;
  scan.info.warnings = layouts[chosen].warnings;
  if (sc.series.size() > 1) scan.info.warnings.push_back(std::to_string(sc.series.size()) + " image series found; used " + s.label);
  if (sc.unreadable_files)
    scan.info.warnings.push_back(std::to_string(sc.unreadable_files) + " file(s) could not be opened (permission denied), e.g. " +
                                 sc.first_unreadable);
  if (sc.special_files)
    scan.info.warnings.push_back(std::to_string(sc.special_files) + " entr" + (sc.special_files == 1 ? "y" : "ies") +
                                 " that are not regular files (FIFOs, devices, sockets) skipped, e.g. " + sc.first_special);
  scan.volume = dicom::assemble(s, layouts[chosen], scan.info.warnings, budget);
  scan.dicom = dicom::source_of(s, layouts[chosen]);
  return scan;
}

// The NIfTI library replaces NaN/Inf by 0 and zero-fills a short file while
// reading, hiding both; check the payload ourselves. Also catches
// zero-sized dimensions. Throws ms::Error(InputInvalid).
void check_nifti_payload(const std::string& path) {
  gzFile f = gzopen(path.c_str(), "rb");  // reads plain .nii too
  if (!f) return;  // ITK will report it
  struct Closer {
    gzFile f;
    ~Closer() { gzclose(f); }
  } closer{f};
  unsigned char hdr[348];
  if (gzread(f, hdr, sizeof hdr) != static_cast<int>(sizeof hdr)) throw Error(ExitCode::InputInvalid, path + ": NIfTI header is truncated");
  auto i32 = [&](int off, bool sw) { return checks::header_i32(hdr, off, sw); };
  auto i16 = [&](int off, bool sw) { return checks::header_i16(hdr, off, sw); };
  bool swap = false;
  if (i32(0, false) != 348) {
    if (i32(0, false) == 540 || i32(0, true) == 540) return;  // NIfTI-2: left to ITK
    // Neither: the NIfTI library still reads such a header (by its magic),
    // unchecked; a NaN affine in one aborted it (found by fuzzing).
    if (i32(0, true) != 348)
      throw Error(ExitCode::InputInvalid, path + ": not a NIfTI-1 or NIfTI-2 header (sizeof_hdr " + std::to_string(i32(0, false)) + ")");
    swap = true;
  }
  const int ndim = i16(40, swap);
  if (ndim < 1 || ndim > 7) throw Error(ExitCode::InputInvalid, path + ": NIfTI header has " + std::to_string(ndim) + " dimensions");
  std::uint64_t nvox = 1;
  for (int d = 1; d <= ndim; ++d) {
    const int n = i16(40 + 2 * d, swap);
    if (n <= 0) throw Error(ExitCode::InputInvalid, path + ": NIfTI dimension " + std::to_string(d) + " has size " + std::to_string(n));
    nvox *= static_cast<std::uint64_t>(n);
  }
  // The geometry fields ITK turns into a direction matrix: a NaN there made
  // vnl's SVD abort the process (found by fuzzing). pixdim[1..ndim] always;
  // the quaternion and offsets when qform_code > 0; the affine rows when sform_code > 0.
  auto f32 = [&](int off) { return checks::header_f32(hdr, off, swap); };
  // Finite is not enough: an sform offset of -2e38 mm made the SVD spin
  // forever (found by fuzzing). No scan's voxel size, orientation or origin
  // comes near a kilometre (1e6 mm).
  constexpr float kMaxGeometryMm = 1e6f;
  auto all_sane = [&](int off, int n) {
    for (int k = 0; k < n; ++k)
      if (!(std::abs(f32(off + 4 * k)) <= kMaxGeometryMm)) return false;  // NaN fails too
    return true;
  };
  if (!all_sane(80, ndim) || (i16(252, swap) > 0 && !all_sane(256, 6)) || (i16(254, swap) > 0 && !all_sane(280, 12)))
    throw Error(ExitCode::InputInvalid, path + ": NIfTI header has NaN, infinite or absurd (beyond 1e6 mm) voxel sizes or orientation");
  const int datatype = i16(70, swap), bitpix = i16(72, swap);
  const float vox_offset = f32(108);
  const bool single_file = std::memcmp(hdr + 344, "n+1", 3) == 0;
  if (!single_file || bitpix <= 0) return;  // .hdr/.img pairs: leave to ITK
  if (!std::isfinite(vox_offset) || vox_offset < 0 || vox_offset > 1e12f)  // found by fuzzing (cast of -7e32)
    throw Error(ExitCode::InputInvalid, path + ": NIfTI header has an invalid data offset (vox_offset " + std::to_string(vox_offset) + ")");
  const std::uint64_t skip = static_cast<std::uint64_t>(vox_offset) > 348 ? static_cast<std::uint64_t>(vox_offset) - 348 : 0;
  std::vector<unsigned char> buf(1 << 20);
  for (std::uint64_t left = skip; left > 0;) {
    const int got = gzread(f, buf.data(), static_cast<unsigned>(std::min<std::uint64_t>(left, buf.size())));
    if (got <= 0) throw Error(ExitCode::InputInvalid, path + ": NIfTI file ends before its image data");
    left -= static_cast<std::uint64_t>(got);
  }
  const std::uint64_t bytes = nvox * static_cast<std::uint64_t>(bitpix / 8);
  std::uint64_t read = 0, bad = 0;
  const int unit = datatype == 16 ? 4 : datatype == 64 ? 8 : 0;  // float32 / float64
  while (read < bytes) {
    const int got = gzread(f, buf.data(), static_cast<unsigned>(std::min<std::uint64_t>(bytes - read, buf.size())));
    if (got <= 0) break;
    if (unit) {
      for (int o = 0; o + unit <= got; o += unit) {
        if (unit == 4) {
          std::uint32_t v;
          std::memcpy(&v, buf.data() + o, 4);
          if (swap) v = __builtin_bswap32(v);
          float x;
          std::memcpy(&x, &v, 4);
          bad += !std::isfinite(x);
        } else {
          std::uint64_t v;
          std::memcpy(&v, buf.data() + o, 8);
          if (swap) v = __builtin_bswap64(v);
          double x;
          std::memcpy(&x, &v, 8);
          bad += !std::isfinite(x);
        }
      }
    }
    read += static_cast<std::uint64_t>(got);
  }
  if (read < bytes)
    throw Error(ExitCode::InputInvalid, path + ": NIfTI file holds " + std::to_string(read) + " bytes of image data, its header promises " +
                                            std::to_string(bytes));
  if (bad) throw Error(ExitCode::InputInvalid, path + ": " + std::to_string(bad) + " voxels are NaN or infinite");
}

// NRRD headers that combine "space:" with per-axis "spacings:" (legal in
// older NRRD writers, e.g. VTK's headsq) are rejected by ITK's reader. When the
// space is not anatomical (3D-left-handed / 3D-right-handed) it carries no
// orientation, so drop it into a temporary copy of the header, with the data
// file paths made absolute, and read that. Returns "" when not applicable.
std::string patched_nrrd_header(const std::string& path, std::string& note) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return "";
  std::string line, out;
  bool changed = false, in_header = true;
  const fs::path dir = fs::absolute(fs::path(path)).parent_path();
  while (in_header && std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) break;  // end of an attached header: this only patches detached headers
    const std::string l = lower(line);
    if (l.rfind("space:", 0) == 0 && (l.find("3d-left-handed") != std::string::npos || l.find("3d-right-handed") != std::string::npos)) {
      note = "NRRD space '" + trim(line.substr(6)) + "' is not anatomical: axes taken as L, P, S (use --orientation if wrong)";
      changed = true;
      continue;
    }
    if (l.rfind("data file:", 0) == 0 || l.rfind("datafile:", 0) == 0) {
      std::string rest = trim(line.substr(line.find(':') + 1));
      if (!rest.empty() && rest[0] != '/' && lower(rest).rfind("list", 0) != 0) rest = (dir / rest).string();
      line = "data file: " + rest;
    }
    out += line + "\n";
  }
  if (!changed || lower(path).size() < 5 || lower(path).substr(lower(path).size() - 5) != ".nhdr") return "";
  const fs::path tmp = fs::temp_directory_path() / ("mandisym-" + std::to_string(::getpid()) + "-" + fs::path(path).filename().string());
  std::ofstream o(tmp, std::ios::binary);
  o << out;
  return o ? tmp.string() : "";
}

// Bytes a volume occupies on disk: the header file plus, for a detached
// header (NRRD "data file:", MetaImage "ElementDataFile"), the one data file
// it names. Empty when that is a list, a pattern or a missing file. NIfTI is
// binary (its bytes can spell anything), so only its own size counts.
std::optional<std::uintmax_t> bytes_on_disk(const std::string& path) {
  std::error_code ec;
  std::uintmax_t bytes = fs::file_size(path, ec);
  if (ec) return std::nullopt;
  const std::string kind = volume_kind(path);
  if (kind != "nrrd" && kind != "meta") return bytes;
  std::ifstream in(path, std::ios::binary);
  std::string line;
  for (int n = 0; n < 200 && std::getline(in, line); ++n) {
    if (line.empty() || line == "\r") break;  // end of an attached NRRD header
    const std::string l = lower(line);
    if (!(l.rfind("data file:", 0) == 0 || l.rfind("datafile:", 0) == 0 || l.rfind("elementdatafile", 0) == 0)) continue;
    const std::string name = trim(line.substr(line.find_first_of(":=") + 1));
    if (name.empty() || lower(name) == "local") break;
    const fs::path data = fs::path(name).is_absolute() ? fs::path(name) : fs::path(path).parent_path() / name;
    const auto more = fs::file_size(data, ec);
    if (ec) return std::nullopt;
    return bytes + more;
  }
  return bytes;
}

// What a volume header declares, checked before ITK allocates it (found by
// fuzzing: a 200-byte NRRD or MetaImage header can declare terabytes, and ITK
// allocates the whole image before it reads a voxel). Refused: more voxels
// than this machine's memory holds as float, or more bytes than the file(s)
// can hold even at deflate's best ratio (~1032:1). The data files of detached
// headers (.nhdr "data file:", .mhd "ElementDataFile") count when they name
// one existing file; a file list or pattern is left to the memory check.
// MetaIO trusts the header's NDims: it loops over it before checking it
// (found by fuzzing: NDims = 3800000000000004 ran for minutes) and copies as
// many numbers as a line holds into arrays sized by it (NDims = 1 with a
// 9-number TransformMatrix corrupted the heap: "free(): invalid next size").
// So NDims must be 1 to 4 and each geometry field must hold NDims (vectors) or
// NDims^2 (matrices) numbers before ITK sees the file.
// Whether a header line is text: valid UTF-8 without control characters
// other than tab.
bool is_header_text(const std::string& line) {
  for (std::size_t i = 0; i < line.size();) {
    const auto c = static_cast<unsigned char>(line[i]);
    if (c < 0x80) {
      if (c < 0x20 && c != '\t') return false;
      if (c == 0x7f) return false;
      ++i;
      continue;
    }
    const int extra = c >= 0xf0 && c <= 0xf4 ? 3 : c >= 0xe0 && c <= 0xef ? 2 : c >= 0xc2 && c <= 0xdf ? 1 : -1;
    if (extra < 0 || i + static_cast<std::size_t>(extra) >= line.size()) return false;  // not a lead byte, or cut short
    for (int k = 1; k <= extra; ++k)
      if ((static_cast<unsigned char>(line[i + static_cast<std::size_t>(k)]) & 0xc0) != 0x80) return false;
    i += static_cast<std::size_t>(extra) + 1;
  }
  return true;
}

void check_meta_header(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string line;
  long ndims = -1;
  std::string compressed;  // CompressedDataSize as written
  struct Field {
    std::string name;
    std::size_t count;
    bool matrix;
  };
  std::vector<Field> fields;
  for (int n = 0; n < 200 && std::getline(in, line); ++n) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    // A header is text: MetaIO overran a buffer on an ElementDataFile name of
    // bytes that are not (found by fuzzing: strlen past a heap block).
    if (!is_header_text(line))
      throw Error(ExitCode::InputInvalid, path + ": MetaImage header line " + std::to_string(n + 1) + " is not text");
    if (trim(line).empty()) continue;
    // Every header line is "Key = Value" with a short word for a key: MetaIO
    // reads everything up to the next '=' as the key and strcpy's it into a
    // fixed buffer (found by fuzzing: a long line without '=' overflowed it).
    const auto eq = line.find('=');
    const std::string raw_key = eq == std::string::npos ? "" : trim(line.substr(0, eq));
    const bool word = !raw_key.empty() && raw_key.size() <= 64 &&
                      std::all_of(raw_key.begin(), raw_key.end(), [](unsigned char c) { return std::isalnum(c) || c == '_'; });
    if (!word) throw Error(ExitCode::InputInvalid, path + ": MetaImage header line " + std::to_string(n + 1) + " is not 'Key = Value'");
    const std::string key = lower(raw_key);
    const std::string value = trim(line.substr(eq + 1));
    if (key == "elementdatafile") {
      // A '%' makes the name a file-list pattern ("slice%03d.raw 1 40 1") that
      // MetaIO hands to snprintf as the format, unchecked (found by fuzzing:
      // "LOCA%000000000002" aborted in the format parser). Only one integer
      // conversion, %d or %0Nd with N < 10, is a pattern; anything else is refused.
      const std::string name = value.substr(0, value.find_first_of(" \t"));
      if (value.find('%') != std::string::npos) {
        const auto pc = name.find('%');
        std::size_t k = pc == std::string::npos ? 0 : pc + 1;
        if (k < name.size() && name[k] == '0') ++k;
        if (k < name.size() && std::isdigit(static_cast<unsigned char>(name[k]))) ++k;
        const bool one_int = pc != std::string::npos && k < name.size() && name[k] == 'd' &&
                             name.find('%', k) == std::string::npos && value.find('%', name.size()) == std::string::npos;
        if (!one_int)
          throw Error(ExitCode::InputInvalid, path + ": MetaImage ElementDataFile '" + value.substr(0, 40) +
                                                  "' is not a file name or a %d file-list pattern");
      }
      // MetaIO allocates CompressedDataSize bytes before reading them (found
      // by fuzzing: 1.8e19): it must be one number no larger than the bytes
      // on disk (this file and a named data file).
      if (!compressed.empty()) {
        const auto on_disk = bytes_on_disk(path);
        char* end = nullptr;
        const unsigned long long declared = std::strtoull(compressed.c_str(), &end, 10);
        if (*end != '\0' || compressed[0] == '-' || (on_disk && declared > *on_disk))
          throw Error(ExitCode::InputInvalid, path + ": MetaImage header has CompressedDataSize = " + compressed.substr(0, 24) +
                                                  ", more than the file holds");
      }
      break;
    }
    if (key == "compresseddatasize") {
      compressed = value;
      continue;
    }
    if (key == "ndims") {
      char* end = nullptr;
      ndims = std::strtol(value.c_str(), &end, 10);
      if (value.empty() || trim(end) != "" || ndims < 1 || ndims > 4)
        throw Error(ExitCode::InputInvalid, path + ": MetaImage header has NDims = " + value.substr(0, 24) + " (expected 1 to 4)");
      continue;
    }
    static const char* const kVectors[] = {"dimsize", "elementspacing", "elementsize", "offset", "position", "origin",
                                           "centerofrotation"};
    static const char* const kMatrices[] = {"transformmatrix", "rotation", "orientation"};
    bool vec = false, mat = false;
    for (const char* k : kVectors) vec |= key == k;
    for (const char* k : kMatrices) mat |= key == k;
    if (!vec && !mat) continue;
    std::istringstream numbers(value);
    std::string tok;
    std::size_t count = 0;
    while (numbers >> tok) ++count;
    fields.push_back({trim(line.substr(0, eq)), count, mat});
  }
  for (const auto& [name, count, mat] : fields) {
    if (ndims < 0) throw Error(ExitCode::InputInvalid, path + ": MetaImage header has " + name + " before NDims");
    const std::size_t want = mat ? static_cast<std::size_t>(ndims * ndims) : static_cast<std::size_t>(ndims);
    if (count != want)
      throw Error(ExitCode::InputInvalid, path + ": MetaImage header has " + std::to_string(count) + " numbers in " + name +
                                              ", NDims = " + std::to_string(ndims) + " needs " + std::to_string(want));
  }
}

// The reader of a volume file's kind, named explicitly: left to ITK's
// factory, a header its reader refuses is offered to every other reader,
// GDCM's among them, which asserted on one (fuzz_volume, bounded
// exploration: a .nhdr holding MetaImage lines aborted the run, exit 134).
// Files of no known kind (a mask in another ITK format) keep the factory.
itk::ImageIOBase::Pointer image_io_for(const std::string& kind, const std::string& path) {
  if (kind == "nifti") return itk::NiftiImageIO::New().GetPointer();
  if (kind == "nrrd") return itk::NrrdImageIO::New().GetPointer();
  if (kind == "meta") return itk::MetaImageIO::New().GetPointer();
  return itk::ImageIOFactory::CreateImageIO(path.c_str(), itk::CommonEnums::IOFileMode::ReadMode);
}

// What the header declares (ITK's ImageIO reads it, no pixels), before any
// allocation: one scalar component, at most three dimensions (a fourth of
// size 1 is fine), and a run on that many voxels within the memory budget.
// Returns the bytes of stored voxel data declared (0 when the header cannot
// be read: the reader that follows says why).
std::uint64_t check_declared_size(const std::string& path, const char* what, std::uint64_t budget) {
  StderrCapture quiet;  // the reader that follows reports any failure
  const std::string kind = volume_kind(path);
  const itk::ImageIOBase::Pointer io = image_io_for(kind, path);
  if (!io || (!kind.empty() && !io->CanReadFile(path.c_str()))) return 0;  // the reader says why
  io->SetFileName(path);
  long double voxels = 1, stored = 0;
  unsigned components = 1, ndims = 0;
  std::vector<std::size_t> dims;
  try {
    io->ReadImageInformation();
    ndims = io->GetNumberOfDimensions();
    for (unsigned d = 0; d < ndims; ++d) dims.push_back(io->GetDimensions(d));
    for (auto n : dims) voxels *= static_cast<long double>(n);
    components = io->GetNumberOfComponents();
    stored = voxels * components * io->GetComponentSize();  // throws for an unknown pixel type
  } catch (const std::exception&) {  // itk::ExceptionObject or a library's std::length_error
    return 0;  // the reader says why
  }
  if (components != 1)
    throw Error(ExitCode::InputInvalid, path + ": " + what + " has " + std::to_string(components) +
                                            " components per voxel (colour, vector or complex), not one number per voxel as a CT");
  for (unsigned d = 3; d < ndims; ++d)
    if (dims[d] > 1)
      throw Error(ExitCode::InputInvalid, path + ": " + what + " holds " + std::to_string(dims[d]) + " volumes along dimension " +
                                              std::to_string(d + 1) + "; MandiSym reads one 3D CT");
  const auto v = voxels >= 1.8e19L ? UINT64_MAX : static_cast<std::uint64_t>(voxels);
  checks::check_budget(path, std::string(what) + " header", v, budget);
  const auto on_disk = bytes_on_disk(path);
  auto mb = [](long double b) { return std::to_string(static_cast<long long>(std::min(b / 1e6L, 1e15L))) + " MB"; };
  // Backstop for encodings the data check does not follow (text, hex, bzip2):
  // deflate cannot compress beyond ~1032:1.
  constexpr long double kMaxInflation = 1100;
  if (on_disk && stored > kMaxInflation * std::max<long double>(static_cast<long double>(*on_disk), 1))
    throw Error(ExitCode::InputInvalid, path + ": " + what + " header declares " + mb(stored) + " of voxel data but the file" +
                                            " holds " + std::to_string(*on_disk) + " bytes");
  return stored >= 1.8e19L ? UINT64_MAX : static_cast<std::uint64_t>(stored);
}

// Everything checked before ITK reads a volume file (masks and label maps
// too), in an order that names the first problem: the file itself, NIfTI
// header and payload, MetaImage header syntax, the data files a detached
// header names, the declared size against the budget, and that the data holds it.
void check_before_reading(const std::string& path, const char* what, const ReadOptions& opt) {
  const std::string kind = volume_kind(path);
  const std::uint64_t budget = checks::effective_budget(opt.max_memory_bytes);
  checks::require_regular_file(path, path, "the file");
  if (kind == "nifti") {
    checks::check_nifti_header(path, budget);
    check_nifti_payload(path);
  }
  if (kind == "meta") check_meta_header(path);
  const checks::DataLayout layout = checks::data_layout(path, kind, opt.allow_external_data_files);
  const std::uint64_t declared = check_declared_size(path, what, budget);
  checks::check_data_holds(path, kind, layout, declared);
}

LoadedScan read_volume_file(const std::string& path, const std::string& kind, const ReadOptions& opt) {
  check_before_reading(path, "volume", opt);
  // qform and sform disagreeing (one flipped, say): ITK picks one silently.
  std::string why;
  if (kind == "nifti" && opt.orientation.empty() && checks::nifti_orientation(path, &why) == checks::NiftiOrientation::Disagree)
    throw Error(ExitCode::InputInvalid, path + ": NIfTI " + why + "; give the orientation with --orientation");
  auto reader = itk::ImageFileReader<FloatImage>::New();
  reader->SetImageIO(image_io_for(kind, path));
  reader->SetFileName(path);
  std::string note;
  LoadedScan scan;
  if (const std::string failed = try_update(reader, &scan.volume.hu); !failed.empty()) {
    const std::string patched = kind == "nrrd" ? patched_nrrd_header(path, note) : "";
    if (patched.empty()) throw Error(ExitCode::InputInvalid, path + ": cannot read " + kind + " volume: " + failed);
    struct Remove {
      std::string f;
      ~Remove() {
        std::error_code ec;
        fs::remove(f, ec);
      }
    } remove_patched{patched};
    const std::uint64_t declared = check_declared_size(patched, "volume", checks::effective_budget(opt.max_memory_bytes));
    checks::check_data_holds(path, kind, checks::data_layout(path, kind, opt.allow_external_data_files), declared);
    reader = itk::ImageFileReader<FloatImage>::New();
    reader->SetImageIO(image_io_for(kind, path));
    reader->SetFileName(patched);
    if (const std::string failed2 = try_update(reader, &scan.volume.hu); !failed2.empty())
      throw Error(ExitCode::InputInvalid, path + ": cannot read " + kind + " volume: " + failed2);
  }
  scan.info.path = path;
  scan.info.kind = kind;
  scan.info.file_count = 1;
  if (!note.empty()) scan.info.warnings.push_back(note);
  FloatImage::Pointer img = reader->GetOutput();
  scan.volume.geom = geometry_of(img.GetPointer());
  if (scan.volume.hu.size() != scan.volume.geom.voxel_count())
    throw Error(ExitCode::InputInvalid, path + ": cannot read " + kind + " volume: the reader returned " +
                                            std::to_string(scan.volume.hu.size()) + " voxels for a grid of " +
                                            std::to_string(scan.volume.geom.voxel_count()));
  return scan;
}

// Direction matrix from a 3-letter code naming where the i, j, k axes point
// (L/R, P/A, S/I), e.g. "LPS" (identity) or "LAI".
std::array<double, 9> direction_from_code(const std::string& code, const std::string& path) {
  if (code.size() != 3) throw Error(ExitCode::Usage, "--orientation: expected 3 letters from L/R, P/A, S/I, got '" + code + "'");
  std::array<double, 9> d{};
  bool used[3] = {false, false, false};
  for (int c = 0; c < 3; ++c) {
    int axis = -1;
    double sign = 1;
    switch (std::toupper(static_cast<unsigned char>(code[c]))) {
      case 'L': axis = 0; break;
      case 'R': axis = 0; sign = -1; break;
      case 'P': axis = 1; break;
      case 'A': axis = 1; sign = -1; break;
      case 'S': axis = 2; break;
      case 'I': axis = 2; sign = -1; break;
      default: break;
    }
    if (axis < 0 || used[axis])
      throw Error(ExitCode::Usage, path + ": --orientation '" + code + "' must name each of L/R, P/A, S/I once");
    used[axis] = true;
    d[3 * axis + c] = sign;
  }
  return d;
}

}  // namespace

namespace {

// Brings a grid and its values to the canonical array order (core/array_order.h).
template <class T>
AxisReorder canonical_order(Geometry& g, std::vector<T>& values) {
  const AxisReorder order = canonical_reorder(g);
  if (order.identity()) return order;
  values = reordered_values(values, g, order);
  g = reordered(g, order);
  return order;
}

}  // namespace

Mask in_stored_order(const Mask& mask, const AxisReorder& stored_order) {
  if (stored_order.identity()) return mask;
  const AxisReorder back = inverse(stored_order);
  Mask out;
  out.data = reordered_values(mask.data, mask.geom, back);
  out.geom = reordered(mask.geom, back);
  return out;
}

LoadedScan read_scan(const std::string& path, const ReadOptions& options) {
  register_factories();
  std::error_code ec;
  if (!fs::exists(path, ec)) throw Error(ExitCode::InputNotFound, path + ": no such file or directory");
  // Only folders and regular files: a FIFO blocks the reader forever, a device never ends.
  if (struct stat st {}; ::stat(path.c_str(), &st) == 0 && !S_ISDIR(st.st_mode)) checks::require_regular_file(path, path, "INPUT");
  const bool dir = fs::is_directory(path, ec);
  if (::access(path.c_str(), dir ? (R_OK | X_OK) : R_OK) != 0)
    throw Error(ExitCode::InputNotFound, path + ": cannot be read (" + std::strerror(errno) + ")");
  LoadedScan scan;
  const std::string kind = fs::is_directory(path, ec) ? "" : volume_kind(path);
  if (kind.empty())
    scan = read_dicom(path, options);  // a folder, or a single (e.g. enhanced multi-frame) DICOM file
  else
    scan = read_volume_file(path, kind, options);
  if (!options.orientation.empty()) {
    if (scan.info.kind == "dicom")
      throw Error(ExitCode::Usage, path + ": --orientation applies to volume files; DICOM carries its own orientation");
    scan.volume.geom.direction = direction_from_code(options.orientation, path);
    scan.info.warnings.erase(std::remove_if(scan.info.warnings.begin(), scan.info.warnings.end(),
                                            [](const std::string& w) { return w.find("not anatomical") != std::string::npos; }),
                             scan.info.warnings.end());
  }
  scan.stored_order = canonical_order(scan.volume.geom, scan.volume.hu);
  finish(scan, options.hu_offset);
  // Left and right are never guessed: a NIfTI without qform or sform code
  // needs --orientation (checked last, so that any other problem is named first).
  std::string why;
  if (kind == "nifti" && options.orientation.empty() && checks::nifti_orientation(path, &why) == checks::NiftiOrientation::NotCoded)
    throw Error(ExitCode::InputInvalid, path + ": NIfTI has no orientation (qform_code = sform_code = 0): left and right are " +
                                            "unknown and never guessed; give the axes with --orientation (e.g. LPS)");
  return scan;
}

namespace {

// Writes a buffer on a grid as an ITK image file (format from the extension).
template <class ImageT, class Values>
void write_image(const Geometry& geom, const Values& values, const std::string& path, const char* what) {
  register_factories();
  auto img = make_image<ImageT>(geom);
  std::copy(values.begin(), values.end(), img->GetBufferPointer());
  auto writer = itk::ImageFileWriter<ImageT>::New();
  writer->SetInput(img);
  writer->SetFileName(path);
  writer->UseCompressionOn();
  try {
    writer->Update();
  } catch (const itk::ExceptionObject& e) {
    throw Error(ExitCode::OutputFailed, path + ": cannot write " + what + ": " + first_line(e.GetDescription()));
  }
}

}  // namespace

void write_volume(const Volume& volume, const std::string& path) {
  write_image<FloatImage>(volume.geom, volume.hu, path, "volume");
}

void write_mask(const Mask& mask, const std::string& path) { write_image<MaskImage>(mask.geom, mask.data, path, "mask"); }

namespace {
// A mask or label map read as float whatever its stored type (so that a
// float or signed file is not converted by a narrowing cast), after the same
// existence and NIfTI payload checks as a volume. Non-finite values refused.
FloatImage::Pointer read_float_image(const std::string& path, const char* what) {
  register_factories();
  std::error_code ec;
  if (!fs::exists(path, ec)) throw Error(ExitCode::InputNotFound, path + ": no such file");
  if (::access(path.c_str(), R_OK) != 0) throw Error(ExitCode::InputNotFound, path + ": cannot be read (" + std::strerror(errno) + ")");
  check_before_reading(path, what, ReadOptions{});
  auto reader = itk::ImageFileReader<FloatImage>::New();
  if (const std::string kind = volume_kind(path); !kind.empty()) reader->SetImageIO(image_io_for(kind, path));
  reader->SetFileName(path);
  if (const std::string failed = try_update(reader); !failed.empty())
    throw Error(ExitCode::InputInvalid, path + ": cannot read " + what + ": " + failed);
  FloatImage::Pointer img = reader->GetOutput();
  const float* buf = img->GetBufferPointer();
  const std::size_t n = img->GetLargestPossibleRegion().GetNumberOfPixels();
  std::size_t bad = 0;
  for (std::size_t i = 0; i < n; ++i) bad += !std::isfinite(buf[i]);
  if (bad) throw Error(ExitCode::InputInvalid, path + ": " + what + " has " + std::to_string(bad) + " NaN or infinite voxels");
  return img;
}
}  // namespace

Mask read_mask(const std::string& path) {
  const FloatImage::Pointer img = read_float_image(path, "mask");
  Mask m;
  m.geom = geometry_of(img.GetPointer());
  const float* buf = img->GetBufferPointer();
  m.data.resize(m.geom.voxel_count());
  for (std::size_t i = 0; i < m.data.size(); ++i) m.data[i] = buf[i] != 0;
  canonical_order(m.geom, m.data);
  return m;
}

LabelMap read_label_map(const std::string& path) {
  const FloatImage::Pointer img = read_float_image(path, "label map");
  LabelMap m;
  m.geom = geometry_of(img.GetPointer());
  const float* buf = img->GetBufferPointer();
  m.labels.resize(m.geom.voxel_count());
  for (std::size_t i = 0; i < m.labels.size(); ++i) {
    const float v = std::round(buf[i]);
    if (std::abs(v) > 2.0e9f)
      throw Error(ExitCode::InputInvalid, path + ": label map value " + std::to_string(v) + " is not a label");
    m.labels[i] = static_cast<std::int32_t>(v);
  }
  canonical_order(m.geom, m.labels);
  return m;
}

namespace {

using DicomSliceImage = itk::Image<short, 2>;
using DicomShortImage = itk::Image<short, 3>;

// The voxels as written: HU rounded to integers, clamped to [-1024, 30000].
DicomShortImage::Pointer stored_image(const Volume& ct) {
  auto img = make_image<DicomShortImage>(ct.geom);
  short* buf = img->GetBufferPointer();
  for (std::size_t i = 0; i < ct.hu.size(); ++i) {
    const float v = std::round(ct.hu[i]);
    buf[i] = static_cast<short>(std::clamp(v, -1024.0f, 30000.0f));
  }
  return img;
}

std::string dicom_number(double v) {
  std::ostringstream s;
  s << std::setprecision(10) << v;
  return s.str();
}

// ImageOrientationPatient: the row direction, then the column direction.
std::string image_orientation(const Geometry& g) {
  std::string iop;
  for (int c = 0; c < 2; ++c)
    for (int r = 0; r < 3; ++r) iop += (iop.empty() ? "" : "\\") + dicom_number(g.direction[3 * r + c]);
  return iop;
}

void set_tag(itk::MetaDataDictionary& d, const char* tag, const std::string& v) {
  itk::EncapsulateMetaData<std::string>(d, tag, v);
}

// The UIDs every slice of the series shares.
struct SeriesUids {
  std::string study, series, frame_of_reference;
};

// The header of slice k: CT Image Storage with its study, patient and
// equipment attributes from spec (Type 2 attributes a phantom has no value
// for left empty).
void set_slice_identity(itk::MetaDataDictionary& d, const DicomSeriesSpec& spec, const SeriesUids& uids,
                        const std::string& sop_instance_uid, std::size_t k) {
  set_tag(d, "0008|0016", "1.2.840.10008.5.1.4.1.1.2");  // CT Image Storage
  set_tag(d, "0008|0018", sop_instance_uid);
  set_tag(d, "0008|0060", "CT");
  set_tag(d, "0008|0008", "DERIVED\\SECONDARY\\AXIAL");
  set_tag(d, "0008|0020", spec.study_date);
  set_tag(d, "0008|0021", spec.study_date);
  set_tag(d, "0008|0022", spec.study_date);   // AcquisitionDate
  set_tag(d, "0008|0023", spec.study_date);   // ContentDate
  set_tag(d, "0008|0012", spec.study_date);   // InstanceCreationDate
  for (const char* tag : {"0008|0030", "0008|0031", "0008|0032", "0008|0033", "0008|0013"}) set_tag(d, tag, spec.study_time);
  set_tag(d, "0020|0012", "1");               // AcquisitionNumber
  set_tag(d, "0020|0010", "1");               // StudyID
  set_tag(d, "0018|5100", "HFS");             // PatientPosition (head first supine), Type 2C in CT
  set_tag(d, "0020|0060", "");                // Laterality, Type 2C: the head is not a paired structure
  set_tag(d, "0020|1040", "");                // PositionReferenceIndicator, Type 2: none for a phantom
  set_tag(d, "0018|0060", "");                // KVP, Type 2: a phantom has no tube voltage
  set_tag(d, "0008|0070", spec.manufacturer);
  set_tag(d, "0008|1090", spec.model);
  set_tag(d, "0008|1030", spec.study_description);
  set_tag(d, "0008|103e", spec.series_description);
  set_tag(d, "0010|0010", spec.patient_name);
  set_tag(d, "0010|0020", spec.patient_id);
  set_tag(d, "0010|0030", "");
  set_tag(d, "0010|0040", "O");
  set_tag(d, "0018|1210", spec.kernel);
  set_tag(d, "0020|000d", uids.study);
  set_tag(d, "0020|000e", uids.series);
  set_tag(d, "0020|0052", uids.frame_of_reference);
  set_tag(d, "0020|0011", "1");
  set_tag(d, "0020|0013", std::to_string(k + 1));
}

// The image plane and pixel value attributes of slice k (iop: image_orientation).
void set_slice_plane(itk::MetaDataDictionary& d, const Geometry& g, const std::string& iop, std::size_t k) {
  set_tag(d, "0018|0050", dicom_number(g.spacing[2]));
  set_tag(d, "0018|0088", dicom_number(g.spacing[2]));
  const Vec3 p = g.index_to_lps(0, 0, static_cast<double>(k));
  set_tag(d, "0020|0032", dicom_number(p[0]) + "\\" + dicom_number(p[1]) + "\\" + dicom_number(p[2]));
  set_tag(d, "0020|0037", iop);
  set_tag(d, "0020|1041", dicom_number(dot(p, Vec3{g.direction[2], g.direction[5], g.direction[8]})));
  set_tag(d, "0028|0030", dicom_number(g.spacing[1]) + "\\" + dicom_number(g.spacing[0]));  // row spacing \ column spacing
  set_tag(d, "0028|0004", "MONOCHROME2");
  set_tag(d, "0028|1052", "-1024");
  set_tag(d, "0028|1053", "1");
  set_tag(d, "0028|1054", "HU");
  set_tag(d, "0028|1050", "400");
  set_tag(d, "0028|1051", "2000");
}

// GDCM's writer for the transfer syntax spec.compression names.
itk::GDCMImageIO::Pointer dicom_image_io(const std::string& compression) {
  auto gdcm_io = itk::GDCMImageIO::New();
  gdcm_io->KeepOriginalUIDOn();
  if (compression == "raw") return gdcm_io;
  gdcm_io->UseCompressionOn();
  if (compression == "jpeg-lossless")
    gdcm_io->SetCompressionType(itk::GDCMImageIO::CompressionEnum::JPEG);
  else if (compression == "jpeg2000")
    gdcm_io->SetCompressionType(itk::GDCMImageIO::CompressionEnum::JPEG2000);
  else
    throw Error(ExitCode::Usage, "unknown DICOM compression '" + compression + "' (expected raw, jpeg-lossless or jpeg2000)");
  return gdcm_io;
}

}  // namespace

std::string write_dicom_series(const Volume& ct, const DicomSeriesSpec& spec, const std::string& dir) {
  register_factories();
  const Geometry& g = ct.geom;
  const DicomShortImage::Pointer img = stored_image(ct);
  gdcm::UIDGenerator uidgen;
  SeriesUids uids;
  uids.study = spec.study_uid.empty() ? uidgen.Generate() : spec.study_uid;
  uids.series = spec.series_uid.empty() ? uidgen.Generate() : spec.series_uid;
  uids.frame_of_reference = uidgen.Generate();
  const std::string iop = image_orientation(g);

  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw Error(ExitCode::OutputFailed, dir + ": cannot create folder: " + ec.message());

  std::vector<itk::MetaDataDictionary> dicts(g.size[2]);
  std::vector<itk::MetaDataDictionary*> dict_ptrs;
  std::vector<std::string> files;
  for (std::size_t k = 0; k < g.size[2]; ++k) {
    set_slice_identity(dicts[k], spec, uids, uidgen.Generate(), k);
    set_slice_plane(dicts[k], g, iop, k);
    dict_ptrs.push_back(&dicts[k]);
    std::ostringstream name;
    name << spec.file_prefix << std::setw(4) << std::setfill('0') << (k + 1) << ".dcm";
    files.push_back((fs::path(dir) / name.str()).string());
  }

  auto gdcm_io = dicom_image_io(spec.compression);
  auto writer = itk::ImageSeriesWriter<DicomShortImage, DicomSliceImage>::New();
  writer->SetInput(img);
  writer->SetImageIO(gdcm_io);
  writer->SetFileNames(files);
  writer->SetMetaDataDictionaryArray(&dict_ptrs);
  writer->SetUseCompression(spec.compression != "raw");  // the writer overrides the IO flag
  try {
    writer->Update();
  } catch (const itk::ExceptionObject& e) {
    throw Error(ExitCode::OutputFailed, dir + ": cannot write DICOM series: " + first_line(e.GetDescription()));
  }
  return uids.series;
}

}  // namespace ms::io
