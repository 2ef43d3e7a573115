// Small value types exchanged between pipeline stages. No ITK, VTK, Eigen or
// CGAL here: every stage can include this header whatever its own dependencies.
// Conventions (METHOD.md §0): patient LPS millimetres, +x Left, +y Posterior,
// +z Superior. Volumes are stored x-fastest (index i along columns).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

namespace ms {

using Vec3 = std::array<double, 3>;

// Voxel grid geometry. direction is row-major 3x3; its columns are the LPS
// directions of the i, j, k index axes (as ITK's Image::GetDirection()).
struct Geometry {
  std::array<std::size_t, 3> size{0, 0, 0};
  Vec3 spacing{1, 1, 1};
  Vec3 origin{0, 0, 0};
  std::array<double, 9> direction{1, 0, 0, 0, 1, 0, 0, 0, 1};

  std::size_t voxel_count() const { return size[0] * size[1] * size[2]; }
  std::size_t linear(std::size_t i, std::size_t j, std::size_t k) const {
    return i + size[0] * (j + size[1] * k);
  }
  // Physical LPS position of a (continuous) index.
  Vec3 index_to_lps(double i, double j, double k) const;
  // Continuous index of an LPS position (inverse of index_to_lps).
  Vec3 lps_to_index(const Vec3& p) const;
  double voxel_volume_mm3() const { return spacing[0] * spacing[1] * spacing[2]; }
  bool same_grid(const Geometry& o, double tol = 1e-4) const;
};

// CT volume in Hounsfield units.
struct Volume {
  Geometry geom;
  std::vector<float> hu;
};

// Trilinear HU at an LPS point; NaN outside the grid (between voxel centres).
double interpolate(const Volume& volume, const Vec3& lps);
// The same for voxel values hu laid out on grid g (a volume's voxels seen
// through another geometry, e.g. the scan's own frame: atlas::fit_ct).
double interpolate(const Geometry& g, const float* hu, const Vec3& lps);

// Binary mask (0/1) on a grid.
struct Mask {
  Geometry geom;
  std::vector<std::uint8_t> data;
  std::size_t count() const;
};

// Dice overlap 2|a ∩ b| / (|a| + |b|) of two masks on the same grid (1 when both are empty).
double dice(const Mask& a, const Mask& b);

// Integer label map (e.g. an external segmentation) on a grid.
struct LabelMap {
  Geometry geom;
  std::vector<std::int32_t> labels;
};

// Triangle mesh in LPS mm. Closed, 2-manifold, outward-oriented when it comes
// out of the surface stage (METHOD.md §0).
struct Mesh {
  std::vector<Vec3> vertices;
  std::vector<std::array<int, 3>> faces;
};

// Plane n·x = n·point with unit normal n. For the symmetry plane, n points to
// the patient's left.
struct Plane {
  Vec3 point{0, 0, 0};
  Vec3 normal{1, 0, 0};
  double signed_distance(const Vec3& p) const;
  Vec3 reflect(const Vec3& p) const;
};

// Anatomical landmark names of METHOD.md §2.
inline const std::vector<std::string>& landmark_names() {
  static const std::vector<std::string> n = {"Co_L", "Co_R", "Cr_L", "Cr_R",
                                             "Go_L", "Go_R", "Me",   "Pog"};
  return n;
}
// Label mirror σ: swaps _L and _R, midline names map to themselves.
std::string mirror_label(const std::string& name);

// A named set of landmarks; a landmark that could not be found is absent.
struct LandmarkSet {
  std::vector<std::pair<std::string, Vec3>> points;
  const Vec3* find(const std::string& name) const;
  bool has(const std::string& name) const { return find(name) != nullptr; }
  void set(const std::string& name, const Vec3& p);
};

// Provenance of the input scan, kept for the report. PatientName/ID are never
// stored here.
struct ScanInfo {
  std::string path;
  std::string kind;        // dicom | nifti | nrrd | meta
  std::string series_uid;
  std::string modality;
  std::string study_date;
  std::string manufacturer;
  std::string model;
  std::string kernel;
  std::string series_description;
  std::size_t file_count = 0;
  std::string pixel_sha256;  // of the HU voxel values as loaded (float32, x-fastest)
  double lowest_hu = std::numeric_limits<double>::quiet_NaN();  // the lowest voxel value, HU after --hu-offset; NaN: not read
  std::vector<std::string> warnings;
};

// The DICOM series a volume was read from, as the DICOM writers reference it
// (docs/pacs.md): UIDs, and every frame used, ordered along the slice normal.
struct DicomSourceFrame {
  std::string file;
  unsigned frame = 0;  // 0-based index within a multi-frame file
  std::string sop_instance_uid;
  Vec3 ipp{0, 0, 0}, row_dir{1, 0, 0}, col_dir{0, 1, 0};  // LPS mm; direction of a row (i), of a column (j)
  double spacing_i = 1, spacing_j = 1;                     // mm along row_dir, col_dir
  unsigned rows = 0, cols = 0;
};
struct DicomSource {
  std::string study_uid, series_uid, frame_of_reference_uid, sop_class_uid, modality;
  std::string first_file;  // a file of the series, for the patient and study modules
  std::vector<DicomSourceFrame> frames;
};

// Small vector helpers.
inline Vec3 operator+(const Vec3& a, const Vec3& b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
inline Vec3 operator-(const Vec3& a, const Vec3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
inline Vec3 operator*(double s, const Vec3& a) { return {s * a[0], s * a[1], s * a[2]}; }
inline double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
inline Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
double norm(const Vec3& a);
Vec3 normalized(const Vec3& a);
double distance(const Vec3& a, const Vec3& b);

}  // namespace ms
