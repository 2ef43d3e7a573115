#include "landmarks/palate.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "reference/reference.h"

namespace ms::landmarks {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// A nasal-floor candidate: the top of a bone run with air (or soft tissue)
// above it, on one para-sagittal profile, at antero-posterior position a and height h (mm in
// the mandible's plane frame).
struct Candidate {
  double a, h;
  int profile;
  bool air;  // air above (else soft tissue)
};

struct Line {
  double h0 = 0, slope = 0;  // h = h0 + slope (a - a_ref)
  double at(double a, double a_ref) const { return h0 + slope * (a - a_ref); }
};

// The line through the most candidates within +-1.5 mm, refined; the checks
// that make it a palate. Frame: o, e_ap, e_si; heights from o along e_si.
PalatalPlane fit_floor(const std::vector<Candidate>& cand, int profiles, const Vec3& o, const Vec3& e_ap, const Vec3& e_si,
                       double a_ref, double h_incisal, const PalateOptions& opt) {
  PalatalPlane r;
  if (cand.size() < opt.min_samples) {
    r.reason = "no nasal floor above the teeth (" + std::to_string(cand.size()) + " samples)";
    return r;
  }

  // The line through the most candidates within +-1.5 mm: every slope in
  // 0.5 degree steps, a sliding 3 mm window over the sorted offsets. Ties
  // keep the lowest line (the nasal floor is the lowest long bone-air
  // interface above the teeth).
  Line best;
  std::size_t best_count = 0;
  std::vector<double> off(cand.size());
  for (double deg = -opt.max_tilt_deg; deg <= opt.max_tilt_deg + 1e-9; deg += 0.5) {
    const double s = std::tan(deg * M_PI / 180.0);
    for (std::size_t i = 0; i < cand.size(); ++i) off[i] = cand[i].h - s * (cand[i].a - a_ref);
    std::sort(off.begin(), off.end());
    for (std::size_t i = 0, j = 0; i < off.size(); ++i) {
      while (j < off.size() && off[j] <= off[i] + 3.0) ++j;
      if (j - i > best_count || (j - i == best_count && off[i] + 1.5 < best.h0)) {
        best_count = j - i;
        best = {off[i] + 1.5, s};
      }
    }
  }
  // Least-squares refinement on the inliers (per profile, the candidate
  // closest to the line, within 1.5 mm).
  std::vector<const Candidate*> in;
  for (int it = 0; it < 3; ++it) {
    std::vector<const Candidate*> closest(static_cast<std::size_t>(profiles) + 1, nullptr);
    for (const Candidate& c : cand) {
      const double e = std::abs(c.h - best.at(c.a, a_ref));
      const Candidate*& b = closest[static_cast<std::size_t>(c.profile)];
      if (e < 1.5 && (!b || e < std::abs(b->h - best.at(b->a, a_ref)))) b = &c;
    }
    in.clear();
    for (const Candidate* c : closest)
      if (c) in.push_back(c);
    if (in.size() < 3) break;
    double sa = 0, sh = 0, saa = 0, sah = 0;
    for (const Candidate* c : in) {
      const double x = c->a - a_ref;
      sa += x, sh += c->h, saa += x * x, sah += x * c->h;
    }
    const double m = static_cast<double>(in.size()), det = m * saa - sa * sa;
    if (det <= 1e-9) break;
    best.slope = (m * sah - sa * sh) / det;
    best.h0 = (sh - best.slope * sa) / m;
  }
  double ss = 0, a0 = kInf, a1 = -kInf;
  std::size_t under_air = 0;
  for (const Candidate* c : in) {
    const double e = c->h - best.at(c->a, a_ref);
    under_air += c->air;
    ss += e * e;
    a0 = std::min(a0, c->a);
    a1 = std::max(a1, c->a);
  }
  r.samples = in.size();
  r.floor = 2 * under_air >= in.size() ? "air" : "soft tissue";  // what most of the floor has above it
  r.rms_mm = in.empty() ? 0.0 : std::sqrt(ss / static_cast<double>(in.size()));
  r.length_mm = in.empty() ? 0.0 : a1 - a0;
  r.tilt_deg = std::atan(best.slope) * 180.0 / M_PI;
  r.superior = normalized(e_si - best.slope * e_ap);
  r.anterior = o + a0 * e_ap + best.at(a0, a_ref) * e_si;
  r.posterior = o + a1 * e_ap + best.at(a1, a_ref) * e_si;
  char buf[160];
  if (r.samples < opt.min_samples || r.length_mm < opt.min_length_mm) {
    std::snprintf(buf, sizeof buf, "no nasal floor above the teeth (longest line: %zu samples over %.0f mm)", r.samples,
                  r.length_mm);
    r.reason = buf;
  } else if (r.rms_mm > opt.max_rms_mm) {
    std::snprintf(buf, sizeof buf, "the nasal floor is not a line (residual %.1f mm)", r.rms_mm);
    r.reason = buf;
  } else if (std::abs(r.tilt_deg) > opt.max_tilt_deg) {
    std::snprintf(buf, sizeof buf, "the nasal floor is tilted %.0f degrees", r.tilt_deg);
    r.reason = buf;
  } else if (best.at(0.5 * (a0 + a1), a_ref) < h_incisal) {
    r.reason = "the line found is below the incisal edges, not a palate";
  } else {
    r.found = true;
  }
  return r;
}

// Where the palate can be, from the mandible surface in the plane frame
// (origin o; heights along e_si, antero-posterior along e_ap): above the
// incisal edges (h_incisal: the highest point within 20 mm of the front of
// the chin, near the plane), between the front of the chin (amin) and the
// back of the rami (amax); hmax: the highest point (the condyles).
struct SearchRegion {
  double amin, amax, hmax, h_incisal;
};

SearchRegion search_region(const Mesh& mandible, const Vec3& o, const Vec3& e_ml, const Vec3& e_ap, const Vec3& e_si) {
  double umax = 0;
  SearchRegion r{kInf, -kInf, -kInf, -kInf};
  for (const Vec3& v : mandible.vertices) {
    const Vec3 d = v - o;
    umax = std::max(umax, std::abs(dot(d, e_ml)));
    r.amax = std::max(r.amax, dot(d, e_ap));
    r.hmax = std::max(r.hmax, dot(d, e_si));
  }
  for (const Vec3& v : mandible.vertices)
    if (std::abs(dot(v - o, e_ml)) < 0.12 * umax) r.amin = std::min(r.amin, dot(v - o, e_ap));
  for (const Vec3& v : mandible.vertices) {
    const Vec3 d = v - o;
    if (std::abs(dot(d, e_ml)) < 0.12 * umax && dot(d, e_ap) < r.amin + 20.0) r.h_incisal = std::max(r.h_incisal, dot(d, e_si));
  }
  return r;
}

}  // namespace

PalatalPlane find_palatal_plane(const Volume& ct, const Mesh& mandible, const Plane& midsagittal, const PalateOptions& opt) {
  PalatalPlane r;
  if (mandible.vertices.size() < 100 || ct.hu.empty()) {
    r.reason = "no mandible surface";
    return r;
  }
  Vec3 e_ml, e_ap, e_si;  // +L, +P, +S (the scan's superior, projected into the plane)
  reference::plane_frame(midsagittal, e_ml, e_ap, e_si);
  const Vec3 o = midsagittal.point;

  // Where the palate can be, from the mandible (search_region).
  const SearchRegion sr = search_region(mandible, o, e_ml, e_ap, e_si);
  const double amin = sr.amin, amax = sr.amax, hmax = sr.hmax, h_incisal = sr.h_incisal;
  if (!std::isfinite(amin) || !std::isfinite(h_incisal)) {
    r.reason = "no symphysis on the mandible surface";
    return r;
  }

  // Para-sagittal profiles: 4-8 mm either side of the plane (lateral to the
  // nasal septum, inside the nasal cavity), every 1 mm antero-posteriorly.
  const double min_spacing = std::min({ct.geom.spacing[0], ct.geom.spacing[1], ct.geom.spacing[2]});
  const double step = std::max(0.2, 0.5 * min_spacing);
  // (profiles run 60 mm above the highest place a floor is looked for: the
  // air above a nasal floor must end there, the cavity is closed above)
  const double h_lo = h_incisal - 10.0, h_hi = hmax + 30.0, roof_mm = 60.0;
  const double a_lo = amin - 5.0, a_hi = amin + 0.7 * (amax - amin);
  const auto nh = static_cast<std::size_t>((h_hi + roof_mm - h_lo) / step) + 1;
  const auto nsearch = static_cast<std::size_t>((h_hi - h_lo) / step) + 1;
  const auto roof = static_cast<std::size_t>(roof_mm / step);
  const auto air_from = static_cast<std::size_t>(std::lround(1.5 / step)), air_to = static_cast<std::size_t>(std::lround(5.5 / step));
  const auto peak_back = static_cast<std::size_t>(std::lround(3.0 / step));
  std::vector<Candidate> cand;
  std::vector<double> P(nh);
  int profile = 0;
  for (double a = a_lo; a <= a_hi; a += 1.0)
    for (double u : {-8.0, -6.0, -4.0, 4.0, 6.0, 8.0}) {
      ++profile;
      const Vec3 base = o + u * e_ml + a * e_ap;
      for (std::size_t k = 0; k < nh; ++k) P[k] = interpolate(ct, base + (h_lo + static_cast<double>(k) * step) * e_si);
      for (std::size_t k = 0; k < nsearch; ++k) {
        if (!(P[k] >= opt.plate_hu) || !(P[k + 1] < opt.plate_hu)) continue;  // top of a bone run
        std::size_t air = 0, low = 0, n = 0;
        double above = 0;
        bool inside = true;
        for (std::size_t j = k + air_from; j <= k + air_to; ++j, ++n) {
          if (std::isnan(P[j])) inside = false;
          air += P[j] < opt.air_hu;
          low += P[j] < opt.plate_hu;
          above += P[j];
        }
        // At least 80 % of 1.5-5.5 mm above is air (a patent nasal airway) or
        // at least not bone (mucosa, secretions).
        if (!inside || low * 5 < n * 4) continue;
        // The edge: where the profile crosses halfway between the bone's peak
        // (within 3 mm below) and what is above.
        std::size_t kp = k;
        for (std::size_t j = k > peak_back ? k - peak_back : 0; j <= k; ++j)
          if (P[j] > P[kp]) kp = j;
        const double level = 0.5 * (P[kp] + above / static_cast<double>(n));
        std::size_t j = kp;
        while (j + 1 < k + air_to && P[j + 1] >= level) ++j;
        const double t = P[j] > P[j + 1] ? (P[j] - level) / (P[j] - P[j + 1]) : 0.5;
        // Air above must be a cavity (tissue again within 60 mm), not the
        // outside of the head or of a cropped volume.
        bool is_air = air * 5 >= n * 4;
        if (is_air) {
          bool closed = false;
          for (std::size_t q = k + air_to; q < std::min(nh, k + roof) && !std::isnan(P[q]) && !closed; ++q)
            closed = P[q] > opt.air_hu + 400.0;
          if (!closed) continue;
        }
        cand.push_back({a, h_lo + (static_cast<double>(j) + std::clamp(t, 0.0, 1.0)) * step, profile, is_air});
      }
    }
  // The nasal floor is the longest straight bone top above the teeth with
  // air or mucosa above it: the line through the most candidates of either
  // kind. Candidates with air above alone (a patent airway) find the same
  // line with fewer samples, or, when mucosa or secretions cover the floor, a
  // turbinate's or a sinus's edge higher up (Visible Human female: 48 samples
  // 30 mm above the floor at 25 degrees, against 262 on the floor); the line
  // with more support is kept, the air one on a tie.
  const double a_ref = 0.5 * (a_lo + a_hi);
  std::vector<Candidate> air;
  for (const Candidate& c : cand)
    if (c.air) air.push_back(c);
  const PalatalPlane by_air = fit_floor(air, profile, o, e_ap, e_si, a_ref, h_incisal, opt);
  const PalatalPlane by_all = fit_floor(cand, profile, o, e_ap, e_si, a_ref, h_incisal, opt);
  r = by_all.found && (!by_air.found || by_all.samples > by_air.samples) ? by_all : by_air;
  return r;
}

}  // namespace ms::landmarks
