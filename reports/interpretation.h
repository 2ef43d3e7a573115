// Interpretation bands for the report's headline numbers: a pure mapping from
// numbers to a band ("within typical range", "mild", "marked") with what the
// number means, the thresholds and where they come from. The thresholds and
// their sources are documented in docs/report.md; the report cites them.
//
// Only two bands rest on published cut-offs (menton deviation, ramus-height
// asymmetry index); the mirror-distance band uses a common convention and the
// SAF band is provisional, derived from the project's own phantom numbers.
// Nothing here is clinically validated for this pipeline.
#pragma once

#include <limits>
#include <string>
#include <vector>

#include "reports/run_summary.h"

namespace ms::reports {

enum class Band { Typical, Mild, Marked, Unbanded, Unavailable };

// Short human label, e.g. "within typical range".
const char* band_label(Band b);
// Stable machine name: typical, mild, marked, unbanded, unavailable.
const char* band_name(Band b);

// value < mild: Typical; mild <= value < marked: Mild; value >= marked:
// Marked. Non-finite values: Unavailable.
struct Thresholds {
  double mild = 0, marked = 0;
};
Band classify(double value, const Thresholds& t);

// Thresholds in force (see docs/report.md for their sources).
inline constexpr Thresholds kSafThresholds{0.015, 0.021};            // rad, provisional (phantoms)
inline constexpr Thresholds kMirrorP95Thresholds{2.0, 4.0};          // mm, convention
inline constexpr Thresholds kMentonThresholds{2.0, 4.0};             // mm, published
inline constexpr Thresholds kRamusIndexThresholds{3.0, 6.0};         // %, Habets 3 %; 6 % is ours

// Habets' asymmetry index, 100 |L - R| / (L + R), in percent (NaN when it
// cannot be computed).
double habets_index_pct(double left, double right);

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// The numbers the bands are computed from; NaN where not available.
struct InterpretationInputs {
  double saf_score = kNaN;                       // rad
  double mirror_rms_mm = kNaN, mirror_p95_mm = kNaN;
  double ramus_L_mm = kNaN, ramus_R_mm = kNaN;   // |Co-Go|
  double menton_to_plane_mm = kNaN;              // signed, + toward the patient's left
  // The plane menton_to_plane_mm is measured from: the cranial mid-sagittal
  // plane when the scan holds the skull (closer to the cited studies' facial
  // midline), else the mandible's own symmetry plane.
  bool menton_plane_cranial = false;
  double menton_to_mandible_plane_mm = kNaN;     // always the mandible's own plane
  double gonial_L_deg = kNaN, gonial_R_deg = kNaN;
  double body_L_mm = kNaN, body_R_mm = kNaN;     // |Go-Me|
};

struct Interpretation {
  std::string key;         // saf_score, mirror_distance, ramus_height, menton_deviation, gonial_angle, body_length
  std::string title;       // card title
  std::string value_text;  // headline value with unit
  std::string detail;      // supporting numbers (L, R, index, ...)
  double banded_value = kNaN;  // the quantity compared with the thresholds
  Band band = Band::Unavailable;
  std::string meaning;     // what the number measures, one or two sentences
  std::string thresholds;  // the thresholds in words
  std::vector<std::string> sources;  // reference ids (interpretation_references())
  bool provisional = false;  // band not from a published cut-off for this quantity
  // What the value is measured from, when that can differ between runs
  // (menton deviation: "cranial_plane" or "mandible_plane"); empty otherwise.
  std::string measured_from;
};

// One entry per headline number, in display order. Pure: no I/O.
std::vector<Interpretation> interpret(const InterpretationInputs& in);

struct Reference {
  std::string id;        // short id used in Interpretation::sources
  std::string citation;  // full citation
};
const std::vector<Reference>& interpretation_references();

// The inputs from a run (landmarks, plane, scores, bilateral measures).
InterpretationInputs interpretation_inputs(const RunSummary& s);

}  // namespace ms::reports
