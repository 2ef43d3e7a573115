#include "reports/figures.h"

#include <algorithm>
#include <cmath>

#include "io/png.h"
#include "reference/reference.h"

namespace ms::reports {

std::vector<std::string> write_qc_slices(const Volume& ct, const Mask& mask, const std::string& dir) {
  const Geometry& g = ct.geom;
  // centre of the mask
  double c[3] = {0, 0, 0};
  std::size_t n = 0;
  for (std::size_t k = 0; k < g.size[2]; ++k)
    for (std::size_t j = 0; j < g.size[1]; ++j)
      for (std::size_t i = 0; i < g.size[0]; ++i)
        if (mask.data[g.linear(i, j, k)]) c[0] += i, c[1] += j, c[2] += k, ++n;
  if (n == 0) return {};
  const std::size_t ci = static_cast<std::size_t>(c[0] / n), cj = static_cast<std::size_t>(c[1] / n),
                    ck = static_cast<std::size_t>(c[2] / n);
  std::vector<std::string> out;
  // Bone window (level 400, width 2000); mask outline in orange.
  auto grey = [](float hu) { return static_cast<std::uint8_t>(std::clamp((hu + 600.0f) / 2000.0f * 255.0f, 0.0f, 255.0f)); };
  // plane: 0 axial (i,j at k), 1 coronal (i,k at j), 2 sagittal (j,k at i)
  for (int plane = 0; plane < 3; ++plane) {
    const std::size_t W = plane == 2 ? g.size[1] : g.size[0];
    const std::size_t H = plane == 0 ? g.size[1] : g.size[2];
    auto at = [&](long u, long v) -> std::size_t {
      if (plane == 0) return g.linear(u, v, ck);
      if (plane == 1) return g.linear(u, cj, v);
      return g.linear(ci, u, v);
    };
    std::vector<std::uint8_t> px(W * H * 3);
    for (std::size_t v = 0; v < H; ++v)
      for (std::size_t u = 0; u < W; ++u) {
        // Radiological display: patient right on the image left for axial and
        // coronal views (i grows towards patient left), superior at the top.
        const std::size_t row = plane == 0 ? v : H - 1 - v;
        const std::size_t idx = at(static_cast<long>(u), static_cast<long>(v));
        const std::uint8_t gv = grey(ct.hu[idx]);
        std::uint8_t* p = &px[3 * (row * W + u)];
        p[0] = p[1] = p[2] = gv;
        if (mask.data[idx]) {
          bool edge = false;
          for (int du = -1; du <= 1 && !edge; ++du)
            for (int dv = -1; dv <= 1 && !edge; ++dv) {
              const long uu = static_cast<long>(u) + du, vv = static_cast<long>(v) + dv;
              if (uu < 0 || vv < 0 || uu >= static_cast<long>(W) || vv >= static_cast<long>(H)) continue;
              edge = !mask.data[at(uu, vv)];
            }
          if (edge) p[0] = 255, p[1] = 140, p[2] = 0;
          else p[0] = static_cast<std::uint8_t>(std::min(255, gv + 40));
        }
      }
    const char* names[3] = {"qc_axial", "qc_coronal", "qc_sagittal"};
    const std::string path = dir + "/" + names[plane] + ".png";
    io::write_png(path, px, static_cast<int>(W), static_cast<int>(H), 3);
    out.push_back(path);
  }
  return out;
}

bool write_head_frame_slice(const Volume& ct, const Plane& midsagittal, const landmarks::PalatalPlane& palate,
                            const LandmarkSet& landmarks, const std::string& path) {
  Vec3 e_ml, e_ap, e_si;
  reference::plane_frame(midsagittal, e_ml, e_ap, e_si);
  const Vec3 o = midsagittal.point;
  // The window: the palatal line (found or not) and every landmark, with margins.
  double a0 = 1e9, a1 = -1e9, h0 = 1e9, h1 = -1e9;
  auto take = [&](const Vec3& p) {
    const double a = dot(p - o, e_ap), h = dot(p - o, e_si);
    a0 = std::min(a0, a), a1 = std::max(a1, a), h0 = std::min(h0, h), h1 = std::max(h1, h);
  };
  take(palate.anterior);
  take(palate.posterior);
  for (const auto& [name, p] : landmarks.points) take(p);
  if (a1 < a0) return false;
  a0 -= 40, a1 += 30, h0 -= 20, h1 += 45;
  const double px = 0.5;  // mm per pixel, whatever the scan (readable on coarse scans)
  const int W = static_cast<int>((a1 - a0) / px) + 1, H = static_cast<int>((h1 - h0) / px) + 1;
  if (W < 8 || H < 8 || W > 4000 || H > 4000) return false;
  std::vector<std::uint8_t> img(static_cast<std::size_t>(W) * H * 3, 0);
  for (int r = 0; r < H; ++r)
    for (int c = 0; c < W; ++c) {
      const double hu = interpolate(ct, o + (a0 + c * px) * e_ap + (h1 - r * px) * e_si);
      const auto g = std::isnan(hu) ? std::uint8_t{0} : static_cast<std::uint8_t>(std::clamp((hu + 600.0) / 2000.0 * 255.0, 0.0, 255.0));
      std::uint8_t* q = &img[3 * (static_cast<std::size_t>(r) * W + c)];
      q[0] = q[1] = q[2] = g;
    }
  auto dot_at = [&](double a, double h, int half, std::uint8_t R, std::uint8_t G, std::uint8_t B) {
    const int c = static_cast<int>(std::lround((a - a0) / px)), r = static_cast<int>(std::lround((h1 - h) / px));
    for (int dr = -half; dr <= half; ++dr)
      for (int dc = -half; dc <= half; ++dc) {
        const int rr = r + dr, cc = c + dc;
        if (rr < 0 || cc < 0 || rr >= H || cc >= W) continue;
        std::uint8_t* q = &img[3 * (static_cast<std::size_t>(rr) * W + cc)];
        q[0] = R, q[1] = G, q[2] = B;
      }
  };
  if (palate.found) {
    const double pa0 = dot(palate.anterior - o, e_ap), ph0 = dot(palate.anterior - o, e_si);
    const double pa1 = dot(palate.posterior - o, e_ap), ph1 = dot(palate.posterior - o, e_si);
    const double slope = pa1 > pa0 ? (ph1 - ph0) / (pa1 - pa0) : 0.0;
    for (double a = a0; a <= a1; a += 0.25 * px) {
      const bool support = a >= pa0 && a <= pa1;
      if (support || std::fmod(a - a0, 4.0) < 2.0) dot_at(a, ph0 + slope * (a - pa0), support ? 1 : 0, 0, 220, 255);
    }
  }
  for (const char* name : {"Me", "Pog"})
    if (const Vec3* p = landmarks.find(name)) dot_at(dot(*p - o, e_ap), dot(*p - o, e_si), 3, 40, 220, 60);
  io::write_png(path, img, W, H, 3);
  return true;
}

}  // namespace ms::reports
