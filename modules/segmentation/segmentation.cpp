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

}  // namespace ms::segmentation
