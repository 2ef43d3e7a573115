// ITK-facing translation unit: no system Eigen here (ENGINEERING.md).
#include "segmentation/segmentation.h"
#include "segmentation/atlas_zone.h"
#include "segmentation/occlusion.h"
#include "segmentation/voxel_ops.h"

#include <itkBinShrinkImageFilter.h>
#include <itkImage.h>
#include <itkRegionOfInterestImageFilter.h>

#include <algorithm>
#include <map>
#include <cmath>
#include <limits>
#include <functional>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <set>

#include "atlas/atlas.h"
#include "core/components.h"
#include "core/distance_transform.h"
#include "core/debug_lap.h"
#include "core/error.h"
#include "io/itk_geometry.h"

namespace ms::segmentation {
namespace {

using MaskImage = itk::Image<unsigned char, 3>;
using LabelImage = itk::Image<unsigned int, 3>;

struct Component {
  unsigned label = 0;
  std::size_t voxels = 0;
  Vec3 lo{1e30, 1e30, 1e30}, hi{-1e30, -1e30, -1e30};  // LPS bounding box
};

}  // namespace

namespace {

// Truncation: mask voxels on any face of the grid.
bool touches_border(const Mask& m) {
  const Geometry& g = m.geom;
  for (std::size_t k = 0; k < g.size[2]; ++k)
    for (std::size_t j = 0; j < g.size[1]; ++j) {
      const bool face_kj = k == 0 || j == 0 || k + 1 == g.size[2] || j + 1 == g.size[1];
      for (std::size_t i = 0; i < g.size[0]; i += face_kj ? 1 : g.size[0] - 1) {
        if (m.data[g.linear(i, j, k)]) return true;
        if (g.size[0] == 1) break;
      }
    }
  return false;
}

}  // namespace

namespace {

using FloatImage = itk::Image<float, 3>;

// A core that falls apart one depth step deeper into pieces of which the
// second largest holds at least this fraction is two bones welded together
// (maxilla and mandible through teeth in occlusion: the upper jaw's core is a
// third to a half of the lower's), not a mandible losing a thin part (a
// condyle head or a crown is under a tenth of it).
constexpr double kSecondBoneFraction = 0.2;

// Depth (mm) at which the watershed landscape's depth term saturates.
constexpr float kLandscapeDepthMm = 4.0f;
// HU above soft tissue at which its brightness term saturates (enamel, dense cortex).
constexpr float kLandscapeHuSpan = 2600.0f;

// The watershed landscape at a bone voxel: deep and bright flood first, so
// boundaries settle on geometric necks (cusp contacts) and in intensity
// valleys (occlusal gap, joint space). Depth (mm, capped) and HU above the
// calibrated soft tissue hu0 (capped) each contribute down to -1: levels lie
// in [-2, 0].
inline float landscape_level(float depth_mm, float hu, float hu0) {
  return -std::min(depth_mm, kLandscapeDepthMm) / kLandscapeDepthMm - std::clamp(hu - hu0, 0.0f, kLandscapeHuSpan) / kLandscapeHuSpan;
}
// Longest path through bone (mm) the crowns-by-their-roots partition follows:
// a molar's root and crown together are ~20 mm.
constexpr double kRootReachMm = 25.0;
// Deepest a crown's bone can lie below its surface (mm): half the widest
// crown, a first molar's ~11 mm bucco-lingual diameter (Wheeler's Dental
// Anatomy); an upper and a lower crown welded together are no wider. A piece
// deeper than this is a block of other bone (the skull base by a condyle
// bridged to it: 6.2-13.6 mm on resampled phantoms of another design), not a
// crown (2.3-4.3 mm on the project's phantoms in occlusion).
constexpr float kCrownMaxDepthMm = 5.5f;

// MANDISYM_DEBUG_SEG=1: time of each step on stderr (profiling aid).
struct SegLap : DebugLap {
  SegLap() : DebugLap("MANDISYM_DEBUG_SEG", "seg") {}
};

// Soft tissue on a calibrated scan (HU).
constexpr double kSoftTissueHu = 40.0;

// Calibration offset: the soft-tissue peak of the histogram (expected near
// kSoftTissueHu) within [-60, 160] HU. Returns 0 when there is no usable peak.
double estimate_offset(const Volume& ct, std::size_t* soft_voxels) {
  constexpr int lo = -60, hi = 160, bw = 4;
  std::vector<double> h((hi - lo) / bw + 1, 0.0);
  std::size_t n = 0;
  for (float v : ct.hu)
    if (v >= lo && v <= hi) {
      h[static_cast<std::size_t>((v - lo) / bw)] += 1;
      ++n;
    }
  *soft_voxels = n;
  if (n < 1000) return 0.0;
  std::vector<double> sm(h.size(), 0.0);  // 3-bin smoothing
  for (std::size_t i = 0; i < h.size(); ++i)
    for (int d = -2; d <= 2; ++d) {
      const long j = static_cast<long>(i) + d;
      if (j >= 0 && j < static_cast<long>(h.size())) sm[i] += h[static_cast<std::size_t>(j)];
    }
  const std::size_t peak = static_cast<std::size_t>(std::max_element(sm.begin(), sm.end()) - sm.begin());
  if (peak == 0 || peak + 1 == sm.size()) return 0.0;  // no interior peak: leave calibration alone
  return lo + (peak + 0.5) * bw - kSoftTissueHu;
}

struct Features {
  std::size_t voxels = 0;
  double located = 1.0;  // fraction inside the located region (1 when none is given)
  double prior_sum = 0;  // sum over the core's voxels of the atlas's mandible probability
  Vec3 lo{1e30, 1e30, 1e30}, hi{-1e30, -1e30, -1e30}, sum{0, 0, 0};
  Vec3 centroid() const { return (1.0 / static_cast<double>(voxels)) * sum; }
  double extent(int a) const { return hi[a] - lo[a]; }
};

std::vector<Features> component_features(const LabelImage* labels, unsigned n, const Geometry& g) {
  std::vector<Features> f(n + 1);
  const auto* buf = labels->GetBufferPointer();
  // Run by run along i: LPS is affine in the index, so a run's extremes are at
  // its ends and its sum is its length times the mean of its ends.
  for (std::size_t k = 0; k < g.size[2]; ++k)
    for (std::size_t j = 0; j < g.size[1]; ++j) {
      const unsigned* row = buf + g.linear(0, j, k);
      for (std::size_t i = 0; i < g.size[0];) {
        const unsigned l = row[i];
        std::size_t e = i;
        while (e + 1 < g.size[0] && row[e + 1] == l) ++e;
        if (l) {
          const Vec3 p = g.index_to_lps(static_cast<double>(i), static_cast<double>(j), static_cast<double>(k));
          const Vec3 q = g.index_to_lps(static_cast<double>(e), static_cast<double>(j), static_cast<double>(k));
          const double len = static_cast<double>(e - i + 1);
          Features& c = f[l];
          c.voxels += e - i + 1;
          c.sum = c.sum + (0.5 * len) * (p + q);
          for (int a = 0; a < 3; ++a) {
            c.lo[a] = std::min({c.lo[a], p[a], q[a]});
            c.hi[a] = std::max({c.hi[a], p[a], q[a]});
          }
        }
        i = e + 1;
      }
    }
  return f;
}

// The mandible among bone components: wide (left-right), deep
// (antero-posterior) and tall enough to hold body, rami and condyles, not
// larger than a mandible can be; the lowest such (the skull and maxilla lie above it;
// clavicles are neither deep nor tall; spine and hyoid are narrow or small).
// On a crop around a mandible located on a coarser grid, only cores at least
// min_located inside that region qualify (Options::locate_outside_fraction).
unsigned pick_mandible(const std::vector<Features>& f, double voxel_mm3, double shrink_mm, double min_located) {
  unsigned best = 0;
  double best_z = 1e30;
  for (unsigned l = 1; l < f.size(); ++l) {
    const Features& c = f[l];
    if (c.voxels == 0 || c.located < min_located) continue;
    const double vol_cm3 = c.voxels * voxel_mm3 / 1000.0;
    const double w = c.extent(0) + 2 * shrink_mm, d = c.extent(1) + 2 * shrink_mm, h = c.extent(2) + 2 * shrink_mm;
    // A mandible with teeth is at most ~120 cm3: a larger core is still fused to the skull.
    if (w < 55 || w > 170 || d < 45 || d > 170 || h < 45 || h > 160 || vol_cm3 < 2.0 || vol_cm3 > 150.0) continue;
    // A mandible is wider (bicondylar) than it is tall (condylion to menton);
    // the cervical spine fused with the skull base is the reverse.
    if (h > 1.3 * w) continue;
    if (c.centroid()[2] < best_z) {
      best_z = c.centroid()[2];
      best = l;
    }
  }
  return best;
}

// Identification by the atlas (docs/segmentation.md, step 4): each voxel of
// a core counts the atlas's mandible probability there minus
// kPriorBackground, so that a core holding the mandible scores by its size
// and loses by every voxel of another bone fused to it (skull base, maxilla,
// spine); the vault, the occiput and the vertebrae, where the atlas gives
// no mandible, score below zero. A core qualifies when its mean probability
// is at least kMinCorePrior. The probabilities of the training mandibles
// (3 mm, aligned by similarity) are 0.5-0.95 in the mandible's bone, so
// these thresholds hold with a misfit of several millimetres (docs/atlas.md).
// A core must also hold at least kMinCoreShare of the atlas's mandible mass
// (sum of p, mm3): a piece of a mandible whose thin cortex broke its core
// into fragments is not the mandible's core (the whole-bone solid is tried
// next): such a fragment held 1 % (Visible Human female), while the deepest
// core of a thin, slab-averaged phantom mandible (1 x 1 x 3 mm) still holds 14 %.
constexpr double kPriorBackground = 0.25;
constexpr double kMinCorePrior = 0.3;
constexpr double kMinCoreShare = 0.1;

// Score of a core in cm3 of mandible evidence (above); -inf when it does not qualify.
double atlas_merit(const Features& c, double voxel_mm3, double atlas_mm3) {
  if (c.voxels == 0) return -std::numeric_limits<double>::infinity();
  const double mean = c.prior_sum / static_cast<double>(c.voxels);
  if (mean < kMinCorePrior || c.prior_sum * voxel_mm3 < kMinCoreShare * atlas_mm3) return -std::numeric_limits<double>::infinity();
  return (c.prior_sum - kPriorBackground * static_cast<double>(c.voxels)) * voxel_mm3 / 1000.0;
}

unsigned pick_by_atlas(const std::vector<Features>& f, double voxel_mm3, double atlas_mm3, double min_located) {
  unsigned best = 0;
  double best_merit = 0;
  for (unsigned l = 1; l < f.size(); ++l) {
    if (f[l].located < min_located) continue;
    const double m = atlas_merit(f[l], voxel_mm3, atlas_mm3);
    if (m > best_merit) best_merit = m, best = l;
  }
  return best;
}

// The atlas's mandible probability at every bone voxel of a grid (0 elsewhere).
std::vector<float> prior_at_bone(const atlas::MandiblePrior& prior, const std::uint8_t* bone, const Geometry& g) {
  std::vector<float> out(g.voxel_count(), 0.0f);
  const long nz = static_cast<long>(g.size[2]);
#pragma omp parallel for schedule(static)
  for (long k = 0; k < nz; ++k)
    for (std::size_t j = 0; j < g.size[1]; ++j)
      for (std::size_t i = 0; i < g.size[0]; ++i) {
        const std::size_t idx = g.linear(i, j, static_cast<std::size_t>(k));
        if (bone[idx])
          out[idx] = static_cast<float>(prior.at(g.index_to_lps(static_cast<double>(i), static_cast<double>(j), static_cast<double>(k))));
      }
  return out;
}

// HU values of the crop region (geometry cg) of ct.
std::vector<float> crop_values(const Volume& ct, const MaskImage::RegionType& region, const Geometry& cg) {
  std::vector<float> out(cg.voxel_count());
  const auto ri = region.GetIndex();
  for (std::size_t k = 0; k < cg.size[2]; ++k)
    for (std::size_t j = 0; j < cg.size[1]; ++j)
      for (std::size_t i = 0; i < cg.size[0]; ++i)
        out[cg.linear(i, j, k)] = ct.hu[ct.geom.linear(i + ri[0], j + ri[1], k + ri[2])];
  return out;
}

template <class ImageT>
typename ImageT::Pointer crop(const ImageT* img, const typename ImageT::RegionType& region) {
  auto roi = itk::RegionOfInterestImageFilter<ImageT, ImageT>::New();
  roi->SetInput(img);
  roi->SetRegionOfInterest(region);
  roi->Update();
  return roi->GetOutput();
}

// Connected components of a mask as a label image (core/components.h: ITK's
// connected components and relabelling, by decreasing size, components under
// min_voxels dropped). *count: the number of labels.
LabelImage::Pointer components(const MaskImage* m, bool fully_connected, std::size_t min_voxels, std::size_t* count) {
  auto out = LabelImage::New();
  out->CopyInformation(m);
  out->SetRegions(m->GetLargestPossibleRegion());
  out->Allocate();
  const auto size = m->GetLargestPossibleRegion().GetSize();
  *count = label_components(m->GetBufferPointer(), Dims3{size[0], size[1], size[2]}, fully_connected, min_voxels,
                            out->GetBufferPointer())
               .count;
  return out;
}

// The mask with its enclosed cavities filled: background components
// (face-connected, or face+edge+vertex when fully_connected) that do not
// reach a face of the grid. What ITK's BinaryFillholeImageFilter does, without
// the shape label map it builds on the way (perimeters of every component).
MaskImage::Pointer filled(const MaskImage* in, bool fully_connected) {
  const auto size = in->GetLargestPossibleRegion().GetSize();
  auto out = MaskImage::New();
  out->CopyInformation(in);
  out->SetRegions(in->GetLargestPossibleRegion());
  out->Allocate();
  fill_holes(in->GetBufferPointer(), Dims3{size[0], size[1], size[2]}, fully_connected, out->GetBufferPointer());
  return out;
}

// A bone cut by the scan's edge is open there: its cortex ends at the cut, and
// the cancellous interior reaches the grid's face, where hole filling takes it
// for outside (a ramus cut by a field of view 20 mm off centre lost 24 of its
// 77 cm3). Its own cross-section closes it: on each face of the grid listed in
// `faces` (bit 2a: low face of axis a, bit 2a+1: high face), the background of
// that face's slice not reachable from the slice's rim (8-connected when the
// filling's 3D background is fully connected, else 4-connected) is the lid. With `inside` given, only holes
// made wholly of its voxels are (cancellous bone, not the soft tissue a ring
// of several bones encloses). Returns the lid's voxels, set in m.
std::vector<std::size_t> cap_cut_faces(std::uint8_t* m, const Dims3& d, unsigned faces, bool fully_connected,
                                       const std::uint8_t* inside = nullptr) {
  std::vector<std::size_t> lid;
  for (int a = 0; a < 3; ++a)
    for (int hi = 0; hi < 2; ++hi) {
      if (!(faces & (1u << (2 * a + hi)))) continue;
      const int u = (a + 1) % 3, v = (a + 2) % 3;
      const std::size_t nu = d[u], nv = d[v], w = hi ? d[a] - 1 : 0;
      if (nu < 3 || nv < 3) continue;
      auto at = [&](std::size_t i, std::size_t j) {
        std::array<std::size_t, 3> q{};
        q[a] = w, q[u] = i, q[v] = j;
        return q[0] + d[0] * (q[1] + d[1] * q[2]);
      };
      std::vector<std::uint8_t> open(nu * nv, 0);
      std::vector<std::size_t> stack;
      auto push = [&](std::size_t i, std::size_t j) {
        const std::size_t p = i + nu * j;
        if (!open[p] && !m[at(i, j)]) open[p] = 1, stack.push_back(p);
      };
      for (std::size_t i = 0; i < nu; ++i) push(i, 0), push(i, nv - 1);
      for (std::size_t j = 0; j < nv; ++j) push(0, j), push(nu - 1, j);
      if (inside)
        for (std::size_t j = 0; j < nv; ++j)
          for (std::size_t i = 0; i < nu; ++i)
            if (!inside[at(i, j)]) push(i, j);
      while (!stack.empty()) {
        const std::size_t p = stack.back();
        stack.pop_back();
        const std::size_t i = p % nu, j = p / nu;
        for (int dj = -1; dj <= 1; ++dj)
          for (int di = -1; di <= 1; ++di) {
            if (!fully_connected && di != 0 && dj != 0) continue;
            const long ii = static_cast<long>(i) + di, jj = static_cast<long>(j) + dj;
            if (ii >= 0 && jj >= 0 && ii < static_cast<long>(nu) && jj < static_cast<long>(nv))
              push(static_cast<std::size_t>(ii), static_cast<std::size_t>(jj));
          }
      }
      for (std::size_t j = 0; j < nv; ++j)
        for (std::size_t i = 0; i < nu; ++i) {
          const std::size_t q = at(i, j);
          if (!m[q] && !open[i + nu * j]) m[q] = 1, lid.push_back(q);
        }
    }
  return lid;
}

// A sub-box of a grid: the voxels of a mask with a margin, where local work
// (morphology, distances to the mask) needs to be done.
struct Box {
  std::array<std::size_t, 3> lo{0, 0, 0};
  Dims3 size{0, 0, 0};
};

// Bounding box of the set voxels grown by pad, clipped to the grid (empty mask: empty box).
Box bounding_box(const std::uint8_t* m, const Dims3& dims, std::size_t pad) {
  std::array<std::size_t, 3> lo{dims[0], dims[1], dims[2]}, hi{0, 0, 0};
  bool any = false;
  for (std::size_t k = 0; k < dims[2]; ++k)
    for (std::size_t j = 0; j < dims[1]; ++j) {
      const std::uint8_t* row = m + dims[0] * (j + dims[1] * k);
      const std::uint8_t* first = std::find_if(row, row + dims[0], [](std::uint8_t x) { return x != 0; });
      if (first == row + dims[0]) continue;
      std::size_t last = dims[0] - 1;
      while (!row[last]) --last;
      lo[0] = std::min(lo[0], static_cast<std::size_t>(first - row)), hi[0] = std::max(hi[0], last);
      lo[1] = std::min(lo[1], j), hi[1] = std::max(hi[1], j);
      lo[2] = std::min(lo[2], k), hi[2] = std::max(hi[2], k);
      any = true;
    }
  Box b;
  if (!any) return b;
  for (int a = 0; a < 3; ++a) {
    b.lo[a] = lo[a] > pad ? lo[a] - pad : 0;
    b.size[a] = std::min(dims[a] - 1, hi[a] + pad) - b.lo[a] + 1;
  }
  return b;
}

// The box's part of a grid's values, and back.
template <class T>
std::vector<T> extract(const T* grid, const Dims3& dims, const Box& b) {
  std::vector<T> out(b.size[0] * b.size[1] * b.size[2]);
  for (std::size_t k = 0; k < b.size[2]; ++k)
    for (std::size_t j = 0; j < b.size[1]; ++j)
      std::copy_n(grid + b.lo[0] + dims[0] * ((j + b.lo[1]) + dims[1] * (k + b.lo[2])), b.size[0],
                  out.data() + b.size[0] * (j + b.size[1] * k));
  return out;
}
template <class T>
void insert(const std::vector<T>& part, const Box& b, T* grid, const Dims3& dims) {
  for (std::size_t k = 0; k < b.size[2]; ++k)
    for (std::size_t j = 0; j < b.size[1]; ++j)
      std::copy_n(part.data() + b.size[0] * (j + b.size[1] * k), b.size[0],
                  grid + b.lo[0] + dims[0] * ((j + b.lo[1]) + dims[1] * (k + b.lo[2])));
}

// Face neighbours of a grid's voxels: whether a voxel lies on the grid's
// border (where a neighbour may be missing) is computed once, slice by
// slice, so that the voxels inside need no index arithmetic.
class FaceNeighbours {
 public:
  explicit FaceNeighbours(const Geometry& g)
      : nx_(static_cast<long>(g.size[0])), ny_(static_cast<long>(g.size[1])), nz_(static_cast<long>(g.size[2])),
        step_{1, static_cast<std::size_t>(nx_), static_cast<std::size_t>(nx_ * ny_)}, edge_(g.voxel_count()) {
#pragma omp parallel for schedule(static)
    for (long k = 0; k < nz_; ++k)
      for (long j = 0; j < ny_; ++j) {
        const std::size_t row = static_cast<std::size_t>(nx_) * static_cast<std::size_t>(j + ny_ * k);
        const bool edge_row = j == 0 || k == 0 || j == ny_ - 1 || k == nz_ - 1;
        for (long i = 0; i < nx_; ++i) edge_[row + static_cast<std::size_t>(i)] = edge_row || i == 0 || i == nx_ - 1;
      }
  }
  // Calls f(neighbour, axis) for the face neighbours of voxel c inside the grid.
  template <class F>
  void each(std::size_t c, F&& f) const {
    if (!edge_[c]) {
      for (int a = 0; a < 3; ++a) f(c - step_[a], a), f(c + step_[a], a);
      return;
    }
    const long i = static_cast<long>(c) % nx_, j = (static_cast<long>(c) / nx_) % ny_, k = static_cast<long>(c) / (nx_ * ny_);
    const long idx[3] = {i, j, k}, len[3] = {nx_, ny_, nz_};
    for (int a = 0; a < 3; ++a) {
      if (idx[a] > 0) f(c - step_[a], a);
      if (idx[a] + 1 < len[a]) f(c + step_[a], a);
    }
  }

 private:
  long nx_, ny_, nz_;
  std::size_t step_[3];
  std::vector<std::uint8_t> edge_;
};

// A watershed landscape quantised to 2^16 levels over [lo, hi], a range fixed
// by the landscape's definition, not by the voxels at hand (a crop of the
// grid then floods in the same order as the whole grid: near-equal saddles,
// e.g. crowns in occlusion, are decided the same way), with the grid's face
// neighbours: built once, flooded from several marker sets.
struct Landscape {
  static constexpr std::size_t kLevels = 1u << 16;
  Landscape(const std::vector<float>& level, const Geometry& g, float lo, float hi) : bucket(g.voxel_count()), neighbours(g) {
    const double scale = (kLevels - 1) / (static_cast<double>(hi) - lo);
#pragma omp parallel for schedule(static)
    for (long c = 0; c < static_cast<long>(bucket.size()); ++c)
      bucket[static_cast<std::size_t>(c)] = static_cast<std::uint16_t>(
          std::clamp((static_cast<double>(level[static_cast<std::size_t>(c)]) - lo) * scale + 0.5, 0.0, kLevels - 1.0));
  }
  std::vector<std::uint16_t> bucket;  // each voxel's quantised level
  FaceNeighbours neighbours;
};

// The flooding of watershed_from_markers on voxel indices of type Index
// (32 bits when the grid allows: half the queue's memory traffic).
template <class Index>
std::vector<unsigned> flood_from_markers(const Landscape& land, const std::uint8_t* inside, const unsigned* markers) {
  const std::size_t n = land.bucket.size();
  std::vector<unsigned> label(markers, markers + n);
  const auto& bucket = land.bucket;
  const auto& neighbours = land.neighbours;
  std::vector<std::vector<Index>> queue(Landscape::kLevels);
  for (std::size_t c = 0; c < n; ++c) {
    if (!label[c]) continue;
    bool border = false;
    neighbours.each(c, [&](std::size_t q, int) { border |= !label[q] && inside[q]; });
    if (border) queue[inside[c] ? bucket[c] : 0].push_back(static_cast<Index>(c));
  }
  for (std::size_t b = 0; b < Landscape::kLevels; ++b) {
    std::vector<Index>& cur = queue[b];
    for (std::size_t h = 0; h < cur.size(); ++h) {  // cur grows while it is read
      const std::size_t c = cur[h];
      const unsigned l = label[c];
      neighbours.each(c, [&](std::size_t q, int) {
        if (label[q] || !inside[q]) return;
        label[q] = l;
        queue[std::max<std::size_t>(b, bucket[q])].push_back(static_cast<Index>(q));
      });
    }
    std::vector<Index>().swap(cur);
  }
  return label;
}

// Marker-controlled watershed by priority flooding (Meyer; the flooding of
// ITK's MorphologicalWatershedFromMarkersImageFilter without watershed lines,
// face-connected), restricted to the voxels where inside is set: the voxels
// next to a marker enter a hierarchical queue at their level; the lowest is
// taken and its unlabelled neighbours take its label, entering the queue at
// their own level or, when lower, at the current one (first in, first out
// within a level; levels quantised, see Landscape). Voxels outside `inside`
// and not reached keep label 0. Linear in the voxels flooded.
std::vector<unsigned> watershed_from_markers(const Landscape& land, const std::uint8_t* inside, const unsigned* markers) {
  if (land.bucket.size() <= std::numeric_limits<std::uint32_t>::max())
    return flood_from_markers<std::uint32_t>(land, inside, markers);
  return flood_from_markers<std::size_t>(land, inside, markers);
}

}  // namespace

void fill_holes(const std::uint8_t* m, const Dims3& d, bool fully_connected, std::uint8_t* out) {
  const std::size_t n = d[0] * d[1] * d[2];
  std::vector<std::uint8_t> bg(n);
  for (std::size_t i = 0; i < n; ++i) bg[i] = !m[i];
  std::vector<std::uint32_t> lab(n);
  const std::size_t n_background = label_components(bg.data(), d, fully_connected, 0, lab.data()).count;
  std::vector<std::uint8_t> open(n_background + 1, 0);  // reaches a face
  for (std::size_t k = 0; k < d[2]; ++k)
    for (std::size_t j = 0; j < d[1]; ++j) {
      const bool face = k == 0 || j == 0 || k + 1 == d[2] || j + 1 == d[1];
      const std::size_t row = d[0] * (j + d[1] * k);
      if (face)
        for (std::size_t i = 0; i < d[0]; ++i) open[lab[row + i]] = 1;
      else
        open[lab[row]] = open[lab[row + d[0] - 1]] = 1;
    }
  for (std::size_t i = 0; i < n; ++i) out[i] = m[i] || !open[lab[i]];
}

std::vector<unsigned> watershed(const std::vector<float>& level, const Geometry& g, float lo, float hi,
                                const std::vector<std::uint8_t>& inside, const std::vector<unsigned>& markers) {
  const Landscape land(level, g, lo, hi);
  return watershed_from_markers(land, inside.data(), markers.data());
}

// What a grid's segmentation needs to know beyond its voxels.
struct GridContext {
  double native_max_spacing = 0;  // the scan's own coarsest spacing (the grid may be finer)
  // Whether the scan resolves the cortex (the surface at the half-maximum):
  // voxels up to 1.25 mm along two axes at least, slices up to the coarsest
  // spacing worked at directly (max_working_spacing_mm). Thin in-plane voxels
  // resolve it in-plane (0.5 x 0.5 x 2 mm: Dice 0.918 at 250 HU, 0.978 at the
  // half-maximum); a thicker slab averages a 1.5-3 mm cortex with soft tissue
  // on every horizontal surface, the shell the half-maximum keeps opens and
  // the interior drains (1 x 1 x 3 mm slabs: 0.68, against 0.88 at 250 HU).
  bool cortex_resolved = false;
  // Calibration offset (HU) estimated on the whole scan; NaN: estimate on this grid.
  double offset_hu = std::numeric_limits<double>::quiet_NaN();
  // Faces of this grid that cut through the scan (a crop, not the scan's
  // edge), as {-x, +x, -y, +y, -z, +z}: bone cut there belongs to something
  // larger outside and is never a fragment of the mandible.
  std::array<bool, 6> cut{};
  // The mandible's region as located on a coarser grid (LPS geometry), or
  // null: on a crop, only cores inside it can be the mandible.
  const Mask* located = nullptr;
  // The mandible atlas placed in the scan (LPS), or null / not found: then
  // the mandible is identified by size and position (pick_mandible).
  const atlas::Fit* atlas = nullptr;
};

// Whether the voxel of mask m nearest to (continuous) index q is set (false outside m's grid).
static bool set_at_index(const Mask& m, const Vec3& q) {
  const long x = std::lround(q[0]), y = std::lround(q[1]), z = std::lround(q[2]);
  return x >= 0 && y >= 0 && z >= 0 && x < long(m.geom.size[0]) && y < long(m.geom.size[1]) && z < long(m.geom.size[2]) &&
         m.data[m.geom.linear(static_cast<std::size_t>(x), static_cast<std::size_t>(y), static_cast<std::size_t>(z))] != 0;
}

// Whether the voxel of mask m nearest to LPS point p is set (false outside m's grid).
static bool set_near(const Mask& m, const Vec3& p) { return set_at_index(m, m.geom.lps_to_index(p)); }

// Steps 1-5 of docs/segmentation.md on one grid: the mandible's region and the
// other bones' regions (watershed), on the bone bounding box.
struct Separated {
  MaskImage::RegionType region;      // crop of the input grid
  Geometry cg;                       // crop geometry
  std::vector<std::uint8_t> mand;    // mandible region (bone, before surface placement)
  std::vector<std::uint8_t> other;   // bone given to other markers
  bool separated = false;
  Result info;                       // method, offsets, warnings, radius, marker source
};

// Largest region that can be a fragment of the mandible: max_voxels, or a
// fraction of the mandible's own region if that is larger. A process is a
// fraction of the mandible, whatever the mandible's size (a coronoid process
// cut off by the core depth was 4.4 cm3 of a 75 cm3 region).
static std::size_t fragment_limit(std::size_t mandible_region, std::size_t max_voxels, double max_fraction) {
  return std::max(max_voxels, static_cast<std::size_t>(max_fraction * static_cast<double>(mandible_region)));
}

// Labels of a watershed (0 = none) that belong to the mandible: its own label,
// plus every region of at most fragment_limit() bone voxels whose face contacts with the
// mandible's (growing) region outnumber its contacts with any other single
// region; repeated until nothing joins (a fragment of a fragment).
static std::vector<bool> mandible_fragments(const LabelImage::PixelType* w, const MaskImage::PixelType* bone,
                                            const Geometry& g, unsigned n, unsigned mand, std::size_t max_voxels,
                                            double max_fraction, const std::array<bool, 6>& cut) {
  std::vector<bool> joined(n + 1, false);
  // Regions with bone on a cut face of the grid are parts of larger bones.
  std::vector<bool> on_cut(n + 1, false);
  for (int a = 0; a < 3; ++a)
    for (int side = 0; side < 2; ++side) {
      if (!cut[2 * a + side]) continue;
      const int b = (a + 1) % 3, c = (a + 2) % 3;
      std::size_t v[3];
      v[a] = side ? g.size[a] - 1 : 0;
      for (v[c] = 0; v[c] < g.size[c]; ++v[c])
        for (v[b] = 0; v[b] < g.size[b]; ++v[b]) {
          const std::size_t idx = g.linear(v[0], v[1], v[2]);
          if (bone[idx] && w[idx] != 0 && w[idx] <= n) on_cut[w[idx]] = true;
        }
    }
  joined[mand] = true;
  std::vector<std::size_t> size(n + 1, 0);
  std::map<std::pair<unsigned, unsigned>, std::size_t> contact;  // (a < b) -> face count
  const std::size_t sx = g.size[0], sxy = g.size[0] * g.size[1];
  for (std::size_t k = 0; k < g.size[2]; ++k)
    for (std::size_t j = 0; j < g.size[1]; ++j)
      for (std::size_t i = 0; i < g.size[0]; ++i) {
        const std::size_t idx = g.linear(i, j, k);
        const unsigned a = w[idx];
        if (!bone[idx] || a == 0 || a > n) continue;  // the watershed also floods the background
        ++size[a];
        const std::size_t nb[3] = {i + 1 < g.size[0] ? idx + 1 : idx, j + 1 < g.size[1] ? idx + sx : idx,
                                   k + 1 < g.size[2] ? idx + sxy : idx};
        for (std::size_t q : nb) {
          const unsigned c = w[q];
          if (bone[q] && c != 0 && c != a && c <= n) ++contact[std::minmax(a, c)];
        }
      }
  const std::size_t limit = fragment_limit(size[mand], max_voxels, max_fraction);
  for (bool changed = true; changed;) {
    changed = false;
    for (unsigned l = 1; l <= n; ++l) {
      if (joined[l] || on_cut[l] || size[l] == 0 || size[l] > limit) continue;
      std::size_t with_mandible = 0, best_other = 0;
      std::map<unsigned, std::size_t> others;
      for (const auto& [key, cnt] : contact) {
        if (key.first != l && key.second != l) continue;
        const unsigned o = key.first == l ? key.second : key.first;
        if (joined[o])
          with_mandible += cnt;
        else
          best_other = std::max(best_other, others[o] += cnt);
      }
      if (std::getenv("MANDISYM_DEBUG_SEG"))
        std::fprintf(stderr, "region %u: %zu voxels, contacts mandible %zu, other best %zu\n", l, size[l], with_mandible, best_other);
      if (with_mandible > best_other) joined[l] = changed = true;
    }
  }
  return joined;
}

// Another bone touching the mandible (docs/segmentation.md, "Other bones
// attached beyond the band"): a thick part kept beyond the band that lies
// more than a third (kOtherBoneOutsideSupport) where no training mandible
// reaches (p < kAtlasSupportP, the placed atlas) and is the size of a bone
// (kOtherBoneMinMm3) is dropped. Parts of the mandible measured beyond the
// band lie at most 0.10 outside (crowns); other bones 0.23-0.74 (a hyoid
// 0.74, a skull joined through teeth or joints 0.47-0.63). The hyoid is the
// bone that comes to touch the lower border (an open mouth, a flexed neck):
// its body alone is ~25 x 10 x 10 mm (Gray's Anatomy, 42nd ed.), about
// 2 cm3. A lump smaller than an eighth of that is the mandible's own surface
// where the atlas's support ends (random phantom anatomies: 20-40 mm3 at the
// posterior border of rami wider than any training mandible's), and is kept.
constexpr double kOtherBoneOutsideSupport = 1.0 / 3.0;
constexpr double kOtherBoneMinMm3 = 250.0;
// Parts are taken beyond the band but never nearer the dense core than this
// (mm): the mandible's cortex is 2-3 mm thick (body and inferior border,
// e.g. Katranji et al. 2007, J Oral Maxillofac Surg 65:1546), so bone within
// it of the core is the mandible's own. A fixed distance keeps the parts the
// same at every voxel size: with the band alone (two voxels) at 0.7 mm the
// crowns, the lingual surface and a hyoid touching it were one part (12 cm3,
// 0.15 outside the support, kept; at 3 mm the hyoid is a part of its own,
// 0.86 outside).
constexpr float kOtherBoneFromCoreMm = 3.0f;

// The support half of that rule: more than kOtherBoneOutsideSupport of a
// piece's voxels lie outside the atlas's support.
inline bool mostly_outside_support(std::size_t outside, std::size_t voxels) {
  return static_cast<double>(outside) > kOtherBoneOutsideSupport * static_cast<double>(voxels);
}

// "A crown follows its root" (docs/segmentation.md, step 5): with the teeth
// in occlusion a lower crown is welded to the upper one as widely as it hangs
// on its root, and the watershed can give it to the maxilla. Through bone, it
// is nearer the mandible's core (its own root) than any other large core
// (the upper crown and root lie between). So: a geodesic Voronoi partition of
// the bone among the mandible's core and the cores of regions too large to be
// fragments (6-connected paths in mm, computed to max_mm, on a bucket queue
// of 1/8 of the finest spacing); connected pieces of other regions that fall
// to the mandible's core and hold a voxel at least min_depth_mm deep (a
// crown, not a thin plate such as the roof of a glenoid fossa) and none
// deeper than max_depth_mm (a crown's half width: deeper is a block of other
// bone) join the mandible, unless, with the atlas placed (prior: its
// probability at every bone voxel; empty without it), the piece lies mostly
// outside its support (mostly_outside_support): a crown lies within it, the
// skull base behind a condyle bridged to it does not. Never the reverse.
// Returns the voxels moved.
static std::size_t reclaim_by_roots(std::vector<unsigned>& w, const MaskImage::PixelType* bone, const LabelImage::PixelType* markers,
                                    const std::vector<bool>& source, unsigned mand, const std::vector<float>& depth,
                                    const std::vector<float>& prior, const Geometry& g, const FaceNeighbours& neighbours,
                                    float min_depth_mm, float max_depth_mm, double max_mm) {
  const std::size_t n = g.voxel_count();
  if (n > std::numeric_limits<std::uint32_t>::max()) return 0;  // 32-bit queues (a crop is far smaller)
  // Only where the mandible's region touches another region's bone.
  bool touches = false;
  for (std::size_t c = 0; c < n && !touches; ++c)
    if (bone[c] && w[c] == mand)
      neighbours.each(c, [&](std::size_t q, int) { touches |= bone[q] && w[q] != 0 && w[q] != mand; });
  if (!touches) return 0;
  const double unit = std::min({g.spacing[0], g.spacing[1], g.spacing[2]}) / 8.0;
  const std::uint32_t weight[3] = {static_cast<std::uint32_t>(std::lround(g.spacing[0] / unit)),
                                   static_cast<std::uint32_t>(std::lround(g.spacing[1] / unit)),
                                   static_cast<std::uint32_t>(std::lround(g.spacing[2] / unit))};
  const std::uint32_t far = static_cast<std::uint32_t>(std::ceil(max_mm / unit));
  std::vector<std::uint32_t> dist(n, std::numeric_limits<std::uint32_t>::max());
  std::vector<unsigned> nearest(n, 0);
  std::vector<std::vector<std::uint32_t>> queue(far + 1);
  for (std::size_t c = 0; c < n; ++c)
    if (bone[c] && markers[c] && markers[c] < source.size() && source[markers[c]])
      dist[c] = 0, nearest[c] = markers[c], queue[0].push_back(static_cast<std::uint32_t>(c));
  for (std::uint32_t d = 0; d <= far; ++d) {
    for (const std::uint32_t c : queue[d]) {
      if (dist[c] != d) continue;  // reached earlier by a shorter path
      neighbours.each(c, [&](std::size_t q, int a) {
        const std::uint32_t nd = d + weight[a];
        if (!bone[q] || nd > far || nd >= dist[q]) return;
        dist[q] = nd;
        nearest[q] = nearest[c];
        queue[nd].push_back(static_cast<std::uint32_t>(q));
      });
    }
    std::vector<std::uint32_t>().swap(queue[d]);
  }
  std::vector<std::uint8_t> cand(n, 0);
  for (std::size_t c = 0; c < n; ++c) cand[c] = bone[c] && w[c] != 0 && w[c] != mand && nearest[c] == mand;
  std::size_t moved = 0;
  std::vector<std::uint32_t> piece;
  for (std::size_t s = 0; s < n; ++s) {
    if (cand[s] != 1) continue;
    piece.assign(1, static_cast<std::uint32_t>(s));
    cand[s] = 2;
    float deepest = 0;
    std::size_t outside = 0;
    for (std::size_t h = 0; h < piece.size(); ++h) {
      deepest = std::max(deepest, depth[piece[h]]);
      outside += !prior.empty() && prior[piece[h]] < kAtlasSupportP;
      neighbours.each(piece[h], [&](std::size_t q, int) {
        if (cand[q] == 1) cand[q] = 2, piece.push_back(static_cast<std::uint32_t>(q));
      });
    }
    const bool joins = deepest >= min_depth_mm && deepest <= max_depth_mm && !mostly_outside_support(outside, piece.size());
    if (std::getenv("MANDISYM_DEBUG_SEG") && piece.size() > 20)
      std::fprintf(stderr, "  nearer the mandible's core: %zu voxels, deepest %.1f mm, %.2f outside the atlas's support%s\n",
                   piece.size(), deepest, static_cast<double>(outside) / static_cast<double>(piece.size()), joins ? " -> mandible" : "");
    if (!joins) continue;
    for (const std::uint32_t c : piece) w[c] = mand;
    moved += piece.size();
  }
  return moved;
}

// The cores of a solid deeper than `depth` mm (step 3; depth_map: depth
// inside the solid): its face-connected components of at least max(8
// voxels, 100 mm3), numbered by decreasing size, with their features, their
// atlas mass (when prior is given: the placed atlas's probability at each
// voxel) and the fraction of each inside the located region (when
// in_located is given).
struct Cores {
  LabelImage::Pointer labels;
  unsigned n = 0;
  std::vector<Features> f;  // f[l] for labels 1..n
};

static Cores cores_at(const std::vector<float>& depth_map, double depth, const Geometry& cg, const std::vector<float>& prior,
                      const std::vector<std::uint8_t>& in_located) {
  const double voxel_mm3 = cg.voxel_volume_mm3();
  auto core = io::make_image<MaskImage>(cg);
  auto* c = core->GetBufferPointer();
  for (std::size_t i = 0; i < cg.voxel_count(); ++i) c[i] = depth_map[i] > depth;
  std::size_t n_cores = 0;
  Cores out;
  out.labels = components(core.GetPointer(), false, static_cast<std::size_t>(std::max(8.0, 100.0 / voxel_mm3)), &n_cores);
  out.n = static_cast<unsigned>(n_cores);
  out.f = component_features(out.labels.GetPointer(), out.n, cg);
  const auto* lab = out.labels->GetBufferPointer();
  if (!prior.empty())
    for (std::size_t i = 0; i < cg.voxel_count(); ++i)
      if (lab[i]) out.f[lab[i]].prior_sum += prior[i];
  if (!in_located.empty()) {
    std::vector<std::size_t> inside(out.n + 1, 0);
    for (std::size_t i = 0; i < cg.voxel_count(); ++i)
      if (lab[i]) inside[lab[i]] += in_located[i];
    for (unsigned l = 1; l <= out.n; ++l)
      out.f[l].located = out.f[l].voxels ? static_cast<double>(inside[l]) / static_cast<double>(out.f[l].voxels) : 0.0;
  }
  return out;
}

// How a core is judged (step 4): with the atlas, by its atlas evidence;
// without, by size and position (pick_mandible) and height.
struct CoreJudge {
  bool by_atlas = false;
  double voxel_mm3 = 1, atlas_mm3 = 0, min_located = 0;
  unsigned pick(const std::vector<Features>& f, double rr) const {
    return by_atlas ? pick_by_atlas(f, voxel_mm3, atlas_mm3, min_located) : pick_mandible(f, voxel_mm3, rr, min_located);
  }
  // How good a mandible core is, to choose between depths: its atlas
  // evidence (cm3), or without the atlas its height (mm; a core cut off
  // below fused teeth is shorter than one reaching the condyles).
  double merit(const std::vector<Features>& f, unsigned l, double rr) const {
    return by_atlas ? atlas_merit(f[l], voxel_mm3, atlas_mm3) : f[l].extent(2) + 2 * rr;
  }
  double margin() const { return by_atlas ? 0.5 : 1.0; }  // cm3 of evidence, or mm of height
};

// The markers chosen (step 3): the cores at the depth r_used, the mandible's
// among them (mand; 0 when none was found), and the solid they were cut from.
struct MarkerChoice {
  LabelImage::Pointer markers;
  unsigned n = 0, mand = 0;
  std::vector<Features> feats;
  std::string source;
  double r_used = 0;
};

// The mandible's core in one solid (step 3; sd: depth inside it): every
// depth from rsep to r_max in 0.5 mm steps is tried and the best mandible
// core wins by the judge's merit, but not a core that is two bones: teeth in
// occlusion weld the maxilla to the mandible's core at shallow depths, and
// that core scores higher still. Cores are nested (a deeper core lies inside
// exactly one shallower core), so a welded core shows itself one step
// deeper, where it falls apart into two large cores (the second at least
// kSecondBoneFraction); a mandible that only loses thin parts (condyles,
// coronoids, crowns) keeps one large core and small ones. When every
// candidate looked like two bones, the best of them.
static MarkerChoice deepest_mandible_core(const std::vector<float>& sd, const char* name, double rsep, double r_max, const Geometry& cg,
                                          const std::vector<float>& prior, const std::vector<std::uint8_t>& in_located,
                                          const CoreJudge& judge, bool debug) {
  const double voxel_mm3 = judge.voxel_mm3, atlas_mm3 = judge.atlas_mm3;
  MarkerChoice choice;
  struct Trial {
    double rr = 0;
    LabelImage::Pointer m;
    unsigned n = 0, l = 0;
    std::vector<Features> f;
    double merit = 0;  // merit of the mandible core
  };
  Trial pending, tallest_any;
  double best_merit = 0;
  auto adopt = [&](Trial& t) {
    best_merit = t.merit;
    choice = {t.m, t.n, t.l, t.f, name, t.rr};
  };
  // Decides the pending trial given the cores one step deeper (null: none).
  auto decide = [&](const LabelImage* deeper, unsigned n_deeper) {
    if (!pending.l) return;
    bool two_bones = false;
    if (deeper) {
      std::vector<std::size_t> piece(n_deeper + 1, 0);
      const auto* a = pending.m->GetBufferPointer();
      const auto* d = deeper->GetBufferPointer();
      for (std::size_t i = 0; i < cg.voxel_count(); ++i)
        if (a[i] == pending.l && d[i]) ++piece[d[i]];
      std::sort(piece.begin() + 1, piece.end(), std::greater<>());
      std::size_t total = 0;
      for (std::size_t k = 1; k < piece.size(); ++k) total += piece[k];
      two_bones = piece.size() > 2 && static_cast<double>(piece[2]) >= kSecondBoneFraction * static_cast<double>(total);
      if (debug)
        std::fprintf(stderr, "  r %.1f core one step deeper: pieces %.1f, %.1f cm3 of %.1f%s\n", pending.rr,
                     piece.size() > 1 ? piece[1] * voxel_mm3 / 1000 : 0.0, piece.size() > 2 ? piece[2] * voxel_mm3 / 1000 : 0.0,
                     total * voxel_mm3 / 1000, two_bones ? ": two bones" : "");
    }
    if (pending.merit > tallest_any.merit) tallest_any = {pending.rr, nullptr, 0, pending.l, {}, pending.merit};
    if (!two_bones && pending.merit > best_merit + judge.margin()) adopt(pending);
  };
  auto trial_at = [&](double rr) {
    Trial t;
    t.rr = rr;
    Cores c = cores_at(sd, rr, cg, prior, in_located);
    t.m = c.labels, t.n = c.n, t.f = std::move(c.f);
    t.l = judge.pick(t.f, rr);
    return t;
  };
  for (double rr = rsep; rr <= r_max; rr += 0.5) {
    Trial t = trial_at(rr);
    if (t.l) t.merit = judge.merit(t.f, t.l, rr);
    if (debug && judge.by_atlas) {
      unsigned top = 0;
      for (unsigned l = 1; l <= t.n; ++l)
        if (!top || t.f[l].prior_sum > t.f[top].prior_sum) top = l;
      if (top)
        std::fprintf(stderr, "  %s r %.1f: most atlas mass in core %u: %.1f cm3, mean p %.2f, share %.2f of %.1f cm3%s\n", name, rr, top,
                     t.f[top].voxels * voxel_mm3 / 1000, t.f[top].prior_sum / t.f[top].voxels, t.f[top].prior_sum * voxel_mm3 / atlas_mm3,
                     atlas_mm3 / 1000, top == t.l ? " (taken)" : "");
    }
    if (debug && t.l)
      std::fprintf(stderr, "  %s r %.1f: mandible core %.1f cm3 w %.0f d %.0f h %.0f (%u cores)\n", name, rr,
                   t.f[t.l].voxels * voxel_mm3 / 1000, t.f[t.l].extent(0) + 2 * rr, t.f[t.l].extent(1) + 2 * rr, t.merit, t.n);
    decide(t.m.GetPointer(), t.n);
    pending = std::move(t);
  }
  decide(nullptr, 0);
  if (!choice.mand && tallest_any.l) {  // every candidate looked like two bones: the best of them
    Trial t = trial_at(tallest_any.rr);
    t.merit = tallest_any.merit;
    if (t.l) adopt(t);
  }
  return choice;
}

// Drops from kept (the band and its thick attached parts) every part beyond
// from2 (nd2 > from2: squared mm to the core) that is another bone by the
// rule above; prior: the placed atlas's probability at every bone voxel.
static void drop_other_bones(std::vector<std::uint8_t>& kept, const std::vector<float>& nd2, float from2,
                             const std::vector<float>& prior, const Geometry& cg, bool debug) {
  std::vector<std::uint8_t> beyond(kept.size(), 0);
  for (std::size_t i = 0; i < kept.size(); ++i) beyond[i] = kept[i] && nd2[i] > from2;
  std::vector<std::uint32_t> lab(kept.size());
  const std::size_t n = label_components(beyond.data(), cg.size, false, 0, lab.data()).count;
  std::vector<std::size_t> voxels(n + 1, 0), outside(n + 1, 0);
  for (std::size_t i = 0; i < kept.size(); ++i)
    if (lab[i]) ++voxels[lab[i]], outside[lab[i]] += prior[i] < kAtlasSupportP;
  std::vector<std::uint8_t> other(n + 1, 0);
  for (std::size_t l = 1; l <= n; ++l) {
    const double mm3 = static_cast<double>(voxels[l]) * cg.voxel_volume_mm3();
    other[l] = mm3 >= kOtherBoneMinMm3 && mostly_outside_support(outside[l], voxels[l]);
    if (debug && mm3 >= kOtherBoneMinMm3)
      std::fprintf(stderr, "  part attached beyond the band: %.2f cm3, %.2f outside the atlas's support (%s)\n", mm3 / 1000,
                   static_cast<double>(outside[l]) / static_cast<double>(voxels[l]), other[l] ? "another bone: dropped" : "kept");
  }
  for (std::size_t i = 0; i < kept.size(); ++i)
    if (lab[i] && other[lab[i]]) kept[i] = 0;
}

// What of the mandible's watershed region rm is kept (step 6): the part
// within `band` mm of its core (core_m), so that thin bright structures
// flooded from it (streaks) stay out, and beyond it, up to `reach` mm, what
// is thick (survives an opening by a one-voxel ball: streaks are rays and
// sheets one or two voxels thin; a tooth crown whose thin shell left no core
// within the band stays), only where attached through bone to the band part
// (a separate bone without a marker of its own, the hyoid, is flooded by
// whichever region reaches it through the background and must stay out:
// beyond the band, drop_other_bones drops it when the atlas is placed,
// prior is its probability at every bone voxel, empty without it).
static std::vector<std::uint8_t> band_and_attached(const std::vector<std::uint8_t>& rm, const std::vector<std::uint8_t>& core_m, float band,
                                                   float reach, const std::vector<float>& prior, const Geometry& cg, SegLap& lap) {
  const Dims3& cdims = cg.size;
  const Box mbox = bounding_box(rm.data(), cdims, 2);  // where the band distance and the opening are needed
  const float band2 = band * band, reach2 = reach * reach;
  std::vector<float> nd2(cg.voxel_count(), kNoFeature);  // mm^2 to the core, exact up to reach^2
  insert(squared_distance_transform(extract(core_m.data(), cdims, mbox).data(), mbox.size, cg.spacing, reach2), mbox, nd2.data(), cdims);
  lap("band distance");
  std::vector<std::uint8_t> thick(cg.voxel_count(), 0);
  if (reach > band) {
    std::vector<std::uint8_t> part = extract(rm.data(), cdims, mbox);
    open_ball(part, mbox.size, {1, 1, 1});
    insert(part, mbox, thick.data(), cdims);
  }
  lap("opening");
  auto cand = io::make_image<MaskImage>(cg);
  auto* cm = cand->GetBufferPointer();
  for (std::size_t i = 0; i < cg.voxel_count(); ++i) cm[i] = rm[i] && (nd2[i] <= band2 || (thick[i] && nd2[i] <= reach2));
  std::size_t n_parts = 0;
  const LabelImage::Pointer parts = components(cand.GetPointer(), false, 0, &n_parts);
  const auto* cl = parts->GetBufferPointer();
  std::vector<bool> attached(n_parts + 1, false);
  for (std::size_t i = 0; i < cg.voxel_count(); ++i)
    if (cl[i] && nd2[i] <= band2) attached[cl[i]] = true;
  std::vector<std::uint8_t> kept(cg.voxel_count(), 0);
  for (std::size_t i = 0; i < kept.size(); ++i) kept[i] = cl[i] && attached[cl[i]];
  const float other_from = std::max(band, kOtherBoneFromCoreMm);
  if (!prior.empty() && reach > band) drop_other_bones(kept, nd2, other_from * other_from, prior, cg, lap.on());
  return kept;
}

// The separation's watershed landscape (step 5): landscape_level at every
// bone voxel, 0 elsewhere.
static Landscape separation_landscape(const std::uint8_t* bone, const std::vector<float>& bone_depth, const std::vector<float>& hu_crop,
                                      double offset_hu, const Geometry& cg) {
  std::vector<float> landscape(cg.voxel_count());
  const float hu0 = static_cast<float>(offset_hu);
#pragma omp parallel for schedule(static)
  for (std::size_t i = 0; i < cg.voxel_count(); ++i) landscape[i] = bone[i] ? landscape_level(bone_depth[i], hu_crop[i], hu0) : 0.0f;
  return Landscape(landscape, cg, -2.0f, 0.0f);
}

// The regions of the markers (step 5), flooded through bone. With the dense
// solid given (markers cut from it), they flood the dense bone first, then
// the rest of the bone: a joint space bridged by partial volume (above the
// bone threshold, below the dense one) must not let the skull's flood into
// the condyle before the mandible's own reaches it through the condylar
// process (it did: 0.8 mm, 1 mm joint space, the condylar processes went to
// the skull).
static std::vector<unsigned> flood_regions(const Landscape& land, const std::uint8_t* bone, const std::uint8_t* dense_solid,
                                           const unsigned* markers) {
  if (!dense_solid) return watershed_from_markers(land, bone, markers);
  std::vector<std::uint8_t> dense_bone(land.bucket.size());
  for (std::size_t i = 0; i < dense_bone.size(); ++i) dense_bone[i] = bone[i] && dense_solid[i];
  const std::vector<unsigned> first = watershed_from_markers(land, dense_bone.data(), markers);
  return watershed_from_markers(land, bone, first.data());
}

// The dense-bone solid of separate() (step 3): bone at or above dense_hu
// (cortex and enamel), with its thick enclosed cavities (cancellous cores)
// filled. A bone cut by the scan's edge (scan_edge faces) is closed there
// first. A thin enclosed cavity is a joint space or an occlusal gap wrapped
// by bone: filling it would weld the condyle to its fossa, the lower teeth to
// the upper, so only cavities reaching max(1 mm, 0.75 voxel) deep are filled.
static MaskImage::Pointer dense_solid_of(const MaskImage* bone, const std::vector<float>& hu_crop, double dense_hu, unsigned scan_edge,
                                         double max_spacing, const Geometry& cg) {
  auto dense = io::make_image<MaskImage>(cg);
  auto* dn = dense->GetBufferPointer();
  const auto* b = bone->GetBufferPointer();
  for (std::size_t i = 0; i < cg.voxel_count(); ++i) dn[i] = b[i] && hu_crop[i] >= dense_hu;
  const std::vector<std::size_t> lid = cap_cut_faces(dn, cg.size, scan_edge, false, b);
  const MaskImage::Pointer dense_filled = filled(dense.GetPointer(), false);  // a thin shell must not leak diagonally
  for (std::size_t i : lid) dn[i] = 0;
  auto cavity = io::make_image<MaskImage>(cg);
  const auto* fill = dense_filled->GetBufferPointer();
  for (std::size_t i = 0; i < cg.voxel_count(); ++i) cavity->GetBufferPointer()[i] = fill[i] && !dn[i];
  std::size_t n_cavities = 0;
  const LabelImage::Pointer cavities = components(cavity.GetPointer(), false, 0, &n_cavities);
  // Only whether a cavity reaches `thick` deep matters: its depth map
  // needs to be exact no deeper (the transform then looks that far only).
  const float thick = static_cast<float>(std::max(1.0, 0.75 * max_spacing));
  const std::vector<float> cdepth = depth_inside(cavity->GetBufferPointer(), cg.size, cg.spacing, thick + static_cast<float>(max_spacing));
  const auto* cl = cavities->GetBufferPointer();
  std::vector<float> depth(n_cavities + 1, 0.0f);
  for (std::size_t i = 0; i < cg.voxel_count(); ++i)
    if (cl[i]) depth[cl[i]] = std::max(depth[cl[i]], cdepth[i]);
  auto solid = io::make_image<MaskImage>(cg);
  auto* ds = solid->GetBufferPointer();
  for (std::size_t i = 0; i < cg.voxel_count(); ++i) ds[i] = dn[i] || (cl[i] && depth[cl[i]] >= thick);
  return solid;
}

// The bone crop of separate() (step 2): the bone mask at `threshold`, cropped
// to its bounding box grown by 2 voxels, enclosed cavities filled; which of
// the crop's faces lie on cut faces of the grid (ctx.cut) and which on the
// scan's own edge (cap_cut_faces).
struct BoneCrop {
  MaskImage::Pointer bone;
  MaskImage::RegionType region;
  Geometry cg;
  std::array<bool, 6> cut{};
  unsigned scan_edge = 0;
};

static BoneCrop bone_crop(const Volume& ct, double threshold, const GridContext& ctx) {
  const Geometry& g = ct.geom;
  auto full = io::make_image<MaskImage>(g);
  std::array<long, 3> lo{long(g.size[0]), long(g.size[1]), long(g.size[2])}, hi{-1, -1, -1};
  {
    auto* b = full->GetBufferPointer();
    for (std::size_t k = 0; k < g.size[2]; ++k)
      for (std::size_t j = 0; j < g.size[1]; ++j)
        for (std::size_t i = 0; i < g.size[0]; ++i) {
          const std::size_t idx = g.linear(i, j, k);
          if (ct.hu[idx] < threshold) continue;
          b[idx] = 1;
          const long v[3] = {long(i), long(j), long(k)};
          for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], v[a]), hi[a] = std::max(hi[a], v[a]);
        }
  }
  if (hi[0] < 0) throw Error(ExitCode::NoMandible, "no mandible found: no voxel reaches the bone threshold (" +
                                                        std::to_string(static_cast<int>(threshold)) + " HU)");
  BoneCrop out;
  for (int a = 0; a < 3; ++a) {
    const long l = std::max(0L, lo[a] - 2), h = std::min(long(g.size[a]) - 1, hi[a] + 2);
    out.region.SetIndex(a, l);
    out.region.SetSize(a, static_cast<itk::SizeValueType>(h - l + 1));
  }
  out.bone = crop<MaskImage>(full.GetPointer(), out.region);
  full = nullptr;
  out.cg = io::geometry_of(out.bone.GetPointer());
  const auto& region = out.region;
  for (int a = 0; a < 3; ++a) {
    const bool at_low = region.GetIndex()[a] == 0;
    const bool at_high = region.GetIndex()[a] + static_cast<long>(region.GetSize()[a]) == long(g.size[a]);
    out.cut[2 * a] = ctx.cut[2 * a] && at_low;
    out.cut[2 * a + 1] = ctx.cut[2 * a + 1] && at_high;
    if (at_low && !ctx.cut[2 * a]) out.scan_edge |= 1u << (2 * a);
    if (at_high && !ctx.cut[2 * a + 1]) out.scan_edge |= 1u << (2 * a + 1);
  }
  out.bone = filled(out.bone.GetPointer(), true);
  return out;
}

// Voxels of the crop cg inside the located region (nearest coarse voxel);
// empty when the scan was not located first.
static std::vector<std::uint8_t> located_voxels(const GridContext& ctx, const Geometry& cg) {
  std::vector<std::uint8_t> in_located;
  if (!ctx.located) return in_located;
  in_located.assign(cg.voxel_count(), 0);
  // Crop index -> located-grid index is affine: its origin and one step per axis.
  const Mask& loc = *ctx.located;
  auto to_loc = [&](double i, double j, double k) { return loc.geom.lps_to_index(cg.index_to_lps(i, j, k)); };
  const Vec3 q0 = to_loc(0, 0, 0);
  const Vec3 qi = to_loc(1, 0, 0) - q0, qj = to_loc(0, 1, 0) - q0, qk = to_loc(0, 0, 1) - q0;
  const long nz = static_cast<long>(cg.size[2]);
#pragma omp parallel for schedule(static)
  for (long k = 0; k < nz; ++k)
    for (std::size_t j = 0; j < cg.size[1]; ++j) {
      const Vec3 row = q0 + static_cast<double>(j) * qj + static_cast<double>(k) * qk;
      for (std::size_t i = 0; i < cg.size[0]; ++i)
        in_located[cg.linear(i, j, static_cast<std::size_t>(k))] = set_at_index(loc, row + static_cast<double>(i) * qi);
    }
  return in_located;
}

// Step 1 (calibration): the warning when the soft-tissue peak lies more than
// 50 HU from kSoftTissueHu.
static void warn_about_calibration(double offset, std::vector<std::string>& warnings) {
  if (std::abs(offset) > 50)
    warnings.push_back("soft tissue peaks at " + std::to_string(static_cast<int>(std::lround(kSoftTissueHu + offset))) +
                       " HU instead of ~40 HU: thresholds shifted by " + std::to_string(static_cast<int>(std::lround(offset))) +
                       " HU (calibration offset?)");
}

// What step 4 (identification) weighs the cores by: the placed atlas's
// mandible probability at every bone voxel (empty without the atlas), and
// the judge that picks the mandible's core.
struct CoreEvidence {
  std::vector<float> prior;
  CoreJudge judge;
};

static CoreEvidence core_evidence(const GridContext& ctx, const std::uint8_t* bone, const Geometry& cg, double voxel_mm3,
                                  double min_located) {
  CoreEvidence e;
  const bool by_atlas = ctx.atlas && ctx.atlas->found;
  double atlas_mm3 = 0.0;
  if (by_atlas) {
    const atlas::MandiblePrior placed(atlas::shipped(), ctx.atlas->pose);
    e.prior = prior_at_bone(placed, bone, cg);
    atlas_mm3 = placed.mass_mm3();
  }
  e.judge = CoreJudge{by_atlas, voxel_mm3, atlas_mm3, min_located};
  return e;
}

// Steps 3-4 (markers, identification): the mandible's core deepened until it
// separates, in the dense-bone solid first, then in the whole bone mask.
// bone_depth: the bone mask's depth map when it was computed here (reused for
// the watershed landscape), else empty.
struct MarkerSearch {
  MarkerChoice choice;
  std::vector<float> bone_depth;
};

static MarkerSearch markers_by_core_depth(const MaskImage::Pointer& dense_solid, const MaskImage::Pointer& bone, double rsep,
                                          double r_max, float depth_cap, const Geometry& cg, const CoreEvidence& evidence,
                                          const std::vector<std::uint8_t>& in_located, SegLap& lap) {
  MarkerSearch out;
  for (const auto& [solid, name] : {std::make_pair(dense_solid, "dense bone"), std::make_pair(bone, "bone")}) {
    std::vector<float> sd = depth_inside(solid->GetBufferPointer(), cg.size, cg.spacing, depth_cap);
    lap("depth map");
    out.choice = deepest_mandible_core(sd, name, rsep, r_max, cg, evidence.prior, in_located, evidence.judge, lap.on());
    if (solid == bone) out.bone_depth = std::move(sd);
    if (out.choice.mand) break;
  }
  return out;
}

static void print_cores(const MarkerChoice& choice, double voxel_mm3) {
  const std::vector<Features>& feats = choice.feats;
  for (unsigned l = 1; l <= choice.n; ++l)
    std::fprintf(stderr, "core %u: %.1f cm3 w %.0f d %.0f h %.0f centroid z %.1f (z %.1f to %.1f)%s\n", l, feats[l].voxels * voxel_mm3 / 1000,
                 feats[l].extent(0), feats[l].extent(1), feats[l].extent(2), feats[l].centroid()[2], feats[l].lo[2], feats[l].hi[2],
                 l == choice.mand ? "  <- mandible" : "");
}

// No mandible core separated: without the atlas, the widest, lowest bone
// component of the undivided mask (with a warning); with it, an error (the
// atlas's zone is then taken, segment_by_atlas_and_image).
static std::vector<std::uint8_t> unseparated_mandible(const MaskImage* bone, const Options& opt, double threshold, double voxel_mm3,
                                                      const Geometry& cg, bool by_atlas, std::vector<std::string>& warnings) {
  if (by_atlas) throw Error(ExitCode::NoMandible, "no mandible core separated by the image");
  warnings.push_back("mandible not separated from the other bones: no bone core has a mandible's size; "
                     "the result may include skull or spine");
  std::size_t n_bones = 0;
  const LabelImage::Pointer bones =
      components(bone, false, static_cast<std::size_t>(opt.min_component_cm3 * 1000.0 / voxel_mm3), &n_bones);
  const unsigned n2 = static_cast<unsigned>(n_bones);
  if (n2 == 0)
    throw Error(ExitCode::NoMandible, "no mandible found: no bone (no connected region above " +
                                          std::to_string(static_cast<int>(threshold)) + " HU of at least " +
                                          std::to_string(static_cast<int>(std::lround(opt.min_component_cm3))) + " cm3)");
  auto f2 = component_features(bones.GetPointer(), n2, cg);
  const auto* lab = bones->GetBufferPointer();
  unsigned best = 0;
  for (unsigned l = 1; l <= n2; ++l)
    if (f2[l].extent(0) >= 40.0 && (best == 0 || f2[l].centroid()[2] < f2[best].centroid()[2])) best = l;
  if (best == 0) throw Error(ExitCode::NoMandible, "no mandible found: no bone is at least 40 mm wide left-right");
  std::vector<std::uint8_t> crop_mask(cg.voxel_count(), 0);
  for (std::size_t i = 0; i < crop_mask.size(); ++i) crop_mask[i] = lab[i] == best;
  return crop_mask;
}

// Step 5, "a crown follows its root" (reclaim_by_roots): the partition's
// sources are the mandible's core and the cores of regions too large to be
// fragments (the fragment rule's limit). Returns the voxels moved.
static std::size_t crowns_follow_roots(std::vector<unsigned>& wsl, const std::uint8_t* bone, const unsigned* markers,
                                       const MarkerChoice& choice, const std::vector<float>& bone_depth,
                                       const std::vector<float>& prior, const Geometry& cg, const FaceNeighbours& neighbours,
                                       const Options& opt, std::size_t max_fragment_voxels) {
  const unsigned n_markers = choice.n, mand = choice.mand;
  std::vector<std::size_t> region_size(n_markers + 1, 0);
  for (std::size_t i = 0; i < cg.voxel_count(); ++i)
    if (bone[i] && wsl[i] && wsl[i] <= n_markers) ++region_size[wsl[i]];
  const std::size_t limit = fragment_limit(region_size[mand], max_fragment_voxels, opt.fragment_merge_fraction);
  std::vector<bool> source(n_markers + 1, false);
  for (unsigned l = 1; l <= n_markers; ++l) source[l] = l == mand || region_size[l] > limit;
  return reclaim_by_roots(wsl, bone, markers, source, mand, bone_depth, prior, cg, neighbours,
                          static_cast<float>(opt.crown_min_depth_mm), kCrownMaxDepthMm, kRootReachMm);
}

// Step 5, "fragments join the mandible" (mandible_fragments), on scans that
// resolve them; else the mandible's own label only.
static std::vector<bool> mandible_labels(const unsigned* w, const std::uint8_t* bone, const Geometry& cg, const MarkerChoice& choice,
                                         const Options& opt, std::size_t max_fragment_voxels, const std::array<bool, 6>& cut,
                                         bool fine_scan) {
  if (fine_scan)
    return mandible_fragments(w, bone, cg, choice.n, choice.mand, max_fragment_voxels, opt.fragment_merge_fraction, cut);
  std::vector<bool> joined(choice.n + 1, false);
  joined[choice.mand] = true;
  return joined;
}

// The mandible's region (with its fragments) and its core (step 5, "band,
// then thick parts"): what band_and_attached is given.
struct MandibleRegion {
  std::vector<std::uint8_t> region, core;
};

static MandibleRegion mandible_region(const unsigned* w, const std::uint8_t* bone, const unsigned* markers,
                                      const std::vector<bool>& joined, std::size_t n) {
  MandibleRegion out;
  out.region.resize(n);
  for (std::size_t i = 0; i < n; ++i) out.region[i] = bone[i] && w[i] != 0 && joined[w[i]];
  out.core.resize(n);
  for (std::size_t i = 0; i < n; ++i) out.core[i] = markers[i] != 0 && joined[markers[i]];
  return out;
}

// Step 5 (reconstruction): the watershed from all markers
// (separation_landscape, flood_regions), crowns by their roots, fragments,
// then the band and the thick attached parts of the mandible's region.
// Fills out.mand and out.other.
static void reconstruct(Separated& out, const MaskImage* bone, const MaskImage* dense_solid, const MarkerChoice& choice,
                        std::vector<float>& bone_depth, const std::vector<float>& hu_crop, double offset, float depth_cap,
                        const std::array<bool, 6>& crop_cut, double max_spacing, const std::vector<float>& prior,
                        const GridContext& ctx, const Options& opt, SegLap& lap) {
  const Geometry& cg = out.cg;
  const double voxel_mm3 = cg.voxel_volume_mm3();
  const auto* b = bone->GetBufferPointer();
  const auto* m = choice.markers->GetBufferPointer();
  if (bone_depth.empty()) bone_depth = depth_inside(b, cg.size, cg.spacing, depth_cap);
  const Landscape land = separation_landscape(b, bone_depth, hu_crop, offset, cg);
  std::vector<unsigned> wsl =
      flood_regions(land, b, out.info.marker_source == std::string("dense bone") ? dense_solid->GetBufferPointer() : nullptr, m);
  lap("watershed");
  // Crowns and fragments are looked for only where the scan resolves them:
  // on scans coarser than the working grid (interpolated), fragments are
  // skull-base pieces as often as teeth (OpenKBP pt_246: Dice 0.79 -> 0.77 with them joined).
  const bool fine_scan = ctx.native_max_spacing <= opt.max_working_spacing_mm;
  const auto max_fragment_voxels = static_cast<std::size_t>(opt.fragment_merge_cm3 * 1000.0 / voxel_mm3);
  if (fine_scan && opt.crown_min_depth_mm > 0) {
    const std::size_t moved = crowns_follow_roots(wsl, b, m, choice, bone_depth, prior, cg, land.neighbours, opt, max_fragment_voxels);
    if (lap.on()) std::fprintf(stderr, "  %zu voxels nearer the mandible's core joined it\n", moved);
    lap("crowns by their roots");
  }
  const unsigned* w = wsl.data();
  const std::vector<bool> joined = mandible_labels(w, b, cg, choice, opt, max_fragment_voxels, crop_cut, fine_scan);
  lap("fragments");
  const MandibleRegion rm = mandible_region(w, b, m, joined, cg.voxel_count());
  // Two voxels of the coarser of the grid and the scan. Scans coarser than
  // the working grid never resolved thin shells, and their band is already
  // two scan voxels wide: band only. The thick parts reach at most
  // Options::thick_reach_mm from the core (a crown's height).
  const float band = static_cast<float>(choice.r_used + 2.0 * std::max(max_spacing, ctx.native_max_spacing));
  const float reach = static_cast<float>(std::max<double>(band, opt.thick_reach_mm));
  out.mand = band_and_attached(rm.region, rm.core, band, fine_scan ? reach : band, prior, cg, lap);
  out.other.assign(out.mand.size(), 0);
  for (std::size_t i = 0; i < out.mand.size(); ++i) out.other[i] = b[i] && w[i] != 0 && !joined[w[i]];
  lap("attached parts");
  if (lap.on()) {
    std::size_t n_region = 0, n_kept = 0;
    for (std::size_t i = 0; i < out.mand.size(); ++i) n_region += rm.region[i], n_kept += out.mand[i];
    std::fprintf(stderr, "  mandible region %.1f cm3 (watershed), %.1f cm3 kept (band and thick parts)\n",
                 n_region * voxel_mm3 / 1000, n_kept * voxel_mm3 / 1000);
  }
}

// Steps 1-5 of docs/segmentation.md on one grid.
static Separated separate(const Volume& ct, const Options& opt, const GridContext& ctx) {
  Separated out;
  Result& r = out.info;
  SegLap lap;
  const Geometry& g = ct.geom;
  r.method = "auto";
  std::size_t soft = 0;
  const double offset = std::isnan(ctx.offset_hu) ? estimate_offset(ct, &soft) : ctx.offset_hu;
  warn_about_calibration(offset, r.warnings);
  const double threshold = opt.bone_threshold_hu + offset;

  // Step 2: bone mask, cropped to its bounding box, cavities filled (work is done on the crop).
  BoneCrop crop_of_bone = bone_crop(ct, threshold, ctx);
  const MaskImage::Pointer bone = std::move(crop_of_bone.bone);
  out.region = crop_of_bone.region;
  out.cg = crop_of_bone.cg;
  const Geometry& cg = out.cg;
  lap("bone mask, crop, fill");
  const double max_spacing = std::max({g.spacing[0], g.spacing[1], g.spacing[2]});
  const double voxel_mm3 = g.voxel_volume_mm3();
  const std::vector<float> hu_crop = crop_values(ct, out.region, cg);

  // Steps 3-4: markers are cores (deeper than rsep) of a solid. Thin contacts
  // (cusp contacts, bridged joint spaces, streak rays) have no core, so the
  // cores separate. First the dense-bone solid (cortex and enamel, holes
  // filled so the cancellous core counts): partial-volume valleys between
  // teeth in occlusion and across a narrow joint space fall below its
  // threshold. Then the whole bone mask.
  const double rsep = std::max(1.0, 0.75 * max_spacing);
  const std::vector<std::uint8_t> in_located = located_voxels(ctx, cg);
  const double min_located = ctx.located ? 1.0 - opt.locate_outside_fraction : 0.0;
  const CoreEvidence evidence = core_evidence(ctx, bone->GetBufferPointer(), cg, voxel_mm3, min_located);
  lap("atlas prior");
  const MaskImage::Pointer dense_solid =
      dense_solid_of(bone.GetPointer(), hu_crop, offset + opt.dense_threshold_hu, crop_of_bone.scan_edge, max_spacing, cg);
  lap("dense solid");
  const double r_max = std::max(rsep, 3.0) + 1e-9;  // the deepest core tried
  // Depths matter up to the deepest core, the landscape's cap and the crown
  // step's depths (least and most): the transforms need look no deeper
  // (exact up to it, deeper beyond).
  const float depth_cap =
      std::max({static_cast<float>(r_max), kLandscapeDepthMm, static_cast<float>(opt.crown_min_depth_mm), kCrownMaxDepthMm});
  MarkerSearch search = markers_by_core_depth(dense_solid, bone, rsep, r_max, depth_cap, cg, evidence, in_located, lap);
  const MarkerChoice& choice = search.choice;
  if (choice.mand) r.marker_source = choice.source;
  lap("cores");
  if (lap.on()) print_cores(choice, voxel_mm3);

  if (choice.mand == 0)
    out.mand = unseparated_mandible(bone.GetPointer(), opt, threshold, voxel_mm3, cg, evidence.judge.by_atlas, r.warnings);
  else
    reconstruct(out, bone.GetPointer(), dense_solid.GetPointer(), choice, search.bone_depth, hu_crop, offset, depth_cap,
                crop_of_bone.cut, max_spacing, evidence.prior, ctx, opt, lap);
  out.separated = choice.mand != 0;
  r.threshold_hu = threshold;
  r.offset_hu = offset;
  r.separation_radius_mm = choice.mand ? choice.r_used : 0.0;
  return out;
}

// Truncation of r.mask on its grid, and its warning (replacing any earlier
// one: a mask cut from a crop, voted or trimmed is judged again).
const char* const kTruncatedWarning = "the mandible touches the edge of the scan: it may be truncated";

static void set_truncation(Result& r) {
  r.warnings.erase(std::remove(r.warnings.begin(), r.warnings.end(), kTruncatedWarning), r.warnings.end());
  r.truncated = touches_border(r.mask);
  if (r.truncated) r.warnings.push_back(kTruncatedWarning);
}

// Step 6's surface level (docs/segmentation.md): the mask's boundary moved
// in to surface_hu (the half-maximum between soft tissue and cortex) where
// the scan resolves the cortex, its interior kept. In place on crop_mask
// (grid cg, HU hu_crop); cut_faces: faces of the grid on the scan's edge.
static void to_surface_level(std::vector<std::uint8_t>& crop_mask, const std::vector<float>& hu_crop, const Geometry& cg, double surface_hu,
                             double bone_hu, double soft_tissue_hu, unsigned cut_faces) {
  // Keep voxels above the surface level, plus voxels enclosed by them and
  // by the neighbouring bones: where the separation cut the mandible from
  // another bone (a condyle from its fossa across a bridged joint space),
  // its cortex is open, and the cancellous interior must not drain away
  // through the cut (it did: 0.8 mm, teeth in occlusion, 1 mm joint space,
  // 47 of 80 cm3 kept).
  // The level moves the boundary in by the partial-volume layer only: a
  // voxel deeper than 1.5 voxels inside the mask stays whatever its value.
  // Where the cortex is faint (low-density bone), the shell above the level
  // has holes, and through them the whole interior drained (bone HU scaled
  // to a 1000 HU cortex and 250 HU cancellous: Dice 0.68).
  const double step = std::max({cg.spacing[0], cg.spacing[1], cg.spacing[2]});
  const float deep = static_cast<float>(1.5 * step);
  const std::vector<float> depth = depth_inside(crop_mask.data(), cg.size, cg.spacing, deep + static_cast<float>(step));
  // The shell that encloses the interior is drawn at the local
  // half-maximum where that is lower: half-way between soft tissue and the
  // brightest mask voxel within two voxels. 700 HU is the half-maximum of a
  // cortex of ~1400 HU; a cortex thinner than the voxels plus the scanner's
  // blur (a child's mandible at 1 mm) peaks lower, its shell above 700 HU
  // had gaps and the cancellous core of the thin parts drained (scale 0.7
  // at 1 mm: 24.2 of 26.8 cm3 kept, Dice 0.90). The boundary itself stays
  // at 700 HU: the voxels between the two levels are not kept, only what
  // the shell encloses, so a blurred edge is not fattened (PSF sigma 1 mm
  // with the local level as the boundary: Dice 0.966 -> 0.951).
  const float soft_hu = static_cast<float>(soft_tissue_hu);
  const auto local_level = [&](std::size_t i) {
    const long nx = static_cast<long>(cg.size[0]), ny = static_cast<long>(cg.size[1]), nz = static_cast<long>(cg.size[2]);
    const long x = static_cast<long>(i % cg.size[0]), y = static_cast<long>((i / cg.size[0]) % cg.size[1]),
               z = static_cast<long>(i / (cg.size[0] * cg.size[1]));
    float peak = hu_crop[i];
    for (long c = std::max(0L, z - 2); c <= std::min(nz - 1, z + 2); ++c)
      for (long b = std::max(0L, y - 2); b <= std::min(ny - 1, y + 2); ++b)
        for (long a = std::max(0L, x - 2); a <= std::min(nx - 1, x + 2); ++a) {
          const std::size_t q = static_cast<std::size_t>((c * ny + b) * nx + a);
          if (crop_mask[q]) peak = std::max(peak, hu_crop[q]);
        }
    return std::min(static_cast<float>(surface_hu), 0.5f * (soft_hu + peak));
  };
  auto hi_img = io::make_image<MaskImage>(cg);
  auto* h = hi_img->GetBufferPointer();
  const long nvox = static_cast<long>(crop_mask.size());
#pragma omp parallel for schedule(static)
  for (long li = 0; li < nvox; ++li) {
    const std::size_t i = static_cast<std::size_t>(li);
    if (!crop_mask[i]) h[i] = hu_crop[i] >= bone_hu;
    else if (hu_crop[i] >= surface_hu || depth[i] > deep) h[i] = 1;
    else h[i] = hu_crop[i] >= local_level(i);
  }
  cap_cut_faces(h, cg.size, cut_faces, true);
  const MaskImage::Pointer hi_filled = filled(hi_img.GetPointer(), true);
  const auto* fh = hi_filled->GetBufferPointer();
  for (std::size_t i = 0; i < crop_mask.size(); ++i)
    crop_mask[i] = crop_mask[i] && (hu_crop[i] >= surface_hu || (fh[i] && !h[i]) || depth[i] > deep);
}

// Steps 6-7 on the input grid: surface placement, clean-up, truncation.
// cortex_resolved: by the scan itself (the grid may be a finer interpolation
// of it, which does not resolve a cortex the scan did not; GridContext).
static Result finalize(const Volume& ct, const Options& opt, const MaskImage::RegionType& separation_region,
                       std::vector<std::uint8_t> separation_mask, Result r, bool cortex_resolved) {
  SegLap lap;
  const Geometry& g = ct.geom;
  // Work in the mask's bounding box with a margin of 3 voxels (the closing
  // ball's radius + 1): every step below is local, and the margin of
  // background keeps hole filling and closing as on the whole region.
  const Dims3 sdims{separation_region.GetSize()[0], separation_region.GetSize()[1], separation_region.GetSize()[2]};
  const Box box = bounding_box(separation_mask.data(), sdims, 3);
  if (box.size[0] == 0) throw Error(ExitCode::NoMandible, "no mandible found: the mandible mask is empty");
  std::vector<std::uint8_t> crop_mask = extract(separation_mask.data(), sdims, box);
  separation_mask = {};
  MaskImage::RegionType region;
  for (int a = 0; a < 3; ++a) {
    region.SetIndex(a, separation_region.GetIndex()[a] + static_cast<long>(box.lo[a]));
    region.SetSize(a, box.size[a]);
  }
  const Geometry cg = [&] {
    Geometry c = g;
    for (int a = 0; a < 3; ++a) c.size[a] = region.GetSize()[a];
    c.origin = g.index_to_lps(static_cast<double>(region.GetIndex()[0]), static_cast<double>(region.GetIndex()[1]),
                              static_cast<double>(region.GetIndex()[2]));
    return c;
  }();
  const double voxel_mm3 = g.voxel_volume_mm3();
  const double offset = r.offset_hu;
  const std::vector<float> hu_crop = crop_values(ct, region, cg);
  // Faces of the box on the scan's edge: a mandible cut there is capped by its
  // own cross-section before each hole filling (cap_cut_faces).
  unsigned cut_faces = 0;
  for (int a = 0; a < 3; ++a) {
    if (region.GetIndex()[a] == 0) cut_faces |= 1u << (2 * a);
    if (static_cast<std::size_t>(region.GetIndex()[a]) + region.GetSize()[a] == g.size[a]) cut_faces |= 1u << (2 * a + 1);
  }
  // Surface at the half-maximum between soft tissue and cortical bone: the
  // 250 HU bone threshold lies outside the edge of a blurred cortex. Only
  // where the scan resolves the cortex (GridContext::cortex_resolved); the
  // cancellous core below that level is restored by the hole filling.
  if (cortex_resolved) {
    r.surface_level_hu = offset + opt.surface_threshold_hu;
    to_surface_level(crop_mask, hu_crop, cg, r.surface_level_hu, offset + opt.bone_threshold_hu, offset + kSoftTissueHu, cut_faces);
  }
  if (lap.on()) std::fprintf(stderr, "  after surface level: %zu voxels\n", static_cast<std::size_t>(std::count(crop_mask.begin(), crop_mask.end(), 1)));
  lap("surface level");

  // Close small gaps (a ball of 1-2 voxels), fill the cancellous interior.
  auto mimg = io::make_image<MaskImage>(cg);
  {
    std::vector<std::uint8_t> closed = crop_mask;
    std::array<int, 3> radius;
    for (int a = 0; a < 3; ++a) radius[a] = g.spacing[a] < 0.7 ? 2 : 1;
    close_ball(closed, cg.size, radius);
    std::copy(closed.begin(), closed.end(), mimg->GetBufferPointer());
  }
  const std::vector<std::size_t> lid = cap_cut_faces(mimg->GetBufferPointer(), cg.size, cut_faces, true);
  const MaskImage::Pointer fill = filled(mimg.GetPointer(), true);
  if (r.surface_level_hu != 0) {
    // Where the boundary sits at the half-maximum (the scan resolves the
    // cortex), the closing serves the filling only (it shuts the shell where
    // the cortex is a voxel short); the voxels it adds itself lie outside
    // that boundary: they bridged the embrasures between teeth and rounded
    // every crease (3-5 k voxels of ~82 k at 1 mm, Dice -0.003 to -0.004).
    // Keep the mask and what the closed shell encloses. On coarser scans the
    // closing stays: it restores partial-volume bone below the 250 HU
    // threshold, which clinical contours include (OpenKBP 0.812 / 0.867 /
    // 0.789 without it, 0.822 / 0.872 / 0.791 with it).
    auto* fo = fill->GetBufferPointer();
    const auto* cm = mimg->GetBufferPointer();
    for (std::size_t i = 0; i < crop_mask.size(); ++i) fo[i] = crop_mask[i] || (fo[i] && !cm[i]);
    for (std::size_t i : lid) fo[i] = 1;
  }

  r.mask.geom = g;
  lap("closing, fill");
  r.mask.data.assign(g.voxel_count(), 0);
  const auto* out = fill->GetBufferPointer();
  const auto ri = region.GetIndex();
  // Closing (as if the box were embedded in background) and hole filling
  // only add voxels: the result holds its input, so a mandible cut by the
  // scan's edge still touches it (truncation).
  for (std::size_t k = 0; k < cg.size[2]; ++k)
    for (std::size_t j = 0; j < cg.size[1]; ++j)
      for (std::size_t i = 0; i < cg.size[0]; ++i)
        if (out[cg.linear(i, j, k)]) r.mask.data[g.linear(i + ri[0], j + ri[1], k + ri[2])] = 1;
  r.voxels = r.mask.count();
  if (r.voxels == 0) throw Error(ExitCode::NoMandible, "no mandible found: the mandible mask is empty");
  r.volume_mm3 = r.voxels * voxel_mm3;
  set_truncation(r);
  return r;
}

// Mean of each f[0] x f[1] x f[2] block of ct (trailing partial blocks
// dropped), on a grid whose voxel I is centred on its block: ITK's
// BinShrinkImageFilter over ct's voxels in place (bit-identical to the loop it
// replaced and 2x faster: bench/resampling_vs_itk.cpp).
Volume bin_average(const Volume& ct, const std::array<unsigned, 3>& f) {
  auto shrink = itk::BinShrinkImageFilter<FloatImage, FloatImage>::New();
  itk::BinShrinkImageFilter<FloatImage, FloatImage>::ShrinkFactorsType factors;
  for (unsigned a = 0; a < 3; ++a) factors[a] = f[a];
  shrink->SetInput(io::float_view(ct));
  shrink->SetShrinkFactors(factors);
  shrink->Update();
  const FloatImage* out = shrink->GetOutput();
  Volume coarse;
  coarse.geom = io::geometry_of(out);
  const float* p = out->GetBufferPointer();
  coarse.hu.assign(p, p + coarse.geom.voxel_count());
  return coarse;
}

// Steps 1-7 on the grid of ct (binned for separation when finer than
// opt.separation_spacing_mm).
static Result segment_on_grid(const Volume& ct, const Options& opt, const GridContext& ctx) {
  const Geometry& g = ct.geom;
  // Inputs finer than ~0.8 mm: separate on a bin-averaged grid, place the
  // surface at full resolution (docs/segmentation.md, "Multi-resolution").
  std::array<unsigned, 3> f{1, 1, 1};
  for (int a = 0; a < 3; ++a)
    f[a] = std::max(1u, static_cast<unsigned>(std::floor(opt.separation_spacing_mm / g.spacing[a] + 1e-6)));
  if (f[0] * f[1] * f[2] == 1) {
    Separated sp = separate(ct, opt, ctx);
    return finalize(ct, opt, sp.region, std::move(sp.mand), sp.info, ctx.cortex_resolved);
  }
  const Volume coarse = bin_average(ct, f);
  if (coarse.geom.size[0] < 8 || coarse.geom.size[1] < 8 || coarse.geom.size[2] < 8) {
    Separated sp = separate(ct, opt, ctx);
    return finalize(ct, opt, sp.region, std::move(sp.mand), sp.info, ctx.cortex_resolved);
  }
  Separated sp = separate(coarse, opt, ctx);
  // Full-resolution region: the coarse mandible region, grown by one coarse
  // voxel into anything not given to another bone.
  const auto ci = sp.region.GetIndex();
  const auto cs = sp.region.GetSize();
  MaskImage::RegionType region;
  for (int a = 0; a < 3; ++a) {
    const long lo = std::max(0L, (static_cast<long>(ci[a]) - 1) * static_cast<long>(f[a]));
    const long hi = std::min(static_cast<long>(g.size[a]), (static_cast<long>(ci[a] + cs[a]) + 1) * static_cast<long>(f[a]));
    region.SetIndex(a, lo);
    region.SetSize(a, static_cast<itk::SizeValueType>(hi - lo));
  }
  const Geometry& cg = sp.cg;
  auto at = [&](const std::vector<std::uint8_t>& m, long I, long J, long K) -> bool {
    I -= ci[0], J -= ci[1], K -= ci[2];
    if (m.empty() || I < 0 || J < 0 || K < 0 || I >= long(cg.size[0]) || J >= long(cg.size[1]) || K >= long(cg.size[2])) return false;
    return m[cg.linear(static_cast<std::size_t>(I), static_cast<std::size_t>(J), static_cast<std::size_t>(K))] != 0;
  };
  const double bone_hu = opt.bone_threshold_hu + sp.info.offset_hu;
  const auto ri = region.GetIndex();
  const auto rs = region.GetSize();
  Geometry fg = g;
  for (int a = 0; a < 3; ++a) fg.size[a] = rs[a];
  std::vector<std::uint8_t> mask(fg.voxel_count(), 0);
  const long nz = static_cast<long>(rs[2]);
#pragma omp parallel for schedule(static)
  for (long k = 0; k < nz; ++k)
    for (std::size_t j = 0; j < rs[1]; ++j)
      for (std::size_t i = 0; i < rs[0]; ++i) {
        const long x = static_cast<long>(i) + ri[0], y = static_cast<long>(j) + ri[1], z = k + ri[2];
        if (ct.hu[g.linear(x, y, z)] < bone_hu) continue;
        const long I = std::min<long>(x / f[0], long(coarse.geom.size[0]) - 1), J = std::min<long>(y / f[1], long(coarse.geom.size[1]) - 1),
                   K = std::min<long>(z / f[2], long(coarse.geom.size[2]) - 1);
        bool keep = at(sp.mand, I, J, K);
        if (!keep && !at(sp.other, I, J, K))
          for (int dk = -1; dk <= 1 && !keep; ++dk)
            for (int dj = -1; dj <= 1 && !keep; ++dj)
              for (int di = -1; di <= 1 && !keep; ++di) keep = at(sp.mand, I + di, J + dj, K + dk);
        mask[fg.linear(i, j, static_cast<std::size_t>(k))] = keep;
      }
  return finalize(ct, opt, region, std::move(mask), sp.info, ctx.cortex_resolved);
}

// The region located on the coarse grid, grown by one coarse voxel
// (26-neighbourhood), on that grid (segment_located's "located region").
static Mask grown_by_one_voxel(const Separated& located) {
  Mask region;
  region.geom = located.cg;
  region.data.assign(located.mand.size(), 0);
  const Dims3& d = located.cg.size;
  for (std::size_t k = 0; k < d[2]; ++k)
    for (std::size_t j = 0; j < d[1]; ++j)
      for (std::size_t i = 0; i < d[0]; ++i) {
        if (!located.mand[located.cg.linear(i, j, k)]) continue;
        for (std::size_t z = k ? k - 1 : 0; z <= std::min(k + 1, d[2] - 1); ++z)
          for (std::size_t y = j ? j - 1 : 0; y <= std::min(j + 1, d[1] - 1); ++y)
            for (std::size_t x = i ? i - 1 : 0; x <= std::min(i + 1, d[0] - 1); ++x) region.data[located.cg.linear(x, y, z)] = 1;
      }
  return region;
}

// Fine scans (docs/segmentation.md, "Locating the mandible first"): steps 1-5
// on a bin-averaged grid of about opt.locate_spacing_mm find the mandible's
// region; steps 1-7 then run at full resolution on the scan cropped to that
// region's bounding box grown by opt.locate_margin_mm, with the calibration
// offset of the whole scan. The crop must not change the answer: when the
// located run does not separate, or its mask reaches a cut face of the crop
// or lies outside the located region, the whole scan is segmented instead.
static Result segment_located(const Volume& ct, const Options& opt, const GridContext& whole) {
  const Geometry& g = ct.geom;
  SegLap lap;
  std::array<unsigned, 3> f{1, 1, 1};
  for (int a = 0; a < 3; ++a)
    f[a] = opt.locate_spacing_mm > 0 ? std::max(1u, static_cast<unsigned>(std::floor(opt.locate_spacing_mm / g.spacing[a] + 1e-6))) : 1u;
  if (f[0] * f[1] * f[2] < 4) return segment_on_grid(ct, opt, whole);
  const Volume coarse = bin_average(ct, f);
  if (coarse.geom.size[0] < 16 || coarse.geom.size[1] < 16 || coarse.geom.size[2] < 16) return segment_on_grid(ct, opt, whole);
  auto fall_back = [&](const char* why) {
    if (lap.on()) std::fprintf(stderr, "  locate: %s; segmenting the whole scan\n", why);
    return segment_on_grid(ct, opt, whole);
  };
  Separated located;
  try {
    located = separate(coarse, opt, whole);
  } catch (const Error&) {
    return fall_back("nothing located on the coarse grid");
  }
  if (!located.separated) return fall_back("not separated on the coarse grid");
  const Box b = bounding_box(located.mand.data(), located.cg.size, 0);
  if (b.size[0] == 0) return fall_back("empty region on the coarse grid");
  lap("locate (coarse grid)");
  // Crop: the located region's blocks, grown by the margin.
  std::array<std::size_t, 3> lo{}, size{};
  std::array<bool, 6> cut{};
  for (int a = 0; a < 3; ++a) {
    const long m = static_cast<long>(std::ceil(opt.locate_margin_mm / g.spacing[a]));
    const long first = static_cast<long>(located.region.GetIndex()[a] + b.lo[a]) * f[a];
    const long last = static_cast<long>(located.region.GetIndex()[a] + b.lo[a] + b.size[a]) * f[a] - 1;
    const long l = std::max(0L, first - m), h = std::min(static_cast<long>(g.size[a]) - 1, last + m);
    lo[a] = static_cast<std::size_t>(l);
    size[a] = static_cast<std::size_t>(h - l + 1);
    cut[2 * a] = l > 0;
    cut[2 * a + 1] = h + 1 < static_cast<long>(g.size[a]);
  }
  Volume sub;
  sub.geom = g;
  sub.geom.size = size;
  sub.geom.origin = g.index_to_lps(static_cast<double>(lo[0]), static_cast<double>(lo[1]), static_cast<double>(lo[2]));
  sub.hu.resize(sub.geom.voxel_count());
  for (std::size_t k = 0; k < size[2]; ++k)
    for (std::size_t j = 0; j < size[1]; ++j)
      std::copy_n(ct.hu.data() + g.linear(lo[0], j + lo[1], k + lo[2]), size[0], sub.hu.data() + sub.geom.linear(0, j, k));
  const Mask region = grown_by_one_voxel(located);
  GridContext in_crop = whole;
  in_crop.offset_hu = located.info.offset_hu;
  in_crop.cut = cut;
  in_crop.located = &region;
  Result r;
  try {
    r = segment_on_grid(sub, opt, in_crop);
  } catch (const Error&) {
    return fall_back("nothing found in the crop");
  }
  if (r.separation_radius_mm <= 0) return fall_back("not separated in the crop");
  // The mask on a cut face: the mandible (or what was taken for it) goes on
  // outside the crop. Mask voxels outside the located region, grown by one
  // coarse voxel: the crop found another bone, or more than the mandible.
  const Geometry& sg = sub.geom;
  std::size_t on_cut = 0, outside = 0, total = 0;
  for (std::size_t k = 0; k < sg.size[2]; ++k)
    for (std::size_t j = 0; j < sg.size[1]; ++j)
      for (std::size_t i = 0; i < sg.size[0]; ++i) {
        if (!r.mask.data[sg.linear(i, j, k)]) continue;
        ++total;
        on_cut += (cut[0] && i == 0) || (cut[1] && i + 1 == sg.size[0]) || (cut[2] && j == 0) || (cut[3] && j + 1 == sg.size[1]) ||
                  (cut[4] && k == 0) || (cut[5] && k + 1 == sg.size[2]);
        outside += !set_near(region, sg.index_to_lps(static_cast<double>(i), static_cast<double>(j), static_cast<double>(k)));
      }
  if (lap.on())
    std::fprintf(stderr, "  crop %zu x %zu x %zu of %zu x %zu x %zu: mask %zu voxels, %zu on cut faces, %.4f outside the located region\n",
                 size[0], size[1], size[2], g.size[0], g.size[1], g.size[2], total, on_cut,
                 total ? static_cast<double>(outside) / static_cast<double>(total) : 0.0);
  if (on_cut > 0) return fall_back("the mask reaches a cut face of the crop");
  if (static_cast<double>(outside) > opt.locate_outside_fraction * static_cast<double>(total))
    return fall_back("the mask lies outside the located region");
  // Back onto the scan's grid; truncation is the scan's edge, not the crop's.
  Mask full;
  full.geom = g;
  full.data.assign(g.voxel_count(), 0);
  for (std::size_t k = 0; k < size[2]; ++k)
    for (std::size_t j = 0; j < size[1]; ++j)
      std::copy_n(r.mask.data.data() + sg.linear(0, j, k), size[0], full.data.data() + g.linear(lo[0], j + lo[1], k + lo[2]));
  r.mask = std::move(full);
  set_truncation(r);
  r.cropped = true;
  return r;
}

// Trilinear interpolation of ct onto a grid with the same origin, direction
// and extent and spacing min(native, max_spacing) per axis.
Volume interpolate_finer(const Volume& ct, double max_spacing) {
  const Geometry& g = ct.geom;
  Volume o;
  o.geom = g;
  std::array<double, 3> step{};  // native index units per working voxel
  for (int a = 0; a < 3; ++a) {
    if (g.spacing[a] <= max_spacing) {
      step[a] = 1.0;
      continue;
    }
    const double ext = static_cast<double>(g.size[a] - 1) * g.spacing[a];
    o.geom.size[a] = static_cast<std::size_t>(std::floor(ext / max_spacing + 1e-9)) + 1;
    o.geom.spacing[a] = max_spacing;
    step[a] = max_spacing / g.spacing[a];
  }
  o.hu.assign(o.geom.voxel_count(), 0.0f);
  const long nz = static_cast<long>(o.geom.size[2]);
  auto axis = [&](int a, std::size_t i, long* i0, double* f) {
    const double x = static_cast<double>(i) * step[a];
    *i0 = std::min(static_cast<long>(x), std::max(0L, static_cast<long>(g.size[a]) - 2));
    *f = g.size[a] > 1 ? std::min(1.0, x - static_cast<double>(*i0)) : 0.0;
  };
#pragma omp parallel for schedule(static)
  for (long k = 0; k < nz; ++k)
    for (std::size_t j = 0; j < o.geom.size[1]; ++j)
      for (std::size_t i = 0; i < o.geom.size[0]; ++i) {
        long x0, y0, z0;
        double fx, fy, fz;
        axis(0, i, &x0, &fx);
        axis(1, j, &y0, &fy);
        axis(2, static_cast<std::size_t>(k), &z0, &fz);
        double acc = 0;
        for (int c = 0; c < 8; ++c) {
          const int dx = c & 1, dy = (c >> 1) & 1, dz = (c >> 2) & 1;
          const double w = (dx ? fx : 1 - fx) * (dy ? fy : 1 - fy) * (dz ? fz : 1 - fz);
          if (w == 0) continue;
          acc += w * ct.hu[g.linear(static_cast<std::size_t>(x0 + dx), static_cast<std::size_t>(y0 + dy), static_cast<std::size_t>(z0 + dz))];
        }
        o.hu[o.geom.linear(i, j, static_cast<std::size_t>(k))] = static_cast<float>(acc);
      }
  return o;
}

// A mask on a finer grid (same origin and direction) back onto grid g: a
// voxel is set when more than half of the fine voxels in its footprint are.
Mask coarsen(const Mask& fine, const Geometry& g) {
  Mask m;
  m.geom = g;
  m.data.assign(g.voxel_count(), 0);
  const Geometry& fg = fine.geom;
  std::array<double, 3> r{};
  for (int a = 0; a < 3; ++a) r[a] = g.spacing[a] / fg.spacing[a];
  auto range = [&](int a, std::size_t i, long* lo, long* hi) {
    *lo = std::max(0L, static_cast<long>(std::ceil((static_cast<double>(i) - 0.5) * r[a] - 1e-9)));
    *hi = std::min(static_cast<long>(fg.size[a]) - 1, static_cast<long>(std::floor((static_cast<double>(i) + 0.5) * r[a] - 1e-9)));
    if (*hi < *lo) *hi = *lo = std::min(static_cast<long>(fg.size[a]) - 1, std::lround(static_cast<double>(i) * r[a]));
  };
  const long nz = static_cast<long>(g.size[2]);
#pragma omp parallel for schedule(static)
  for (long k = 0; k < nz; ++k)
    for (std::size_t j = 0; j < g.size[1]; ++j)
      for (std::size_t i = 0; i < g.size[0]; ++i) {
        long i0, i1, j0, j1, k0, k1;
        range(0, i, &i0, &i1);
        range(1, j, &j0, &j1);
        range(2, static_cast<std::size_t>(k), &k0, &k1);
        std::size_t on = 0, all = 0;
        for (long z = k0; z <= k1; ++z)
          for (long y = j0; y <= j1; ++y)
            for (long x = i0; x <= i1; ++x, ++all)
              on += fine.data[fg.linear(static_cast<std::size_t>(x), static_cast<std::size_t>(y), static_cast<std::size_t>(z))];
        m.data[g.linear(i, j, static_cast<std::size_t>(k))] = 2 * on > all;
      }
  return m;
}

// An adult mandible is about 90-125 mm wide across the condyles. A whole
// (untruncated) mask much narrower is likely another bone taken for it: with
// 3 mm slab-averaged slices and the teeth 1 mm apart the mandible, welded to
// the skull, had no core of its own and the maxilla's was taken (Dice 0.06,
// 75 mm wide) without a word. Said, not refused: a child's mandible is
// narrower.
static void check_width(Result& r) {
  if (r.truncated || r.voxels == 0) return;
  const Geometry& g = r.mask.geom;
  const Box b = bounding_box(r.mask.data.data(), g.size, 0);
  double lo = 1e30, hi = -1e30;
  for (std::size_t k = b.lo[2]; k < b.lo[2] + b.size[2]; ++k)
    for (std::size_t j = b.lo[1]; j < b.lo[1] + b.size[1]; ++j)
      for (std::size_t i = b.lo[0]; i < b.lo[0] + b.size[0]; ++i)
        if (r.mask.data[g.linear(i, j, k)]) {
          const double x = g.index_to_lps(static_cast<double>(i), static_cast<double>(j), static_cast<double>(k))[0];
          lo = std::min(lo, x), hi = std::max(hi, x);
        }
  const double width = hi - lo + std::min(g.spacing[0], g.spacing[1]);
  if (width < 80.0)
    r.warnings.push_back("the structure taken for the mandible is only " + std::to_string(static_cast<int>(std::lround(width))) +
                         " mm wide left to right (an adult mandible is about 90-125 mm across the condyles, a young "
                         "child's from about 75): it may be another bone; check the segmentation (thick slices with the "
                         "teeth in occlusion: docs/segmentation.md)");
}

static Result segment_auto_with(const Volume& ct, const Options& opt, GridContext whole);

// Whether the scan resolves the mandible's cortex (the surface is then placed
// at the half-maximum, finalize()): in-plane and slice spacing up to 1.25 mm.
static bool resolves_cortex(const Geometry& g, const Options& opt) {
  const double native = std::max({g.spacing[0], g.spacing[1], g.spacing[2]});
  const double mid = std::max(std::min(g.spacing[0], g.spacing[1]), std::min(std::max(g.spacing[0], g.spacing[1]), g.spacing[2]));
  return mid <= 1.25 && native <= opt.max_working_spacing_mm + 1e-6;
}

// The scan's index box holding the placed atlas's box, grown by one voxel
// and clipped to the scan (empty when they do not meet).
static MaskImage::RegionType atlas_region(const Geometry& g, const atlas::Atlas& a, const atlas::Pose& pose) {
  std::array<double, 3> lo{1e30, 1e30, 1e30}, hi{-1e30, -1e30, -1e30};
  for (int c = 0; c < 8; ++c) {
    const Vec3 corner{a.grid.origin[0] + a.grid.spacing * ((c & 1) ? a.grid.n[0] - 1 : 0),
                      a.grid.origin[1] + a.grid.spacing * ((c & 2) ? a.grid.n[1] - 1 : 0),
                      a.grid.origin[2] + a.grid.spacing * ((c & 4) ? a.grid.n[2] - 1 : 0)};
    const Vec3 q = g.lps_to_index(pose.apply(corner));
    for (int d = 0; d < 3; ++d) lo[d] = std::min(lo[d], q[d]), hi[d] = std::max(hi[d], q[d]);
  }
  MaskImage::RegionType region;
  for (int d = 0; d < 3; ++d) {
    const long l = std::max(0L, static_cast<long>(std::floor(lo[d])) - 1);
    const long h = std::min(static_cast<long>(g.size[d]) - 1, static_cast<long>(std::ceil(hi[d])) + 1);
    region.SetIndex(d, l);
    region.SetSize(d, h >= l ? static_cast<itk::SizeValueType>(h - l + 1) : 0);
  }
  return region;
}

// Calibration offset of the scan (estimate_offset) and, when it is large,
// the warning that says so.
static double calibration_offset(const Volume& ct, std::vector<std::string>& warnings) {
  std::size_t soft = 0;
  const double offset = estimate_offset(ct, &soft);
  warn_about_calibration(offset, warnings);
  return offset;
}

// Where most training mandibles lie once the atlas is placed: bone there is
// the mandible's marker for the zone's watershed.
constexpr double kZoneMarkerP = 0.5;

// Voxels no larger than this resolve the temporomandibular joint's superior
// space (adult 2.5 mm, Ikeda & Kawamura 2009) as a valley below the bone
// threshold, so the watershed can cut the zone there. A gap w wide sampled
// at spacing s always has a voxel whose footprint is at most 1 - w / (2 s)
// bone: 17 % at 1.5 mm, ~210 HU between cortex (~1000) and soft tissue
// (~50), under the 250 HU threshold; 29 % (~320 HU) at 1.75 mm. Measured at
// 1.5 mm (docs/segmentation.md, step 4): the Visible Human female Co 2.7 /
// 4.4 -> 0.3 / 1.3 mm from its reference with the cut; the independent
// phantom family Co 3.8-5.6 -> 0.6-2.1 mm on 11 of 13 cases (5.9-6.1 mm on
// the two whose joint space no 1.5 mm voxel shows). Coarser scans keep the zone
// (openkbp-train at ~4 mm: mean Dice 0.866 either way, worst 0.733 -> 0.719
// with the cut).
constexpr double kJointResolvingSpacingMm = 1.5;

// Body cross-section (voxels at or above kBodyHu + offset_hu) of each slice
// across grid axis `axis`.
constexpr double kBodyHu = -500.0;

static std::vector<std::size_t> body_profile(const std::vector<float>& hu, const Geometry& g, int axis, double offset_hu) {
  std::vector<std::size_t> body(g.size[axis], 0);
  const float tissue = static_cast<float>(offset_hu + kBodyHu);
  for (std::size_t k = 0; k < g.size[2]; ++k)
    for (std::size_t j = 0; j < g.size[1]; ++j) {
      const float* row = hu.data() + g.linear(0, j, k);
      for (std::size_t i = 0; i < g.size[0]; ++i) {
        const std::size_t v[3] = {i, j, k};
        body[v[axis]] += row[i] >= tissue;
      }
    }
  return body;
}

// The grid axis whose direction is nearest to the LPS direction `dir`, and
// the sign (+1 or -1) of an index step along `dir`.
static std::pair<int, int> grid_axis_nearest(const Geometry& g, const Vec3& dir) {
  int best = 0;
  double best_cos = 0;
  for (int a = 0; a < 3; ++a) {
    const double c = g.direction[a] * dir[0] + g.direction[3 + a] * dir[1] + g.direction[6 + a] * dir[2];
    if (std::abs(c) > std::abs(best_cos)) best = a, best_cos = c;
  }
  return {best, best_cos >= 0 ? 1 : -1};
}

// The grid axis whose direction is nearest to LPS axis `lps` (0 L, 1 P, 2 S).
static int grid_axis_along(const Geometry& g, int lps) {
  Vec3 e{0, 0, 0};
  e[lps] = 1;
  return grid_axis_nearest(g, e).first;
}

// Where the scanned body ends (docs/segmentation.md, "The scanned body"): a
// scan may hold the head only up to a level and pad the rest of its grid
// with air or noise (OpenKBP's volumes end at the field of view that way).
// Across the scan's vertical axis, the scanned part is the run of slices
// around the mandible's whose body cross-section is at least
// kScannedBodyFraction of its median over the mandible's slices: the head
// above the mandible (cranium, ~150 x 190 mm) and the neck below (~110 x
// 120 mm) are never under half the cross-section at the mandible's level
// (face and jaws, ~140 x 160 mm; Farkas 1994), while a scan's end drops it
// to a few percent within a slice.
constexpr double kScannedBodyFraction = 0.25;

// The scanned run (above) of the body profile `body` around the slices
// [lo, hi] the mandible lies in: first and last slice; the whole profile
// when the mandible's middle slice is itself not scanned.
static std::array<std::size_t, 2> scanned_run(const std::vector<std::size_t>& body, std::size_t lo, std::size_t hi) {
  std::vector<std::size_t> at_mandible(body.begin() + static_cast<long>(lo), body.begin() + static_cast<long>(hi + 1));
  std::nth_element(at_mandible.begin(), at_mandible.begin() + static_cast<long>(at_mandible.size() / 2), at_mandible.end());
  const double floor = kScannedBodyFraction * static_cast<double>(at_mandible[at_mandible.size() / 2]);
  auto scanned = [&](std::size_t k) { return static_cast<double>(body[k]) >= floor; };
  std::size_t first = lo + (hi - lo) / 2, last = first;
  if (!scanned(first)) return {0, body.size() - 1};
  while (first > 0 && scanned(first - 1)) --first;
  while (last + 1 < body.size() && scanned(last + 1)) ++last;
  return {first, last};
}

// The zone cut where the image separates it from other bone
// (docs/segmentation.md, "the atlas's zone", step 4): the separation's
// watershed (landscape: depth and brightness, step 5 there) flooded from two
// marker sets the atlas alone gives, bone where most training mandibles lie
// (p >= kZoneMarkerP) and bone beyond every one (p < kAtlasSupportP). The
// floods meet in the intensity valleys and at the necks between them, a joint
// space or an occlusal gap, where the zone's threshold p >= kAtlasZoneP cuts
// through the fossa's roof or the articular eminence. The zone loses what the
// outer flood takes (only voxels with p < kZoneMarkerP can be taken); it
// gains nothing (a flood without a rival on the far side of a gap crosses it).
// The floods run through the bone's body, not its cortex alone: marrow below
// the bone threshold that the cortex encloses (fill_holes, face-connected
// background) is flooded too, at its own depth and brightness, so a condylar
// head of thin cortex around fatty marrow stays joined to its ramus through
// the whole width of its neck. Through the cortex alone the neck is a valley
// as shallow as a joint space blurred by a softer kernel, and the outer flood
// took the head (the Visible Human female blurred by 0.5 mm: condylion 10 mm
// off). Only bone voxels are markers, and only bone leaves the zone.
static std::vector<std::uint8_t> zone_cut_by_watershed(const std::vector<std::uint8_t>& zone, const std::vector<std::uint8_t>& bone,
                                                       const std::vector<float>& p, const std::vector<float>& hu, double offset_hu,
                                                       const Geometry& cg) {
  std::vector<std::uint8_t> body(bone.size(), 0);
  fill_holes(bone.data(), Dims3{cg.size[0], cg.size[1], cg.size[2]}, /*fully_connected=*/false, body.data());
  const std::vector<float> depth = depth_inside(body.data(), cg.size, cg.spacing, kLandscapeDepthMm);
  std::vector<float> level(bone.size(), 0.0f);
  std::vector<unsigned> markers(bone.size(), 0);
  const float hu0 = static_cast<float>(offset_hu);
  for (std::size_t i = 0; i < bone.size(); ++i) {
    if (!body[i]) continue;
    level[i] = landscape_level(depth[i], hu[i], hu0);
    if (bone[i]) markers[i] = p[i] >= kZoneMarkerP ? 1u : p[i] < kAtlasSupportP ? 2u : 0u;
  }
  const std::vector<unsigned> label = watershed(level, cg, -2.0f, 0.0f, body, markers);
  std::vector<std::uint8_t> out(zone.size(), 0);
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = zone[i] && label[i] != 2;
  return out;
}

// A mandible may reach a little beyond every training mandible at the fitted
// pose: the similarity fit leaves a few millimetres (tests/atlas recovers a
// known pose within 3 mm) and a population reaches beyond 90 training cases.
// So the image's mask is checked against the training mandibles' support
// grown by this (mm in the atlas's frame, times the fitted scale in the
// scan). Another bone taken with the mandible lies farther out (the vault,
// the maxilla, the spine: OpenKBP's old wrong masks 0.58-0.82 in support).
// Random phantom anatomies whose rami are longer than any training mandible's
// (docs/phantom.md): 96-98 % within 5 mm of the support, 91-96 % within it.
constexpr double kSupportToleranceMm = 5.0;

// The shipped atlas with its mandible field replaced by the support grown by
// kSupportToleranceMm: 1 within, 0 beyond (placed like the prior, read at 0.5).
static const atlas::Atlas& grown_support_atlas() {
  static const atlas::Atlas grown = [] {
    atlas::Atlas a = atlas::shipped();
    const atlas::Grid& g = a.grid;
    std::vector<std::uint8_t> support(a.mandible.size());
    for (std::size_t i = 0; i < support.size(); ++i) support[i] = a.mandible[i] >= kAtlasSupportP;
    const float tol2 = static_cast<float>(kSupportToleranceMm * kSupportToleranceMm);
    const std::vector<float> d2 =
        squared_distance_transform(support.data(), {std::size_t(g.n[0]), std::size_t(g.n[1]), std::size_t(g.n[2])},
                                   {g.spacing, g.spacing, g.spacing}, 4 * tol2);
    for (std::size_t i = 0; i < d2.size(); ++i) a.mandible[i] = d2[i] <= tol2 ? 1.0f : 0.0f;
    return a;
  }();
  return grown;
}

// The shipped atlas's sigmoid notch height (atlas frame, mm), found once.
static double shipped_notch_height() {
  static const double notch = atlas::sigmoid_notch_height(atlas::shipped());
  return notch;
}

// Where a process taller than every training mandible's may stand
// (atlas_zone_mask's in_room): within the support grown by
// kSupportToleranceMm and above the atlas's sigmoid notch (the placed
// atlas's frame; atlas::sigmoid_notch_height).
class ProcessRoom {
 public:
  ProcessRoom(const Geometry& g, const atlas::Pose& pose)
      : g_(g), pose_(pose), grown_(grown_support_atlas(), pose), notch_(shipped_notch_height()) {}
  bool operator()(std::size_t i) const {
    const Vec3 q = g_.index_to_lps(static_cast<double>(i % g_.size[0]), static_cast<double>(i / g_.size[0] % g_.size[1]),
                                   static_cast<double>(i / (g_.size[0] * g_.size[1])));
    return pose_.inverse(q)[2] >= notch_ && grown_.at(q) >= 0.5;  // false when the notch is NaN
  }

 private:
  const Geometry& g_;
  const atlas::Pose& pose_;
  atlas::MandiblePrior grown_;
  double notch_;
};

// The faces of the scanned part of grid g (hu on it) around `mask`: per
// axis, the first and last index; along the vertical axis, the scanned run
// around the mask's slices (scanned_run), else the grid's ends.
static std::array<std::array<std::size_t, 2>, 3> scanned_faces(const std::vector<float>& hu, const Geometry& g,
                                                               const std::vector<std::uint8_t>& mask, double offset_hu) {
  std::array<std::array<std::size_t, 2>, 3> faces{};
  for (int a = 0; a < 3; ++a) faces[a] = {0, g.size[a] - 1};
  const int ver = grid_axis_along(g, 2);
  const Box b = bounding_box(mask.data(), g.size, 0);
  if (b.size[0] == 0 || std::abs(g.direction[6 + ver]) < 0.9) return faces;
  faces[ver] = scanned_run(body_profile(hu, g, ver, offset_hu), b.lo[ver], b.lo[ver] + b.size[ver] - 1);
  return faces;
}

// Identification and separation by the atlas (docs/segmentation.md): within
// the placed atlas's box, (1) the bone mask at the bone threshold, (2) the
// atlas's mandible probability at each bone voxel, (3) the zone and its free
// appendices (atlas_zone_mask), its rim (add_zone_rim) and the condyles' tops
// up to a joint space the slices show (extend_to_joint_space), (4) on scans that resolve the joint space,
// the zone cut where the image separates it from other bone
// (zone_cut_by_watershed), (5) the surface level, closing and hole filling of
// finalize().
static Result segment_by_atlas(const Volume& ct, const Options& opt, const atlas::Fit& fit) {
  SegLap lap;
  Result r;
  r.method = "auto";
  r.marker_source = "atlas";
  r.offset_hu = calibration_offset(ct, r.warnings);
  r.threshold_hu = opt.bone_threshold_hu + r.offset_hu;
  const MaskImage::RegionType region = atlas_region(ct.geom, atlas::shipped(), fit.pose);
  Geometry cg = ct.geom;
  for (int a = 0; a < 3; ++a) cg.size[a] = region.GetSize()[a];
  if (cg.voxel_count() == 0) throw Error(ExitCode::NoMandible, "no mandible found: the mandible atlas lies outside the scan");
  cg.origin = ct.geom.index_to_lps(static_cast<double>(region.GetIndex()[0]), static_cast<double>(region.GetIndex()[1]),
                                   static_cast<double>(region.GetIndex()[2]));
  const std::vector<float> hu = crop_values(ct, region, cg);
  // The rim and the joint cut are exclusive (docs/segmentation.md, step 3):
  // where the voxels resolve the joint space the image draws the zone's
  // edge at the joints, and a rim several voxels deep would end in a ledge
  // below the condyle's top.
  const bool resolves_joints = std::max({cg.spacing[0], cg.spacing[1], cg.spacing[2]}) <= kJointResolvingSpacingMm + 1e-6;
  std::vector<std::uint8_t> bone(hu.size()), not_soft(hu.size());
  const float soft_max = static_cast<float>(r.offset_hu + kSoftTissueMaxHu);
  for (std::size_t i = 0; i < hu.size(); ++i)
    bone[i] = hu[i] >= r.threshold_hu, not_soft[i] = bone[i] || (!resolves_joints && hu[i] > soft_max);
  const atlas::MandiblePrior prior(atlas::shipped(), fit.pose);
  const std::vector<float> p = prior_at_bone(prior, not_soft.data(), cg);
  lap("atlas: bone and prior");
  const ProcessRoom room(cg, fit.pose);
  std::vector<std::uint8_t> mask = atlas_zone_mask(bone, p, cg.size, std::cref(room));
  lap("atlas: zone and appendices");
  if (resolves_joints) {
    mask = zone_cut_by_watershed(mask, bone, p, hu, r.offset_hu, cg);
    lap("atlas: zone cut by the watershed");
  } else {
    mask = add_zone_rim(mask, bone, not_soft, p, cg.size, cg.spacing, scanned_faces(hu, cg, mask, r.offset_hu));
    lap("atlas: zone's rim");
    const auto [up_axis, up_step] = grid_axis_nearest(cg, fit.pose.superior());
    std::vector<std::uint8_t> up = extend_to_joint_space(mask, bone, cg.size, up_axis, up_step, cg.spacing[up_axis], std::cref(room));
    lap("atlas: up to the joint space");
    if (std::getenv("MANDISYM_DEBUG_SEG"))
      std::fprintf(stderr, "  zone: %td voxels up to the joint space (grid axis %d)\n",
                   std::count(up.begin(), up.end(), 1) - std::count(mask.begin(), mask.end(), 1), up_axis);
    mask = std::move(up);
  }
  if (std::find(mask.begin(), mask.end(), 1) == mask.end())
    throw Error(ExitCode::NoMandible, "no mandible found: no bone lies where the mandible atlas places the mandible (" +
                                          std::to_string(static_cast<int>(r.threshold_hu)) + " HU)");
  return finalize(ct, opt, region, std::move(mask), std::move(r), /*cortex_resolved=*/false);
}

// Sums over a mask's voxels, in one pass over its bounding box (the placed
// fields are read only there; nothing of the grid's size is allocated): the
// voxels, the placed atlas's mandible probability, how many lie where
// `grown` (when given) reads at least 0.5, and the probability on the
// positive side of `midline` (when given).
struct MaskSums {
  double n = 0, p = 0, in_grown = 0, p_plus = 0;
};

static MaskSums sums_over(const Mask& m, const atlas::MandiblePrior& prior, const atlas::MandiblePrior* grown,
                          const Plane* midline = nullptr) {
  const Geometry& g = m.geom;
  const Box b = bounding_box(m.data.data(), g.size, 0);
  double n = 0, p = 0, in_grown = 0, p_plus = 0;
  const long k0 = static_cast<long>(b.lo[2]), k1 = static_cast<long>(b.lo[2] + b.size[2]);
#pragma omp parallel for schedule(static) reduction(+ : n, p, in_grown, p_plus)
  for (long k = k0; k < k1; ++k)
    for (std::size_t j = b.lo[1]; j < b.lo[1] + b.size[1]; ++j)
      for (std::size_t i = b.lo[0]; i < b.lo[0] + b.size[0]; ++i) {
        if (!m.data[g.linear(i, j, static_cast<std::size_t>(k))]) continue;
        const Vec3 q = g.index_to_lps(static_cast<double>(i), static_cast<double>(j), static_cast<double>(k));
        const double pq = prior.at(q);
        n += 1;
        p += pq;
        if (grown) in_grown += grown->at(q) >= 0.5;
        if (midline && midline->signed_distance(q) > 0) p_plus += pq;
      }
  return {n, p, in_grown, p_plus};
}

// Atlas evidence of a mask: the sum of the placed atlas's mandible
// probability over its voxels times their volume (mm3).
static double atlas_evidence_mm3(const Mask& m, const atlas::MandiblePrior& prior) {
  return sums_over(m, prior, nullptr).p * m.geom.voxel_volume_mm3();
}

// Soft Dice of the mask with the atlas's mandible probability p:
// 2 sum_mask(p) / (|mask| + sum(p)), volumes in mm3; sum(p) is the atlas's
// integral times scale^3 (its part outside the scan counted too: a mandible
// cut by the scan's edge agrees less); and the balance of the two halves:
// the atlas evidence of the mask on the weaker side of the atlas's
// mid-sagittal plane over that on the stronger. Sets r.atlas_agreement and
// r.atlas_halves_balance when the atlas was placed.
static void measure_against_atlas(Result& r) {
  if (!r.atlas.found) return;
  const atlas::MandiblePrior prior(atlas::shipped(), r.atlas.pose);
  const Plane midline = r.atlas.pose.midsagittal();
  const MaskSums s = sums_over(r.mask, prior, nullptr, &midline);
  const double n_mm3 = s.n * r.mask.geom.voxel_volume_mm3();
  r.atlas_agreement = n_mm3 > 0 ? 2 * s.p * r.mask.geom.voxel_volume_mm3() / (n_mm3 + prior.mass_mm3()) : 0.0;
  const double minus = s.p - s.p_plus;
  r.atlas_halves_balance = std::max(s.p_plus, minus) > 0 ? std::min(s.p_plus, minus) / std::max(s.p_plus, minus) : 0.0;
}


// How an image-separated mask stands against the placed atlas: the fraction
// of its voxels within the training mandibles' support, and its share of the
// zone mask's atlas evidence (zone_mm3, atlas_evidence_mm3 of the zone mask).
struct ZoneCheck {
  double in_support = 0;  // fraction of the image mask within the grown support
  double evidence = 0;    // its atlas evidence over the zone mask's
};

static ZoneCheck check_against_zone(const Mask& image, double zone_mm3, const atlas::MandiblePrior& prior, const atlas::Pose& pose) {
  const atlas::MandiblePrior grown(grown_support_atlas(), pose);
  const MaskSums m = sums_over(image, prior, &grown);
  const double e = m.p * image.geom.voxel_volume_mm3();
  return {m.n > 0 ? m.in_grown / m.n : 0.0, zone_mm3 > 0 ? e / zone_mm3 : 0.0};
}

// Identification by the atlas, separation by the image where it resolves
// the contacts (docs/segmentation.md, "the atlas's zone"): on scans up to
// max_working_spacing_mm the core/watershed separation runs first, and its
// mask is taken when it lies within the training mandibles' support
// (kImageInSupport) and holds most of the zone mask's atlas evidence
// (kImageEvidenceShare): it then draws the borders the image shows (teeth
// in occlusion, a resolved joint space) where the zone follows the atlas.
// The zone's evidence for that check is measured on a ~1 mm bin-averaged
// grid (kZoneCheckSpacingMm); the zone mask at full resolution is made only
// when it is the answer.
constexpr double kImageInSupport = 0.97;
constexpr double kImageEvidenceShare = 0.6;
constexpr double kZoneCheckSpacingMm = 1.0;

// Teeth in occlusion (docs/segmentation.md, "Teeth in occlusion"): upper
// teeth are welded to the lower ones in the scan (welded_occlusion). The weld
// is cut at the occlusal contact plane (fit_occlusal_plane,
// cut_at_occlusal_plane), the image separation runs again on the cut scan,
// and its mask is taken when the atlas verifies it as it would the first.
// tried: set when the cut was made (a plane was found).
static std::optional<Result> separate_at_occlusal_plane(const Volume& ct, const Options& opt, const atlas::Fit& fit,
                                                        const GridContext& whole, const WeldedOcclusion& weld, double offset_hu,
                                                        const atlas::MandiblePrior& prior, double zone_mm3, bool& tried) {
  const bool debug = std::getenv("MANDISYM_DEBUG_SEG") != nullptr;
  const OcclusalPlane plane = fit_occlusal_plane(weld);
  if (debug)
    std::fprintf(stderr, "  occlusal plane: %s, tilt %.1f deg, contacts' spread %.1f mm\n", plane.found ? "found" : "not found",
                 plane.tilt_deg, plane.spread_mm);
  if (!plane.found) return std::nullopt;
  const atlas::Pose& pose = fit.pose;
  Vec3 anterior = pose.apply({0, -1, 0}) - pose.apply({0, 0, 0});
  anterior = (1.0 / norm(anterior)) * anterior;
  Volume cut = ct;
  const std::size_t n_cut = cut_at_occlusal_plane(cut, plane, weld, pose.midsagittal(), anterior, offset_hu);
  tried = true;
  Result again;
  try {
    again = segment_auto_with(cut, opt, whole);
  } catch (const Error&) {
    return std::nullopt;
  }
  if (again.separation_radius_mm <= 0) return std::nullopt;
  const ZoneCheck c = check_against_zone(again.mask, zone_mm3, prior, pose);
  if (debug)
    std::fprintf(stderr, "  cut at the occlusal plane (%zu voxels): %.3f in its support, %.3f of the zone's evidence\n", n_cut,
                 c.in_support, c.evidence);
  if (c.in_support < kImageInSupport || c.evidence < kImageEvidenceShare) return std::nullopt;
  again.marker_source += " (verified by the atlas; teeth in occlusion cut at the occlusal plane)";
  return again;
}

// Dice between a mask on a grid and one on its bin-shrunk grid (bin_average
// by factors f: coarse voxel c covers the f0 f1 f2 fine voxels c f .. c f +
// f - 1), counted on the fine grid, in one pass over the fine mask's
// bounding box.
static double dice_across_bins(const Mask& fine, const Mask& coarse, const std::array<unsigned, 3>& f) {
  const Geometry& g = fine.geom;
  const Geometry& c = coarse.geom;
  const double per_bin = static_cast<double>(f[0]) * f[1] * f[2];
  const double b = per_bin * static_cast<double>(std::count_if(coarse.data.begin(), coarse.data.end(), [](std::uint8_t v) { return v != 0; }));
  const Box box = bounding_box(fine.data.data(), g.size, 0);
  double a = 0, both = 0;
  const long k0 = static_cast<long>(box.lo[2]), k1 = static_cast<long>(box.lo[2] + box.size[2]);
#pragma omp parallel for schedule(static) reduction(+ : a, both)
  for (long k = k0; k < k1; ++k)
    for (std::size_t j = box.lo[1]; j < box.lo[1] + box.size[1]; ++j)
      for (std::size_t i = box.lo[0]; i < box.lo[0] + box.size[0]; ++i) {
        if (!fine.data[g.linear(i, j, static_cast<std::size_t>(k))]) continue;
        const std::size_t ci = i / f[0], cj = j / f[1], ck = static_cast<std::size_t>(k) / f[2];
        a += 1;
        both += ci < c.size[0] && cj < c.size[1] && ck < c.size[2] && coarse.data[c.linear(ci, cj, ck)];
      }
  return a + b > 0 ? 2 * both / (a + b) : 0.0;
}

static Result segment_by_atlas_and_image(const Volume& ct, const Options& opt, const atlas::Fit& fit, const GridContext& whole) {
  const Geometry& g = ct.geom;
  // The image separates what its voxels resolve (resolves_cortex: 1.25 mm
  // along two axes, slices up to max_working_spacing_mm; a thin in-plane
  // grid under 2 mm slices still does). The Visible Human head reconstructed
  // at 1.5 / 1.75 / 2 mm took the image's mask and lost Cr by 9-19 mm, at
  // 2 mm both rami (60-88 mm); the zone: Co <= 5.8, Cr <= 2.6 mm from the
  // reference (docs/segmentation.md).
  if (!resolves_cortex(g, opt)) return segment_by_atlas(ct, opt, fit);
  Result image;
  try {
    image = segment_auto_with(ct, opt, whole);
  } catch (const Error&) {
    return segment_by_atlas(ct, opt, fit);
  }
  if (image.separation_radius_mm <= 0) return segment_by_atlas(ct, opt, fit);
  std::array<unsigned, 3> f{1, 1, 1};
  for (int a = 0; a < 3; ++a) f[a] = std::max(1u, static_cast<unsigned>(std::floor(kZoneCheckSpacingMm / g.spacing[a] + 1e-6)));
  const atlas::MandiblePrior prior(atlas::shipped(), fit.pose);
  double zone_mm3 = 0;
  Mask zone_check;  // the zone on the check grid (bins f of ct's voxels)
  try {
    zone_check = segment_by_atlas(f[0] * f[1] * f[2] > 1 ? bin_average(ct, f) : ct, opt, fit).mask;
    zone_mm3 = atlas_evidence_mm3(zone_check, prior);
  } catch (const Error&) {
    zone_mm3 = 0;  // no zone: nothing to measure the image's mask against
  }
  SegLap lap;
  const WeldedOcclusion weld =
      welded_occlusion(ct, [&prior](const Vec3& q) { return prior.at(q); }, fit.pose.superior(), fit.pose.midsagittal(),
                       fit.pose.scale, opt.dense_threshold_hu, image.offset_hu);
  lap("occlusion weld search");
  if (std::getenv("MANDISYM_DEBUG_SEG"))
    std::fprintf(stderr, "  image separation: %zu cheek-teeth columns run %.0f mm above the zone through enamel (%.0f mm2)\n",
                 weld.columns, kWeldRiseMm, weld.area_mm2);
  bool plane_cut_tried = false;
  if (weld.welded())
    if (std::optional<Result> cut =
            separate_at_occlusal_plane(ct, opt, fit, whole, weld, image.offset_hu, prior, zone_mm3, plane_cut_tried))
      return std::move(*cut);
  const ZoneCheck c = check_against_zone(image.mask, zone_mm3, prior, fit.pose);
  if (std::getenv("MANDISYM_DEBUG_SEG"))
    std::fprintf(stderr, "  image separation vs atlas: %.3f in its support, %.3f of the zone's evidence\n", c.in_support, c.evidence);
  if (zone_mm3 > 0 && c.in_support >= kImageInSupport && c.evidence >= kImageEvidenceShare) {
    image.marker_source += " (verified by the atlas)";
    image.taken_image_zone_dice = dice_across_bins(image.mask, zone_check, f);
    return image;
  }
  Result zone = segment_by_atlas(ct, opt, fit);
  zone.image_zone_dice = dice(zone.mask, image.mask);
  if (weld.welded()) zone.welded_occlusion_mm2 = weld.area_mm2, zone.occlusion_cut_refused = plane_cut_tried;
  return zone;
}

static Result segment_auto(const Volume& ct, const Options& opt) {
  GridContext whole;
  // Where the mandible is: the atlas placed in the scan (docs/atlas.md).
  SegLap lap;
  const atlas::Fit fit = opt.use_atlas ? atlas::fit_ct(ct, opt.bone_threshold_hu) : atlas::Fit{};
  lap("atlas fit");
  whole.atlas = &fit;
  Result out = fit.found ? segment_by_atlas_and_image(ct, opt, fit, whole) : segment_auto_with(ct, opt, whole);
  out.atlas = fit;
  if (opt.use_atlas && !fit.found) {
    char why[160];
    if (fit.ncc < -1)  // no pose left enough of the atlas inside the scan to be scored
      std::snprintf(why, sizeof why, "the mandible atlas could not be placed: no pose leaves %.0f %% of it inside the scanned field",
                    100 * atlas::kMinCoverage);
    else
      std::snprintf(why, sizeof why, "the mandible atlas did not fit this scan (NCC %.2f, below %.2f)", fit.ncc, atlas::kMinFitNcc);
    out.warnings.push_back(std::string(why) + ": the mandible was identified by size and position alone (docs/atlas.md)");
  }
  return out;
}

static Result segment_auto_with(const Volume& ct, const Options& opt, GridContext whole) {
  const Geometry& g = ct.geom;
  const double native = std::max({g.spacing[0], g.spacing[1], g.spacing[2]});
  whole.native_max_spacing = native;
  whole.cortex_resolved = resolves_cortex(g, opt);
  if (native <= opt.max_working_spacing_mm + 1e-6) return segment_located(ct, opt, whole);
  // Coarse scans (docs/segmentation.md, "Coarse scans"): the cores and necks
  // the separation relies on are a few mm across, so axes coarser than
  // max_working_spacing_mm are interpolated, segmented there, and the mask
  // is brought back to the scan's grid.
  // Which contacts fall below a core depth depends on how the interpolated
  // grid happens to sample them, so the separation runs on several working
  // grids around max_working_spacing_mm and the separated masks vote.
  std::vector<Result> runs;
  Result fallback;
  bool have_fallback = false;
  for (double factor : {0.8, 0.9, 1.0, 1.1, 1.25}) {
    const Volume fine = interpolate_finer(ct, factor * opt.max_working_spacing_mm);
    Result r;
    try {
      r = segment_on_grid(fine, opt, whole);
    } catch (const Error&) {
      if (factor == 1.0) throw;
      continue;
    }
    r.mask = coarsen(r.mask, g);
    if (r.separation_radius_mm > 0 && r.mask.count() > 0)
      runs.push_back(std::move(r));
    else if (factor == 1.0) {
      fallback = std::move(r);
      have_fallback = true;
    }
  }
  Result out;
  if (runs.empty()) {
    if (!have_fallback) throw Error(ExitCode::NoMandible, "no mandible found: the mandible mask is empty");
    out = std::move(fallback);
  } else {
    std::vector<std::uint8_t> votes(g.voxel_count(), 0);
    for (const Result& r : runs)
      for (std::size_t i = 0; i < votes.size(); ++i) votes[i] += r.mask.data[i];
    Mask consensus;
    consensus.geom = g;
    consensus.data.assign(g.voxel_count(), 0);
    for (std::size_t i = 0; i < votes.size(); ++i) consensus.data[i] = 2 * votes[i] > runs.size();
    // Report the parameters of the run closest to the consensus.
    std::size_t best = 0;
    double best_overlap = -1;
    for (std::size_t k = 0; k < runs.size(); ++k) {
      const double d = dice(runs[k].mask, consensus);
      if (d > best_overlap) best_overlap = d, best = k;
    }
    out = std::move(runs[best]);
    out.mask = std::move(consensus);
  }
  out.voxels = out.mask.count();
  if (out.voxels == 0) throw Error(ExitCode::NoMandible, "no mandible found: the mandible mask is empty");
  out.volume_mm3 = static_cast<double>(out.voxels) * g.voxel_volume_mm3();
  set_truncation(out);
  return out;
}

// Skull base welded to the condyles (docs/segmentation.md, "Skull base
// welded to a condyle"). Above its body the mandible is two rami and their
// processes; no axial cross-section of a side there exceeds the ramus's own
// (condylar head ~20 x 10 mm, ramus ~30 x 8 mm). Where a scan does not
// resolve the joint space (thick slices, coarse pixels), the temporal bone
// over the fossa is one solid with the condyle and the separation has
// nothing to cut: on OpenKBP pt_246 (3.9 x 3.9 x 2.5 mm, the field of view
// ending ~20 mm above the condyles) 16 cm3 of it came with the mandible, its
// cross-sections 2.2-4 times the ramus's. A side's part above the slice where
// it first widens beyond kProcessWideningRatio times its median cross-section
// above the chin is removed, but only when it runs to the top of the scan
// (or of the body in it, when the volume is padded with empty slices): a
// large condyle (hyperplasia, a tumour) ends inside the scan and is kept.
constexpr double kProcessWideningRatio = 2.0;

void trim_welded_skull_base(const Volume& ct, Result& r) {
  const Geometry& g = r.mask.geom;
  // Grid axes along the patient's left-right and inferior-superior axes.
  const int lat = grid_axis_along(g, 0), ver = grid_axis_along(g, 2);
  if (lat == ver || std::abs(g.direction[lat]) < 0.9 || std::abs(g.direction[6 + ver]) < 0.9) return;
  const Box b = bounding_box(r.mask.data.data(), g.size, 0);
  if (b.size[0] == 0) return;
  const std::size_t ns = g.size[ver];
  // up[p]: the slice at position p from the feet; the map is its own
  // inverse, so up[s] is also slice s's position.
  std::vector<std::size_t> up(ns);
  for (std::size_t p = 0; p < ns; ++p) up[p] = g.direction[6 + ver] > 0 ? p : ns - 1 - p;
  const double mid = static_cast<double>(b.lo[lat]) + 0.5 * static_cast<double>(b.size[lat] - 1);
  const double near_mid = 10.0 / g.spacing[lat];  // the chin and incisors span the midline
  std::vector<std::size_t> area[2] = {std::vector<std::size_t>(ns, 0), std::vector<std::size_t>(ns, 0)}, central(ns, 0);
  auto side_of = [&](std::size_t l) { return static_cast<double>(l) > mid ? 1 : 0; };
  for (std::size_t k = b.lo[2]; k < b.lo[2] + b.size[2]; ++k)
    for (std::size_t j = b.lo[1]; j < b.lo[1] + b.size[1]; ++j)
      for (std::size_t i = b.lo[0]; i < b.lo[0] + b.size[0]; ++i) {
        if (!r.mask.data[g.linear(i, j, k)]) continue;
        const std::size_t v[3] = {i, j, k};
        ++area[side_of(v[lat])][v[ver]];
        central[v[ver]] += std::abs(static_cast<double>(v[lat]) - mid) <= near_mid;
      }
  std::size_t chin_top = ns;  // position of the highest slice with mask voxels at the midline
  for (std::size_t p = 0; p < ns; ++p)
    if (central[up[p]]) chin_top = p;
  if (chin_top + 1 >= ns) return;
  std::array<std::size_t, 2> cut{ns, ns};
  for (int s = 0; s < 2; ++s) {
    std::vector<std::size_t> a;
    for (std::size_t p = chin_top + 1; p < ns; ++p)
      if (area[s][up[p]]) a.push_back(area[s][up[p]]);
    if (a.size() < 3) continue;
    std::nth_element(a.begin(), a.begin() + static_cast<long>(a.size() / 2), a.end());
    const double median = static_cast<double>(a[a.size() / 2]);
    // From where the side has narrowed to the ramus: the slices just above
    // the chin may still hold the body's molar part (a head pitched forward).
    bool narrowed = false;
    for (std::size_t p = chin_top + 1; p < ns && cut[s] == ns; ++p) {
      const auto a_p = static_cast<double>(area[s][up[p]]);
      if (!narrowed) narrowed = a_p <= median;
      else if (a_p > kProcessWideningRatio * median) cut[s] = p;
    }
    if (std::getenv("MANDISYM_DEBUG_SEG")) {
      std::fprintf(stderr, "  side %d above the chin (slice %zu from the feet): median %.0f voxels, widens at %zu:", s, chin_top, median, cut[s]);
      for (std::size_t p = chin_top + 1; p < ns; ++p)
        if (area[s][up[p]]) std::fprintf(stderr, " %zu", area[s][up[p]]);
      std::fprintf(stderr, "\n");
    }
  }
  if (cut[0] == ns && cut[1] == ns) return;
  // The top of the scan: its last slice, or the last one through the body
  // (a quarter of the widest body cross-section above -500 HU) when empty
  // slices pad the volume beyond it.
  const std::vector<std::size_t> body = body_profile(ct.hu, ct.geom, ver, r.offset_hu);
  const std::size_t widest = *std::max_element(body.begin(), body.end());
  std::size_t top = ns - 1;
  while (top > 0 && 4 * body[up[top]] < widest) --top;
  for (int s = 0; s < 2; ++s) {
    if (cut[s] == ns || area[s][up[top]] == 0) continue;  // ends inside the scan
    std::size_t removed = 0;
    for (std::size_t k = b.lo[2]; k < b.lo[2] + b.size[2]; ++k)
      for (std::size_t j = b.lo[1]; j < b.lo[1] + b.size[1]; ++j)
        for (std::size_t i = b.lo[0]; i < b.lo[0] + b.size[0]; ++i) {
          const std::size_t v[3] = {i, j, k};
          std::uint8_t& m = r.mask.data[g.linear(i, j, k)];
          if (!m || side_of(v[lat]) != s) continue;
          if (up[v[ver]] >= cut[s]) m = 0, ++removed;
        }
    char msg[256];
    std::snprintf(msg, sizeof msg,
                  "%.1f cm3 above the %s condyle removed: it widens to more than %.0f times the ramus and runs to the "
                  "top of the scan (skull base not separable from the condyle at this resolution)",
                  static_cast<double>(removed) * g.voxel_volume_mm3() / 1000.0,
                  (g.direction[lat] > 0) == (s == 1) ? "left" : "right", kProcessWideningRatio);
    r.warnings.push_back(msg);
  }
  r.voxels = r.mask.count();
  r.volume_mm3 = static_cast<double>(r.voxels) * g.voxel_volume_mm3();
  set_truncation(r);
}

// Padding: slabs at the faces of the grid in which every voxel holds one
// value (a volume boxed to a fixed size, the space beyond a field of view).
// Nothing was scanned there, so the scan's edge is where they begin: a
// mandible cut there is capped and truncated as at any edge (padded 1 mm
// phantoms cut through the condyles: Dice 0.020 and 0.780 uncropped, 0.981
// and 0.980 cropped). Not on coarse scans: their working grids are
// interpolated from the grid's origin, and a crop moves where they sample
// (OpenKBP pt_243, whose top is padded: 0.822 -> 0.655).
static Box scanned_box(const Volume& ct) {
  const Geometry& g = ct.geom;
  Box b;
  b.size = g.size;
  auto constant = [&](int axis, std::size_t at) {
    float v = 0;
    bool first = true;
    const std::size_t n[3] = {axis == 0 ? 1 : g.size[0], axis == 1 ? 1 : g.size[1], axis == 2 ? 1 : g.size[2]};
    for (std::size_t k = 0; k < n[2]; ++k)
      for (std::size_t j = 0; j < n[1]; ++j)
        for (std::size_t i = 0; i < n[0]; ++i) {
          const std::size_t idx[3] = {axis == 0 ? at : i, axis == 1 ? at : j, axis == 2 ? at : k};
          const float h = ct.hu[g.linear(idx[0], idx[1], idx[2])];
          if (first) v = h, first = false;
          else if (h != v) return false;
        }
    return true;
  };
  for (int a = 0; a < 3; ++a) {
    while (b.size[a] > 0 && constant(a, b.lo[a])) ++b.lo[a], --b.size[a];
    while (b.size[a] > 0 && constant(a, b.lo[a] + b.size[a] - 1)) --b.size[a];
  }
  return b;
}

// The scanned body's end (docs/segmentation.md, "The scanned body"): the
// scanned run of slices around the mask (scanned_run) becomes the scanned
// grid, and a mask reaching an end slice of the run inside the grid is cut
// by the scan: truncated.
static void end_at_scanned_body(const Volume& ct, Result& r) {
  const Geometry& g = r.mask.geom;
  const int ver = grid_axis_along(g, 2);
  const Box b = bounding_box(r.mask.data.data(), g.size, 0);
  if (b.size[0] == 0 || std::abs(g.direction[6 + ver]) < 0.9) return;
  const std::vector<std::size_t> body = body_profile(ct.hu, ct.geom, ver, r.offset_hu);
  const auto [lo, hi] = scanned_run(body, b.lo[ver], b.lo[ver] + b.size[ver] - 1);
  if (lo == 0 && hi + 1 == g.size[ver]) return;
  Geometry sg = r.scanned_grid;
  Vec3 first{0, 0, 0};  // index of the run's first slice's corner voxel
  first[ver] = static_cast<double>(lo);
  sg.origin = g.index_to_lps(first[0], first[1], first[2]);
  sg.size[ver] = hi - lo + 1;
  r.scanned_grid = sg;
  // The mask in an end slice of the run (inside the grid) is cut by the scan.
  std::size_t cut = 0;
  for (std::size_t k = b.lo[2]; k < b.lo[2] + b.size[2]; ++k)
    for (std::size_t j = b.lo[1]; j < b.lo[1] + b.size[1]; ++j)
      for (std::size_t i = b.lo[0]; i < b.lo[0] + b.size[0]; ++i) {
        const std::size_t v[3] = {i, j, k};
        cut += r.mask.data[g.linear(i, j, k)] && ((lo > 0 && v[ver] <= lo) || (hi + 1 < g.size[ver] && v[ver] >= hi));
      }
  if (cut == 0) return;
  if (!r.truncated) r.warnings.push_back(kTruncatedWarning);
  r.truncated = true;
  r.warnings.push_back("the scanned body ends at the mandible (its cross-section falls below " +
                       std::to_string(static_cast<int>(kScannedBodyFraction * 100)) +
                       " % of that at the mandible's level): the slices beyond are padding, and the mandible is cut there");
}

static Result segment_scanned(const Volume& ct, const Options& opt) {
  SegLap lap;
  Result r = segment_auto(ct, opt);
  lap("identification and separation");
  if (r.separation_radius_mm > 0) trim_welded_skull_base(ct, r);
  check_width(r);
  measure_against_atlas(r);
  r.scanned_grid = ct.geom;
  end_at_scanned_body(ct, r);
  lap("skull base, width, agreement, scanned body");
  return r;
}

Result segment_mandible(const Volume& ct, const Options& opt) {
  const Geometry& g = ct.geom;
  if (std::max({g.spacing[0], g.spacing[1], g.spacing[2]}) > opt.max_working_spacing_mm + 1e-6) return segment_scanned(ct, opt);
  const Box b = scanned_box(ct);
  if (b.size == ct.geom.size) return segment_scanned(ct, opt);
  if (b.size[0] == 0 || b.size[1] == 0 || b.size[2] == 0)
    throw Error(ExitCode::NoMandible, "no mandible found: every voxel of the scan holds the same value");
  // Segmented within the scanned box; its faces are the scan's edge (truncation, caps).
  Volume sub;
  sub.geom = ct.geom;
  sub.geom.size = b.size;
  sub.geom.origin = ct.geom.index_to_lps(static_cast<double>(b.lo[0]), static_cast<double>(b.lo[1]), static_cast<double>(b.lo[2]));
  sub.hu = extract(ct.hu.data(), ct.geom.size, b);
  Result r = segment_scanned(sub, opt);
  Mask full;
  full.geom = ct.geom;
  full.data.assign(ct.geom.voxel_count(), 0);
  insert(r.mask.data, b, full.data.data(), ct.geom.size);
  r.mask = std::move(full);
  return r;
}

Result from_label_map(const Geometry& ct, const LabelMap& lm, int label, const std::string& source) {
  std::set<std::int32_t> present;
  for (auto v : lm.labels)
    if (v != 0) present.insert(v);
  if (present.empty()) throw Error(ExitCode::NoMandible, source + ": the label map is empty");
  if (label < 0 && present.size() > 1) {
    std::string list;
    for (auto v : present) list += (list.empty() ? "" : ", ") + std::to_string(v);
    throw Error(ExitCode::Usage, source + ": holds labels " + list + "; pass --label N (TotalSegmentator mandible = 1)");
  }
  const std::int32_t want = label < 0 ? *present.begin() : label;
  if (!present.count(want)) throw Error(ExitCode::NoMandible, source + ": label " + std::to_string(want) + " is not in the map");
  Result r;
  r.method = "external";
  r.scanned_grid = ct;
  r.mask.geom = ct;
  r.mask.data.assign(ct.voxel_count(), 0);
  const bool same = lm.geom.same_grid(ct, 1e-3);
  std::size_t inside = 0;
  for (std::size_t k = 0; k < ct.size[2]; ++k)
    for (std::size_t j = 0; j < ct.size[1]; ++j)
      for (std::size_t i = 0; i < ct.size[0]; ++i) {
        const std::size_t idx = ct.linear(i, j, k);
        std::int32_t v;
        if (same) {
          v = lm.labels[idx];
          ++inside;
        } else {
          const Vec3 c = lm.geom.lps_to_index(ct.index_to_lps(i, j, k));
          const long a = std::lround(c[0]), b = std::lround(c[1]), d = std::lround(c[2]);
          if (a < 0 || b < 0 || d < 0 || a >= long(lm.geom.size[0]) || b >= long(lm.geom.size[1]) || d >= long(lm.geom.size[2]))
            continue;
          ++inside;
          v = lm.labels[lm.geom.linear(a, b, d)];
        }
        r.mask.data[idx] = v == want;
      }
  if (inside == 0) throw Error(ExitCode::InputInvalid, source + ": the label map does not overlap the CT");
  r.voxels = r.mask.count();
  if (r.voxels == 0) throw Error(ExitCode::NoMandible, source + ": label " + std::to_string(want) + " is empty on the CT grid");
  r.volume_mm3 = r.voxels * ct.voxel_volume_mm3();
  if (!same) r.warnings.push_back(source + " was resampled to the CT grid (nearest neighbour)");
  // Components (6-connected) of the selected label.
  auto img = io::make_image<MaskImage>(ct);
  std::copy(r.mask.data.begin(), r.mask.data.end(), img->GetBufferPointer());
  std::size_t n_parts = 0;
  components(img.GetPointer(), false, 0, &n_parts);
  if (n_parts > 1)
    r.warnings.push_back(source + ": the mandible label has " + std::to_string(n_parts) +
                         " separate parts (kept all; fracture or segmentation gaps?)");
  set_truncation(r);
  return r;
}

}  // namespace ms::segmentation
