// mandisym-atlas-build: builds the mandible atlas (docs/atlas.md) from CT
// scans with mandible masks. Run through scripts/build-atlas.
//
//   mandisym-atlas-build --data DIR --folds CSV --use 1,2,3,4 --out FILE [--iterations N]
//   mandisym-atlas-build --place CT [--hu-offset H] --out PRIOR.nii.gz
//
// --place fits the shipped atlas to one scan (as `mandisym run` does) and
// writes the placed mandible probability on the scan's grid (float, 0-1), to
// inspect a placement or to study the prior outside the pipeline.
//
// DIR/<id>/ct.nii.gz (stored HU + 1000) and DIR/<id>/mask.nii.gz for every id
// of the CSV (id,fold) whose fold is listed in --use.
//
// 1. Each training scan's bone fraction and mask fraction on 3 mm grids.
// 2. Initial poses: translation to each mask's centroid.
// 3. Mean: the bone fraction (context) and the mask fraction (mandible)
//    sampled through each pose onto the atlas grid and averaged, then
//    averaged with their left-right mirror (the training data do not say
//    which side is left).
// 4. Each mask is registered (similarity, NCC) to the mean mandible, the
//    poses' mean scale and pitch are taken out, and step 3 is repeated.
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "atlas/atlas.h"
#include "core/error.h"
#include "io/volume_io.h"

using namespace ms;
using namespace ms::atlas;

namespace {

constexpr double kSpacingMm = 3.0;
constexpr double kBoneHu = 250.0;       // the segmentation's bone threshold (docs/segmentation.md)
constexpr double kHalfBoxMm[3] = {87, 87, 81};  // atlas box half-size: the mandible and ~30 mm of context

struct Case {
  std::string id;
  Field bone, mask_blurred, mask;
  Pose pose;
};

Vec3 centroid(const Mask& m) {
  Vec3 s{0, 0, 0};
  double n = 0;
  for (std::size_t k = 0; k < m.geom.size[2]; ++k)
    for (std::size_t j = 0; j < m.geom.size[1]; ++j)
      for (std::size_t i = 0; i < m.geom.size[0]; ++i)
        if (m.data[m.geom.linear(i, j, k)]) {
          s = s + m.geom.index_to_lps(double(i), double(j), double(k));
          n += 1;
        }
  return (1.0 / n) * s;
}

// Mean of each case's field sampled through its pose; unknown samples skipped
// (unknown_as_zero: counted as 0), then mirrored left-right.
std::vector<float> mean_field(const Grid& g, const std::vector<Case>& cases, Field Case::*which, bool unknown_as_zero) {
  std::vector<float> out(g.count(), 0.0f);
  const long nz = g.n[2];
#pragma omp parallel for schedule(static)
  for (long k = 0; k < nz; ++k)
    for (int j = 0; j < g.n[1]; ++j)
      for (int i = 0; i < g.n[0]; ++i) {
        const Vec3 a{g.origin[0] + g.spacing * i, g.origin[1] + g.spacing * j, g.origin[2] + g.spacing * k};
        double s = 0, n = 0;
        for (const Case& c : cases) {
          const float v = (c.*which).at(c.pose.apply(a));
          if (std::isnan(v)) {
            if (unknown_as_zero) n += 1;
            continue;
          }
          s += v, n += 1;
        }
        out[g.linear(i, j, static_cast<int>(k))] = n > 0 ? static_cast<float>(s / n) : 0.0f;
      }
  std::vector<float> sym(out.size());
  for (int k = 0; k < g.n[2]; ++k)
    for (int j = 0; j < g.n[1]; ++j)
      for (int i = 0; i < g.n[0]; ++i)
        sym[g.linear(i, j, k)] = 0.5f * (out[g.linear(i, j, k)] + out[g.linear(g.n[0] - 1 - i, j, k)]);
  return sym;
}

std::map<std::string, std::string> parse(int argc, char** argv) {
  std::map<std::string, std::string> a;
  for (int i = 1; i + 1 < argc; i += 2) a[argv[i]] = argv[i + 1];
  return a;
}

}  // namespace

static int place(const std::string& ct_path, double hu_offset, const std::string& out) {
  io::ReadOptions ro;
  ro.hu_offset = hu_offset;
  io::LoadedScan s = io::read_scan(ct_path, ro);
  const Fit fit = fit_ct(s.volume, kBoneHu);
  std::fprintf(stderr, "fit: found %d ncc %.3f mirrored %.3f scale %.3f\n", fit.found, fit.ncc, fit.mirrored_ncc, fit.pose.scale);
  const MandiblePrior prior(shipped(), fit.pose);
  Volume& v = s.volume;
  const Geometry& g = v.geom;
  for (std::size_t k = 0; k < g.size[2]; ++k)
    for (std::size_t j = 0; j < g.size[1]; ++j)
      for (std::size_t i = 0; i < g.size[0]; ++i)
        v.hu[g.linear(i, j, k)] = fit.found ? static_cast<float>(prior.at(g.index_to_lps(double(i), double(j), double(k)))) : 0.0f;
  io::write_volume(v, out);
  return fit.found ? 0 : 3;
}

// The ids of a folds CSV (header id,fold) whose fold is listed in `use` (e.g. "1,2,3,4").
static std::vector<std::string> fold_ids(const std::string& csv, const std::string& use) {
  std::vector<std::string> ids;
  std::ifstream in(csv);
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    const auto comma = line.find(',');
    if (comma == std::string::npos) continue;
    const std::string fold = line.substr(comma + 1);
    if (("," + use + ",").find("," + fold + ",") != std::string::npos) ids.push_back(line.substr(0, comma));
  }
  return ids;
}

// Builds the atlas from the training scans (the file's header, steps 1-4).
static int build(std::map<std::string, std::string>& args) {
  if (!args.count("--data") || !args.count("--folds") || !args.count("--out")) {
    std::fprintf(stderr, "usage: mandisym-atlas-build --data DIR --folds CSV --use 1,2,3,4 --out FILE [--iterations N]\n");
    return 2;
  }
  const std::string use = args.count("--use") ? args["--use"] : "1,2,3,4";
  const int iterations = args.count("--iterations") ? std::stoi(args["--iterations"]) : 2;
  const std::vector<std::string> ids = fold_ids(args["--folds"], use);
  if (ids.empty()) {
    std::fprintf(stderr, "mandisym-atlas-build: no case of folds %s in %s\n", use.c_str(), args["--folds"].c_str());
    return 2;
  }
  Grid g;
  g.spacing = kSpacingMm;
  for (int a = 0; a < 3; ++a) {
    g.n[a] = static_cast<int>(std::lround(2 * kHalfBoxMm[a] / kSpacingMm)) + 1;
    g.origin[a] = -kHalfBoxMm[a];
  }
  std::vector<Case> cases;
  try {
    for (const std::string& id : ids) {
      io::ReadOptions ro;
      ro.hu_offset = -1000;  // OpenKBP stores HU + 1000
      const io::LoadedScan s = io::read_scan(args["--data"] + "/" + id + "/ct.nii.gz", ro);
      const Mask m = io::read_mask(args["--data"] + "/" + id + "/mask.nii.gz");
      if (m.count() == 0) continue;
      Case c;
      c.id = id;
      c.bone = bone_fraction(s.volume, kSpacingMm, kBoneHu, kFieldBlurMm);
      c.mask_blurred = mask_fraction(m, kSpacingMm, kFieldBlurMm);
      c.mask = mask_fraction(m, kSpacingMm, 0);
      c.pose.t = centroid(m);
      cases.push_back(std::move(c));
      std::fprintf(stderr, "\r%zu/%zu read", cases.size(), ids.size());
    }
  } catch (const Error& e) {
    std::fprintf(stderr, "\nmandisym-atlas-build: %s\n", e.what());
    return 4;
  }
  std::fprintf(stderr, "\n");
  Atlas atlas;
  atlas.grid = g;
  atlas.cases = static_cast<int>(cases.size());
  for (int it = 0;; ++it) {
    atlas.mandible = mean_field(g, cases, &Case::mask, true);
    atlas.context = mean_field(g, cases, &Case::bone, false);
    if (it == iterations) break;
    double sum_ncc = 0, min_ncc = 1, log_scale = 0, pitch = 0;
    for (Case& c : cases) {
      double s = 0;
      c.pose = refine(g, atlas.mandible, c.mask_blurred, c.pose, &s);
      sum_ncc += s, min_ncc = std::min(min_ncc, s);
      log_scale += std::log(c.pose.scale), pitch += c.pose.pitch;
    }
    // Keep the atlas at the cohort's mean size and head flexion.
    const double n = static_cast<double>(cases.size());
    for (Case& c : cases) c.pose.scale /= std::exp(log_scale / n), c.pose.pitch -= pitch / n;
    std::fprintf(stderr, "iteration %d: mask-to-mean NCC mean %.3f, worst %.3f\n", it + 1, sum_ncc / n, min_ncc);
  }
  std::ostringstream src;
  src << cases.size() << " OpenKBP training scans (folds " << use << " of scripts/cohort-folds.csv), " << iterations
      << " alignment iterations, 3 mm, mirrored";
  atlas.source = src.str();
  // Fit of each training scan's bone to the context, as a check of the run-time search.
  double worst = 1, sum = 0;
  std::string worst_id;
  for (const Case& c : cases) {
    const Fit f = fit(atlas, c.bone);
    const double err = distance(f.pose.t, c.pose.t);
    sum += err;
    if (f.ncc < worst) worst = f.ncc, worst_id = c.id;
    std::printf("%s fit ncc %.3f mirrored %.3f, centre %.1f mm from the mask's pose, scale %.3f vs %.3f\n", c.id.c_str(), f.ncc,
                f.mirrored_ncc, err, f.pose.scale, c.pose.scale);
  }
  std::printf("training fits: mean centre error %.1f mm, worst NCC %.3f (%s)\n", sum / cases.size(), worst, worst_id.c_str());
  const std::vector<std::uint8_t> bytes = serialise(atlas);
  std::ofstream out(args["--out"], std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  if (!out) {
    std::fprintf(stderr, "mandisym-atlas-build: cannot write %s\n", args["--out"].c_str());
    return 7;
  }
  std::fprintf(stderr, "wrote %s (%zu bytes): %s\n", args["--out"].c_str(), bytes.size(), atlas.source.c_str());
  return 0;
}

int main(int argc, char** argv) {
  auto args = parse(argc, argv);
  if (args.count("--place")) {
    if (!args.count("--out")) {
      std::fprintf(stderr, "usage: mandisym-atlas-build --place CT [--hu-offset H] --out PRIOR.nii.gz\n");
      return 2;
    }
    try {
      return place(args["--place"], args.count("--hu-offset") ? std::stod(args["--hu-offset"]) : 0.0, args["--out"]);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "mandisym-atlas-build: %s\n", e.what());
      return 1;
    }
  }
  return build(args);
}
