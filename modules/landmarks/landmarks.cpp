#include "landmarks/landmarks.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <limits>
#include <memory>
#include <queue>
#include <array>

#include "core/debug_lap.h"
#include "core/hull2d.h"
#include "geometry/mesh_geometry.h"
#include "reference/reference.h"

namespace ms::landmarks {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

using geometry::EdgeGraph;
using Graph = EdgeGraph;

void dijkstra(const Graph& g, int source, double radius, std::vector<double>& dist, std::vector<int>* touched = nullptr) {
  geometry::dijkstra(g, {source}, radius, dist, nullptr, touched);
}

// Vertices within radius of source (geodesic), reusing a scratch buffer.
std::vector<int> ball(const Graph& g, int source, double radius, std::vector<double>& scratch) {
  std::vector<int> touched;
  dijkstra(g, source, radius, scratch, &touched);
  for (int v : touched) scratch[static_cast<std::size_t>(v)] = kInf;
  return touched;
}

// Average geodesic distance from agd_samples farthest-point samples.
std::vector<double> average_geodesic_distance(const Graph& g, std::size_t n, int samples) {
  std::vector<double> agd(n, 0.0), mind(n, kInf), d(n);
  int next = 0;
  {  // start from the vertex farthest from vertex 0
    std::fill(d.begin(), d.end(), kInf);
    dijkstra(g, 0, kInf, d);
    double far = -1;
    for (std::size_t i = 0; i < n; ++i)
      if (d[i] != kInf && d[i] > far) far = d[i], next = static_cast<int>(i);
  }
  int used = 0;
  for (int s = 0; s < samples; ++s) {
    std::fill(d.begin(), d.end(), kInf);
    dijkstra(g, next, kInf, d);
    ++used;
    double far = -1;
    for (std::size_t i = 0; i < n; ++i) {
      if (d[i] == kInf) continue;  // another component
      agd[i] += d[i];
      mind[i] = std::min(mind[i], d[i]);
      if (mind[i] > far) far = mind[i], next = static_cast<int>(i);
    }
  }
  for (double& a : agd) a /= std::max(1, used);
  return agd;
}

// Geodesic extremities: vertices whose AGD is the largest within radius.
std::vector<int> extremities(const Graph& g, const std::vector<double>& agd, double radius) {
  const std::size_t n = agd.size();
  std::vector<int> cand;
  for (std::size_t v = 0; v < n; ++v) {
    bool top = g.start[v + 1] > g.start[v];
    for (std::size_t e = g.start[v]; e < g.start[v + 1] && top; ++e) top = agd[v] >= agd[static_cast<std::size_t>(g.nbr[e])];
    if (top) cand.push_back(static_cast<int>(v));
  }
  std::sort(cand.begin(), cand.end(), [&](int a, int b) { return agd[static_cast<std::size_t>(a)] > agd[static_cast<std::size_t>(b)]; });
  std::vector<double> scratch(n, kInf);
  std::vector<int> out;
  for (int c : cand) {
    bool top = true;
    for (int w : ball(g, c, radius, scratch))
      if (agd[static_cast<std::size_t>(w)] > agd[static_cast<std::size_t>(c)]) {
        top = false;
        break;
      }
    if (top) out.push_back(c);
  }
  return out;
}

struct P2 {
  double a, h;  // antero-posterior (+posterior), supero-inferior (+superior)
};

// Convex hull, counter-clockwise in (a, h).
std::vector<P2> hull(const std::vector<P2>& p) {
  std::vector<std::array<double, 2>> xy(p.size());
  for (std::size_t i = 0; i < p.size(); ++i) xy[i] = {p[i].a, p[i].h};
  std::vector<P2> out;
  for (std::size_t i : convex_hull_2d(xy)) out.push_back(p[i]);
  return out;
}

// Among candidate vertices, those within tol of the best score (a flat top
// must not be decided by vertex order): the one nearest their centroid.
template <class Score>
int plateau(const std::vector<Vec3>& V, const std::vector<int>& cand, Score score, double tol) {
  double best = -kInf;
  for (int v : cand) best = std::max(best, score(static_cast<std::size_t>(v)));
  Vec3 c{0, 0, 0};
  int cnt = 0;
  for (int v : cand)
    if (score(static_cast<std::size_t>(v)) >= best - tol) c = c + V[static_cast<std::size_t>(v)], ++cnt;
  if (cnt == 0) return -1;
  c = (1.0 / cnt) * c;
  int out = -1;
  double dmin = kInf;
  for (int v : cand)
    if (score(static_cast<std::size_t>(v)) >= best - tol && norm(V[static_cast<std::size_t>(v)] - c) < dmin)
      dmin = norm(V[static_cast<std::size_t>(v)] - c), out = v;
  return out;
}

// Solves the n x n system M x = y (Gaussian elimination, partial pivoting).
template <int N>
bool solve(std::array<std::array<double, N + 1>, N> m, std::array<double, N>& x) {
  for (int c = 0; c < N; ++c) {
    int piv = c;
    for (int r = c + 1; r < N; ++r)
      if (std::abs(m[r][c]) > std::abs(m[piv][c])) piv = r;
    if (std::abs(m[piv][c]) < 1e-12) return false;
    std::swap(m[c], m[piv]);
    for (int r = 0; r < N; ++r) {
      if (r == c) continue;
      const double f = m[r][c] / m[c][c];
      for (int k = c; k <= N; ++k) m[r][k] -= f * m[c][k];
    }
  }
  for (int c = 0; c < N; ++c) x[c] = m[c][N] / m[c][c];
  return true;
}

// Sub-voxel extreme point: around vertex top (the extreme of coordinate z in
// direction sign), fits z = quadratic(x, y) to the vertices within radius
// (least squares, local coordinates) and returns the fitted apex when it is a
// true extremum inside the patch; otherwise the vertex itself. The staircase
// of a voxel surface moves the extreme vertex by up to half a voxel; the fit
// averages it out.
Vec3 refine_extreme(const std::vector<Vec3>& V, int top, const Vec3& ex, const Vec3& ey, const Vec3& ez, double sign,
                    double radius) {
  const Vec3 o = V[static_cast<std::size_t>(top)];
  std::array<std::array<double, 7>, 6> m{};
  int cnt = 0;
  for (const Vec3& p : V) {
    const Vec3 d = p - o;
    if (dot(d, d) > radius * radius) continue;
    const double x = dot(d, ex), y = dot(d, ey), z = sign * dot(d, ez);
    if (z < -radius) continue;  // the far side of a thin process
    const double b[6] = {1, x, y, x * x, x * y, y * y};
    for (int r = 0; r < 6; ++r) {
      for (int c = 0; c < 6; ++c) m[r][c] += b[r] * b[c];
      m[r][6] += b[r] * z;
    }
    ++cnt;
  }
  if (cnt < 12) return o;
  std::array<double, 6> c{};
  if (!solve<6>(m, c)) return o;
  // Apex: gradient zero; a maximum of z (negative definite Hessian).
  const double h11 = 2 * c[3], h12 = c[4], h22 = 2 * c[5], det = h11 * h22 - h12 * h12;
  if (!(h11 < 0 && det > 0)) return o;
  const double x = (-c[1] * h22 + c[2] * h12) / det, y = (-c[2] * h11 + c[1] * h12) / det;
  if (x * x + y * y > 0.25 * radius * radius) return o;
  const double z = c[0] + c[1] * x + c[2] * y + c[3] * x * x + c[4] * x * y + c[5] * y * y;
  return o + x * ex + y * ey + (sign * z) * ez;
}

// Condylar and coronoid processes: their tips lie ~30-35 mm apart
// antero-posteriorly (sigmoid notch width) and within ~15 mm in height in
// adults; the bounds leave room for children and for pose.
constexpr double kProcessSeparationMm = 10.0;
constexpr double kProcessHeightMm = 30.0;
// The condyle caps the posterior border of the ramus: condylion lies within
// half a condylar head (8-10 mm antero-posteriorly) of the border
// (depth_from_posterior_border), plus the border's concavity below the neck,
// while the coronoid tip lies about the minimum ramus breadth in front of it
// (29-33 mm in adults, ~25 mm in children; Humphrey et al. 1999, Kharoshah
// et al. 2010). A process deeper than this is not the condyle...
constexpr double kCondyleMaxDepthMm = 15.0;
// ... and a coronoid tip stands over the front half of the ramus's section
// 10 mm below it (the sigmoid notch lies behind it), while a condyle stands
// over its neck or the back of the ramus, however far a ramus leaning back
// puts its lower border behind it.
constexpr double kCoronoidFrontFraction = 0.5;
// Condylion lies above the coronoid tip in most adults (median 10 mm above on
// the complete clinical contours of openkbp-train folds 1-4, 90 sides; the
// coronoid higher by at most 6.6 mm at the 95th percentile); a coronoid
// standing more than this above the posterior process is coronoid
// hyperplasia (Izumi et al. 2006, rare) or, far more often, a condylar
// process cut short: its stump is not condylion.
constexpr double kCoronoidAboveCondyleMaxMm = 15.0;
// Condylion is the condyle's top, reached by climbing from the condylar
// extremity: the highest point within process_radius_mm, again from there,
// until no point within that radius is higher. The extremity (an AGD maximum)
// can sit low on the broad condylar process: the Visible Human head pitched
// 15 degrees put the right condyle's 18 mm down its neck, and one ball's
// highest point was 11 mm below condylion. Bounded by the condylar process's
// length above the sigmoid notch (~20 mm, Humphrey et al. 1999) in steps of
// process_radius_mm, with a margin, and kept to the points nearer
// (geodesically) the condylar extremity than any other extremity. The
// coronoid tip does not climb: at ~4 mm voxels the notch can be so shallow
// that the ramus's upper edge rises from the coronoid to the condylar neck
// (openkbp-train pt_177: a climb took the coronoid 18 mm back, onto the neck).
constexpr int kProcessClimbSteps = 4;

// The posterior and inferior borders as two chords (the cephalometric
// tangents), where no single hull edge is long enough (a rounded angle, a
// convex ramus, or a head frame tilted so that part of the lower border faces
// posterior): the hull's arc of edges facing posterior or inferior (the cones
// of detect()) is split where two straight segments fit its vertices best
// (least squared distance), each segment at least min_len long. The chords'
// outward normals; ok = false when no split qualifies.
struct BorderPair {
  bool ok = false;
  P2 n_post{0, 0}, n_inf{0, 0};
};

BorderPair border_chords(const std::vector<P2>& hl, double cone, double min_len) {
  const std::size_t m = hl.size();
  BorderPair out;
  if (m < 3) return out;
  auto normal = [&](const P2& p, const P2& q, P2* n) {
    const double da = q.a - p.a, dh = q.h - p.h, len = std::hypot(da, dh);
    if (len < 1e-9) return false;
    *n = {dh / len, -da / len};
    return true;
  };
  auto faces = [&](std::size_t i) {
    P2 n;
    if (!normal(hl[i], hl[(i + 1) % m], &n)) return false;
    return (n.a > cone && n.a >= -n.h) || (-n.h > cone && -n.h > n.a);
  };
  // The arc: the longest run of facing edges (one arc on a convex hull).
  std::vector<P2> arc;
  for (std::size_t start = 0; start < m; ++start) {
    if (!faces(start) || faces((start + m - 1) % m)) continue;
    std::vector<P2> run{hl[start]};
    for (std::size_t e = start; faces(e) && run.size() <= m; e = (e + 1) % m) run.push_back(hl[(e + 1) % m]);
    if (run.size() > arc.size()) arc = std::move(run);
  }
  if (arc.size() < 3) return out;
  auto line_error = [&](std::size_t a, std::size_t b) {
    P2 n;
    if (!normal(arc[a], arc[b], &n)) return kInf;
    double e = 0;
    for (std::size_t k = a; k <= b; ++k) {
      const double d = (arc[k].a - arc[a].a) * n.a + (arc[k].h - arc[a].h) * n.h;
      e += d * d;
    }
    return e;
  };
  double best = kInf;
  for (std::size_t k = 1; k + 1 < arc.size(); ++k) {
    if (std::hypot(arc[k].a - arc[0].a, arc[k].h - arc[0].h) < min_len) continue;
    if (std::hypot(arc.back().a - arc[k].a, arc.back().h - arc[k].h) < min_len) continue;
    const double e = line_error(0, k) + line_error(k, arc.size() - 1);
    if (e >= best) continue;
    P2 n1, n2;
    if (!normal(arc[0], arc[k], &n1) || !normal(arc[k], arc.back(), &n2)) continue;
    best = e;
    // The more posterior-facing chord is the ramus's.
    out.n_post = n1.a > n2.a ? n1 : n2;
    out.n_inf = n1.a > n2.a ? n2 : n1;
    out.ok = true;
  }
  return out;
}

// B point's height on the mid-sagittal profile (docs/landmarks.md): the
// profile is the most anterior extent of the midline band in 1 mm height bins
// from menton up to kProfileMm; B point is the bin lying deepest below the
// profile's upper (anterior) envelope, when at least kBPointDepthMm deep.
// Returns +inf without such a concavity.
constexpr double kProfileMm = 35.0;     // menton to above the alveolar crest of the lower incisors
constexpr double kBPointDepthMm = 1.0;  // shallower: no labial concavity to speak of

double b_point_height(const std::vector<int>& band, const std::vector<double>& A, const std::vector<double>& H, double hme) {
  const int nb = static_cast<int>(kProfileMm);
  std::vector<double> front(nb, -kInf);  // most anterior extent (-A) per bin
  for (int v : band) {
    const double h = H[static_cast<std::size_t>(v)] - hme;
    if (h < 0 || h >= kProfileMm) continue;
    double& f = front[static_cast<std::size_t>(h)];
    f = std::max(f, -A[static_cast<std::size_t>(v)]);
  }
  double deepest = 0;
  int at = -1;
  for (int b = 1; b + 1 < nb; ++b) {
    if (!std::isfinite(front[b])) continue;
    double envelope = -kInf;  // upper envelope at b: chords between bins on either side
    for (int i = 0; i < b; ++i)
      for (int j = b + 1; j < nb; ++j)
        if (std::isfinite(front[i]) && std::isfinite(front[j]))
          envelope = std::max(envelope, front[i] + (front[j] - front[i]) * (b - i) / static_cast<double>(j - i));
    if (envelope - front[b] > deepest) deepest = envelope - front[b], at = b;
  }
  return deepest >= kBPointDepthMm ? hme + at + 0.5 : kInf;
}

// The mesh in the labelling frame (detect() step 1): per vertex the
// medio-lateral (U, + left), antero-posterior (A, + posterior) and
// supero-inferior (H, + superior) coordinates in the symmetry plane's frame.
struct Frame {
  const std::vector<Vec3>& V;
  Vec3 origin;  // the symmetry plane's point: U = A = H = 0
  Vec3 e_ml, e_ap, e_si;
  std::vector<double> U, A, H;
  double umax = 0;  // largest |U|
};

Frame frame_of(const std::vector<Vec3>& V, const Plane& plane, const Vec3& superior) {
  Frame f{V, plane.point, {}, {}, {}, std::vector<double>(V.size()), std::vector<double>(V.size()), std::vector<double>(V.size()), 0.0};
  reference::plane_frame(plane, f.e_ml, f.e_ap, f.e_si, superior);
  for (std::size_t i = 0; i < V.size(); ++i) {
    const Vec3 d = V[i] - plane.point;
    f.U[i] = dot(d, f.e_ml);
    f.A[i] = dot(d, f.e_ap);
    f.H[i] = dot(d, f.e_si);
    f.umax = std::max(f.umax, std::abs(f.U[i]));
  }
  return f;
}

// A side's vertices lie beyond this fraction of the largest |U| (the rami and
// the posterior body, not the symphysis).
constexpr double kSideFraction = 0.35;
// Extreme points: vertices within this of the extreme value form its plateau (mm).
constexpr double kPlateauTolMm = 0.3;

// A mandibular border that turns less than this over a gonial tangent's
// length is straight for the tangent (degrees): the cephalometric ramus and
// mandibular planes are drawn along borders that bend by a few degrees
// (the posterior ramus border's convexity, the antegonial notch), and the
// gonial angle itself turns 110-140 degrees.
constexpr double kStraightBorderDeg = 10.0;
// Hull edges facing within this of 45 degrees below posterior are candidates
// for both gonial tangents (degrees); below 42 degrees an edge is a ramus
// border (the 40 degree lower posterior border of a ramus tilted back 18
// degrees, above).
constexpr double kClassOverlapDeg = 3.0;
// Hull edges facing within this of posterior or of inferior are candidates
// for the gonial tangents (degrees).
constexpr double kBorderConeDeg = 50.0;

// The two gonial tangents of one side (their outward normals in (A, H)).
struct GonialSide {
  std::vector<P2> pts;            // the side's vertices projected sagittally
  std::vector<std::size_t> idx;   // their vertex indices
  P2 n_post{0, 0}, n_inf{0, 0};
  bool ok = false;
};

// The gonial tangents of a rounded angle as a cephalometrist draws them
// (docs/landmarks.md step 4; Jacobson 1995), where the
// hull has no long posterior and inferior stretch: the ramus line is laid on
// the posterior border of the ramus, touching it below the condyle and at
// the angle; the mandibular line is laid on the lower border, touching it
// near the chin and at the angle. On the convex hull of the sagittal
// projection each is the hull edge that bridges the middle of its border:
//   ramus line: the posterior-facing edge of the side's hull (|U| beyond
//   kSideFraction) crossing the height kRamusMiddle of the side's height
//   below its top (condylion, or the side's highest point without one);
//   mandibular line: the lower edge of the half mandible's hull (s U > 0,
//   chin included) crossing kBodyMiddle of the way from menton to the
//   half's most posterior point.
// Adult sides are 75-100 mm high and halves 85-100 mm long, so these are
// about 27 mm below condylion (between the condylar neck and the angle) and
// 30 mm behind menton (the molars), as fractions scaling with a child's
// mandible. Which edge is used moves only when a hull vertex crosses that
// height or depth: a straight or concave border is one edge from end to
// end there, and a convex one has short edges of nearly the same
// direction. (The best two-chord fit of the border used before,
// border_chords, has near-equal minima on such borders: openkbp-train
// pt_141 mirrored moved Go_R 23.7 mm.)
constexpr double kRamusMiddle = 0.3;
constexpr double kBodyMiddle = 0.35;

// The hull edge of `hl` (counter-clockwise) crossing the line x = at, where
// x is the edge point's H (along_h) or A, whose outward normal faces `facing`
// (its component along that side's axis is positive); false when none.
bool crossing_edge(const std::vector<P2>& hl, bool along_h, double at, const P2& facing, P2* normal) {
  for (std::size_t i = 0; i < hl.size(); ++i) {
    const P2 &p = hl[i], &q = hl[(i + 1) % hl.size()];
    const double xp = along_h ? p.h : p.a, xq = along_h ? q.h : q.a;
    if ((xp - at) * (xq - at) > 0 || xp == xq) continue;
    const double da = q.a - p.a, dh = q.h - p.h, len = std::hypot(da, dh);
    const P2 out{dh / len, -da / len};
    if (out.a * facing.a + out.h * facing.h <= 0) continue;
    *normal = out;
    return true;
  }
  return false;
}

// The spanning tangents of side s (above) from its hull, condylion's height
// top_h (NaN when missing) and menton's antero-posterior position me_a.
BorderPair spanning_tangents(const Frame& f, double s, const std::vector<P2>& side_hull, double top_h, double me_a) {
  const auto &U = f.U, &A = f.A, &H = f.H;
  BorderPair out;
  if (!std::isfinite(me_a) || side_hull.size() < 3) return out;
  double h_lo = kInf, h_hi = -kInf, a_back = -kInf;  // the side's height: its hull's
  for (const P2& q : side_hull) h_lo = std::min(h_lo, q.h), h_hi = std::max(h_hi, q.h);
  std::vector<P2> half;
  for (std::size_t v = 0; v < U.size(); ++v)
    if (s * U[v] > 0) a_back = std::max(a_back, A[v]), half.push_back({A[v], H[v]});
  const double top = std::isfinite(top_h) ? top_h : h_hi;
  if (!(top > h_lo) || !(a_back > me_a)) return out;
  const bool post = crossing_edge(side_hull, true, top - kRamusMiddle * (top - h_lo), P2{1, 0}, &out.n_post);
  const bool inf = crossing_edge(hull(half), false, me_a + kBodyMiddle * (a_back - me_a), P2{0, -1}, &out.n_inf);
  // A gonial angle: the ramus line faces more posteriorly than the
  // mandibular line, and they are not near parallel.
  out.ok = post && inf && -out.n_post.h < -out.n_inf.h && out.n_post.a * out.n_inf.a + out.n_post.h * out.n_inf.h < std::cos(20 * M_PI / 180);
  return out;
}

// The two gonial tangents from the convex hull `hl` of a side's sagittal
// projection (gonial_tangents): outward normals and lengths of its longest
// posterior- and inferior-facing straight stretches.
struct StretchPair {
  P2 n_post{0, 0}, n_inf{0, 0};
  double len_post = 0, len_inf = 0;
};
StretchPair longest_stretches(const std::vector<P2>& hl, double h_mid) {
  struct Edge {
    double len;
    P2 out;
    double top;  // the higher end's H
  };
  std::vector<Edge> post, inf;
  const double cone = std::cos(kBorderConeDeg * M_PI / 180);
  for (std::size_t i = 0; i < hl.size(); ++i) {
    const P2 &p = hl[i], &q = hl[(i + 1) % hl.size()];
    const double da = q.a - p.a, dh = q.h - p.h, len = std::hypot(da, dh);
    if (len < 1e-9) continue;
    const P2 out{dh / len, -da / len};  // outward normal of a counter-clockwise hull
    // Hull edges facing posterior / inferior (within 50 degrees), each the
    // nearer of the two: a ramus tilted back 18 degrees (gonial angle
    // opened 8) has a lower posterior border facing 40 degrees below
    // posterior, and in both cones it paired with the upper posterior
    // border, whose bisector put gonion half-way up the ramus. Within
    // kClassOverlapDeg of 45 degrees an edge may be either, so that a facet
    // there (the angle's own) does not change its class, and the pair, with
    // a fraction of a degree of the frame (openkbp-train pt_172 mirrored:
    // Go_R 5.1 mm).
    const double below = std::atan2(-out.h, out.a) * 180 / M_PI;  // degrees below posterior
    if (out.a > cone && below <= 45 + kClassOverlapDeg) post.push_back({len, out, std::max(p.h, q.h)});
    if (-out.h > cone && below >= 45 - kClassOverlapDeg) inf.push_back({len, out, std::max(p.h, q.h)});
  }
  // A border that bends less than kStraightBorderDeg is one straight
  // stretch: its tangent is the chord of its hull edges within that of the
  // edge (length-weighted mean normal; on a convex hull they are
  // contiguous), not whichever of two nearly equal edges is a little longer,
  // and its length is the stretch's (the sum of those edges' lengths): a
  // border bending 8 degrees is one hull edge or two, as the staircase of
  // the surface happens to fall (openkbp-train pt_172 and its mirror image).
  auto stretch = [&](const std::vector<Edge>& edges, const P2& n, P2* chord) {
    P2 m{0, 0};
    double length = 0;
    for (const Edge& e : edges)
      if (e.out.a * n.a + e.out.h * n.h >= std::cos(kStraightBorderDeg * M_PI / 180)) m.a += e.len * e.out.a, m.h += e.len * e.out.h, length += e.len;
    const double l = std::hypot(m.a, m.h);
    *chord = l > 1e-9 ? P2{m.a / l, m.h / l} : n;
    return length;
  };
  // The pair of distinct stretches, one of each, with the largest total
  // length (taking the longest of each separately let one edge at ~45
  // degrees be both when the head was pitched 20 degrees: a concave
  // posterior border's single long edge faces 24 degrees below posterior).
  // The ramus line touches the posterior border below the condyle: its
  // stretch reaches the upper half of the side (h_mid), which a facet of
  // the angle does not (openkbp-train pt_141: a 35 mm facet at 34 degrees,
  // as long as the ramus border).
  // (The pair is chosen by its edges' lengths, the chord taken about them:
  // chosen by the stretches' lengths, each about a different edge of a
  // gently bulging border, the phantoms' ramus series read 2.57 / 4.69 mm
  // for 2 / 4 mm.)
  const Edge* bp = nullptr;
  const Edge* bq = nullptr;
  for (const Edge& p : post) {
    if (p.top < h_mid) continue;
    for (const Edge& q : inf) {
      if (-p.out.h >= -q.out.h) continue;  // the posterior one less inferior than the inferior one
      if (!bp || p.len + q.len > bp->len + bq->len) bp = &p, bq = &q;
    }
  }
  StretchPair best;
  if (bp) best.len_post = stretch(post, bp->out, &best.n_post), best.len_inf = stretch(inf, bq->out, &best.n_inf);
  return best;
}

// Gonion, first pass (detect() step 4): the posterior ramus tangent and the
// inferior border tangent of side s (+1 left, -1 right), from the convex
// hull of the side's sagittal projection: its longest posterior- and
// inferior-facing straight stretches, or, where the borders are rounded,
// the edges bridging their middles (spanning_tangents). top_h: condylion's
// height (NaN when missing), me_a: menton's antero-posterior position.
GonialSide gonial_tangents(const Frame& f, double s, double top_h, double me_a) {
  const auto& V = f.V;
  const auto &U = f.U, &A = f.A, &H = f.H;
  auto on_side = [&](std::size_t v) { return s * U[v] > kSideFraction * f.umax; };
  GonialSide gs;
  for (std::size_t v = 0; v < V.size(); ++v)
    if (on_side(v)) {
      gs.pts.push_back({A[v], H[v]});
      gs.idx.push_back(v);
    }
  const std::vector<P2> hl = hull(gs.pts);
  double h_lo = kInf, h_hi = -kInf;
  for (const P2& q : gs.pts) h_lo = std::min(h_lo, q.h), h_hi = std::max(h_hi, q.h);
  const StretchPair sp = longest_stretches(hl, 0.5 * (h_lo + h_hi));
  gs.n_post = sp.n_post, gs.n_inf = sp.n_inf;
  // Both tangents must be long enough to be borders, not facets: a fifth
  // of the side's height (15 mm on an adult's ~73 mm; a fixed 15 mm lost
  // both gonia of a child's mandible, scale 0.7: posterior tangent 14.4 mm
  // of a 51 mm side), and never under 5 mm (no side, a sliver of one).
  const double min_tangent = gs.pts.empty() ? kInf : std::max(5.0, 0.2 * (h_hi - h_lo));
  gs.ok = sp.len_post > min_tangent && sp.len_inf > min_tangent;
  if (!gs.ok) {
    // A convex (rounded) ramus or lower border has no single long hull
    // edge: the tangents are then the hull edges bridging the middle of
    // each border (spanning_tangents); without menton, the best two-chord
    // fit of the hull's posterior-inferior arc (border_chords).
    BorderPair bp = spanning_tangents(f, s, hl, top_h, me_a);
    const bool spanning = bp.ok;
    if (!bp.ok) bp = border_chords(hl, std::cos(kBorderConeDeg * M_PI / 180), min_tangent);
    if (std::getenv("MANDISYM_DEBUG_LANDMARKS"))
      std::fprintf(stderr, "gonion: side %+.0f: hull stretches %.1f / %.1f mm under %.1f: %s\n", s, sp.len_post, sp.len_inf, min_tangent,
                   spanning ? "spanning edges" : bp.ok ? "two chords" : "none");
    if (bp.ok) gs.n_post = bp.n_post, gs.n_inf = bp.n_inf, gs.ok = true;
  }
  return gs;
}

// How far (mm) vertex v lies in front of the posterior border of side s's
// ramus: the most posterior extent of the side's surface from kBorderBandMm[0]
// to kBorderBandMm[1] below v (below the processes and the sigmoid notch,
// above the angle; where a ramus leans back, its lower part). The hull edges
// of gonial_tangents do not serve: with the condylar process missing, the
// longest posterior-facing edge runs from the coronoid tip down to the border
// and the coronoid lies on it. NaN when the side has no surface there.
constexpr double kBorderBandMm[2] = {10.0, 40.0};
double depth_from_posterior_border(const Frame& f, double s, std::size_t v) {
  const auto &U = f.U, &A = f.A, &H = f.H;
  double back = -kInf;
  for (std::size_t i = 0; i < U.size(); ++i) {
    const double below = H[v] - H[i];
    if (s * U[i] > kSideFraction * f.umax && below >= kBorderBandMm[0] && below <= kBorderBandMm[1]) back = std::max(back, A[i]);
  }
  return back > -kInf ? back - A[v] : std::numeric_limits<double>::quiet_NaN();
}

// Where vertex v stands over the side's cross-section kSectionBelowMm below
// it: 0 over its front, 1 over its back (antero-posteriorly, sections
// 3 mm thick); NaN without a section.
constexpr double kSectionBelowMm = 10.0;
double position_over_section(const Frame& f, double s, std::size_t v) {
  const auto &U = f.U, &A = f.A, &H = f.H;
  double lo = kInf, hi = -kInf;
  for (std::size_t i = 0; i < U.size(); ++i)
    if (s * U[i] > kSideFraction * f.umax && std::abs(H[v] - kSectionBelowMm - H[i]) <= 1.5) lo = std::min(lo, A[i]), hi = std::max(hi, A[i]);
  return hi - lo > 1e-9 ? (A[v] - lo) / (hi - lo) : std::numeric_limits<double>::quiet_NaN();
}

// Gonion, second pass: the cephalometric construction (constructed gonion;
// Jacobson 1995). Each side's two tangents are laid on its outline where it
// is outermost (support lines, as a ruler on a lateral film) and meet at T;
// the bisector of their angle is followed from T into the bone, and gonion
// is the first surface point the side's sagittal projection has on it.
// Following the bisector, rather than taking the surface point extreme
// along it, keeps gonion in place on a rounded or flat angle: there the
// border runs across the bisector, so a small change of shape moves the
// crossing little, while the extreme point slides along the border (8.3 mm
// between two storages of the same scan, openkbp-train pt_101).
//
// The first crossing of side gs's surface with its bisector: where the
// mesh's edges cross the plane through the bisector along U (interpolated,
// so the staircase of the vertices does not move it), the crossings within
// kPlateauTolMm of the first; of those, the middle one across the border
// (the median in U). NaN when none.
Vec3 bisector_crossing(const Frame& f, const std::vector<std::array<int, 3>>& faces, const GonialSide& gs) {
  const P2 &np = gs.n_post, &ni = gs.n_inf;
  const double det = np.a * ni.h - np.h * ni.a, bl = std::hypot(np.a + ni.a, np.h + ni.h);
  if (std::abs(det) < 1e-6 || bl < 1e-9) return std::numeric_limits<double>::quiet_NaN() * Vec3{1, 1, 1};
  double cp = -kInf, ci = -kInf;  // the support lines n . p = c
  for (const P2& q : gs.pts) cp = std::max(cp, np.a * q.a + np.h * q.h), ci = std::max(ci, ni.a * q.a + ni.h * q.h);
  const P2 T{(cp * ni.h - np.h * ci) / det, (np.a * ci - cp * ni.a) / det};
  const P2 b{(np.a + ni.a) / bl, (np.h + ni.h) / bl};  // outward
  if (std::getenv("MANDISYM_DEBUG_LANDMARKS"))  // the tangents (docs/landmarks.md)
    std::fprintf(stderr, "gonion: n_post %.3f %.3f n_inf %.3f %.3f T %.2f %.2f\n", np.a, np.h, ni.a, ni.h, T.a, T.h);
  std::vector<char> on(f.V.size(), 0);
  for (std::size_t v : gs.idx) on[v] = 1;
  auto across = [&](int v) { return (f.A[v] - T.a) * b.h - (f.H[v] - T.h) * b.a; };
  auto depth = [&](const Vec3& p) { return -(dot(p - f.origin, f.e_ap) - T.a) * b.a - (dot(p - f.origin, f.e_si) - T.h) * b.h; };
  std::vector<std::pair<double, Vec3>> hits;  // (depth, point)
  for (const auto& tri : faces)
    for (int e = 0; e < 3; ++e) {
      const int u = tri[e], w = tri[(e + 1) % 3];
      if (u > w || !on[u] || !on[w]) continue;  // each edge once (from the face where u < w)
      const double su = across(u), sw = across(w);
      if ((su < 0) == (sw < 0)) continue;
      const Vec3 p = f.V[u] + (su / (su - sw)) * (f.V[w] - f.V[u]);
      hits.push_back({depth(p), p});
    }
  if (hits.empty()) return std::numeric_limits<double>::quiet_NaN() * Vec3{1, 1, 1};
  double first = kInf;
  for (const auto& h : hits) first = std::min(first, h.first);
  std::vector<std::pair<double, Vec3>> rim;  // (U, point) of the first crossings
  for (const auto& h : hits)
    if (h.first <= first + kPlateauTolMm) rim.push_back({dot(h.second - f.origin, f.e_ml), h.second});
  // The median in U; of an even count the mean of the two middle ones (two
  // neighbouring crossings), so that a mirrored surface gives the mirrored
  // point.
  std::sort(rim.begin(), rim.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
  const std::size_t m = rim.size() / 2;
  return rim.size() % 2 ? rim[m].second : 0.5 * (rim[m - 1].second + rim[m].second);
}

void place_gonia(const Frame& f, const std::vector<std::array<int, 3>>& faces, const GonialSide (&gonial)[2], LandmarkSet& out) {
  for (int si = 0; si < 2; ++si) {
    if (!gonial[si].ok) continue;
    const Vec3 go = bisector_crossing(f, faces, gonial[si]);
    if (std::isfinite(go[0])) out.set(si == 0 ? "Go_L" : "Go_R", go);
  }
}

// The symphysis's midline (docs/landmarks.md, step 5): menton and pogonion
// are midline points, and the symphysis's lower border and labial profile
// are flat across it (within 0.5-1 mm over +-15 mm on the Visible Human
// female), so their lowest and most anterior points are ill-conditioned
// laterally: openkbp-train pt_92 resampled (turned 10 degrees and back)
// moved "the lowest point" 9.8 mm across the chin. The midline is where the
// arch's outer walls are: the lateral middle of the surface in slabs
// kArchSlabMm thick at kArchDepthsMm behind the chin's front, at the chin's
// level (up to kChinLevelMm above the symphysis's lowest point, below the
// tooth roots). It follows a deviated chin (the walls move with it) and
// mirrors with the scan. Returns U; 0 (the
// symmetry plane) when no slab has surface on both sides of it.
constexpr double kArchDepthsMm[3] = {6.0, 9.0, 12.0};
constexpr double kArchSlabMm = 3.0;
constexpr double kChinLevelMm = 15.0;  // about half the symphysis's height (~30 mm)
double symphysis_midline(const Frame& f, double afront, double hlow) {
  const auto &U = f.U, &A = f.A, &H = f.H;
  double sum = 0;
  int used = 0;
  for (double d : kArchDepthsMm) {
    double lo = kInf, hi = -kInf;
    for (std::size_t v = 0; v < U.size(); ++v)
      if (std::abs(A[v] - afront - d) <= 0.5 * kArchSlabMm && H[v] <= hlow + kChinLevelMm) lo = std::min(lo, U[v]), hi = std::max(hi, U[v]);
    if (lo < 0 && hi > 0) sum += 0.5 * (lo + hi), ++used;
  }
  return used > 0 ? sum / used : 0.0;
}

// The height of the surface's lowest crossing of the vertical line at
// (u, a) in the frame (the line along e_si): the triangles whose (U, A)
// projection holds the point, interpolated; NaN when none does (a hole).
double lowest_crossing(const Frame& f, const std::vector<std::array<int, 3>>& faces, double u, double a) {
  double lowest = kInf;
  for (const auto& t : faces) {
    const auto i = static_cast<std::size_t>(t[0]), j = static_cast<std::size_t>(t[1]), k = static_cast<std::size_t>(t[2]);
    const double u1 = f.U[j] - f.U[i], a1 = f.A[j] - f.A[i], u2 = f.U[k] - f.U[i], a2 = f.A[k] - f.A[i];
    const double det = u1 * a2 - u2 * a1;
    if (std::abs(det) < 1e-12) continue;  // a triangle seen edge-on from below
    const double pu = u - f.U[i], pa = a - f.A[i];
    const double s = (pu * a2 - u2 * pa) / det, t2 = (u1 * pa - pu * a1) / det;
    if (s < 0 || t2 < 0 || s + t2 > 1) continue;
    lowest = std::min(lowest, f.H[i] + s * (f.H[j] - f.H[i]) + t2 * (f.H[k] - f.H[i]));
  }
  return lowest < kInf ? lowest : std::numeric_limits<double>::quiet_NaN();
}

// 4. Midline: menton = lowest point of the symphysis, pogonion = most
//    anterior point of the chin, both on the symphysis's midline. The
//    symphysis is the front of the midline band (within 20 mm of its most
//    anterior point), so that a pitched head does not move menton back along
//    the flat lower border.
constexpr double kMidlineStripMm = 3.0;  // half-width of the strip about the symphysis's midline
void place_midline(const Frame& f, const std::vector<std::array<int, 3>>& faces, double apex_radius_mm, LandmarkSet& out) {
  const auto& V = f.V;
  const auto &U = f.U, &A = f.A, &H = f.H;
  const double umax = f.umax;
  const Vec3 &e_ap = f.e_ap, &e_si = f.e_si;
  std::vector<int> band;
  double afront = kInf;
  for (std::size_t v = 0; v < V.size(); ++v)
    if (std::abs(U[v]) < 0.12 * umax && A[v] < 0) {
      band.push_back(static_cast<int>(v));
      afront = std::min(afront, A[v]);
    }
  double hlow = kInf;
  for (int v : band)
    if (A[static_cast<std::size_t>(v)] < afront + 20.0) hlow = std::min(hlow, H[static_cast<std::size_t>(v)]);
  const double umid = band.empty() ? 0.0 : symphysis_midline(f, afront, hlow);
  // The strip about the midline, its front 20 mm the symphysis.
  std::vector<int> strip, sym;
  for (std::size_t v = 0; v < V.size(); ++v)
    if (std::abs(U[v] - umid) < kMidlineStripMm && A[v] < 0) strip.push_back(static_cast<int>(v));
  for (int v : strip)
    if (A[static_cast<std::size_t>(v)] < afront + 20.0) sym.push_back(v);
  const int me = plateau(V, sym, [&](std::size_t v) { return -H[v]; }, kPlateauTolMm);
  if (me >= 0) {
    // The lower border is nearly flat antero-posteriorly: a quadratic apex
    // there is ill-conditioned, and any one vertex of the flat bottom is
    // where the triangulation happened to put it (the same scan mirrored
    // moved it 0.9 mm). Menton is the centre of the bottom — the mean of the
    // vertices within kPlateauTolMm of the lowest — on the midline, on the
    // surface: where the vertical line there leaves the bone at the bottom
    // (the strip's lowest vertex can lie up to 3 mm to one side, and the
    // border there 1-2.5 mm lower than on the midline on ~4 mm scans).
    double amean = 0, hmin = kInf;
    int cnt = 0;
    for (int v : sym) hmin = std::min(hmin, H[static_cast<std::size_t>(v)]);
    for (int v : sym)
      if (H[static_cast<std::size_t>(v)] <= hmin + kPlateauTolMm) amean += A[static_cast<std::size_t>(v)], ++cnt;
    amean /= cnt;
    const double hsurf = lowest_crossing(f, faces, umid, amean);
    out.set("Me", f.origin + umid * f.e_ml + amean * e_ap + (std::isnan(hsurf) ? hmin : hsurf) * e_si);
    const double hme = H[static_cast<std::size_t>(me)];
    // The chin lies below the alveolar process and the incisors: within
    // 18 mm of menton, and below B point (the deepest point of the labial
    // concavity) when the profile has one: in a head extended in the
    // scanner the alveolar process otherwise comes further forward.
    const double top = std::min(hme + 18.0, b_point_height(strip, A, H, hme));
    std::vector<int> chin;
    for (int v : strip)
      if (H[static_cast<std::size_t>(v)] < top) chin.push_back(v);
    const int pog = plateau(V, chin, [&](std::size_t v) { return -A[v]; }, kPlateauTolMm);
    if (pog >= 0) out.set("Pog", refine_extreme(V, pog, f.e_ml, e_si, e_ap, -1.0, apex_radius_mm));
  }
}

// 5. A landmark at the edge of a truncated scan is not the anatomical point,
// nor one whose neighbourhood (the apex radius its extreme point is refined
// over) reaches the scan's edge: the bone there is cut (a gonion 2 mm inside
// a lateral cut was the middle of what was left of the angle, 2.7 mm off).
const char* const kAtTheEdge = "it lies at the edge of the scan: the mandible is cut there (truncated), so its extreme point is not in the scan";

// Returns the mesh vertices on the scan's edge.
std::vector<Vec3> drop_landmarks_at_edge(const Mesh& mesh, const Geometry& scan_grid, double apex_radius_mm, LandmarkSet& landmarks,
                                         std::map<std::string, std::string>& why) {
  const Geometry& sg = scan_grid;
  auto at_edge = [&](const Vec3& p) {
    const Vec3 q = sg.lps_to_index(p);
    bool edge = false;
    for (int a = 0; a < 3; ++a) edge |= q[a] < 1.5 || q[a] > static_cast<double>(sg.size[a]) - 2.5;
    return edge;
  };
  std::vector<Vec3> cut;  // mesh vertices on the scan's edge
  for (const Vec3& v : mesh.vertices)
    if (at_edge(v)) cut.push_back(v);
  LandmarkSet kept;
  for (const auto& [name, p] : landmarks.points) {
    bool edge = at_edge(p);
    for (std::size_t i = 0; i < cut.size() && !edge; ++i) edge = norm(cut[i] - p) <= apex_radius_mm;
    if (edge)
      why[name] = kAtTheEdge;
    else
      kept.set(name, p);
  }
  landmarks = kept;
  return cut;
}

// Which ends of the head a truncated scan cuts the mandible at (Result::cut_at):
// each face of the scanned grid that mesh vertices lie on (within
// drop_landmarks_at_edge's 1.5 voxels), named by the head-frame axis its
// outward normal is nearest to (e_ap points to the back, e_ml to the left).
std::vector<std::string> cut_at(const std::vector<Vec3>& cut, const Geometry& sg, const Vec3& e_ml, const Vec3& e_ap,
                                const Vec3& e_si) {
  bool face[6] = {false, false, false, false, false, false};
  for (const Vec3& v : cut) {
    const Vec3 q = sg.lps_to_index(v);
    for (int a = 0; a < 3; ++a) {
      face[2 * a] = face[2 * a] || q[a] < 1.5;
      face[2 * a + 1] = face[2 * a + 1] || q[a] > static_cast<double>(sg.size[a]) - 2.5;
    }
  }
  std::vector<std::string> out;
  for (int f = 0; f < 6; ++f) {
    if (!face[f]) continue;
    const int a = f / 2;
    const double sign = f % 2 ? 1.0 : -1.0;
    const Vec3 n = sign * Vec3{sg.direction[a], sg.direction[3 + a], sg.direction[6 + a]};
    const double si = dot(n, e_si), ap = dot(n, e_ap), ml = dot(n, e_ml);
    const char* name = std::abs(si) >= std::abs(ap) && std::abs(si) >= std::abs(ml) ? (si > 0 ? "top" : "bottom")
                       : std::abs(ap) >= std::abs(ml)                               ? (ap > 0 ? "back" : "front")
                                                                                    : (ml > 0 ? "left side" : "right side");
    if (std::find(out.begin(), out.end(), name) == out.end()) out.push_back(name);
  }
  return out;
}

}  // namespace

Plane mandible_plane(const Mesh& mesh) {
  Vec3 c{0, 0, 0};
  for (const auto& v : mesh.vertices) c = c + v;
  c = (1.0 / static_cast<double>(std::max<std::size_t>(1, mesh.vertices.size()))) * c;
  reference::Options ro;
  ro.icp_rounds = 8;
  ro.icp_cauchy_mm = 0;  // a frame for labelling: the Huber fit is enough
  // The mirror-ICP converges from about 20 degrees off; a head turned 45
  // degrees in the scanner (its plane 45 degrees from the scan's x axis) went
  // elsewhere and left no left/right pair. So the start: of the planes
  // through the centroid turned about the scan's vertical axis in 10 degree
  // steps up to 60, the one whose reflection of a vertex sample lies closest
  // to the surface (mean distance); the scan's x axis unless one more than 15
  // degrees away is better (heads within that turn start as before).
  Vec3 start{1, 0, 0};
  std::unique_ptr<geometry::ClosestPointIndex> index;  // built once, shared with the ICP
  if (mesh.faces.size() > 100) {
    index = std::make_unique<geometry::ClosestPointIndex>(mesh);
    const std::size_t step = std::max<std::size_t>(1, mesh.vertices.size() / 400);
    double best = std::numeric_limits<double>::infinity();
    int best_deg = 0;
    for (int deg = -60; deg <= 60; deg += 10) {
      const double a = deg * M_PI / 180.0;
      const Plane pl{c, Vec3{std::cos(a), std::sin(a), 0}};
      double sum = 0;  // the same sample at every angle: sums compare as means
      for (std::size_t i = 0; i < mesh.vertices.size(); i += step) sum += index->closest(pl.reflect(mesh.vertices[i])).distance;
      if (sum < best) best = sum, best_deg = deg;
    }
    if (std::abs(best_deg) > 15) start = {std::cos(best_deg * M_PI / 180.0), std::sin(best_deg * M_PI / 180.0), 0};
  }
  Plane pl = reference::refine_plane_on_surface(mesh, Plane{c, start}, ro, nullptr, index.get());
  if (pl.normal[0] < 0) pl.normal = -1.0 * pl.normal;
  pl.point = c - pl.signed_distance(c) * pl.normal;
  return pl;
}

namespace {

// Why a landmark is missing (docs/landmarks.md, "Missing landmarks").
const char* const kNoExtremity = "the surface has no geodesic extremity on this side above the body (the ramus is cut or not segmented)";
const char* const kCondyleNotSegmented =
    "the condyle is not on the segmented surface: the ramus's process lies more than 15 mm in front of its posterior "
    "border, over its front, where the coronoid is (a condylar head joined to the skull base at this voxel size is left "
    "out of the mask with it, or the scan ends below it)";
const char* const kCondyleStump =
    "the condyle is not on the segmented surface: the ramus's posterior process ends more than 15 mm below the coronoid tip, "
    "a condylar process cut short (its head joined to the skull base at this voxel size and left out of the mask), not "
    "condylion";
const char* const kNoSecondProcess =
    "one process only: no geodesic extremity of this ramus lies at least 10 mm in front of or behind its highest one within 30 mm of "
    "its height, so the coronoid process is not separate from the condyle on the surface (thin or lost at this voxel size, joined "
    "to the zygomatic arch, or filling the sigmoid notch)";

// Every landmark not found gets its reason (detect() step 6). cut_side[s]:
// the surface of side s (0 left, 1 right) reaches the scan's edge; a
// bilateral landmark missing there is put down to the cut first.
void explain_missing(const GonialSide (&gonial)[2], const bool (&cut_side)[2], Result& r) {
  for (const auto& name : landmark_names()) {
    if (r.landmarks.has(name)) {
      r.why_missing.erase(name);
      continue;
    }
    r.missing.push_back(name);
    const bool bilateral = name.size() > 2 && name[name.size() - 2] == '_';
    const bool on_cut_side = bilateral && cut_side[name.back() == 'L' ? 0 : 1];
    if (on_cut_side && r.why_missing[name] != kAtTheEdge)
      r.why_missing[name] = std::string("this side of the mandible is cut by the edge of the scan (truncated)") +
                            (r.why_missing[name].empty() ? "" : ", and " + r.why_missing[name]);
    if (!r.why_missing[name].empty()) continue;
    if (name == "Go_L" || name == "Go_R")
      r.why_missing[name] = gonial[name == "Go_L" ? 0 : 1].ok
                                ? "the bisector of this side's ramus and body border tangents meets no surface (the tangents are "
                                  "parallel)"
                                : "the posterior ramus border and the inferior body border of this side were not found (no convex-hull "
                                  "edges facing posterior and inferior in the sagittal projection)";
    else if (name == "Me" || name == "Pog")
      r.why_missing[name] = "no symphysis: no surface near the symmetry plane in front of the rami";
    else
      r.why_missing[name] = "not found on the surface";
  }
}

// The condylar and coronoid processes of side s (+1 left, -1 right) among
// the geodesic extremities (detect() step 3): their apex vertices (`apex`:
// the highest point near an extremity), -1 when not found, with the reason.
struct Processes {
  int co = -1, cr = -1;
  const char* why_co = nullptr;
  const char* why_cr = nullptr;
};
// Whether vertex v lies nearer, antero-posteriorly, to the placed atlas's
// condyle top than to its coronoid top on side s (Options::atlas_condyles);
// false without the atlas. The similarity fit places them within a few
// millimetres; they stand 25 mm apart (atlas::process_tops).
bool nearer_the_atlas_condyle(const Frame& f, double s, std::size_t v, const Options& opt) {
  auto on_side = [&](const std::vector<Vec3>& tops) -> std::optional<double> {
    for (const Vec3& t : tops)
      if (s * dot(t - f.origin, f.e_ml) > 0) return dot(t - f.origin, f.e_ap);
    return std::nullopt;
  };
  const std::optional<double> co = on_side(opt.atlas_condyles), cr = on_side(opt.atlas_coronoids);
  return co && cr && std::abs(f.A[v] - *co) < std::abs(f.A[v] - *cr);
}

Processes condyle_and_coronoid(const Frame& f, double s, const std::vector<int>& ext, const std::function<int(int)>& apex,
                               const std::function<int(int, int)>& climb, const Options& opt) {
  const auto &U = f.U, &A = f.A, &H = f.H;
  Processes out;
  auto on_side = [&](std::size_t v) { return s * U[v] > kSideFraction * f.umax; };
  std::vector<int> top;
  for (int e : ext)
    if (on_side(static_cast<std::size_t>(e))) top.push_back(e);
  std::sort(top.begin(), top.end(), [&](int a, int b) { return H[static_cast<std::size_t>(a)] > H[static_cast<std::size_t>(b)]; });
  if (top.empty()) {
    out.why_co = out.why_cr = kNoExtremity;
    return out;
  }
  // Two processes: distinct antero-posteriorly (> kProcessSeparationMm), at
  // a similar height (< kProcessHeightMm apart). The highest extremity and
  // the highest other one that forms such a pair with it; the posterior of
  // the two is the condyle. (Only the second highest was tried before: where
  // the coronoid is thin at 4 mm voxels a molar cusp ranked second and the
  // pair failed.)
  // The pair must still be distinct at its apexes: an extremity on the
  // front of a condylar neck climbs to the condyle's top (openkbp-train
  // pt_30, right: the "coronoid tip" 9 mm from condylion, on its head).
  const int a0 = apex(top[0]);
  int co = a0, cr = -1, co_ext = top[0];
  for (std::size_t k = 1; k < top.size(); ++k) {
    const std::size_t p = static_cast<std::size_t>(top[0]), q = static_cast<std::size_t>(top[k]);
    if (std::abs(A[p] - A[q]) <= kProcessSeparationMm || std::abs(H[p] - H[q]) >= kProcessHeightMm) continue;
    const int aq = apex(top[k]);
    if (std::abs(A[static_cast<std::size_t>(a0)] - A[static_cast<std::size_t>(aq)]) <= kProcessSeparationMm) continue;
    co = A[p] > A[q] ? a0 : aq;
    cr = A[p] > A[q] ? aq : a0;
    co_ext = A[p] > A[q] ? top[0] : top[k];
    break;
  }
  // Condylion is the condyle's top, climbed to from its extremity.
  const int apex_co = co;
  co = climb(co, co_ext);
  if (std::getenv("MANDISYM_DEBUG_LANDMARKS")) {
    const auto e = static_cast<std::size_t>(co_ext), a = static_cast<std::size_t>(apex_co), t = static_cast<std::size_t>(co);
    std::fprintf(stderr, "condyle s=%+.0f: extremity A %.1f H %.1f, apex H %.1f, climbed to A %.1f H %.1f\n", s, A[e], H[e], H[a], A[t],
                 H[t]);
  }
  const std::size_t c = static_cast<std::size_t>(co);
  if (std::getenv("MANDISYM_DEBUG_LANDMARKS"))
    std::fprintf(stderr, "condyle s=%+.0f: %s, depth from the posterior border %.1f mm, over its section at %.2f, %s\n", s,
                 cr >= 0 ? "a pair" : "one process", depth_from_posterior_border(f, s, c), position_over_section(f, s, c),
                 opt.atlas_condyles.empty() ? "no atlas" : (nearer_the_atlas_condyle(f, s, c, opt) ? "nearer the atlas's condyle" : "nearer the atlas's coronoid"));
  // The condyle caps the posterior border: a process more than
  // kCondyleMaxDepthMm in front of it, over the front half of the ramus
  // (kCoronoidFrontFraction), is the coronoid, unless it stands nearer the
  // placed atlas's condyle than its coronoid. Nor is a stump far below the
  // coronoid condylion (kCoronoidAboveCondyleMaxMm).
  if (depth_from_posterior_border(f, s, c) > kCondyleMaxDepthMm && position_over_section(f, s, c) < kCoronoidFrontFraction &&
      !nearer_the_atlas_condyle(f, s, c, opt)) {
    out.why_co = kCondyleNotSegmented;
    out.cr = co;
    return out;
  }
  if (cr >= 0 && H[static_cast<std::size_t>(cr)] - H[c] > kCoronoidAboveCondyleMaxMm) {
    out.why_co = kCondyleStump;
    out.cr = cr;
    return out;
  }
  out.co = co, out.cr = cr;
  if (cr < 0) out.why_cr = kNoSecondProcess;
  return out;
}

}  // namespace

Result detect(const Mesh& mesh, const Options& opt) {
  Result r;
  r.method = "geodesic extremities + symmetry-plane frame";
  const auto& V = mesh.vertices;
  const std::size_t n = V.size();
  if (n < 100 || mesh.faces.empty()) {
    for (const auto& name : landmark_names()) r.missing.push_back(name);
    r.warnings.push_back("landmarks: the surface is too small");
    return r;
  }
  // 1. Frame: the mandible's own symmetry plane (yaw, roll) and the head's
  //    superior direction (pitch, when given).
  r.plane = opt.plane ? *opt.plane : mandible_plane(mesh);
  const Frame f = frame_of(V, r.plane, opt.superior);
  const Vec3 &e_ml = f.e_ml, &e_ap = f.e_ap, &e_si = f.e_si;
  const auto& H = f.H;

  // 2. Geodesic extremities (METHOD.md §2).
  DebugLap lap("MANDISYM_DEBUG_LANDMARKS", "landmarks");
  const Graph g = geometry::edge_graph(mesh);
  const std::vector<double> agd = average_geodesic_distance(g, n, opt.agd_samples);
  lap("  geodesic distances");
  const std::vector<int> ext = extremities(g, agd, opt.extremity_radius_mm);
  lap("  extremities");
  for (int e : ext) r.extremities.push_back(V[static_cast<std::size_t>(e)]);
  std::vector<double> scratch(n, kInf);
  auto highest_within = [&](int seed) {
    return plateau(V, ball(g, seed, opt.process_radius_mm, scratch), [&](std::size_t v) { return H[v]; }, kPlateauTolMm);
  };
  // The climb to the process's top (kProcessClimbSteps) stays in the
  // extremity's geodesic Voronoi cell among the extremities: from a coronoid
  // whose extremity sits low at the notch it must not reach the condyle.
  std::vector<int> cell(n, -1);
  {
    std::vector<double> d(n, kInf);
    geometry::dijkstra(g, ext, kInf, d, &cell);
  }
  auto climb = [&](int v, int extremity) {
    for (int step = 1; step < kProcessClimbSteps && v >= 0; ++step) {
      const int w = highest_within(v);
      if (w < 0 || cell[static_cast<std::size_t>(w)] != cell[static_cast<std::size_t>(extremity)] ||
          H[static_cast<std::size_t>(w)] <= H[static_cast<std::size_t>(v)] + kPlateauTolMm)
        break;
      v = w;
    }
    return v;
  };

  // 3. Per side: the condylar and coronoid processes are the two highest
  //    extremities of the ramus, the condyle the posterior one.
  GonialSide gonial[2];  // [0] left, [1] right
  for (double s : {1.0, -1.0}) {
    const std::string suf = s > 0 ? "_L" : "_R";
    const Processes pr = condyle_and_coronoid(f, s, ext, highest_within, climb, opt);
    if (pr.co >= 0) r.landmarks.set("Co" + suf, refine_extreme(V, pr.co, e_ml, e_ap, e_si, 1.0, opt.apex_radius_mm));
    if (pr.cr >= 0) r.landmarks.set("Cr" + suf, refine_extreme(V, pr.cr, e_ml, e_ap, e_si, 1.0, opt.apex_radius_mm));
    if (pr.why_co) r.why_missing["Co" + suf] = pr.why_co;
    if (pr.why_cr) r.why_missing["Cr" + suf] = pr.why_cr;
  }

  // 5. Midline: menton and pogonion (place_midline); before gonion, whose
  //    tangents on a rounded angle are placed from menton.
  place_midline(f, mesh.faces, opt.apex_radius_mm, r.landmarks);

  // 4. Gonion: the tangents (gonial_tangents), then the constructed gonion
  //    (place_gonia).
  const Vec3* me = r.landmarks.find("Me");
  for (double s : {1.0, -1.0}) {
    const Vec3* co = r.landmarks.find(s > 0 ? "Co_L" : "Co_R");
    const double nan = std::numeric_limits<double>::quiet_NaN();
    gonial[s > 0 ? 0 : 1] = gonial_tangents(f, s, co ? dot(*co - f.origin, e_si) : nan, me ? dot(*me - f.origin, e_ap) : nan);
  }
  place_gonia(f, mesh.faces, gonial, r.landmarks);

  // 6. Landmarks at the edge of a truncated scan are missing (drop_landmarks_at_edge).
  bool cut_side[2] = {false, false};
  if (opt.scan_grid) {
    const std::vector<Vec3> cut = drop_landmarks_at_edge(mesh, *opt.scan_grid, opt.apex_radius_mm, r.landmarks, r.why_missing);
    for (const Vec3& v : cut)
      if (std::abs(dot(v - f.origin, e_ml)) > kSideFraction * f.umax) cut_side[dot(v - f.origin, e_ml) > 0 ? 0 : 1] = true;
    r.cut_at = cut_at(cut, *opt.scan_grid, e_ml, e_ap, e_si);
  }
  explain_missing(gonial, cut_side, r);
  return r;
}

// The head frame from the palatal plane found and the atlas's superior axis
// (HeadFrame's order); the palatal plane is marked not found when rejected.
static HeadFrame choose_head_frame(PalatalPlane& pp, const PalateOptions& po) {
  HeadFrame f;
  if (pp.found && po.atlas_superior) {
    const double c = std::clamp(dot(pp.superior, *po.atlas_superior), -1.0, 1.0);
    const double deg = std::acos(c) * 180.0 / M_PI;
    if (deg > po.max_atlas_deviation_deg) {
      pp.found = false;
      pp.reason = "the nasal-floor line found is " + std::to_string(static_cast<int>(std::lround(deg))) +
                  " degrees from the head's superior axis given by the mandible atlas (more than " +
                  std::to_string(static_cast<int>(std::lround(po.max_atlas_deviation_deg))) + "): rejected";
    }
  }
  if (pp.found) {
    f.superior = pp.superior, f.source = "palatal";
  } else if (po.atlas_superior) {
    f.superior = *po.atlas_superior, f.source = "mandible", f.why = pp.reason;
  } else {
    f.why = pp.reason;
  }
  return f;
}

Result detect_in_head_frame(const Volume& ct, const Mesh& mesh, Options options, const PalateOptions& palate_options,
                            PalatalPlane* palate, HeadFrame* frame) {
  if (mesh.vertices.size() < 100 || mesh.faces.empty()) return detect(mesh, options);
  DebugLap lap("MANDISYM_DEBUG_LANDMARKS", "landmarks");
  options.plane = mandible_plane(mesh);
  lap("mandible plane");
  PalatalPlane pp = find_palatal_plane(ct, mesh, *options.plane, palate_options);
  lap("palatal plane");
  const HeadFrame hf = choose_head_frame(pp, palate_options);
  options.superior = hf.superior;
  std::vector<std::string> notes;
  if (hf.source == "palatal" && pp.floor != "air")
    notes.push_back("landmarks: the palatal plane was fitted to a nasal floor mostly under soft tissue (mucosa or "
                    "secretions rather than air above it): check it on qc_head_frame.png");
  if (hf.source == "mandible")
    notes.push_back("landmarks: palatal plane not used (" + hf.why +
                    "): 'superior' is the head's axis given by the mandible atlas's pose (within ~15 degrees)");
  if (hf.source == "scan_axes")
    notes.push_back("landmarks: palatal plane not found (" + hf.why +
                    "): 'superior' is the scan's axis, so a pitched head moves Me, Pog and Cr");
  Result r = detect(mesh, options);
  lap("detect");
  r.warnings.insert(r.warnings.begin(), notes.begin(), notes.end());
  if (palate) *palate = pp;
  if (frame) *frame = hf;
  return r;
}

}  // namespace ms::landmarks
