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
#include <array>
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

// The surface with per-vertex normals, its mapper and actor; each view set
// only swaps the scalars and colours of `shaded`.
struct SurfaceActor {
  Ptr<vtkPolyData> shaded;
  Ptr<vtkPolyDataMapper> mapper;
  Ptr<vtkActor> actor;
};

SurfaceActor surface_actor(vtkPolyData* pd) {
  auto normals = Ptr<vtkPolyDataNormals>::New();
  normals->SetInputData(pd);
  normals->SplittingOff();
  normals->ConsistencyOff();  // the mesh is already outward
  normals->Update();
  SurfaceActor s;
  s.shaded = normals->GetOutput();
  s.mapper = Ptr<vtkPolyDataMapper>::New();
  s.mapper->SetInputData(s.shaded);
  s.actor = Ptr<vtkActor>::New();
  s.actor->SetMapper(s.mapper);
  s.actor->GetProperty()->SetColor(0.93, 0.89, 0.80);
  s.actor->GetProperty()->SetSpecular(0.15);
  return s;
}

// Landmarks as green spheres.
void add_landmarks(vtkRenderer* ren, const LandmarkSet& landmarks) {
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
}

// Where the cameras look from: the symmetry plane's frame (so a posed head is
// shown upright), the centre and size of the mesh's bounding box.
struct Framing {
  Vec3 ml, si, ap;  // medio-lateral (plane normal), superior, posterior
  Vec3 centre;
  double size = 0;
};

Framing framing(const Mesh& mesh, vtkPolyData* pd, const Plane& plane, const Vec3& superior) {
  const PlaneFrame frame = plane_frame(mesh, plane, superior);  // shared with the interactive viewer
  double b[6];
  pd->GetBounds(b);
  return {frame.x, frame.y, -1.0 * frame.z, Vec3{(b[0] + b[1]) / 2, (b[2] + b[3]) / 2, (b[4] + b[5]) / 2},
          std::max({b[1] - b[0], b[3] - b[2], b[5] - b[4]})};
}

// The plane as a translucent sheet through the mesh centre's projection.
Ptr<vtkActor> plane_sheet(const Framing& f, const Plane& plane) {
  const Vec3 o = f.centre - plane.signed_distance(f.centre) * f.ml;
  Vec3 p0 = o - 0.6 * f.size * f.ap - 0.5 * f.size * f.si;
  Vec3 p1 = o + 0.6 * f.size * f.ap - 0.5 * f.size * f.si;
  Vec3 p2 = o - 0.6 * f.size * f.ap + 0.5 * f.size * f.si;
  auto ps = Ptr<vtkPlaneSource>::New();
  ps->SetOrigin(p0.data());
  ps->SetPoint1(p1.data());
  ps->SetPoint2(p2.data());
  auto m = Ptr<vtkPolyDataMapper>::New();
  m->SetInputConnection(ps->GetOutputPort());
  auto sheet = Ptr<vtkActor>::New();
  sheet->SetMapper(m);
  sheet->GetProperty()->SetColor(0.35, 0.45, 0.65);
  sheet->GetProperty()->SetOpacity(0.18);
  return sheet;
}

// The horizontal colour bar under the surface.
Ptr<vtkScalarBarActor> colour_bar() {
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
  return bar;
}

// One offscreen window (one OpenGL context, shaders compiled once) for every set.
Ptr<vtkRenderWindow> offscreen_window(vtkRenderer* ren, int width, int height) {
  auto win = Ptr<vtkRenderWindow>::New();
  win->SetOffScreenRendering(1);
  win->AddRenderer(ren);
  win->SetSize(width, height);
  win->SetMultiSamples(0);  // FXAA instead: multisampling costs most of a software-rendered frame
  ren->UseFXAAOn();
  return win;
}

// Colours the surface by the set's values (uncoloured, without a bar, when
// there is not one value per vertex).
void apply_colours(const SurfaceActor& surface, vtkScalarBarActor* bar, const ViewSet& set, std::size_t vertices) {
  const bool coloured = set.values && set.values->size() == vertices;
  const auto lut = lookup(set.colours);
  if (coloured) {
    auto arr = Ptr<vtkDoubleArray>::New();
    arr->SetName("value");
    for (double x : *set.values) arr->InsertNextValue(std::isfinite(x) ? x : 0.0);
    surface.shaded->GetPointData()->SetScalars(arr);
    surface.mapper->SetLookupTable(lut);
    surface.mapper->SetScalarRange(set.colours.lo, set.colours.hi);
    surface.mapper->UseLookupTableScalarRangeOn();
    surface.mapper->SetScalarModeToUsePointData();
    surface.mapper->ScalarVisibilityOn();
    bar->SetLookupTable(lut);
    bar->SetTitle(set.colours.title.c_str());
  } else {
    surface.mapper->ScalarVisibilityOff();
  }
  bar->SetVisibility(coloured);
  surface.shaded->Modified();
}

struct View {
  const char* name;
  Vec3 eye;  // direction from the centre to the camera
  Vec3 up;
  bool plane;  // the plane is seen edge-on from the front and below only
};

std::array<View, 4> views_of(const Framing& f) {
  const Vec3 anterior = -1.0 * f.ap, inferior = -1.0 * f.si;
  return {View{"front", anterior, f.si, true}, View{"below", inferior, anterior, true}, View{"left", f.ml, f.si, false},
          View{"right", -1.0 * f.ml, f.si, false}};
}

// Renders one view and writes it as a PNG; false when the file could not be written.
bool render_view(vtkRenderer* ren, vtkRenderWindow* win, const Framing& f, const View& v, const std::string& file) {
  auto* cam = ren->GetActiveCamera();
  cam->SetFocalPoint(f.centre[0], f.centre[1], f.centre[2]);
  const Vec3 pos = f.centre + (3.0 * f.size) * v.eye;
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
  auto png = Ptr<vtkPNGWriter>::New();
  png->SetFileName(file.c_str());
  png->SetInputConnection(grab->GetOutputPort());
  png->Write();
  return png->GetErrorCode() == 0 && std::filesystem::exists(file);
}

// Every result failed with `why`; files already written are removed.
std::vector<RenderedViews> failed(std::vector<RenderedViews> all, const std::string& why) {
  for (auto& o : all) {
    for (const auto& f : o.files) std::filesystem::remove(f);
    o.files.clear();
    o.error = why;
  }
  return all;
}

}  // namespace

// The scene is built once (surface, landmarks, plane sheet, colour bar, one
// window); each set then recolours the surface and renders the four views.
std::vector<RenderedViews> render_view_sets(const Mesh& mesh, const std::vector<ViewSet>& sets, const LandmarkSet& landmarks,
                                            const Plane& plane, int width, int height, const Vec3& superior) {
  std::vector<RenderedViews> all(sets.size());
  if (sets.empty()) return all;
  if (mesh.faces.empty()) return failed(std::move(all), "no surface to render");
  std::string why;
  if (!ensure_display(&why)) return failed(std::move(all), why);

  auto pd = surface::to_polydata(mesh);
  const SurfaceActor surface = surface_actor(pd);
  auto ren = Ptr<vtkRenderer>::New();
  ren->SetBackground(1, 1, 1);
  ren->AddActor(surface.actor);
  add_landmarks(ren, landmarks);
  const Framing f = framing(mesh, pd, plane, superior);
  const auto sheet = plane_sheet(f, plane);
  ren->AddActor(sheet);
  const auto bar = colour_bar();
  ren->AddActor2D(bar);
  const auto win = offscreen_window(ren, width, height);

  for (std::size_t k = 0; k < sets.size(); ++k) {
    apply_colours(surface, bar, sets[k], mesh.vertices.size());
    for (const View& v : views_of(f)) {
      sheet->SetVisibility(v.plane);
      const std::string file = sets[k].prefix + "_" + v.name + ".png";
      if (!render_view(ren, win, f, v, file)) return failed(std::move(all), "cannot write " + file);
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
