// Output writers: results.json (OUTPUTS.md, schema 1.0), Slicer markups,
// report.html, one-row CSV.
#pragma once

#include <string>

#include "core/json_text.h"
#include "reports/run_summary.h"

namespace ms::reports {

inline constexpr const char* kSchemaVersion = "1.0";

Json results_json(const RunSummary& s);
// srd.json: the SRD descriptors at the landmarks (METHOD.md §6; docs/method.md).
Json srd_json(const asymmetry::SrdResult& srd);
std::string landmarks_markup(const LandmarkSet& landmarks);   // Slicer Fiducial, LPS
std::string plane_markup(const Plane& plane, double size_mm,
                         const std::string& label = "mandible symmetry plane");  // Slicer Plane, LPS
// figures: segmentation QC PNGs; views: 3D view PNGs (files named
// <set>_<view>.png); views_note: why there are no 3D views (empty when there are).
std::string report_html(const RunSummary& s, const std::vector<std::string>& figures,
                        const std::vector<std::string>& views = {}, const std::string& views_note = "");
std::string csv_header();
// A CSV field in double quotes, inner quotes doubled.
std::string csv_quote(const std::string& field);
std::string csv_row(const RunSummary& s, const std::string& status);

// Standard base64 (RFC 4648, with padding) of arbitrary bytes.
std::string base64_encode(const std::string& bytes);

// data: URI of a PNG file (for self-contained HTML); empty if unreadable.
std::string png_data_uri(const std::string& path);

// HTML-escapes &, <, >, ", '.
std::string html_escape(const std::string& s);
// v with prec decimals ("%.*f"); "n/a" when not finite.
std::string fixed(double v, int prec = 2);

// Writes text to path via a temporary file and rename (no half-written file).
void write_text_atomic(const std::string& path, const std::string& text);

}  // namespace ms::reports
