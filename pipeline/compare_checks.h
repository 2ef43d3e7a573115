// `mandisym compare`: strict reading of a run folder's results.json / srd.json
// / mandible.vtp (hostile or hand-edited files give exit 4 with one line naming
// the file and the field), and the consistency checks between PRE and POST
// (dates, identifiers, shape) that become compare.json `warnings` and
// `consistency` (docs/batch.md, "compare: inputs and consistency checks").
#pragma once

#include <map>
#include <string>
#include <vector>

#include "asymmetry/srd.h"
#include "core/json_text.h"
#include "core/types.h"

namespace ms::pipeline::compare_checks {

// Largest |coordinate| accepted in compare inputs, mm: 10 m. Patient
// coordinates of a CT lie within about a metre of the scanner's origin (a bore
// is < 1 m wide, a table travels < 2 m); beyond 10 m a number is corrupt, and
// its squares stay far from overflowing a double.
constexpr double kMaxCoordinateMm = 10000.0;
// Most landmarks read from one results.json: a run writes METHOD.md's 8.
constexpr std::size_t kMaxLandmarks = 64;
// Fewest faces of a usable closed surface (a tetrahedron). Fewer is degenerate:
// nothing to align and no closest-point index.
constexpr std::size_t kMinFaces = 4;
// srd.json `bins` accepted: 1..kMaxSrdBins (a run writes 12; asymmetry/srd.h).
constexpr int kMaxSrdBins = 1024;

// "FILE: field `PATH`: WHAT" as an Error with exit code 4 (invalid input).
[[noreturn]] void bad_field(const std::string& file, const std::string& field, const std::string& what);

// Strict accessors. `field` is the dotted path used in messages.
// The member `key` of object `obj`: nullptr when absent or null; throws when
// present with another type than `type`.
const Json* member(const Json& obj, const std::string& key, JsonKind type, const std::string& file,
                          const std::string& field);
// A finite number within ±kMaxCoordinateMm.
double coordinate(const Json& v, const std::string& file, const std::string& field);
// An array of 3 coordinates.
Vec3 point3(const Json& v, const std::string& file, const std::string& field);

// results.json's landmarks (object of name -> [x,y,z] or null) and symmetry
// plane (point, unit-able normal), checked.
LandmarkSet read_landmarks(const Json& results, const std::string& file);
Plane read_plane(const Json& results, const std::string& file);
// A number at a path of results.json for the score table: NaN with *ok=false
// when a member is absent or null; throws when one has the wrong type.
double score_at(const Json& results, const std::vector<std::string>& path, const std::string& file, bool* ok);
// srd.json (already parsed), checked field by field: a top-level object,
// `bins` an integer 1..kMaxSrdBins, at most kMaxLandmarks `landmarks`, each an
// array of {configuration, mirrored, histogram} blocks whose histogram length
// is a multiple of bins and holds finite numbers >= 0.
struct SrdData {
  int bins = 0;
  std::map<std::string, asymmetry::Srd> landmarks;
};
SrdData read_srd(const Json& srd, const std::string& file);
// The mesh: at least kMinFaces faces, valid vertex indices, finite vertices
// within ±kMaxCoordinateMm. Throws Error(4) naming the file.
void check_mesh(const Mesh& m, const std::string& file);

// One PRE/POST pair as the consistency checks see it.
struct RunView {
  const Json& results;
  const Mesh& mesh;
  const LandmarkSet& landmarks;
  std::string file;  // its results.json, for messages
};

struct Consistency {
  Json block = Json::object();  // compare.json `consistency`: every measured value
  std::vector<std::string> warnings;          // one line each (stderr, compare.json `warnings`)
  Json details = Json::array();  // compare.json `warning_details`: {code, message, evidence}
};

// Dates, identifiers and shape of PRE and POST. Identifiers and dates are
// neither compared nor printed when either run was de-identified.
Consistency check_consistency(const RunView& pre, const RunView& post);

// Enclosed volume of a closed mesh, mm³ (divergence theorem, absolute value).
double enclosed_volume_mm3(const Mesh& m);

}  // namespace ms::pipeline::compare_checks
