// The cohort files of `mandisym batch` (docs/batch.md, "Outputs" and "Group
// comparison"): cohort.csv, cohort.html and, when the CSV source has a
// `group` column, cohort_groups.csv.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace ms::pipeline::cohort {

// One study of a cohort and how its run ended.
struct Study {
  std::string id;    // safe folder name (pseudonymous under --deidentify)
  std::string name;  // as listed (folder entry or CSV id)
  std::string path;
  std::string group;               // the CSV's `group` column ("" when none)
  std::string status = "pending";  // ok | qc_failed | failed | killed | timeout | done-earlier | not run (interrupted)
  int exit_code = -1;              // the child's exit code; -1: it did not exit (killed, timeout, not started): empty in cohort.csv
  int signal = 0;                  // the signal that ended it (killed, timeout), else 0
  std::string error;
  double seconds = -1;               // wall-clock of its run; < 0: not run here
  long peak_kb = -1;                 // peak resident memory of its run (wait4's ru_maxrss); < 0: not run here
  std::vector<std::string> options;  // its own run options (CSV columns), after batch's `--` options
  std::string run_options;           // the options its run was given (scrubbed under --deidentify)

  bool has_result() const { return status == "ok" || status == "done-earlier" || status == "qc_failed"; }
};

// Per-study numbers: the columns of each study's results.csv (without its
// `study` and `status`), then fields of its results.json that results.csv
// lacks (QC status, interpretation bands, menton deviation). Cells are text
// as written; "" where a study has no value.
struct Table {
  std::vector<std::string> columns;
  std::vector<std::vector<std::string>> rows;  // one per study, columns.size() cells

  // The numeric values of a column, with the row each came from.
  std::vector<std::pair<std::size_t, double>> numbers(const std::string& column) const;
};
Table read_results(const std::vector<Study>& studies, const std::filesystem::path& out);

void write_cohort_csv(const std::vector<Study>& studies, const Table& t, const std::filesystem::path& out);
// cohort_groups.csv (only when at least two groups have results); returns
// its rows for the HTML (empty when not written).
std::vector<std::vector<std::string>> write_cohort_groups(const std::vector<Study>& studies, const Table& t,
                                                          const std::filesystem::path& out);
void write_cohort_html(const std::vector<Study>& studies, const Table& t,
                       const std::vector<std::vector<std::string>>& group_rows, const std::filesystem::path& out,
                       bool interrupted);

// Splits one CSV line (RFC 4180 quoting).
std::vector<std::string> split_csv_line(const std::string& line);

}  // namespace ms::pipeline::cohort
