// Interpretation bands as results.json names them and as every report words
// them (report.html, report.pdf): one table, so the wording cannot drift.
#pragma once

#include <string_view>

namespace ms {

struct BandWording {
  std::string_view name;   // results.json interpretation.<key>.band
  std::string_view label;  // what a reader sees
};

inline constexpr BandWording kBandWordings[] = {
    {"typical", "within typical range"}, {"mild", "mild asymmetry"},         {"marked", "marked asymmetry"},
    {"unbanded", "no published band"},   {"unavailable", "not available"},
};

// The label of a band name; an unknown name reads "not available".
constexpr std::string_view band_label_of(std::string_view name) {
  for (const BandWording& w : kBandWordings)
    if (w.name == name) return w.label;
  return "not available";
}

}  // namespace ms
