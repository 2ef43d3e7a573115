#include "pipeline/cranial.h"

#include <exception>

#include "segmentation/cranium.h"
#include "surface/surface.h"

namespace ms::pipeline {

reference::CranialResult fit_cranial_plane(const CranialInputs& in) {
  try {
    segmentation::CraniumOptions co;
    co.threshold_hu = in.threshold_hu;
    Vec3 e_ml, e_ap, e_si;
    reference::plane_frame(in.mandible_plane, e_ml, e_ap, e_si);
    co.floor.normal = e_si;
    const Vec3 *cl = in.landmarks.find("Co_L"), *cr = in.landmarks.find("Co_R");
    if (cl && cr) {
      co.floor.point = 0.5 * (*cl + *cr);
    } else if (in.mandible_surface && !in.mandible_surface->vertices.empty()) {  // no condyles: the top of the mandible
      co.floor.point = in.mandible_surface->vertices.front();
      for (const auto& v : in.mandible_surface->vertices)
        if (dot(v, e_si) > dot(co.floor.point, e_si)) co.floor.point = v;
    } else {
      reference::CranialResult none;
      none.reason = "no condyles and no mandible surface to place the floor";
      return none;
    }
    const auto cranium = segmentation::cranium_mask(*in.ct, *in.mandible, co);
    Mesh mesh;
    if (cranium.volume_cm3 >= 50) {
      // The contour as it comes: only the mirror-ICP reads it (a sample of
      // its vertices and closest points), so neither decimation (seconds on
      // a head's cranium at 1 mm) nor remeshing nor holding vertices to
      // the mask is needed.
      surface::Options mo;
      mo.target_edge_mm = 0;
      mo.target_faces = 0;
      mo.max_boundary_distance_voxels = 0;
      mesh = surface::mesh_from_mask(cranium.mask, mo).mesh;
    }
    return reference::cranial_plane(mesh, cranium.volume_cm3, in.mandible_plane, in.landmarks);
  } catch (const std::exception& e) {
    reference::CranialResult failed;
    failed.reason = e.what();
    return failed;
  }
}

}  // namespace ms::pipeline
