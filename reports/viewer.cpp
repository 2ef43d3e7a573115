// Interactive viewer data and HTML (VTK for the decimation only).
#include "reports/viewer.h"

#include <vtkCellArray.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkQuadricClustering.h>
#include <vtkSmartPointer.h>
#include <vtkStaticPointLocator.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <sstream>

#include "core/json_text.h"
#include "reports/viewer_script.h"  // generated from viewer.js: kViewerScript
#include "reports/writers.h"
#include "surface/vtk_mesh.h"

namespace ms::reports {
namespace {

template <class T>
using Ptr = vtkSmartPointer<T>;

// Little-endian bytes of 32-bit words, whatever the host order.
std::string le_bytes(const std::uint32_t* w, std::size_t n) {
  std::string out(n * 4, '\0');
  for (std::size_t i = 0; i < n; ++i)
    for (int b = 0; b < 4; ++b) out[4 * i + b] = static_cast<char>((w[i] >> (8 * b)) & 0xFFu);
  return out;
}

double value_or_zero(const std::vector<double>& v, std::size_t n, std::size_t i) {
  return v.size() == n && std::isfinite(v[i]) ? v[i] : 0.0;
}

// JSON text that is safe inside a <script> element: no "<" at all, so neither
// "</script>" nor "<!--" can appear.
std::string script_safe(const std::string& json) {
  std::string o;
  o.reserve(json.size());
  for (char c : json) {
    if (c == '<') o += "\\u003c";
    else o += c;
  }
  return o;
}

}  // namespace

Vec3 PlaneFrame::to_frame(const Vec3& p) const {
  const Vec3 d = p - origin;
  return {dot(d, x), dot(d, y), dot(d, z)};
}

PlaneFrame plane_frame(const Mesh& mesh, const Plane& plane, const Vec3& superior) {
  PlaneFrame f;
  // Medio-lateral = the plane normal, superior = the head's superior made
  // orthogonal to it, anterior completes a right-handed frame (the static
  // views use it too).
  f.x = normalized(plane.normal);
  Vec3 up = normalized(superior);
  if (std::abs(dot(up, f.x)) > 0.9) up = {0, 1, 0};
  f.y = normalized(up - dot(up, f.x) * f.x);
  f.z = cross(f.x, f.y);
  if (!mesh.vertices.empty()) {
    Vec3 lo = mesh.vertices.front(), hi = lo;
    for (const auto& v : mesh.vertices)
      for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], v[a]), hi[a] = std::max(hi[a], v[a]);
    f.origin = 0.5 * (lo + hi);
  }
  return f;
}

ViewerMesh viewer_mesh(const Mesh& mesh, const std::vector<double>& mirror, const std::vector<double>& saf,
                       const PlaneFrame& frame, std::size_t max_faces) {
  ViewerMesh out;
  out.source_faces = mesh.faces.size();
  const std::size_t nv = mesh.vertices.size();
  auto emit_vertex = [&](const Vec3& p, std::size_t source) {
    const Vec3 q = frame.to_frame(p);
    for (double c : q) out.positions.push_back(static_cast<float>(c));
    out.mirror.push_back(static_cast<float>(value_or_zero(mirror, nv, source)));
    out.saf.push_back(static_cast<float>(value_or_zero(saf, nv, source)));
  };
  if (mesh.faces.empty()) return out;

  if (max_faces == 0 || mesh.faces.size() <= max_faces) {
    for (std::size_t i = 0; i < nv; ++i) emit_vertex(mesh.vertices[i], i);
    for (const auto& f : mesh.faces)
      for (int k = 0; k < 3; ++k) out.triangles.push_back(static_cast<std::uint32_t>(f[k]));
    return out;
  }

  auto pd = surface::to_polydata(mesh);
  // Quadric clustering (Lindstrom 2000): one representative per grid cell,
  // linear time. The cell size starts where the face count should fall just
  // under the limit (faces scale with 1 / cell area) and grows until it does.
  double b[6];
  pd->GetBounds(b);
  double area = 0;
  for (const auto& f : mesh.faces)
    area += 0.5 * norm(cross(mesh.vertices[f[1]] - mesh.vertices[f[0]], mesh.vertices[f[2]] - mesh.vertices[f[0]]));
  // A regular triangulation of edge h has about 2.3 faces per h^2 of area.
  double cell = std::sqrt(2.3 * area / (0.9 * static_cast<double>(max_faces)));
  vtkSmartPointer<vtkPolyData> dec;
  for (int attempt = 0; attempt < 8; ++attempt, cell *= 1.12) {
    auto cluster = Ptr<vtkQuadricClustering>::New();
    cluster->SetInputData(pd);
    cluster->AutoAdjustNumberOfDivisionsOff();
    int div[3];
    for (int a = 0; a < 3; ++a) div[a] = std::max(1, static_cast<int>(std::ceil((b[2 * a + 1] - b[2 * a]) / cell)));
    cluster->SetNumberOfDivisions(div);
    cluster->UseInputPointsOn();  // representatives are source vertices: exact values
    cluster->Update();
    dec = cluster->GetOutput();
    if (static_cast<std::size_t>(dec->GetNumberOfPolys()) <= max_faces) break;
  }

  auto locator = Ptr<vtkStaticPointLocator>::New();
  locator->SetDataSet(pd);
  locator->BuildLocator();
  const vtkIdType n_out = dec->GetNumberOfPoints();
  for (vtkIdType i = 0; i < n_out; ++i) {
    Vec3 p;
    dec->GetPoint(i, p.data());
    const vtkIdType src = locator->FindClosestPoint(p.data());
    emit_vertex(p, src >= 0 ? static_cast<std::size_t>(src) : 0);
  }
  vtkCellArray* polys = dec->GetPolys();
  auto ids = Ptr<vtkIdList>::New();
  polys->InitTraversal();
  while (polys->GetNextCell(ids)) {
    if (ids->GetNumberOfIds() != 3) continue;
    const vtkIdType a = ids->GetId(0), b = ids->GetId(1), c = ids->GetId(2);
    if (a == b || b == c || a == c) continue;
    out.triangles.push_back(static_cast<std::uint32_t>(a));
    out.triangles.push_back(static_cast<std::uint32_t>(b));
    out.triangles.push_back(static_cast<std::uint32_t>(c));
  }
  // The filter may stop above its target on awkward meshes; never embed more
  // than asked for.
  if (out.triangles.size() / 3 > max_faces) out.triangles.resize(3 * max_faces);
  return out;
}

std::string base64_le(const std::vector<float>& values) {
  std::vector<std::uint32_t> words(values.size());
  static_assert(sizeof(float) == sizeof(std::uint32_t), "32-bit float expected");
  if (!values.empty()) std::memcpy(words.data(), values.data(), values.size() * sizeof(float));
  return base64_le(words);
}

std::string base64_le(const std::vector<std::uint32_t>& values) {
  return base64_encode(le_bytes(values.data(), values.size()));
}

const char* viewer_script() { return kViewerScript; }

std::string viewer_section_html(const ViewerMesh& vm, const PlaneFrame& frame, const Plane& plane,
                                const LandmarkSet& landmarks, const ViewerOptions& options) {
  using Value = Json;
  // Extent of the mesh in the frame: sizes the plane quad and the camera.
  double size = 1;
  if (!vm.positions.empty()) {
    float lo[3], hi[3];
    for (int a = 0; a < 3; ++a) lo[a] = hi[a] = vm.positions[a];
    for (std::size_t i = 0; i < vm.positions.size(); i += 3)
      for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], vm.positions[i + a]), hi[a] = std::max(hi[a], vm.positions[i + a]);
    size = std::max({double(hi[0] - lo[0]), double(hi[1] - lo[1]), double(hi[2] - lo[2]), 1.0});
  }
  auto d = Value::object();
  d["positions"] = base64_le(vm.positions);
  d["triangles"] = base64_le(vm.triangles);
  d["mirror"] = base64_le(vm.mirror);
  d["saf"] = base64_le(vm.saf);
  d["size"] = size;
  // The plane in frame coordinates is x = const (its normal is the frame's x).
  d["plane_x"] = -plane.signed_distance(frame.origin) * dot(normalized(plane.normal), frame.x);
  d["mirror_range"] = json_numbers(std::array<double, 2>{options.mirror_lo, options.mirror_hi});
  d["saf_range"] = json_numbers(std::array<double, 2>{options.saf_lo, options.saf_hi});
  d["landmarks"] = Value::array();
  for (const auto& [name, p] : landmarks.points) {
    auto l = Value::object();
    l["name"] = name;
    l["p"] = json_numbers(frame.to_frame(p));
    d["landmarks"].push_back(l);
  }

  const std::size_t faces = vm.triangles.size() / 3;
  std::ostringstream h;
  h << "<h2 id=\"viewer\">Interactive 3D view</h2>\n"
    << "<div id=\"ms-viewer\" class=\"viewer\" data-viewer=\"loading\">\n"
    << "<div class=\"viewer-bar\"><span>Colour:</span> "
    << "<label><input type=\"radio\" name=\"ms-colour\" value=\"mirror\" checked> mirror distance</label> "
    << "<label><input type=\"radio\" name=\"ms-colour\" value=\"saf\"> SAF map (sided)</label> "
    << "<span class=\"sep\"></span><label><input type=\"checkbox\" id=\"ms-show-landmarks\" checked> landmarks</label> "
    << "<label><input type=\"checkbox\" id=\"ms-show-plane\" checked> symmetry plane</label> "
    << "<span class=\"sep\"></span><span>View:</span> "
    << "<button type=\"button\" data-view=\"front\">front</button><button type=\"button\" data-view=\"below\">below</button>"
    << "<button type=\"button\" data-view=\"left\">left</button><button type=\"button\" data-view=\"right\">right</button>"
    << "<button type=\"button\" data-view=\"oblique\" id=\"ms-reset\">reset</button></div>\n"
    << "<div class=\"viewer-stage\"><canvas aria-label=\"interactive 3D view of the mandible\"></canvas>"
    << "<div class=\"viewer-labels\"></div></div>\n"
    << "<div class=\"viewer-legend\"><div class=\"viewer-ramp\"></div><div class=\"viewer-ticks\"><span></span><span>"
    << "</span><span></span></div><div class=\"viewer-caption muted\"></div></div>\n"
    << "<p class=\"viewer-status warn\" hidden></p>\n"
    << "<noscript><p class=\"muted\">The interactive view needs JavaScript; the static views show the same surface."
    << "</p></noscript>\n"
    << "<p class=\"muted viewer-help\">Drag to rotate, shift-drag or right-drag to pan, wheel to zoom. In the symmetry plane's frame "
    << "(front view: the patient's left on your right). "
    << faces << " triangles";
  if (vm.source_faces > faces) h << " (decimated from " << vm.source_faces << ")";
  h << "; colour scales as the static views: mirror distance " << fixed(options.mirror_lo, 1) << "&hellip;+"
    << fixed(options.mirror_hi, 1) << " mm, SAF map " << fixed(options.saf_lo, 2) << "&hellip;" << fixed(options.saf_hi, 2)
    << " rad.</p>\n</div>\n";
  h << "<script type=\"application/json\" id=\"ms-viewer-data\">" << script_safe(dump_json(d, -1)) << "</script>\n";
  h << "<script>\n" << kViewerScript << "\n</script>\n";
  return h.str();
}

}  // namespace ms::reports
