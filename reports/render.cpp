// VTK rendering translation unit (no ITK, no Eigen).
#include "reports/render.h"

#include <vtkActor.h>
#include <vtkCamera.h>
#include <vtkDoubleArray.h>
#include <vtkLookupTable.h>
#include <vtkPNGWriter.h>
#include <vtkPlaneSource.h>
#include <vtkPointData.h>
#include <vtkPolyData.h>
#include <vtkPolyDataMapper.h>
#include <vtkPolyDataNormals.h>
#include <vtkProperty.h>
#include <vtkRenderWindow.h>
#include <vtkRenderer.h>
#include <vtkScalarBarActor.h>
#include <vtkSmartPointer.h>
#include <vtkSphereSource.h>
#include <vtkTextProperty.h>
#include <vtkWindowToImageFilter.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "reports/display.h"
#include "reports/viewer.h"
#include "surface/vtk_mesh.h"

namespace ms::reports {
namespace {

template <class T>
using Ptr = vtkSmartPointer<T>;

Ptr<vtkLookupTable> lookup(const ColourMap& c) {
  auto lut = Ptr<vtkLookupTable>::New();
  const int n = 256;
  lut->SetNumberOfTableValues(n);
  lut->SetTableRange(c.lo, c.hi);
  for (int i = 0; i < n; ++i) {
    const double t = static_cast<double>(i) / (n - 1);
    double r, g, b;
    if (c.diverging) {  // blue (lo) - white (0) - red (hi)
      const double s = 2 * t - 1;
      if (s < 0) r = 1 + s * 0.85, g = 1 + s * 0.65, b = 1;
      else r = 1, g = 1 - s * 0.75, b = 1 - s * 0.85;
    } else {  // white - orange - dark red
      r = 1 - 0.45 * t * t;
      g = 1 - 0.95 * t;
      b = 1 - 0.95 * std::sqrt(t);
    }
    lut->SetTableValue(i, r, g, b, 1.0);
  }
  lut->SetBelowRangeColor(lut->GetTableValue(0));
  lut->SetAboveRangeColor(lut->GetTableValue(n - 1));
  lut->Build();
  return lut;
}

}  // namespace

std::vector<RenderedViews> render_view_sets(const Mesh& mesh, const std::vector<ViewSet>& sets, const LandmarkSet& landmarks,
                                            const Plane& plane, int width, int height, const Vec3& superior) {
  std::vector<RenderedViews> all(sets.size());
  auto fail = [&](const std::string& why) {
    for (auto& o : all) {
      for (const auto& f : o.files) std::filesystem::remove(f);
      o.files.clear();
      o.error = why;
    }
    return all;
  };
  if (sets.empty()) return all;
  if (mesh.faces.empty()) return fail("no surface to render");
  {
    std::string why;
    if (!ensure_display(&why)) return fail(why);
  }

  // Geometry and normals once; each set only swaps the scalars and colours.
  auto pd = surface::to_polydata(mesh);
  auto normals = Ptr<vtkPolyDataNormals>::New();
  normals->SetInputData(pd);
  normals->SplittingOff();
  normals->ConsistencyOff();  // the mesh is already outward
  normals->Update();
  vtkSmartPointer<vtkPolyData> shaded = normals->GetOutput();
  auto mapper = Ptr<vtkPolyDataMapper>::New();
  mapper->SetInputData(shaded);
  auto actor = Ptr<vtkActor>::New();
  actor->SetMapper(mapper);
  actor->GetProperty()->SetColor(0.93, 0.89, 0.80);
  actor->GetProperty()->SetSpecular(0.15);

  auto ren = Ptr<vtkRenderer>::New();
  ren->SetBackground(1, 1, 1);
  ren->AddActor(actor);

  // Landmarks.
  for (const auto& [name, p] : landmarks.points) {
    auto s = Ptr<vtkSphereSource>::New();
    s->SetCenter(p[0], p[1], p[2]);
    s->SetRadius(1.8);
    s->SetThetaResolution(16);
    s->SetPhiResolution(12);
    auto m = Ptr<vtkPolyDataMapper>::New();
    m->SetInputConnection(s->GetOutputPort());
    auto a = Ptr<vtkActor>::New();
    a->SetMapper(m);
    a->GetProperty()->SetColor(0.1, 0.55, 0.2);
    ren->AddActor(a);
  }

  // Frame of the symmetry plane; the view directions follow it, so a posed
  // head is shown upright.
  const PlaneFrame frame = plane_frame(mesh, plane, superior);  // shared with the interactive viewer
  const Vec3 ml = frame.x, si = frame.y, ap = -1.0 * frame.z;  // ap: posterior
  double b[6];
  pd->GetBounds(b);
  const Vec3 c{(b[0] + b[1]) / 2, (b[2] + b[3]) / 2, (b[4] + b[5]) / 2};
  const double size = std::max({b[1] - b[0], b[3] - b[2], b[5] - b[4]});
  auto plane_actor = Ptr<vtkActor>::New();
  {
    // The plane as a translucent sheet through the mesh centre's projection.
    const Vec3 o = c - plane.signed_distance(c) * ml;
    Vec3 p0 = o - 0.6 * size * ap - 0.5 * size * si;
    Vec3 p1 = o + 0.6 * size * ap - 0.5 * size * si;
    Vec3 p2 = o - 0.6 * size * ap + 0.5 * size * si;
    auto ps = Ptr<vtkPlaneSource>::New();
    ps->SetOrigin(p0.data());
    ps->SetPoint1(p1.data());
    ps->SetPoint2(p2.data());
    auto m = Ptr<vtkPolyDataMapper>::New();
    m->SetInputConnection(ps->GetOutputPort());
    plane_actor->SetMapper(m);
    plane_actor->GetProperty()->SetColor(0.35, 0.45, 0.65);
    plane_actor->GetProperty()->SetOpacity(0.18);
    ren->AddActor(plane_actor);
  }
  auto bar = Ptr<vtkScalarBarActor>::New();
  bar->SetNumberOfLabels(5);
  bar->SetLabelFormat("%.2g");
  bar->SetOrientationToHorizontal();
  bar->SetPosition(0.15, 0.02);
  bar->SetWidth(0.7);
  bar->SetHeight(0.12);
  for (auto* tp : {bar->GetTitleTextProperty(), bar->GetLabelTextProperty()}) {
    tp->SetColor(0.1, 0.1, 0.1);
    tp->SetFontSize(12);
    tp->ShadowOff();
    tp->ItalicOff();
    tp->BoldOff();
  }
  ren->AddActor2D(bar);

  // One window (one OpenGL context, shaders compiled once) for every set.
  auto win = Ptr<vtkRenderWindow>::New();
  win->SetOffScreenRendering(1);
  win->AddRenderer(ren);
  win->SetSize(width, height);
  win->SetMultiSamples(0);  // FXAA instead: multisampling costs most of a software-rendered frame
  ren->UseFXAAOn();

  struct View {
    const char* name;
    Vec3 eye;  // direction from the centre to the camera
    Vec3 up;
    bool plane;  // the plane is seen edge-on from the front and below only
  };
  const Vec3 anterior = -1.0 * ap, inferior = -1.0 * si;
  const View views[] = {
      {"front", anterior, si, true}, {"below", inferior, anterior, true}, {"left", ml, si, false}, {"right", -1.0 * ml, si, false}};
  for (std::size_t k = 0; k < sets.size(); ++k) {
    const ViewSet& set = sets[k];
    const bool coloured = set.values && set.values->size() == mesh.vertices.size();
    const auto lut = lookup(set.colours);
    if (coloured) {
      auto arr = Ptr<vtkDoubleArray>::New();
      arr->SetName("value");
      for (double x : *set.values) arr->InsertNextValue(std::isfinite(x) ? x : 0.0);
      shaded->GetPointData()->SetScalars(arr);
      mapper->SetLookupTable(lut);
      mapper->SetScalarRange(set.colours.lo, set.colours.hi);
      mapper->UseLookupTableScalarRangeOn();
      mapper->SetScalarModeToUsePointData();
      mapper->ScalarVisibilityOn();
      bar->SetLookupTable(lut);
      bar->SetTitle(set.colours.title.c_str());
    } else {
      mapper->ScalarVisibilityOff();
    }
    bar->SetVisibility(coloured);
    shaded->Modified();
    for (const View& v : views) {
      plane_actor->SetVisibility(v.plane);
      auto* cam = ren->GetActiveCamera();
      cam->SetFocalPoint(c[0], c[1], c[2]);
      const Vec3 pos = c + (3.0 * size) * v.eye;
      cam->SetPosition(pos[0], pos[1], pos[2]);
      cam->SetViewUp(v.up[0], v.up[1], v.up[2]);
      cam->SetViewAngle(30);
      ren->ResetCamera();
      cam->Zoom(1.25);
      win->Render();
      auto grab = Ptr<vtkWindowToImageFilter>::New();
      grab->SetInput(win);
      grab->ReadFrontBufferOff();
      grab->Update();
      const std::string file = set.prefix + "_" + v.name + ".png";
      auto png = Ptr<vtkPNGWriter>::New();
      png->SetFileName(file.c_str());
      png->SetInputConnection(grab->GetOutputPort());
      png->Write();
      if (png->GetErrorCode() != 0 || !std::filesystem::exists(file)) return fail("cannot write " + file);
      all[k].files.push_back(file);
    }
  }
  return all;
}

RenderedViews render_views(const Mesh& mesh, const std::vector<double>& values, const ColourMap& colours,
                           const LandmarkSet& landmarks, const Plane& plane, const std::string& prefix, int width,
                           int height) {
  return render_view_sets(mesh, {ViewSet{&values, colours, prefix}}, landmarks, plane, width, height).front();
}

}  // namespace ms::reports
