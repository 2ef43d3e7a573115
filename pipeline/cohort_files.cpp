#include "pipeline/cohort_files.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "core/files.h"
#include "core/json_text.h"
#include "pipeline/cohort_stats.h"
#include "reports/interpretation.h"
#include "reports/writers.h"

namespace fs = std::filesystem;

namespace ms::pipeline::cohort {

namespace {

// Fields of results.json that cohort.csv adds after results.csv's columns:
// column -> path in results.json.
const std::pair<const char*, std::vector<const char*>> kResultsJsonColumns[] = {
    {"qc_status", {"qc", "status"}},
    {"saf_band", {"interpretation", "saf_score", "band"}},
    {"mirror_p95_band", {"interpretation", "mirror_distance", "band"}},
    {"menton_deviation_mm", {"interpretation", "menton_deviation", "value"}},
    {"menton_band", {"interpretation", "menton_deviation", "band"}},
    {"menton_measured_from", {"interpretation", "menton_deviation", "measured_from"}},
};

// A score shown as a distribution and compared between groups, with the
// interpretation band edges (reports/interpretation.h) drawn on its histogram.
struct Score {
  const char* column;
  const char* label;
  reports::Thresholds bands;  // {0, 0}: none
  bool absolute = false;      // compare |value| (signed L - R differences)
};
const Score kScores[] = {
    {"saf_score", "SAF score (rad)", reports::kSafThresholds},
    {"mirror_rms_mm", "mirror distance RMS (mm)", {}},
    {"mirror_p95_mm", "mirror distance p95 (mm)", reports::kMirrorP95Thresholds},
    {"menton_deviation_mm", "menton deviation (mm)", reports::kMentonThresholds},
    {"ramus_height_diff_mm", "|ramus height L - R| (mm)", {}, true},
};

std::string fmt(double v, int prec = 3) {
  char b[64];
  std::snprintf(b, sizeof b, "%.*f", prec, v);
  return b;
}


// The text of a results.json field ("" when absent or null).
std::string field_text(const Json& results, const std::vector<const char*>& path) {
  const Json* v = &results;
  for (const char* key : path)
    if (!(v = find_member(*v, key))) return "";
  if (v->is_string()) return v->get<std::string>();
  if (v->is_number()) return fmt(v->get<double>(), 3);
  return "";
}

// A CSV cell: quoted only when it needs to be (RFC 4180), so numbers stay bare.
std::string cell(const std::string& v) {
  return v.find_first_of(",\"\r\n") == std::string::npos ? v : reports::csv_quote(v);
}

std::string exit_code_text(const Study& s) { return s.exit_code >= 0 ? std::to_string(s.exit_code) : ""; }

std::vector<double> values_of(const Table& t, const std::string& column, bool absolute, const std::vector<std::size_t>& rows) {
  std::vector<double> v;
  const auto all = t.numbers(column);
  for (const auto& [row, x] : all)
    if (std::find(rows.begin(), rows.end(), row) != rows.end()) v.push_back(absolute ? std::abs(x) : x);
  return v;
}

}  // namespace

std::vector<std::string> split_csv_line(const std::string& line) {
  std::vector<std::string> out;
  std::string cur;
  bool q = false;
  for (std::size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (q) {
      if (c == '"' && i + 1 < line.size() && line[i + 1] == '"') cur += '"', ++i;
      else if (c == '"') q = false;
      else cur += c;
    } else if (c == '"') {
      q = true;
    } else if (c == ',') {
      out.push_back(cur), cur.clear();
    } else if (c != '\r') {
      cur += c;
    }
  }
  out.push_back(cur);
  return out;
}

std::vector<std::pair<std::size_t, double>> Table::numbers(const std::string& column) const {
  std::vector<std::pair<std::size_t, double>> v;
  const auto it = std::find(columns.begin(), columns.end(), column);
  if (it == columns.end()) return v;
  const auto c = static_cast<std::size_t>(it - columns.begin());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const std::string& cell = rows[i][c];
    char* end = nullptr;
    const double x = std::strtod(cell.c_str(), &end);
    if (!cell.empty() && *end == '\0' && std::isfinite(x)) v.emplace_back(i, x);
  }
  return v;
}

Table read_results(const std::vector<Study>& studies, const fs::path& out) {
  Table t;
  const std::string header = reports::csv_header();
  const auto results_columns = split_csv_line(header.substr(0, header.size() - 1));
  t.columns.assign(results_columns.begin() + 2, results_columns.end());  // without study, status
  for (const auto& [column, path] : kResultsJsonColumns) t.columns.push_back(column);
  for (const Study& s : studies) {
    std::vector<std::string> row(t.columns.size());
    if (s.has_result()) {
      std::istringstream csv(read_file_or_empty((out / s.id / "results.csv").string()));
      std::string h, r;
      if (std::getline(csv, h) && std::getline(csv, r)) {
        const auto hc = split_csv_line(h), rc = split_csv_line(r);
        for (std::size_t c = 2; c < hc.size() && c < rc.size(); ++c) {
          const auto at = std::find(t.columns.begin(), t.columns.end(), hc[c]);
          if (at != t.columns.end()) row[static_cast<std::size_t>(at - t.columns.begin())] = rc[c];
        }
      }
      try {
        const Json results = parse_json(read_file_or_empty((out / s.id / "results.json").string()));
        std::size_t c = results_columns.size() - 2;
        for (const auto& [column, path] : kResultsJsonColumns) row[c++] = field_text(results, path);
      } catch (const std::exception&) {
      }
    }
    t.rows.push_back(row);
  }
  return t;
}

void write_cohort_csv(const std::vector<Study>& studies, const Table& t, const fs::path& out) {
  std::ostringstream csv;
  const auto q = reports::csv_quote;
  csv << "id,status,exit_code,error,signal,seconds,peak_memory_mb,options";
  for (const auto& c : t.columns) csv << "," << c;
  csv << "\n";
  for (std::size_t i = 0; i < studies.size(); ++i) {
    const Study& s = studies[i];
    csv << q(s.id) << "," << q(s.status) << "," << exit_code_text(s) << "," << q(s.error) << ","
        << (s.signal ? std::to_string(s.signal) : "") << "," << (s.seconds >= 0 ? fmt(s.seconds, 1) : "") << ","
        << (s.peak_kb > 0 ? fmt(static_cast<double>(s.peak_kb) * 1024.0 / 1e6, 0) : "") << "," << q(s.run_options);
    for (const auto& c : t.rows[i]) csv << "," << cell(c);
    csv << "\n";
  }
  reports::write_text_atomic((out / "cohort.csv").string(), csv.str());
}

std::vector<std::vector<std::string>> write_cohort_groups(const std::vector<Study>& studies, const Table& t, const fs::path& out) {
  std::map<std::string, std::vector<std::size_t>> groups;  // group -> rows with a result
  for (std::size_t i = 0; i < studies.size(); ++i)
    if (!studies[i].group.empty() && studies[i].has_result()) groups[studies[i].group].push_back(i);
  std::vector<std::vector<std::string>> rows;
  if (groups.size() < 2) return rows;
  for (const Score& sc : kScores)
    for (auto a = groups.begin(); a != groups.end(); ++a)
      for (auto b = std::next(a); b != groups.end(); ++b) {
        const auto va = values_of(t, sc.column, sc.absolute, a->second), vb = values_of(t, sc.column, sc.absolute, b->second);
        if (va.empty() || vb.empty()) continue;
        const MannWhitney mw = mann_whitney(va, vb);
        const Interval ci = cliffs_delta_bootstrap(va, vb);
        rows.push_back({std::string(sc.absolute ? "abs_" : "") + sc.column, a->first, b->first, std::to_string(va.size()),
                        std::to_string(vb.size()), fmt(quantile(va, 0.5), 4), fmt(quantile(va, 0.25), 4), fmt(quantile(va, 0.75), 4),
                        fmt(quantile(vb, 0.5), 4), fmt(quantile(vb, 0.25), 4), fmt(quantile(vb, 0.75), 4), fmt(mw.u, 1),
                        fmt(mw.p, 4), fmt(cliffs_delta(va, vb), 3), fmt(ci.lo, 3), fmt(ci.hi, 3)});
      }
  std::ostringstream csv;
  csv << "score,group_a,group_b,n_a,n_b,median_a,q1_a,q3_a,median_b,q1_b,q3_b,mann_whitney_u,p_value,cliffs_delta,"
         "cliffs_delta_ci95_lo,cliffs_delta_ci95_hi\n";
  for (const auto& r : rows) {
    for (std::size_t c = 0; c < r.size(); ++c) csv << (c ? "," : "") << (c < 3 ? reports::csv_quote(r[c]) : r[c]);
    csv << "\n";
  }
  reports::write_text_atomic((out / "cohort_groups.csv").string(), csv.str());
  return rows;
}

}  // namespace ms::pipeline::cohort
