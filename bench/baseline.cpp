// Baselines measured in the same run as the kernels, so that kernel times can
// be read as ratios that transfer between machines (docs/benchmarks.md):
//  - sort: copy and std::sort 2^20 pseudo-random doubles on one core (integer
//    and branch heavy, cache-friendly: a proxy for single-core speed);
//  - stream_volume/N: one pass y = a x + b over a float volume of N voxels,
//    read 4 B + write 4 B per voxel, one core (a proxy for memory bandwidth),
//    for each volume size a volume kernel runs on.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <random>
#include <vector>

#include "bench/registry.h"

namespace ms::bench {

namespace {

void sort_doubles(benchmark::State& state) {
  std::vector<double> input(kSortCount);
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> u(-1e6, 1e6);
  for (double& x : input) x = u(rng);
  std::vector<double> work;
  for (auto _ : state) {
    work = input;
    std::sort(work.begin(), work.end());
    benchmark::DoNotOptimize(work.data());
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(kSortCount));
}

void stream_volume(benchmark::State& state, std::size_t voxels) {
  std::vector<float> in(voxels), out(voxels);
  for (std::size_t i = 0; i < voxels; ++i) in[i] = static_cast<float>(i % 4096) - 1024.0f;
  for (auto _ : state) {
    const float* x = in.data();
    float* y = out.data();
    for (std::size_t i = 0; i < voxels; ++i) y[i] = 0.5f * x[i] + 3.0f;
    benchmark::DoNotOptimize(y);
    benchmark::ClobberMemory();
  }
  state.SetBytesProcessed(state.iterations() * static_cast<std::int64_t>(voxels * 2 * sizeof(float)));
  state.counters[kVoxelsCounter] = static_cast<double>(voxels);
}

}  // namespace

void register_baselines(const std::vector<std::size_t>& stream_voxels) {
  benchmark::RegisterBenchmark(kSortBaseline.c_str(), sort_doubles)->Unit(benchmark::kMillisecond)->UseRealTime();
  for (std::size_t n : stream_voxels)
    benchmark::RegisterBenchmark(stream_baseline_name(n).c_str(), stream_volume, n)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
}

}  // namespace ms::bench
