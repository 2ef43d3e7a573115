#include "reports/figures.h"

#include <algorithm>
#include <cmath>

#include "io/png.h"

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

}  // namespace ms::reports
