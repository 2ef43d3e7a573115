// Mesh <-> VTK polydata, for VTK-side code (the report's renderer). Kept out
// of surface.h so that stages which do not use VTK never see its headers.
#pragma once

#include <vtkPolyData.h>
#include <vtkSmartPointer.h>

#include "core/types.h"

namespace ms::surface {

vtkSmartPointer<vtkPolyData> to_polydata(const Mesh& mesh);

}  // namespace ms::surface
