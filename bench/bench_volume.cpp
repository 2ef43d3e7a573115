// Kernels of the ITK-facing stages (the ITK side of the ITK / Eigen split,
// ENGINEERING.md): mandible segmentation, the segmentation QC slices and the
// NIfTI mask writer, on the head phantom at 1.0 and 0.5 mm. Only the stages'
// value-type headers are included; nothing here may include Eigen, CGAL or
// Ceres.
#include <benchmark/benchmark.h>

#include <cstdio>
#include <filesystem>
#include <string>

#include "bench/fixtures.h"
#include "bench/registry.h"
#include "core/distance_transform.h"
#include "io/volume_io.h"
#include "reports/figures.h"
#include "segmentation/segmentation.h"

namespace ms::bench {

namespace {

namespace fs = std::filesystem;

std::string spacing_label(double mm) {
  char b[32];
  std::snprintf(b, sizeof b, "%.1fmm", mm);
  return b;
}

void segment(benchmark::State& state, double spacing_mm) {
  const Volume& ct = head_phantom(spacing_mm).ct;
  segmentation::Result r;
  for (auto _ : state) {
    r = segmentation::segment_mandible(ct);
    benchmark::DoNotOptimize(r.mask.data.data());
  }
  state.counters[kVoxelsCounter] = static_cast<double>(ct.geom.voxel_count());
  state.counters["mask_voxels"] = static_cast<double>(r.voxels);
}

// The segmentation's distance kernel: depth inside the bone mask (HU >= 250)
// of the whole head, an exact Euclidean transform.
void bone_depth(benchmark::State& state, double spacing_mm) {
  const Volume& ct = head_phantom(spacing_mm).ct;
  std::vector<std::uint8_t> bone(ct.hu.size());
  for (std::size_t i = 0; i < bone.size(); ++i) bone[i] = ct.hu[i] >= 250.0f;
  for (auto _ : state) {
    const auto d = depth_inside(bone.data(), ct.geom.size, ct.geom.spacing);
    benchmark::DoNotOptimize(d.data());
  }
  state.counters[kVoxelsCounter] = static_cast<double>(ct.geom.voxel_count());
}

void qc_slices(benchmark::State& state, double spacing_mm) {
  const auto& ph = head_phantom(spacing_mm);
  const fs::path dir = scratch_dir() / ("qc-" + spacing_label(spacing_mm));
  fs::create_directories(dir);
  for (auto _ : state) {
    const auto files = reports::write_qc_slices(ph.ct, ph.mandible, dir.string());
    benchmark::DoNotOptimize(files.data());
  }
  state.counters[kVoxelsCounter] = static_cast<double>(ph.ct.geom.voxel_count());
}

void write_mask(benchmark::State& state, double spacing_mm) {
  const auto& ph = head_phantom(spacing_mm);
  const std::string path = (scratch_dir() / ("mask-" + spacing_label(spacing_mm) + ".nii.gz")).string();
  for (auto _ : state) io::write_mask(ph.mandible, path);
  state.counters[kVoxelsCounter] = static_cast<double>(ph.mandible.geom.voxel_count());
  state.counters["bytes"] = static_cast<double>(fs::file_size(path));
}

}  // namespace

const std::vector<double>& volume_spacings_mm() {
  static const std::vector<double> s{1.0, 0.5};
  return s;
}

void register_volume_kernels() {
  for (double mm : volume_spacings_mm())
    benchmark::RegisterBenchmark(("segmentation/segment_mandible/" + spacing_label(mm)).c_str(), segment, mm)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
  for (double mm : volume_spacings_mm())
    benchmark::RegisterBenchmark(("segmentation/bone_depth_edt/" + spacing_label(mm)).c_str(), bone_depth, mm)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
  for (double mm : volume_spacings_mm())
    benchmark::RegisterBenchmark(("report/qc_slices/" + spacing_label(mm)).c_str(), qc_slices, mm)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
  for (double mm : volume_spacings_mm())
    benchmark::RegisterBenchmark(("report/write_mask_nii_gz/" + spacing_label(mm)).c_str(), write_mask, mm)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
}

}  // namespace ms::bench
