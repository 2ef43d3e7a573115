// Declarative command-line specs: each verb declares its description,
// arguments and options in one place; help text and parsing come from it.
#pragma once

#include <limits>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/types.h"

namespace ms::cli {

struct OptionSpec {
  std::string name;         // without the leading "--"
  std::string value_name;   // empty: a flag
  std::string help;
  std::string default_value;
  // Allowed range of a numeric value (inclusive; NaN: none declared). Shown
  // by --help and enforced by Args::ranged.
  double lo = std::numeric_limits<double>::quiet_NaN();
  double hi = std::numeric_limits<double>::quiet_NaN();
};

struct CommandSpec {
  std::string name;
  std::string synopsis;     // one line
  std::string description;  // paragraph
  std::vector<std::pair<std::string, std::string>> arguments;  // name, help
  std::vector<OptionSpec> options;
  // Words after a lone "--" are kept in Args::passthrough (e.g. `batch`'s run
  // options) and this says what they are for --help; empty: "--" is refused.
  std::string passthrough = "";
};

class Args {
 public:
  std::vector<std::string> positional;
  std::vector<std::string> passthrough;  // after "--" (CommandSpec::passthrough)
  std::map<std::string, std::string> values;  // flags map to "1"
  bool has(const std::string& n) const { return values.count(n) > 0; }
  std::string get(const std::string& n, const std::string& def = "") const;
  double number(const std::string& n, double def) const;   // throws Error(Usage) naming the option
  // A number that must lie in [lo, hi] (unit: for the message); throws
  // Error(Usage) naming the option, the value and the range.
  double number_in(const std::string& n, double def, double lo, double hi, const char* unit) const;
  // A number within the range its OptionSpec declares (copied here by parse).
  double ranged(const std::string& n, double def, const char* unit) const;
  std::map<std::string, std::pair<double, double>> ranges;  // option -> declared [lo, hi]
  Vec3 vec3(const std::string& n, const Vec3& def) const;   // "x,y,z" or a single value for all three
};

// Throws ms::Error(Usage) with a one-line message on unknown options, missing
// values or a wrong number of arguments.
Args parse(const CommandSpec& spec, const std::vector<std::string>& argv);
std::string help(const CommandSpec& spec);

}  // namespace ms::cli
