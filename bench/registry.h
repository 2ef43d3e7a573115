// Registration of the kernel benchmarks (bench/). Benchmarks are registered
// from main() in a fixed order, baselines first, so that every kernel's ratio
// to the baselines of the same run can be computed as it is reported
// (bench/main.cpp).
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace ms::bench {

// Name prefix shared by every baseline benchmark.
inline const std::string kBaselinePrefix = "baseline/";
// Sort baseline: copy and std::sort kSortCount doubles (one core, CPU-bound).
constexpr std::size_t kSortCount = std::size_t{1} << 20;
inline const std::string kSortBaseline = kBaselinePrefix + "sort_doubles/" + std::to_string(kSortCount);
// Memory-bound baseline over a float volume of `voxels` voxels.
inline std::string stream_baseline_name(std::size_t voxels) {
  return kBaselinePrefix + "stream_volume/" + std::to_string(voxels);
}
// Counter a volume kernel sets to the voxel count of its input; the reporter
// then adds its ratio to stream_baseline_name(voxels).
inline const std::string kVoxelsCounter = "voxels";

void register_baselines(const std::vector<std::size_t>& stream_voxels);  // baseline.cpp
void register_volume_kernels();  // bench_volume.cpp: ITK-facing stages (segmentation, QC slices, mask writer)
void register_mesh_kernels();    // bench_mesh.cpp: VTK / CGAL / Ceres / Eigen-facing stages

// Volume kernels' spacings (mm); their stream baselines are registered for them.
const std::vector<double>& volume_spacings_mm();

}  // namespace ms::bench
