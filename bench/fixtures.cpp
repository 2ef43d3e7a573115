#include "bench/fixtures.h"

#include <unistd.h>

#include <cmath>
#include <map>
#include <memory>
#include <mutex>

namespace ms::bench {

namespace {

phantom::PhantomParams head_params(double spacing_mm) {
  phantom::PhantomParams p;
  p.spacing = {spacing_mm, spacing_mm, spacing_mm};
  p.fov_mm = {150, 140, 130};
  p.yaw_deg = 8;
  p.pitch_deg = 6;
  p.roll_deg = -5;
  p.side[0].ramus_height_mm = 4;
  return p;
}

std::mutex cache_mutex;

}  // namespace

const phantom::Phantom& head_phantom(double spacing_mm) {
  static std::map<double, std::unique_ptr<phantom::Phantom>> cache;
  std::lock_guard<std::mutex> lock(cache_mutex);
  auto& slot = cache[spacing_mm];
  if (!slot) slot = std::make_unique<phantom::Phantom>(phantom::generate(head_params(spacing_mm)));
  return *slot;
}

std::size_t head_phantom_voxels(double spacing_mm) {
  // The phantom's rule: grid size = round(fov / spacing) per axis.
  const auto p = head_params(spacing_mm);
  std::size_t n = 1;
  for (int a = 0; a < 3; ++a) n *= static_cast<std::size_t>(std::lround(p.fov_mm[a] / p.spacing[a]));
  return n;
}

const MeshCase& mandible_mesh(double edge_mm) {
  static std::map<double, std::unique_ptr<MeshCase>> cache;
  {
    std::lock_guard<std::mutex> lock(cache_mutex);
    if (auto it = cache.find(edge_mm); it != cache.end()) return *it->second;
  }
  const phantom::Phantom& ph = head_phantom(1.0);  // takes the lock itself
  auto c = std::make_unique<MeshCase>();
  surface::Options so;
  so.target_edge_mm = edge_mm;
  c->surface = surface::mesh_from_mask(ph.mandible, so);
  c->landmarks = landmarks::detect(c->surface.mesh);
  c->reference = reference::fit(c->landmarks.landmarks, &c->surface.mesh);
  std::lock_guard<std::mutex> lock(cache_mutex);
  auto& slot = cache[edge_mm];
  if (!slot) slot = std::move(c);
  return *slot;
}

const std::filesystem::path& scratch_dir() {
  struct Scratch {
    std::filesystem::path path =
        std::filesystem::temp_directory_path() / ("mandisym-bench-" + std::to_string(::getpid()));
    Scratch() { std::filesystem::create_directories(path); }
    ~Scratch() {
      std::error_code ec;
      std::filesystem::remove_all(path, ec);
    }
  };
  static const Scratch s;
  return s.path;
}

}  // namespace ms::bench
