// ITK-facing translation unit: no system Eigen here (ENGINEERING.md).
#include "segmentation/segmentation.h"

#include <itkBinaryBallStructuringElement.h>
#include <itkBinaryFillholeImageFilter.h>
#include <itkBinaryMorphologicalClosingImageFilter.h>
#include <itkConnectedComponentImageFilter.h>
#include <itkImage.h>
#include <itkRelabelComponentImageFilter.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>

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

Result segment_mandible(const Volume& ct, const Options& opt) {
  const Geometry& g = ct.geom;
  auto bone = io::make_image<MaskImage>(g);
  {
    auto* b = bone->GetBufferPointer();
    for (std::size_t i = 0; i < ct.hu.size(); ++i) b[i] = ct.hu[i] >= opt.bone_threshold_hu;
  }
  auto cc = itk::ConnectedComponentImageFilter<MaskImage, LabelImage>::New();
  cc->SetInput(bone);
  cc->FullyConnectedOff();
  auto relabel = itk::RelabelComponentImageFilter<LabelImage, LabelImage>::New();
  relabel->SetInput(cc->GetOutput());
  relabel->SetMinimumObjectSize(
      static_cast<itk::SizeValueType>(opt.min_component_cm3 * 1000.0 / g.voxel_volume_mm3()));
  relabel->Update();
  const auto* labels = relabel->GetOutput()->GetBufferPointer();
  const unsigned n_labels = static_cast<unsigned>(relabel->GetNumberOfObjects());
  if (n_labels == 0)
    throw Error(ExitCode::NoMandible, "no mandible found: no bone (no connected region above " +
                                          std::to_string(static_cast<int>(opt.bone_threshold_hu)) + " HU of at least " +
                                          std::to_string(static_cast<int>(std::lround(opt.min_component_cm3))) + " cm3)");

  std::vector<Component> comps(n_labels + 1);
  for (std::size_t k = 0; k < g.size[2]; ++k)
    for (std::size_t j = 0; j < g.size[1]; ++j)
      for (std::size_t i = 0; i < g.size[0]; ++i) {
        const unsigned l = labels[g.linear(i, j, k)];
        if (!l) continue;
        const Vec3 p = g.index_to_lps(i, j, k);
        Component& c = comps[l];
        c.label = l;
        ++c.voxels;
        for (int a = 0; a < 3; ++a) {
          c.lo[a] = std::min(c.lo[a], p[a]);
          c.hi[a] = std::max(c.hi[a], p[a]);
        }
      }
  // The mandible is the lowest of the wide bones: among components at least
  // 40 mm wide left-right (skull, maxilla, mandible; not the spine or hyoid),
  // the one whose centroid is most inferior along the scan's superior axis.
  // Thin rule: when the teeth or condyles touch, mandible and skull form one
  // component and this picks both (issue C separates them).
  std::vector<double> zsum(n_labels + 1, 0.0);
  for (std::size_t k = 0; k < g.size[2]; ++k)
    for (std::size_t j = 0; j < g.size[1]; ++j)
      for (std::size_t i = 0; i < g.size[0]; ++i)
        if (const unsigned l = labels[g.linear(i, j, k)]) zsum[l] += g.index_to_lps(i, j, k)[2];
  unsigned best = 0;
  double best_z = 1e30;
  for (unsigned l = 1; l <= n_labels; ++l) {
    const Component& c = comps[l];
    if (c.voxels == 0 || c.hi[0] - c.lo[0] < 40.0) continue;
    const double zc = zsum[l] / c.voxels;
    if (zc < best_z) {
      best_z = zc;
      best = l;
    }
  }
  if (best == 0)
    throw Error(ExitCode::NoMandible, "no mandible found: no bone component is at least 40 mm wide left-right");

  auto comp = io::make_image<MaskImage>(g);
  {
    auto* m = comp->GetBufferPointer();
    for (std::size_t i = 0; i < ct.hu.size(); ++i) m[i] = labels[i] == best;
  }
  // Close small cortical gaps, then fill the cancellous interior.
  using SE = itk::BinaryBallStructuringElement<unsigned char, 3>;
  SE se;
  SE::SizeType radius;
  for (int a = 0; a < 3; ++a) radius[a] = g.spacing[a] < 0.7 ? 2 : 1;
  se.SetRadius(radius);
  se.CreateStructuringElement();
  auto close = itk::BinaryMorphologicalClosingImageFilter<MaskImage, MaskImage, SE>::New();
  close->SetInput(comp);
  close->SetKernel(se);
  close->SetForegroundValue(1);
  auto fill = itk::BinaryFillholeImageFilter<MaskImage>::New();
  fill->SetInput(close->GetOutput());
  fill->SetForegroundValue(1);
  fill->FullyConnectedOn();
  fill->Update();

  Result r;
  r.method = "auto";
  r.mask.geom = g;
  const auto* out = fill->GetOutput()->GetBufferPointer();
  r.mask.data.assign(out, out + g.voxel_count());
  r.voxels = r.mask.count();
  r.volume_mm3 = r.voxels * g.voxel_volume_mm3();
  // Truncation: mandible voxels on any face of the scan.
  for (std::size_t k = 0; k < g.size[2] && !r.truncated; ++k)
    for (std::size_t j = 0; j < g.size[1] && !r.truncated; ++j)
      for (std::size_t i = 0; i < g.size[0]; ++i) {
        const bool edge = i == 0 || j == 0 || k == 0 || i + 1 == g.size[0] || j + 1 == g.size[1] || k + 1 == g.size[2];
        if (edge && r.mask.data[g.linear(i, j, k)]) {
          r.truncated = true;
          break;
        }
        if (!edge && j != 0 && j + 1 != g.size[1] && k != 0 && k + 1 != g.size[2]) i = g.size[0] - 2;
      }
  if (r.truncated) r.warnings.push_back("the mandible touches the edge of the scan: it may be truncated");
  return r;
}

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
  auto cc = itk::ConnectedComponentImageFilter<MaskImage, LabelImage>::New();
  cc->SetInput(img);
  cc->Update();
  if (cc->GetObjectCount() > 1)
    r.warnings.push_back(source + ": the mandible label has " + std::to_string(cc->GetObjectCount()) +
                         " separate parts (kept all; fracture or segmentation gaps?)");
  r.truncated = touches_border(r.mask);
  if (r.truncated) r.warnings.push_back("the mandible touches the edge of the scan: it may be truncated");
  return r;
}

}  // namespace ms::segmentation
