// `mandisym phantom`: synthetic head CT (DICOM via ITK/GDCM) with ground truth.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iostream>

#include "core/error.h"
#include "core/json_text.h"
#include "io/png.h"
#include "io/volume_io.h"
#include "phantom/phantom.h"
#include "pipeline/commands.h"
#include "reports/writers.h"

namespace fs = std::filesystem;

namespace ms::pipeline {

const cli::CommandSpec& phantom_spec() {
  static const cli::CommandSpec s{
      "phantom",
      "Write a synthetic head CT (DICOM series) with ground truth.",
      "Writes OUTDIR/dicom/ (CT Image Storage, HU via RescaleIntercept -1024) and OUTDIR/ground_truth/ "
      "(mandible_mask.nii.gz, landmarks.json, landmarks.mrk.json, symmetry_plane.json, asymmetry.json, "
      "params.json) plus OUTDIR/preview/*.png. Anatomy: mandible (body, symphysis and chin, angles, rami, "
      "condyles, coronoids, sigmoid notches; cortical shell over cancellous core; lower teeth), maxilla with upper "
      "teeth and sinuses, skull base with glenoid fossae, skull vault, zygomatic arches, cervical spine, hyoid, "
      "airway and soft tissue. Per-side knobs: L = patient left, R = patient right. Deterministic for a seed.",
      {},
      {{"output", "OUTDIR", "output folder", ""},
       {"spacing", "MM[,MM,MM]", "voxel spacing (x,y,z)", "0.8"},
       {"fov", "MM[,MM,MM]", "field of view (x,y,z); grid size = fov / spacing", "150,150,140"},
       {"noise", "HU", "Gaussian noise standard deviation", "15"},
       {"blur", "MM", "Gaussian PSF sigma (partial-volume blur)", "0.4"},
       {"yaw", "DEG", "head rotation about the superior axis", "0"},
       {"pitch", "DEG", "head rotation about the left axis", "0"},
       {"roll", "DEG", "head rotation about the posterior axis", "0"},
       {"shift", "X,Y,Z", "head translation in LPS mm", "0,0,0"},
       {"occlusal-gap", "MM", "gap between upper and lower teeth (0 = in occlusion)", "1"},
       {"joint-space", "MM", "TMJ space between condyle and glenoid fossa", "2.5"},
       {"metal", "", "amalgam fillings in the lower first molars, with streak artefacts", ""},
       {"edentulous", "", "no teeth in either jaw (the alveolar bone is kept)", ""},
       {"mirror", "", "mirror the whole volume left<->right (ground truth follows)", ""},
       {"ramus-L", "MM", "ramus height change, patient left", "0"},
       {"ramus-R", "MM", "ramus height change, patient right", "0"},
       {"body-L", "MM", "body length change, left", "0"},
       {"body-R", "MM", "body length change, right", "0"},
       {"gonial-L", "DEG", "gonial angle change, left", "0"},
       {"gonial-R", "DEG", "gonial angle change, right", "0"},
       {"condyle-L", "MM", "condylar head size change, left", "0"},
       {"condyle-R", "MM", "condylar head size change, right", "0"},
       {"chin", "MM", "chin (symphysis) deviation, + towards patient left", "0"},
       {"scale", "F", "size of the whole head model, knobs included (0.6..1.4; 0.7 ~ a young child's mandible)", "1"},
       {"cortex", "MM", "cortical shell thickness of the mandible", "2"},
       {"cortical-hu", "HU", "cortical bone density of the mandible", "1600"},
       {"cancellous-hu", "HU", "cancellous bone density of the mandible", "350"},
       {"crown-scale", "F", "tooth crown size (0.7..1.3)", "1"},
       {"random-anatomy", "N", "a member of the random anatomy family (docs/phantom.md): the anatomy knobs above "
        "drawn from adult ranges by seed N; scanner knobs (spacing, fov, noise, blur, pose, metal) are kept", ""},
       {"seed", "N", "random seed", "1"},
       {"compression", "KIND", "DICOM transfer syntax: raw, jpeg-lossless, jpeg2000 (both lossless)", "raw"},
       {"no-preview", "", "do not write preview PNGs", ""},
       {"help", "", "show this help", ""}}};
  return s;
}

namespace {

Json vec(const Vec3& v) { return json_numbers(v); }

Json side_json(const phantom::SideAsymmetry& a) {
  auto o = Json::object();
  o["ramus_height_mm"] = a.ramus_height_mm;
  o["body_length_mm"] = a.body_length_mm;
  o["gonial_angle_deg"] = a.gonial_angle_deg;
  o["condyle_size_mm"] = a.condyle_size_mm;
  return o;
}

// Maximum-intensity projections and a slice, bone window, for eyeballing.
void write_previews(const phantom::Phantom& ph, const std::string& dir) {
  const Geometry& g = ph.ct.geom;
  const long nx = g.size[0], ny = g.size[1], nz = g.size[2];
  auto win = [](float v, float lo, float hi) {
    return static_cast<std::uint8_t>(std::clamp((v - lo) / (hi - lo) * 255.0f, 0.0f, 255.0f));
  };
  std::vector<std::uint8_t> lat(ny * nz), front(nx * nz), axial(nx * ny);
  for (long k = 0; k < nz; ++k)
    for (long j = 0; j < ny; ++j) {
      float m = -2000;
      for (long i = 0; i < nx; ++i) m = std::max(m, ph.ct.hu[g.linear(i, j, k)]);
      lat[(nz - 1 - k) * ny + j] = win(m, 0, 2500);  // anterior on the left, superior up
    }
  for (long k = 0; k < nz; ++k)
    for (long i = 0; i < nx; ++i) {
      float m = -2000;
      for (long j = 0; j < ny; ++j) m = std::max(m, ph.ct.hu[g.linear(i, j, k)]);
      front[(nz - 1 - k) * nx + i] = win(m, 0, 2500);  // patient right on the left
    }
  for (long j = 0; j < ny; ++j)
    for (long i = 0; i < nx; ++i) {
      float m = -2000;
      for (long k = 0; k < nz; ++k)
        if (ph.mandible.data[g.linear(i, j, k)]) m = std::max(m, ph.ct.hu[g.linear(i, j, k)]);
      axial[j * nx + i] = win(m, 0, 2500);  // mandible only, seen from above
    }
  io::write_png(dir + "/lateral_mip.png", lat, static_cast<int>(ny), static_cast<int>(nz), 1);
  io::write_png(dir + "/frontal_mip.png", front, static_cast<int>(nx), static_cast<int>(nz), 1);
  io::write_png(dir + "/mandible_axial_mip.png", axial, static_cast<int>(nx), static_cast<int>(ny), 1);
}

}  // namespace

namespace {

// The phantom's parameters from the command line (the knobs of phantom.h).
phantom::PhantomParams params_from(const cli::Args& a) {
  phantom::PhantomParams p;
  p.spacing = a.vec3("spacing", p.spacing);
  p.fov_mm = a.vec3("fov", p.fov_mm);
  p.noise_hu = a.number("noise", p.noise_hu);
  p.blur_mm = a.number("blur", p.blur_mm);
  p.yaw_deg = a.number("yaw", 0);
  p.pitch_deg = a.number("pitch", 0);
  p.roll_deg = a.number("roll", 0);
  p.shift_mm = a.vec3("shift", p.shift_mm);
  p.occlusal_gap_mm = a.number("occlusal-gap", p.occlusal_gap_mm);
  p.joint_space_mm = a.number("joint-space", p.joint_space_mm);
  p.metal = a.has("metal");
  p.edentulous = a.has("edentulous");
  p.mirror = a.has("mirror");
  const char* sides[2] = {"L", "R"};
  for (int s = 0; s < 2; ++s) {
    p.side[s].ramus_height_mm = a.number(std::string("ramus-") + sides[s], 0);
    p.side[s].body_length_mm = a.number(std::string("body-") + sides[s], 0);
    p.side[s].gonial_angle_deg = a.number(std::string("gonial-") + sides[s], 0);
    p.side[s].condyle_size_mm = a.number(std::string("condyle-") + sides[s], 0);
  }
  p.chin_deviation_mm = a.number("chin", 0);
  p.scale = a.number("scale", 1);
  p.cortex_mm = a.number("cortex", p.cortex_mm);
  p.cortical_hu = a.number("cortical-hu", p.cortical_hu);
  p.cancellous_hu = a.number("cancellous-hu", p.cancellous_hu);
  p.crown_scale = a.number("crown-scale", p.crown_scale);
  const double seed = a.number("seed", 1);
  if (seed < 0 || seed != std::floor(seed)) throw Error(ExitCode::Usage, "--seed: expected a non-negative integer");
  p.seed = static_cast<std::uint64_t>(seed);
  if (a.has("random-anatomy")) {
    const double n = a.number("random-anatomy", 0);
    if (n < 0 || n != std::floor(n)) throw Error(ExitCode::Usage, "--random-anatomy: expected a non-negative integer");
    p = phantom::random_anatomy(static_cast<std::uint64_t>(n), p);
  }
  return p;
}

// ground_truth/: landmarks (JSON and Slicer markup), the true symmetry plane
// and the imposed asymmetry.
void write_ground_truth(const phantom::Phantom& ph, const fs::path& root) {
  auto lm = Json::object();
  lm["coordinate_system"] = "LPS";
  lm["units"] = "mm";
  lm["landmarks"] = Json::object();
  for (const auto& n : landmark_names())
    if (const Vec3* q = ph.landmarks.find(n)) lm["landmarks"][n] = vec(*q);
  reports::write_text_atomic((root / "ground_truth" / "landmarks.json").string(), dump_json(lm) + "\n");
  reports::write_text_atomic((root / "ground_truth" / "landmarks.mrk.json").string(), reports::landmarks_markup(ph.landmarks));

  auto plane = Json::object();
  plane["coordinate_system"] = "LPS";
  plane["point"] = vec(ph.plane.point);
  plane["normal"] = vec(ph.plane.normal);
  reports::write_text_atomic((root / "ground_truth" / "symmetry_plane.json").string(), dump_json(plane) + "\n");

  auto asym = Json::object();
  asym["left"] = side_json(ph.truth.side[0]);
  asym["right"] = side_json(ph.truth.side[1]);
  asym["chin_deviation_mm"] = ph.truth.chin_deviation_mm;
  asym["mirrored"] = ph.params.mirror;
  asym["measured_on_ground_truth_landmarks"]["ramus_height_mm"]["L"] = ph.truth.ramus_height_L;
  asym["measured_on_ground_truth_landmarks"]["ramus_height_mm"]["R"] = ph.truth.ramus_height_R;
  asym["measured_on_ground_truth_landmarks"]["body_length_mm"]["L"] = ph.truth.body_length_L;
  asym["measured_on_ground_truth_landmarks"]["body_length_mm"]["R"] = ph.truth.body_length_R;
  reports::write_text_atomic((root / "ground_truth" / "asymmetry.json").string(), asym.dump(2) + "\n");

}

// ground_truth/params.json: every parameter the phantom was made with.
Json params_json(const cli::Args& a, const phantom::PhantomParams& p, const phantom::Phantom& ph, const std::string& uid,
                        const std::string& compression) {
  auto params = Json::object();
  params["tool_version"] = version();
  params["series_uid"] = uid;
  params["spacing_mm"] = vec(p.spacing);
  params["fov_mm"] = vec(p.fov_mm);
  params["size_voxels"] = json_numbers(ph.ct.geom.size);
  params["noise_hu"] = p.noise_hu;
  params["blur_mm"] = p.blur_mm;
  params["yaw_deg"] = p.yaw_deg;
  params["pitch_deg"] = p.pitch_deg;
  params["roll_deg"] = p.roll_deg;
  params["shift_mm"] = vec(p.shift_mm);
  params["occlusal_gap_mm"] = p.occlusal_gap_mm;
  params["joint_space_mm"] = p.joint_space_mm;
  params["metal"] = p.metal;
  params["edentulous"] = p.edentulous;
  params["mirror"] = p.mirror;
  params["scale"] = p.scale;
  params["cortex_mm"] = p.cortex_mm;
  params["cortical_hu"] = p.cortical_hu;
  params["cancellous_hu"] = p.cancellous_hu;
  params["crown_scale"] = p.crown_scale;
  if (a.has("random-anatomy")) params["random_anatomy"] = a.number("random-anatomy", 0);
  params["seed"] = static_cast<double>(p.seed);
  params["compression"] = compression;
  params["mandible_volume_mm3"] = ph.mandible.count() * ph.mandible.geom.voxel_volume_mm3();
  return params;
}

}  // namespace

int phantom_command(const cli::Args& a) {
  const std::string out = a.get("output");
  if (out.empty()) throw Error(ExitCode::Usage, "phantom: -o OUTDIR is required");
  const phantom::PhantomParams p = params_from(a);

  phantom::Phantom ph;
  const auto t0 = std::chrono::steady_clock::now();
  try {
    ph = phantom::generate(p);
  } catch (const std::invalid_argument& e) {
    throw Error(ExitCode::Usage, e.what());
  }
  const double t_gen = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  const fs::path root(out);
  std::error_code ec;
  fs::create_directories(root / "ground_truth", ec);
  if (ec) throw Error(ExitCode::OutputFailed, out + ": cannot create folder: " + ec.message());
  fs::remove_all(root / "dicom", ec);
  io::DicomSeriesSpec spec;
  spec.compression = a.get("compression", "raw");
  // Deterministic UIDs for a given seed would collide across phantoms with the
  // same seed; fresh UIDs are generated per series instead.
  const std::string uid = io::write_dicom_series(ph.ct, spec, (root / "dicom").string());
  io::write_mask(ph.mandible, (root / "ground_truth" / "mandible_mask.nii.gz").string());

  write_ground_truth(ph, root);
  const Json params = params_json(a, p, ph, uid, spec.compression);
  reports::write_text_atomic((root / "ground_truth" / "params.json").string(), dump_json(params) + "\n");

  if (!a.has("no-preview")) {
    fs::create_directories(root / "preview", ec);
    write_previews(ph, (root / "preview").string());
  }
  std::cout << "phantom: " << ph.ct.geom.size[0] << " x " << ph.ct.geom.size[1] << " x " << ph.ct.geom.size[2]
            << " voxels, generated in " << t_gen << " s\n"
            << "dicom: " << (root / "dicom").string() << "\nground truth: " << (root / "ground_truth").string() << std::endl;
  return 0;
}

}  // namespace ms::pipeline
