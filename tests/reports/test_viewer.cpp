#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>

#include "reports/html_page.h"
#include "reports/viewer.h"
#include "reports/writers.h"

using namespace ms;
using namespace ms::reports;

namespace {

// Closed UV sphere (radius r, centre c): 2 * n_lon * (n_lat - 1) faces.
Mesh uv_sphere(double r, const Vec3& c, int n_lat, int n_lon) {
  Mesh m;
  m.vertices.push_back(c + Vec3{0, 0, r});
  for (int i = 1; i < n_lat; ++i) {
    const double th = M_PI * i / n_lat;
    for (int j = 0; j < n_lon; ++j) {
      const double ph = 2 * M_PI * j / n_lon;
      m.vertices.push_back(c + Vec3{r * std::sin(th) * std::cos(ph), r * std::sin(th) * std::sin(ph), r * std::cos(th)});
    }
  }
  m.vertices.push_back(c + Vec3{0, 0, -r});
  const int south = static_cast<int>(m.vertices.size()) - 1;
  auto ring = [&](int i, int j) { return 1 + (i - 1) * n_lon + (j % n_lon); };
  for (int j = 0; j < n_lon; ++j) m.faces.push_back({0, ring(1, j), ring(1, j + 1)});
  for (int i = 1; i < n_lat - 1; ++i)
    for (int j = 0; j < n_lon; ++j) {
      m.faces.push_back({ring(i, j), ring(i + 1, j), ring(i + 1, j + 1)});
      m.faces.push_back({ring(i, j), ring(i + 1, j + 1), ring(i, j + 1)});
    }
  for (int j = 0; j < n_lon; ++j) m.faces.push_back({south, ring(n_lat - 1, j + 1), ring(n_lat - 1, j)});
  return m;
}

}  // namespace

TEST(Viewer, Base64LittleEndian) {
  EXPECT_EQ(base64_le(std::vector<float>{1.0f}), "AACAPw==");  // 0x3F800000
  EXPECT_EQ(base64_le(std::vector<std::uint32_t>{1u, 0x01020304u}), "AQAAAAQDAgE=");
  EXPECT_EQ(base64_le(std::vector<float>{}), "");
}

// RFC 4648 section 10's test vectors, and every byte value.
TEST(Viewer, Base64MatchesRfc4648) {
  const char* const plain[] = {"", "f", "fo", "foo", "foob", "fooba", "foobar"};
  const char* const coded[] = {"", "Zg==", "Zm8=", "Zm9v", "Zm9vYg==", "Zm9vYmE=", "Zm9vYmFy"};
  for (int i = 0; i < 7; ++i) EXPECT_EQ(base64_encode(plain[i]), coded[i]) << plain[i];
  std::string all;
  for (int b = 0; b < 256; ++b) all += static_cast<char>(b);
  const std::string e = base64_encode(all);
  EXPECT_EQ(e.size(), 344u);
  EXPECT_EQ(e.substr(0, 8), "AAECAwQF");
  EXPECT_EQ(e.substr(e.size() - 8), "/P3+/w==");
}

TEST(Viewer, PlaneFrameIsRightHandedWithXAlongTheNormal) {
  Mesh m = uv_sphere(10, {5, -3, 2}, 8, 8);
  Plane p;
  p.point = {1, 0, 0};
  p.normal = normalized(Vec3{1, 0.2, 0.1});
  const PlaneFrame f = plane_frame(m, p);
  EXPECT_NEAR(dot(f.x, p.normal), 1.0, 1e-12);
  EXPECT_NEAR(dot(f.x, f.y), 0.0, 1e-12);
  EXPECT_NEAR(norm(cross(f.x, f.y) - f.z), 0.0, 1e-12);
  EXPECT_GT(f.y[2], 0.9);   // superior stays up
  EXPECT_LT(f.z[1], -0.9);  // anterior = LPS -y
  const Vec3 q = f.to_frame(f.origin + 2.0 * f.x + 3.0 * f.z);
  EXPECT_NEAR(q[0], 2.0, 1e-12);
  EXPECT_NEAR(q[1], 0.0, 1e-12);
  EXPECT_NEAR(q[2], 3.0, 1e-12);
}

TEST(Viewer, SmallMeshIsEmbeddedAsIs) {
  const Mesh m = uv_sphere(10, {0, 0, 0}, 10, 12);
  std::vector<double> mirror(m.vertices.size()), saf(m.vertices.size());
  for (std::size_t i = 0; i < m.vertices.size(); ++i) mirror[i] = m.vertices[i][0], saf[i] = 0.01 * i;
  Plane p;  // normal +x through the origin
  const PlaneFrame f = plane_frame(m, p);
  const ViewerMesh vm = viewer_mesh(m, mirror, saf, f, 30000);
  ASSERT_EQ(vm.positions.size(), 3 * m.vertices.size());
  ASSERT_EQ(vm.triangles.size(), 3 * m.faces.size());
  EXPECT_EQ(vm.source_faces, m.faces.size());
  for (std::size_t i = 0; i < m.vertices.size(); ++i) {
    EXPECT_NEAR(vm.positions[3 * i], m.vertices[i][0], 1e-5);  // frame x = LPS x here
    EXPECT_FLOAT_EQ(vm.mirror[i], static_cast<float>(mirror[i]));
    EXPECT_FLOAT_EQ(vm.saf[i], static_cast<float>(saf[i]));
  }
  // Missing arrays read as zeros rather than failing.
  const ViewerMesh bare = viewer_mesh(m, {}, {1.0}, f, 30000);
  for (float v : bare.mirror) EXPECT_EQ(v, 0.0f);
  for (float v : bare.saf) EXPECT_EQ(v, 0.0f);
}

TEST(Viewer, LargeMeshIsDecimatedBelowTheLimitKeepingValuesAndShape) {
  const Mesh m = uv_sphere(40, {10, 20, 30}, 150, 200);  // 59,600 faces
  ASSERT_GT(m.faces.size(), 50000u);
  std::vector<double> mirror(m.vertices.size()), saf(m.vertices.size());
  for (std::size_t i = 0; i < m.vertices.size(); ++i) {
    mirror[i] = (m.vertices[i][0] - 10) / 40 * 3;  // -3..3 with LPS x
    saf[i] = std::abs(m.vertices[i][2] - 30) / 40 * 0.25;
  }
  Plane p;
  p.point = {10, 20, 30};
  const PlaneFrame f = plane_frame(m, p);
  const std::size_t limit = 10000;
  const ViewerMesh vm = viewer_mesh(m, mirror, saf, f, limit);
  const std::size_t nv = vm.positions.size() / 3, nf = vm.triangles.size() / 3;
  EXPECT_LE(nf, limit);
  EXPECT_GT(nf, limit / 3);  // decimated, not destroyed
  EXPECT_EQ(vm.source_faces, m.faces.size());
  ASSERT_EQ(vm.mirror.size(), nv);
  ASSERT_EQ(vm.saf.size(), nv);
  for (std::uint32_t idx : vm.triangles) ASSERT_LT(idx, nv);
  for (std::size_t i = 0; i < nv; ++i) {
    const double x = vm.positions[3 * i], y = vm.positions[3 * i + 1], z = vm.positions[3 * i + 2];
    // Still on the sphere, centred in the frame.
    EXPECT_NEAR(std::sqrt(x * x + y * y + z * z), 40.0, 0.5);
    // Values travel with their vertex (frame x = LPS x, frame y = LPS z here).
    EXPECT_NEAR(vm.mirror[i], x / 40 * 3, 0.1);
    EXPECT_NEAR(vm.saf[i], std::abs(y) / 40 * 0.25, 0.01);
  }
}

TEST(Viewer, SectionEmbedsDataScriptAndFallbackSafely) {
  const Mesh m = uv_sphere(10, {0, 0, 0}, 6, 8);
  Plane p;
  p.point = {2, 0, 0};
  const PlaneFrame f = plane_frame(m, p);
  const ViewerMesh vm = viewer_mesh(m, {}, {}, f, 30000);
  LandmarkSet lms;
  lms.points = {{"Me", {0, -10, -5}}, {"Co_L", {8, 0, 5}}};
  const std::string html = viewer_section_html(vm, f, p, lms);
  EXPECT_NE(html.find("id=\"ms-viewer\""), std::string::npos);
  EXPECT_NE(html.find("data-viewer=\"loading\""), std::string::npos);
  EXPECT_NE(html.find("\"name\":\"Co_L\""), std::string::npos);
  EXPECT_NE(html.find("\"plane_x\":2"), std::string::npos);  // plane x = 2 in a frame centred at 0
  EXPECT_NE(html.find(viewer_script()), std::string::npos);
  EXPECT_NE(html.find("no-webgl"), std::string::npos);  // the script's fallback state
  // Nothing fetched from elsewhere, and the data block cannot end the script early.
  EXPECT_EQ(html.find("http"), std::string::npos);
  const auto data_begin = html.find("id=\"ms-viewer-data\">");
  ASSERT_NE(data_begin, std::string::npos);
  const auto data_end = html.find("</script>", data_begin);
  EXPECT_EQ(html.substr(data_begin, data_end - data_begin).find('<'), std::string::npos);
  EXPECT_EQ(std::string(viewer_script()).find("</script"), std::string::npos);
}

// The page skeleton and stylesheet shared by report.html and compare.html
// (reports/html_page.h), compiled in like the viewer's script.

TEST(HtmlPage, StylesheetIsTheRepositoryFileCompiledIn) {
  std::ifstream in(std::string(MANDISYM_SOURCE_DIR) + "/reports/assets/mandisym.css", std::ios::binary);
  ASSERT_TRUE(in);
  std::stringstream file;
  file << in.rdbuf();
  EXPECT_EQ(std::string(page_css()), file.str());
}

TEST(HtmlPage, StylesheetFetchesNothingAndCannotEndTheStyleElement) {
  const std::string css = page_css();
  for (const char* s : {"http", "url(", "@import", "</style", "</STYLE"}) EXPECT_EQ(css.find(s), std::string::npos) << s;
  // The classes the pages use.
  for (const char* c : {".warn{", ".muted{", ".qcfail{", ".views{", ".card{", ".band-marked{", ".viewer{", ".refs{"})
    EXPECT_NE(css.find(c), std::string::npos) << c;
}

TEST(HtmlPage, WrapsTheBodyInTheSkeletonWithTheStylesheetInlined) {
  const std::string page = html_page("A & <B>", "<h1>x</h1>\n");
  EXPECT_EQ(page.rfind("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n", 0), 0u);
  EXPECT_NE(page.find("<title>A &amp; &lt;B&gt;</title>\n<style>\n" + std::string(page_css()) + "</style></head><body>\n<h1>x</h1>\n</body></html>\n"),
            std::string::npos);
  const std::string tail = "</body></html>\n";
  EXPECT_EQ(page.substr(page.size() - tail.size()), tail);
}

TEST(HtmlPage, ReportUsesTheSharedSkeleton) {
  RunSummary s;
  const std::string html = report_html(s, {}, {}, "no display");
  const auto body = html.find("<body>\n");
  ASSERT_NE(body, std::string::npos);
  EXPECT_EQ(html, html_page("MandiSym mandibular asymmetry report", html.substr(body + 7, html.size() - body - 7 - 15)));
  EXPECT_NE(html.find("3D views not rendered: no display"), std::string::npos);
}

// A failed run's banner leads with the likely cause (docs/qc.md), and an
// open upper bound reads "at least", not "20 to n/a".
TEST(HtmlPage, QcBannerGivesTheCauseAndOpenRanges) {
  RunSummary s;
  s.qc.status = "fail";
  s.qc.cause = "the mandible atlas could not be placed in the scan";
  QcCheck reach;
  reach.name = "side_reach_mm", reach.value = 4, reach.lo = 20, reach.hi = std::numeric_limits<double>::infinity();
  reach.passed = false, reach.fatal = true, reach.message = "one half of the mandible is missing";
  s.qc.checks.push_back(reach);
  const std::string html = report_html(s, {}, {}, "no display");
  EXPECT_NE(html.find("Likely cause: the mandible atlas could not be placed in the scan."), std::string::npos);
  EXPECT_NE(html.find("(allowed at least 20.00)"), std::string::npos);
  EXPECT_NE(html.find("<td>at least 20.00</td>"), std::string::npos);
  EXPECT_EQ(html.find("n/a</td><td>FAIL"), std::string::npos);
}
