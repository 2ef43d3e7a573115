// mandisym_bench: Google Benchmark kernels of every pipeline stage, with each
// kernel's time also given as a ratio to baselines measured in the same run
// (docs/benchmarks.md):
//   x_sort    kernel time / time to copy and sort 2^20 doubles on one core
//   x_stream  volume kernels only: kernel time / one memory-bound pass over a
//             float volume with the same number of voxels
// The ratios are added to each run as counters (console and JSON output, and
// the --benchmark_out file when its format is json or console) and printed
// again as a markdown table at the end of a console run.
//
// The baselines always run: a --benchmark_filter is widened with
// "^baseline/" (a negative filter, "-...", is left as it is).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "bench/fixtures.h"
#include "bench/registry.h"
#include "core/memory.h"

namespace ms::bench {

namespace {

double seconds_per_iteration(const benchmark::BenchmarkReporter::Run& r) {
  double scale = 1.0;
  switch (r.time_unit) {
    case benchmark::kNanosecond: scale = 1e-9; break;
    case benchmark::kMicrosecond: scale = 1e-6; break;
    case benchmark::kMillisecond: scale = 1e-3; break;
    case benchmark::kSecond: scale = 1.0; break;
  }
  return r.GetAdjustedRealTime() * scale;
}

bool starts_with(const std::string& s, const std::string& prefix) { return s.compare(0, prefix.size(), prefix) == 0; }

// Baseline times seen so far in this run (fastest iteration run of each).
struct Baselines {
  std::map<std::string, double> seconds;
  const double* find(const std::string& name) const {
    auto it = seconds.find(name);
    return it == seconds.end() ? nullptr : &it->second;
  }
};

// Wraps a reporter: records baseline times, adds x_sort / x_stream counters to
// every kernel run before passing it on.
class RatioReporter : public benchmark::BenchmarkReporter {
 public:
  // owned: whether this reporter deletes inner (the library's default display
  // reporter is not ours to delete).
  RatioReporter(benchmark::BenchmarkReporter* inner, bool owned, Baselines* baselines, bool summary)
      : inner_(inner), owned_(owned ? inner : nullptr), baselines_(baselines), summary_(summary) {}

  bool ReportContext(const Context& context) override {
    // The library may have pointed this reporter at a file (--benchmark_out).
    inner_->SetOutputStream(&GetOutputStream());
    inner_->SetErrorStream(&GetErrorStream());
    return inner_->ReportContext(context);
  }

  void ReportRuns(const std::vector<Run>& runs) override {
    std::vector<Run> out = runs;
    for (Run& r : out) {
      if (r.error_occurred) continue;
      if (r.run_type == Run::RT_Aggregate && r.aggregate_unit != benchmark::kTime) continue;
      const std::string name = r.run_name.function_name;
      const double s = seconds_per_iteration(r);
      if (starts_with(name, kBaselinePrefix)) {
        if (r.run_type == Run::RT_Iteration) {
          auto [it, fresh] = baselines_->seconds.emplace(name, s);
          if (!fresh) it->second = std::min(it->second, s);
        }
        continue;
      }
      double x_sort = -1, x_stream = -1;
      if (const double* b = baselines_->find(kSortBaseline)) r.counters["x_sort"] = x_sort = s / *b;
      if (auto v = r.counters.find(kVoxelsCounter); v != r.counters.end()) {
        const auto voxels = static_cast<std::size_t>(v->second.value + 0.5);
        if (const double* b = baselines_->find(stream_baseline_name(voxels)))
          r.counters["x_stream"] = x_stream = s / *b;
      }
      if (r.run_type == Run::RT_Iteration || r.aggregate_name == "median")
        rows_.push_back({name, s, x_sort, x_stream, r.run_type == Run::RT_Aggregate});
    }
    inner_->ReportRuns(out);
  }

  void Finalize() override {
    inner_->Finalize();
    if (!summary_) return;
    std::ostream& os = GetOutputStream();
    os << "\nRatios to the baselines of this run (" << kSortBaseline;
    if (const double* b = baselines_->find(kSortBaseline)) {
      char t[64];
      std::snprintf(t, sizeof t, ": %.1f ms", *b * 1e3);
      os << t;
    } else {
      os << ": not run";
    }
    os << "; stream_volume/N per volume size):\n\n";
    os << "| kernel | time (ms) | x sort | x stream |\n|---|---:|---:|---:|\n";
    // With repetitions, show the median aggregate only.
    const bool have_median = std::any_of(rows_.begin(), rows_.end(), [](const Row& r) { return r.aggregate; });
    for (const Row& r : rows_) {
      if (have_median && !r.aggregate) continue;
      char line[512];
      char xs[32] = "", xm[32] = "";
      if (r.x_sort >= 0) std::snprintf(xs, sizeof xs, "%.3g", r.x_sort);
      if (r.x_stream >= 0) std::snprintf(xm, sizeof xm, "%.3g", r.x_stream);
      std::snprintf(line, sizeof line, "| %s | %.1f | %s | %s |\n", r.name.c_str(), r.seconds * 1e3, xs, xm);
      os << line;
    }
  }

 private:
  struct Row {
    std::string name;
    double seconds, x_sort, x_stream;
    bool aggregate;
  };
  benchmark::BenchmarkReporter* inner_;
  std::unique_ptr<benchmark::BenchmarkReporter> owned_;
  Baselines* baselines_;
  bool summary_;
  std::vector<Row> rows_;
};

// Value of --flag=VALUE in argv (empty when absent). Read before Initialize,
// which consumes the benchmark flags.
std::string flag_value(int argc, char** argv, const char* flag) {
  const std::string prefix = std::string("--") + flag + "=";
  std::string v;
  for (int i = 1; i < argc; ++i)
    if (starts_with(argv[i], prefix)) v = argv[i] + prefix.size();
  return v;
}

}  // namespace

}  // namespace ms::bench

int main(int argc, char** argv) {
  using namespace ms::bench;
  ms::tune_allocator_for_volumes();  // as mandisym does: kernels see the product's allocator
  const std::string display_format = flag_value(argc, argv, "benchmark_format");
  const std::string out_file = flag_value(argc, argv, "benchmark_out");
  const std::string out_format = flag_value(argc, argv, "benchmark_out_format");

  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;

  std::vector<std::size_t> stream_voxels;
  for (double mm : volume_spacings_mm()) stream_voxels.push_back(head_phantom_voxels(mm));
  register_baselines(stream_voxels);
  register_volume_kernels();
  register_mesh_kernels();

  std::string filter = benchmark::GetBenchmarkFilter();
  if (!filter.empty() && filter != "all" && filter != "." && filter[0] != '-')
    benchmark::SetBenchmarkFilter("^" + kBaselinePrefix + "|" + filter);

  Baselines baselines;
  const bool console = display_format.empty() || display_format == "console";
  RatioReporter display(benchmark::CreateDefaultDisplayReporter(), false, &baselines, console);
  std::unique_ptr<RatioReporter> file;
  if (!out_file.empty() && (out_format.empty() || out_format == "json" || out_format == "console")) {
    benchmark::BenchmarkReporter* inner = out_format == "console"
                                              ? static_cast<benchmark::BenchmarkReporter*>(new benchmark::ConsoleReporter(
                                                    benchmark::ConsoleReporter::OO_None))
                                              : new benchmark::JSONReporter();
    file = std::make_unique<RatioReporter>(inner, true, &baselines, false);
  }
  benchmark::RunSpecifiedBenchmarks(&display, file.get());
  benchmark::Shutdown();
  return 0;
}
