#include "tests/support/openkbp.h"

#include <fstream>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace ms::testing {
namespace {

constexpr std::size_t kN = 128;

std::vector<std::pair<std::size_t, std::string>> read_sparse(const std::string& path) {
  std::ifstream f(path);
  if (!f) throw std::runtime_error("cannot open " + path);
  std::string line;
  std::getline(f, line);  // header ",data"
  std::vector<std::pair<std::size_t, std::string>> rows;
  while (std::getline(f, line)) {
    const auto comma = line.find(',');
    if (comma == std::string::npos) continue;
    rows.emplace_back(std::stoull(line.substr(0, comma)), line.substr(comma + 1));
  }
  return rows;
}

// C-order (row, column, slice) flat index -> our x-fastest (i=column, j=row, k=slice).
std::size_t to_linear(std::size_t flat) {
  const std::size_t slice = flat % kN, col = (flat / kN) % kN, row = flat / (kN * kN);
  return col + kN * (row + kN * slice);
}

}  // namespace

OpenKbpCase load_openkbp(const std::string& dir) {
  std::ifstream vd(dir + "/voxel_dimensions.csv");
  if (!vd) throw std::runtime_error("cannot open " + dir + "/voxel_dimensions.csv");
  double sx = 0, sy = 0, sz = 0;
  vd >> sx >> sy >> sz;
  OpenKbpCase c;
  Geometry& g = c.ct.geom;
  g.size = {kN, kN, kN};
  g.spacing = {sx, sy, sz};
  g.origin = {0, 0, 0};
  g.direction = {1, 0, 0, 0, 1, 0, 0, 0, -1};  // i -> L, j -> P, k -> I
  c.ct.hu.assign(g.voxel_count(), -1000.0f);   // missing indices are 0 = air (HU + 1000)
  for (const auto& [flat, value] : read_sparse(dir + "/ct.csv")) {
    const double v = std::min(4095.0, std::max(0.0, std::stod(value)));
    c.ct.hu[to_linear(flat)] = static_cast<float>(v - 1000.0);
  }
  c.mandible.geom = g;
  c.mandible.data.assign(g.voxel_count(), 0);
  for (const auto& [flat, value] : read_sparse(dir + "/Mandible.csv")) c.mandible.data[to_linear(flat)] = 1;
  return c;
}

double dice(const Mask& a, const Mask& b) { return ms::dice(a, b); }

}  // namespace ms::testing
