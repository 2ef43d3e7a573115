// Geometry <-> itk::Image helpers for ITK-facing translation units only
// (never include this next to system Eigen headers; ENGINEERING.md).
#pragma once

#include <itkImage.h>

#include "core/types.h"

namespace ms::io {

// Grid geometry of an ITK image (size, spacing, origin, direction).
template <class ImageT>
Geometry geometry_of(const ImageT* img) {
  Geometry g;
  const auto region = img->GetLargestPossibleRegion();
  for (int a = 0; a < 3; ++a) {
    g.size[a] = region.GetSize()[a];
    g.spacing[a] = img->GetSpacing()[a];
    g.origin[a] = img->GetOrigin()[a];
  }
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) g.direction[3 * r + c] = img->GetDirection()(r, c);
  return g;
}

// A new ITK image on the grid g, nothing allocated.
template <class ImageT>
typename ImageT::Pointer make_image_header(const Geometry& g) {
  auto img = ImageT::New();
  typename ImageT::RegionType region;
  typename ImageT::SizeType size;
  typename ImageT::SpacingType spacing;
  typename ImageT::PointType origin;
  typename ImageT::DirectionType dir;
  for (int a = 0; a < 3; ++a) {
    size[a] = g.size[a];
    spacing[a] = g.spacing[a];
    origin[a] = g.origin[a];
  }
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) dir(r, c) = g.direction[3 * r + c];
  region.SetSize(size);
  img->SetRegions(region);
  img->SetSpacing(spacing);
  img->SetOrigin(origin);
  img->SetDirection(dir);
  return img;
}

// A new ITK image on the grid g, allocated and zero-filled.
template <class ImageT>
typename ImageT::Pointer make_image(const Geometry& g) {
  auto img = make_image_header<ImageT>(g);
  img->Allocate();
  img->FillBuffer(0);
  return img;
}

// An ITK image over v's voxels, without a copy: ITK filters read v.hu in
// place (v must outlive the image and its filters; none may write to it).
inline itk::Image<float, 3>::Pointer float_view(const Volume& v) {
  auto img = make_image_header<itk::Image<float, 3>>(v.geom);
  img->GetPixelContainer()->SetImportPointer(const_cast<float*>(v.hu.data()), v.hu.size(), /*LetContainerManageMemory=*/false);
  return img;
}

}  // namespace ms::io
