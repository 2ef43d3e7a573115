// Step timing for profiling: when the environment variable named at
// construction is set (e.g. MANDISYM_DEBUG_SEG=1), each call prints the time
// since the previous one to stderr. Costs one getenv when off.
#pragma once

#include <chrono>
#include <cstdio>
#include <cstdlib>

namespace ms {

class DebugLap {
 public:
  DebugLap(const char* env, const char* prefix) : on_(std::getenv(env) != nullptr), prefix_(prefix) {}
  bool on() const { return on_; }
  void operator()(const char* step) {
    if (!on_) return;
    const auto now = std::chrono::steady_clock::now();
    std::fprintf(stderr, "  %s %-22s %6.2f s\n", prefix_, step, std::chrono::duration<double>(now - t_).count());
    t_ = now;
  }

 private:
  bool on_;
  const char* prefix_;
  std::chrono::steady_clock::time_point t_ = std::chrono::steady_clock::now();
};

}  // namespace ms
