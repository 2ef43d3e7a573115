#include "landmarks/landmarks.h"

#include <cmath>
#include <functional>
#include <limits>

namespace ms::landmarks {

Result detect(const Mesh& mesh) {
  Result r;
  r.method = "extreme-vertex (thin)";
  const auto& V = mesh.vertices;
  if (V.empty()) return r;
  Vec3 c{0, 0, 0}, lo{1e30, 1e30, 1e30}, hi{-1e30, -1e30, -1e30};
  for (const auto& v : V) {
    c = c + v;
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], v[a]);
      hi[a] = std::max(hi[a], v[a]);
    }
  }
  c = (1.0 / V.size()) * c;
  const double width = hi[0] - lo[0];

  // argmax of score over vertices passing the filter; nullopt-like -1 if none.
  auto argmax = [&](const std::function<bool(const Vec3&)>& keep, const std::function<double(const Vec3&)>& score) {
    int best = -1;
    double bs = -std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < V.size(); ++i)
      if (keep(V[i]) && score(V[i]) > bs) {
        bs = score(V[i]);
        best = static_cast<int>(i);
      }
    return best;
  };
  for (double s : {1.0, -1.0}) {
    const std::string suf = s > 0 ? "_L" : "_R";
    auto side = [&](const Vec3& v) { return s * (v[0] - c[0]) > 0.15 * width; };
    const int co = argmax([&](const Vec3& v) { return side(v) && v[1] > c[1]; }, [](const Vec3& v) { return v[2]; });
    if (co < 0) continue;
    r.landmarks.set("Co" + suf, V[co]);
    const Vec3 cop = V[co];
    const int cr = argmax([&](const Vec3& v) { return side(v) && v[1] < cop[1] - 12.0 && s * (v[0] - c[0]) > 0.25 * width; },
                          [](const Vec3& v) { return v[2]; });
    if (cr >= 0) r.landmarks.set("Cr" + suf, V[cr]);
    const double ycut = cr >= 0 ? V[cr][1] : c[1];
    const int go = argmax([&](const Vec3& v) { return side(v) && v[1] > ycut && v[2] < cop[2] - 25.0; },
                          [](const Vec3& v) { return (v[1] - v[2]) / std::sqrt(2.0); });
    if (go >= 0) r.landmarks.set("Go" + suf, V[go]);
  }
  const int me = argmax([&](const Vec3& v) { return std::abs(v[0] - c[0]) < 0.15 * width; },
                        [](const Vec3& v) { return -v[2]; });
  if (me >= 0) {
    r.landmarks.set("Me", V[me]);
    const Vec3 mep = V[me];
    const int pog = argmax([&](const Vec3& v) { return std::abs(v[0] - mep[0]) < 12.0 && v[2] < mep[2] + 20.0; },
                           [](const Vec3& v) { return -v[1]; });
    if (pog >= 0) r.landmarks.set("Pog", V[pog]);
  }
  for (const auto& n : landmark_names())
    if (!r.landmarks.has(n)) r.missing.push_back(n);
  return r;
}

}  // namespace ms::landmarks
