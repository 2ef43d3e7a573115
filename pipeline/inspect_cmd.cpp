// `mandisym inspect`: what is in a folder (or file), and what `run` would use.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>

#include "core/error.h"
#include "core/json_text.h"
#include "io/dicom.h"
#include "io/volume_io.h"
#include "pipeline/commands.h"

namespace fs = std::filesystem;

namespace ms::pipeline {

const cli::CommandSpec& inspect_spec() {
  static const cli::CommandSpec s{
      "inspect",
      "List the image series in a folder and show which one `run` would use.",
      "Reads headers only (no pixel data) for DICOM. For each series: modality, description, number of images, "
      "matrix, pixel spacing, slice spacing along the normal, orientation, gantry tilt, extent, and whether it is "
      "usable (with the reason when not). Patient name and ID are never read. For a volume file, prints its grid.",
      {{"PATH", "DICOM folder (searched recursively), DICOM file, or volume file"}},
      {{"json", "", "print JSON instead of a table", ""},
       {"load", "", "also load the chosen series as run would (decode, rescale, resample) and report time and HU range", ""},
       {"help", "", "show this help", ""}}};
  return s;
}

namespace {

std::string shorten(const std::string& uid, std::size_t n) {
  return uid.size() <= n ? uid : "..." + uid.substr(uid.size() - (n - 3));
}

}  // namespace

namespace {

// A volume file (NIfTI, NRRD, MetaImage) rather than a DICOM folder or file.
bool is_volume_file(const std::string& path) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) return false;
  std::string l = path;
  for (auto& c : l) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  for (const char* ext : {".nii", ".nrrd", ".nhdr", ".mha", ".mhd"})
    if (l.find(ext) != std::string::npos) return true;
  return false;
}

std::array<double, 2> value_range(const Volume& v) {
  float mn = 1e30f, mx = -1e30f;
  for (float x : v.hu) mn = std::min(mn, x), mx = std::max(mx, x);
  return {mn, mx};
}

// A volume file: its grid, value range and reading warnings.
int inspect_volume(const std::string& path, bool json) {
  const io::LoadedScan s = io::read_scan(path);
  const Geometry& g = s.volume.geom;
  const auto range = value_range(s.volume);
  if (json) {
    auto o = Json::object();
    o["path"] = path;
    o["kind"] = s.info.kind;
    o["size_voxels"] = json_numbers(g.size);
    o["spacing_mm"] = json_numbers(g.spacing);
    o["origin_mm"] = json_numbers(g.origin);
    o["direction"] = json_numbers(g.direction);
    o["value_range"] = json_numbers(range);
    o["warnings"] = Json::array();
    for (const auto& w : s.info.warnings) o["warnings"].push_back(w);
    std::cout << dump_json(o) << "\n";
    return 0;
  }
  std::printf("%s: %s volume, %zu x %zu x %zu voxels, spacing %.3f x %.3f x %.3f mm, values %.0f..%.0f\n", path.c_str(),
              s.info.kind.c_str(), g.size[0], g.size[1], g.size[2], g.spacing[0], g.spacing[1], g.spacing[2], range[0], range[1]);
  for (const auto& w : s.info.warnings) std::printf("  warning: %s\n", w.c_str());
  return 0;
}

Json series_json(const io::dicom::Series& s, const io::dicom::Layout& L, bool chosen) {
  auto e = Json::object();
  e["label"] = s.label;
  e["series_uid"] = s.uid;
  e["modality"] = s.modality;
  e["description"] = s.description;
  e["images"] = s.frames.size();
  e["files"] = s.files.size();
  e["rows"] = s.frames.empty() ? 0u : s.frames[0].rows;
  e["columns"] = s.frames.empty() ? 0u : s.frames[0].cols;
  e["pixel_spacing_mm"] = s.frames.empty() ? Json() : json_numbers(std::array<double, 2>{s.frames[0].spacing_i, s.frames[0].spacing_j});
  e["slice_spacing_mm"] = L.usable ? Json(L.nominal_spacing) : Json();
  e["orientation"] = L.orientation;
  e["tilt_deg"] = L.tilt_deg;
  e["extent_mm"] = L.extent_mm;
  e["usable"] = L.usable;
  e["problem"] = L.problem;
  e["warnings"] = Json::array();
  for (const auto& w : L.warnings) e["warnings"].push_back(w);
  e["chosen"] = chosen;
  return e;
}

void print_series_table(const io::dicom::ScanResult& sc, const std::vector<io::dicom::Layout>& layouts, int chosen) {
  if (!sc.series.empty())
    std::printf("  %-2s %-24s %-4s %-20s %6s %9s %13s %6s %-8s %5s %7s  %s\n", "#", "series", "mod", "description", "images",
                "matrix", "pixel mm", "slice", "orient", "tilt", "extent", "status");
  for (std::size_t i = 0; i < sc.series.size(); ++i) {
    const auto& s = sc.series[i];
    const auto& L = layouts[i];
    char matrix[32], pix[32];
    std::snprintf(matrix, sizeof matrix, "%ux%u", s.frames[0].cols, s.frames[0].rows);
    std::snprintf(pix, sizeof pix, "%.3fx%.3f", s.frames[0].spacing_i, s.frames[0].spacing_j);
    std::printf("  %-2zu %-24s %-4s %-20.20s %6zu %9s %13s %6.2f %-8s %5.1f %7.1f  %s%s\n", i + 1,
                shorten(s.label, 24).c_str(), s.modality.c_str(), s.description.c_str(), s.frames.size(), matrix, pix,
                L.nominal_spacing, L.orientation.c_str(), L.tilt_deg, L.extent_mm,
                L.usable ? "ok" : ("not usable: " + L.problem).c_str(), static_cast<int>(i) == chosen ? "  <- chosen" : "");
    for (const auto& w : L.warnings) std::printf("       note: %s\n", w.c_str());
  }
}

// --load: the chosen series read as run would read it, timed.
void print_load(const std::string& path) {
  const auto t0 = std::chrono::steady_clock::now();
  const io::LoadedScan s = io::read_scan(path);
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const Geometry& g = s.volume.geom;
  const auto range = value_range(s.volume);
  std::printf("loaded: %zu x %zu x %zu voxels, spacing %.3f x %.3f x %.3f mm, HU %.0f..%.0f, %.2f s\n", g.size[0], g.size[1],
              g.size[2], g.spacing[0], g.spacing[1], g.spacing[2], range[0], range[1], secs);
  for (const auto& w : s.info.warnings) std::printf("  warning: %s\n", w.c_str());
}

}  // namespace

int inspect_command(const cli::Args& a) {
  const std::string path = a.positional.at(0);
  std::error_code ec;
  if (!fs::exists(path, ec)) throw Error(ExitCode::InputNotFound, path + ": no such file or directory");
  if (is_volume_file(path)) return inspect_volume(path, a.has("json"));
  const io::dicom::ScanResult sc = io::dicom::scan(path);
  std::vector<io::dicom::Layout> layouts;
  for (const auto& s : sc.series) layouts.push_back(io::dicom::analyse(s));
  std::string why;
  const int chosen = io::dicom::choose(sc, layouts, &why);
  const int code = chosen >= 0 ? 0 : static_cast<int>(ExitCode::InputInvalid);
  if (a.has("json")) {
    auto o = Json::object();
    o["path"] = path;
    o["files"] = sc.files_seen;
    o["dicom_files"] = sc.dicom_files;
    o["non_image_dicom_files"] = sc.non_image_files;
    o["series"] = Json::array();
    for (std::size_t i = 0; i < sc.series.size(); ++i) o["series"].push_back(series_json(sc.series[i], layouts[i], static_cast<int>(i) == chosen));
    o["choice"] = why;
    std::cout << dump_json(o) << "\n";
    return code;
  }
  std::printf("%s: %zu file(s), %zu DICOM, %zu non-image DICOM, %zu image series\n", path.c_str(), sc.files_seen,
              sc.dicom_files, sc.non_image_files, sc.series.size());
  print_series_table(sc, layouts, chosen);
  std::printf("%s %s\n", chosen >= 0 ? "run would use:" : "run would refuse:", why.c_str());
  if (chosen >= 0 && a.has("load")) print_load(path);
  return code;
}

}  // namespace ms::pipeline
