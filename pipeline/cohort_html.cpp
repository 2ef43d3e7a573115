// cohort.html (docs/batch.md, "Outputs"): the cohort's distributions with
// axes, counts and interpretation band edges, the group comparison, and the
// study table (sticky id and outlier columns, scrolling sideways in place).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <sstream>
#include <vector>

#include "pipeline/cohort_files.h"
#include "reports/html_page.h"
#include "reports/interpretation.h"
#include "reports/writers.h"

namespace fs = std::filesystem;

namespace ms::pipeline::cohort {

namespace {

using reports::html_escape;

struct Histogram {
  std::string column, label;
  reports::Thresholds bands;
};
const Histogram kHistograms[] = {
    {"saf_score", "SAF score (rad)", reports::kSafThresholds},
    {"mirror_rms_mm", "mirror distance RMS (mm)", {}},
    {"mirror_p95_mm", "mirror distance p95 (mm)", reports::kMirrorP95Thresholds},
    {"menton_deviation_mm", "menton deviation (mm)", reports::kMentonThresholds},
    {"ramus_height_diff_mm", "ramus height L - R (mm)", {}},
};

// Outliers: beyond 1.5 IQR of the cohort (Tukey's fences).
constexpr double kTukeyFence = 1.5;

std::string num(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.3g", v);
  return b;
}

// The SVG plot area (px) and the value -> x mapping.
struct Frame {
  static constexpr double kW = 420, kH = 220, kLeft = 46, kRight = 14, kTop = 32, kBottom = 50;
  double lo, hi;
  double x(double v) const { return kLeft + (v - lo) / (hi - lo) * (kW - kLeft - kRight); }
  double y(double count, double top) const { return kH - kBottom - count / top * (kH - kTop - kBottom); }
};

std::string axes_svg(const Frame& f, int top, const std::string& label) {
  std::ostringstream o;
  const double y0 = Frame::kH - Frame::kBottom;
  o << "<line x1=\"" << Frame::kLeft << "\" y1=\"" << y0 << "\" x2=\"" << Frame::kW - Frame::kRight << "\" y2=\"" << y0
    << "\" class=\"axis\"/><line x1=\"" << Frame::kLeft << "\" y1=\"" << Frame::kTop << "\" x2=\"" << Frame::kLeft << "\" y2=\"" << y0
    << "\" class=\"axis\"/>";
  for (int k = 0; k <= 4; ++k) {  // x ticks
    const double v = f.lo + (f.hi - f.lo) * k / 4, x = f.x(v);
    o << "<line x1=\"" << x << "\" y1=\"" << y0 << "\" x2=\"" << x << "\" y2=\"" << y0 + 4 << "\" class=\"axis\"/><text x=\"" << x
      << "\" y=\"" << y0 + 16 << "\" text-anchor=\"middle\">" << num(v) << "</text>";
  }
  for (int c : top > 1 ? std::vector<int>{0, (top + 1) / 2, top} : std::vector<int>{0, top}) {  // y ticks: studies
    const double y = f.y(c, top);
    o << "<line x1=\"" << Frame::kLeft - 4 << "\" y1=\"" << y << "\" x2=\"" << Frame::kLeft << "\" y2=\"" << y
      << "\" class=\"axis\"/><text x=\"" << Frame::kLeft - 7 << "\" y=\"" << y + 4 << "\" text-anchor=\"end\">" << c << "</text>";
  }
  o << "<text x=\"" << (Frame::kLeft + Frame::kW - Frame::kRight) / 2 << "\" y=\"" << Frame::kH - 12
    << "\" text-anchor=\"middle\" class=\"title\">" << html_escape(label) << "</text><text transform=\"translate(12 "
    << (Frame::kTop + y0) / 2 << ") rotate(-90)\" text-anchor=\"middle\" class=\"title\">studies</text>";
  return o.str();
}

std::string band_edges_svg(const Frame& f, const reports::Thresholds& t) {
  std::ostringstream o;
  const std::pair<double, const char*> edges[] = {{t.mild, "mild"}, {t.marked, "marked"}};
  int row = 0;  // labels on two rows, so that close edges do not overprint
  for (const auto& [v, name] : edges)
    if (t.marked > 0 && v >= f.lo && v <= f.hi) {
      const double x = f.x(v);
      o << "<line x1=\"" << x << "\" y1=\"" << Frame::kTop << "\" x2=\"" << x << "\" y2=\"" << Frame::kH - Frame::kBottom
        << "\" class=\"band\"/><text x=\"" << x + 3 << "\" y=\"" << Frame::kTop - 20 + 10 * row++ << "\" class=\"band\">" << name
        << " ≥ " << num(v) << "</text>";
    }
  return o.str();
}

// One histogram: bars with their counts, axes, band edges, outliers as a rug.
std::string histogram_svg(const std::vector<double>& v, const Histogram& h, const std::vector<double>& outliers) {
  if (v.empty()) return "";
  double lo = *std::min_element(v.begin(), v.end()), hi = *std::max_element(v.begin(), v.end());
  if (hi - lo < 1e-12) lo -= 0.5 * std::max(std::abs(lo), 1e-3), hi += 0.5 * std::max(std::abs(hi), 1e-3);
  const int bins = std::clamp(static_cast<int>(std::ceil(std::sqrt(static_cast<double>(v.size())))), 5, 15);
  std::vector<int> count(static_cast<std::size_t>(bins), 0);
  for (double x : v) count[static_cast<std::size_t>(std::min(bins - 1, static_cast<int>((x - lo) / (hi - lo) * bins)))]++;
  const int top = std::max(1, *std::max_element(count.begin(), count.end()));
  const Frame f{lo, hi};
  std::ostringstream o;
  o << "<figure><svg viewBox=\"0 0 " << Frame::kW << " " << Frame::kH << "\" role=\"img\" aria-label=\"" << html_escape(h.label)
    << " histogram\">";
  for (int b = 0; b < bins; ++b) {
    const double x0 = f.x(lo + (hi - lo) * b / bins), x1 = f.x(lo + (hi - lo) * (b + 1) / bins), y = f.y(count[b], top);
    o << "<rect x=\"" << x0 + 1 << "\" y=\"" << y << "\" width=\"" << std::max(1.0, x1 - x0 - 2) << "\" height=\""
      << Frame::kH - Frame::kBottom - y << "\" class=\"bar\"/>";
    if (count[b]) o << "<text x=\"" << (x0 + x1) / 2 << "\" y=\"" << y - 3 << "\" text-anchor=\"middle\">" << count[b] << "</text>";
  }
  for (double x : outliers)
    o << "<line x1=\"" << f.x(x) << "\" y1=\"" << Frame::kH - Frame::kBottom - 7 << "\" x2=\"" << f.x(x) << "\" y2=\""
      << Frame::kH - Frame::kBottom << "\" class=\"outlier\"/>";
  o << band_edges_svg(f, h.bands) << axes_svg(f, top, h.label) << "</svg><figcaption>" << html_escape(h.label) << ": n = " << v.size()
    << (outliers.empty() ? "" : ", " + std::to_string(outliers.size()) + " outlier(s) (orange)") << "</figcaption></figure>\n";
  return o.str();
}

// Distributions, and for each study the scores it is an outlier in.
std::string distributions(const Table& t, std::map<std::size_t, std::vector<std::string>>& outliers) {
  std::ostringstream figs;
  for (const Histogram& h : kHistograms) {
    const auto v = t.numbers(h.column);
    std::vector<double> x, out;
    for (const auto& [i, val] : v) x.push_back(val);
    if (x.size() >= 4) {
      std::vector<double> s = x;
      std::sort(s.begin(), s.end());
      const double q1 = s[s.size() / 4], q3 = s[3 * s.size() / 4], iqr = q3 - q1;
      for (const auto& [i, val] : v)
        if (val > q3 + kTukeyFence * iqr || val < q1 - kTukeyFence * iqr) outliers[i].push_back(h.column), out.push_back(val);
    }
    figs << histogram_svg(x, h, out);
  }
  return figs.str();
}

std::string groups_section(const std::vector<std::vector<std::string>>& rows) {
  if (rows.empty()) return "";
  std::ostringstream h;
  h << "<h2>Groups</h2>\n<p>Per score and pair of groups: median [Q1, Q3], Mann–Whitney U (two-sided, normal approximation), "
       "Cliff's delta with a percentile-bootstrap 95 % interval (2000 resamples). Also in cohort_groups.csv.</p>\n"
       "<div class=\"wrap\"><table><tr><th>score</th><th>group A</th><th>group B</th><th>n</th><th>median A [Q1, Q3]</th>"
       "<th>median B [Q1, Q3]</th><th>U</th><th>p</th><th>Cliff's δ [95 % CI]</th></tr>\n";
  for (const auto& r : rows)
    h << "<tr><td class=\"l\">" << html_escape(r[0]) << "</td><td class=\"l\">" << html_escape(r[1]) << "</td><td class=\"l\">"
      << html_escape(r[2]) << "</td><td>" << r[3] << " / " << r[4] << "</td><td>" << r[5] << " [" << r[6] << ", " << r[7]
      << "]</td><td>" << r[8] << " [" << r[9] << ", " << r[10] << "]</td><td>" << r[11] << "</td><td>" << r[12] << "</td><td>"
      << r[13] << " [" << r[14] << ", " << r[15] << "]</td></tr>\n";
  h << "</table></div>\n";
  return h.str();
}

std::string study_row(const Study& s, const std::vector<std::string>& cells, const std::vector<std::string>& outliers) {
  std::ostringstream h;
  const bool ok = s.status == "ok" || s.status == "done-earlier";
  h << "<tr class=\"" << (ok ? (outliers.empty() ? "" : "out") : s.status == "qc_failed" ? "qc" : "bad") << "\"><td class=\"l id\">";
  if (s.has_result()) h << "<a href=\"" << html_escape(s.id) << "/report.html\">" << html_escape(s.id) << "</a>";
  else h << html_escape(s.id);
  h << "</td><td class=\"l\">" << html_escape(s.status) << (s.error.empty() ? "" : ": " + html_escape(s.error)) << "</td><td>"
    << (s.exit_code >= 0 ? std::to_string(s.exit_code) : "") << (s.signal ? " (signal " + std::to_string(s.signal) + ")" : "")
    << "</td><td>" << (s.seconds >= 0 ? num(s.seconds) : "") << "</td>";
  for (const auto& c : cells) h << "<td>" << html_escape(c) << "</td>";
  std::string o;
  for (const auto& n : outliers) o += (o.empty() ? "" : ", ") + n;
  h << "<td class=\"l out-col\">" << html_escape(o) << "</td></tr>\n";
  return h.str();
}


}  // namespace

void write_cohort_html(const std::vector<Study>& studies, const Table& t, const std::vector<std::vector<std::string>>& group_rows,
                       const fs::path& out, bool interrupted) {
  std::size_t n_ok = 0, n_qc = 0;
  for (const auto& s : studies) n_ok += s.status == "ok" || s.status == "done-earlier", n_qc += s.status == "qc_failed";
  std::map<std::size_t, std::vector<std::string>> outliers;
  const std::string figs = distributions(t, outliers);
  std::ostringstream h;
  h << "<h1>Cohort</h1>\n<p>" << studies.size() << " studies: " << n_ok << " complete, " << n_qc
    << " failed quality control (outputs written), " << studies.size() - n_ok - n_qc << " failed or not run."
    << (interrupted ? " <strong>Interrupted.</strong>" : "")
    << " Outliers: beyond 1.5 IQR of the cohort. Dashed lines: the interpretation bands' edges (docs/report.md).</p>\n"
    << "<h2>Distributions</h2>\n<div class=\"figs\">" << figs << "</div>\n" << groups_section(group_rows)
    << "<h2>Studies</h2>\n<div class=\"wrap\"><table><tr><th class=\"l id\">study</th><th class=\"l\">status</th><th>exit code</th>"
       "<th>seconds</th>";
  for (const auto& c : t.columns) h << "<th>" << html_escape(c) << "</th>";
  h << "<th class=\"l out-col\">outlier in</th></tr>\n";
  for (std::size_t i = 0; i < studies.size(); ++i) h << study_row(studies[i], t.rows[i], outliers[i]);
  h << "</table></div>\n";
  reports::write_text_atomic((out / "cohort.html").string(), reports::html_page("MandiSym cohort", h.str()));
}

}  // namespace ms::pipeline::cohort
