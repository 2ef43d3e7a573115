// `mandisym VERB --help` shows the defaults the Options structs hold.
//
// For each verb whose options fill an Options struct (run: io::ReadOptions,
// segmentation::Options, surface::Options, asymmetry::SafOptions; phantom:
// phantom::PhantomParams, io::DicomSeriesSpec), the printed help is parsed
// and every "(default: X)" is checked against the default-constructed struct:
// numbers by value ("0.8" for a Vec3 means all three axes), words as text,
// and a default described in words ("from the file") against the struct's
// "not set" value. A default shown in help must have an entry here, so a new
// option cannot bring an unchecked default; the few defaults that belong to
// the verb and no struct are listed as such. compare, batch and inspect fill
// no Options struct.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <map>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "asymmetry/saf.h"
#include "core/memory.h"
#include "io/volume_io.h"
#include "phantom/phantom.h"
#include "segmentation/segmentation.h"
#include "surface/surface.h"

namespace {

// The stdout of `mandisym ARGS`.
std::string help_text(const std::string& verb) {
  std::string out;
  if (FILE* p = ::popen((std::string(MANDISYM_BINARY) + " " + verb + " --help").c_str(), "r")) {
    char buf[4096];
    for (std::size_t n; (n = std::fread(buf, 1, sizeof buf, p)) > 0;) out.append(buf, n);
    EXPECT_EQ(::pclose(p), 0) << verb << " --help failed";
  }
  return out;
}

// option -> the default --help shows for it (options without one are left out).
// cli::help prints "  --NAME [VALUE]" and then one line "      HELP (default: X) [LO to HI]".
std::map<std::string, std::string> shown_defaults(const std::string& help) {
  static const std::regex option_line("^  --([a-zA-Z0-9-]+)( .*)?$");
  static const std::regex default_part(R"(\(default: (.*)\)( \[[^\]]*\])?$)");
  std::map<std::string, std::string> out;
  std::istringstream in(help);
  std::string line, option;
  while (std::getline(in, line)) {
    std::smatch m;
    if (std::regex_match(line, m, option_line)) {
      option = m[1];
    } else if (!option.empty() && std::regex_search(line, m, default_part)) {
      out[option] = m[1];
      option.clear();
    } else {
      option.clear();
    }
  }
  return out;
}

// A comma-separated list of numbers, or nothing when `text` is not one.
std::vector<double> numbers(const std::string& text) {
  std::vector<double> v;
  std::stringstream ss(text);
  for (std::string item; std::getline(ss, item, ',');) {
    char* end = nullptr;
    const double x = std::strtod(item.c_str(), &end);
    if (item.empty() || *end != '\0') return {};
    v.push_back(x);
  }
  return v;
}

// What one option's shown default must be.
struct Expected {
  std::string option;
  std::vector<double> values;  // a number (or x,y,z) the struct holds; empty: `text`
  std::string text;            // the words help shows
  bool struct_agrees = true;   // for words: the struct's field holds what they describe
  std::string where;           // the struct field, for the failure message
};

// A number the struct holds.
Expected field(const std::string& option, double v, const std::string& where) { return {option, {v}, "", true, where}; }
// x,y,z the struct holds ("0.8" in help: every axis).
Expected field(const std::string& option, const ms::Vec3& v, const std::string& where) {
  return {option, {v[0], v[1], v[2]}, "", true, where};
}
// Words the struct holds (a choice) or describes (an unset field: "from the file").
Expected words(const std::string& option, const std::string& shown, bool struct_agrees, const std::string& where) {
  return {option, {}, shown, struct_agrees, where};
}

void check_verb(const std::string& verb, const std::vector<Expected>& expected) {
  const std::string help = help_text(verb);
  ASSERT_FALSE(help.empty()) << verb << " --help printed nothing";
  const auto shown = shown_defaults(help);
  ASSERT_FALSE(shown.empty()) << "no '(default: ...)' parsed from " << verb << " --help:\n" << help;
  std::map<std::string, bool> checked;
  for (const Expected& e : expected) {
    SCOPED_TRACE(verb + " --" + e.option + " (" + e.where + ")");
    checked[e.option] = true;
    const auto it = shown.find(e.option);
    ASSERT_NE(it, shown.end()) << "--help shows no default for --" << e.option;
    EXPECT_TRUE(e.struct_agrees) << "the struct does not hold what --help calls the default, '" << it->second << "'";
    if (e.values.empty()) {
      EXPECT_EQ(it->second, e.text);
      continue;
    }
    std::vector<double> v = numbers(it->second);
    if (v.size() == 1 && e.values.size() == 3) v.assign(3, v[0]);  // "0.8": every axis
    ASSERT_EQ(v.size(), e.values.size()) << "--help shows '" << it->second << "'";
    for (std::size_t k = 0; k < v.size(); ++k)
      EXPECT_DOUBLE_EQ(v[k], e.values[k]) << "--help shows '" << it->second << "'";
  }
  for (const auto& [option, value] : shown)
    EXPECT_TRUE(checked.count(option)) << verb << " --" << option << " shows default '" << value
                                       << "' that this test does not check against a struct";
}

}  // namespace

TEST(HelpDefaults, RunShowsTheOptionsStructsDefaults) {
  const ms::io::ReadOptions read;
  const ms::segmentation::Options seg;
  const ms::surface::Options surface;
  const ms::asymmetry::SafOptions saf;
  const std::string budget = std::to_string(static_cast<int>(ms::kMemoryBudgetFraction * 100)) + " % of this machine's (or cgroup's) memory";
  check_verb("run", {
      field("hu-offset", read.hu_offset, "io::ReadOptions::hu_offset"),
      words("series", "finest CT series covering the scan", read.series_uid.empty(), "io::ReadOptions::series_uid empty"),
      words("orientation", "from the file", read.orientation.empty(), "io::ReadOptions::orientation empty"),
      words("max-memory", budget, read.max_memory_bytes == 0, "io::ReadOptions::max_memory_bytes 0: default_memory_budget_bytes()"),
      field("bone-threshold", seg.bone_threshold_hu, "segmentation::Options::bone_threshold_hu"),
      field("target-faces", static_cast<double>(surface.target_faces), "surface::Options::target_faces"),
      field("edge-length", surface.target_edge_mm, "surface::Options::target_edge_mm"),
      field("disk-radius", saf.disk_radius_mm, "asymmetry::SafOptions::disk_radius_mm"),
      field("saf-smoothing", saf.smoothing_mm, "asymmetry::SafOptions::smoothing_mm"),
      // Defaults of the run verb itself (pipeline/run.cpp, run_settings) that
      // no Options struct holds: the mask's label, the SAF anchors, and the
      // closing before meshing, where run sets surface::Options::
      // close_handles_auto (the struct's own default is no closing).
      words("label", "the only label", true, "run: no --label is label -1"),
      words("saf-anchors", "reference", true, "run: RunSettings::anchors"),
      words("close-handles", "auto", true, "run: surface::Options::close_handles_auto set by run_settings"),
      words("threads", "0 (the cores this process may use)", true, "run: threads::set_budget(0) = available_cores()"),
  });
}

TEST(HelpDefaults, PhantomShowsPhantomParamsDefaults) {
  const ms::phantom::PhantomParams p;
  const ms::io::DicomSeriesSpec dicom;
  std::vector<Expected> expected = {
      field("spacing", p.spacing, "PhantomParams::spacing"),
      field("fov", p.fov_mm, "PhantomParams::fov_mm"),
      field("noise", p.noise_hu, "PhantomParams::noise_hu"),
      field("blur", p.blur_mm, "PhantomParams::blur_mm"),
      field("yaw", p.yaw_deg, "PhantomParams::yaw_deg"),
      field("pitch", p.pitch_deg, "PhantomParams::pitch_deg"),
      field("roll", p.roll_deg, "PhantomParams::roll_deg"),
      field("shift", p.shift_mm, "PhantomParams::shift_mm"),
      field("occlusal-gap", p.occlusal_gap_mm, "PhantomParams::occlusal_gap_mm"),
      field("joint-space", p.joint_space_mm, "PhantomParams::joint_space_mm"),
      field("chin", p.chin_deviation_mm, "PhantomParams::chin_deviation_mm"),
      field("scale", p.scale, "PhantomParams::scale"),
      field("cortex", p.cortex_mm, "PhantomParams::cortex_mm"),
      field("cortical-hu", p.cortical_hu, "PhantomParams::cortical_hu"),
      field("cancellous-hu", p.cancellous_hu, "PhantomParams::cancellous_hu"),
      field("crown-scale", p.crown_scale, "PhantomParams::crown_scale"),
      field("seed", static_cast<double>(p.seed), "PhantomParams::seed"),
      words("compression", dicom.compression, true, "io::DicomSeriesSpec::compression"),
  };
  const char* sides[2] = {"L", "R"};
  for (int s = 0; s < 2; ++s) {
    const auto& a = p.side[s];
    const std::string side = std::string("PhantomParams::side[") + sides[s] + "].";
    expected.push_back(field(std::string("ramus-") + sides[s], a.ramus_height_mm, side + "ramus_height_mm"));
    expected.push_back(field(std::string("body-") + sides[s], a.body_length_mm, side + "body_length_mm"));
    expected.push_back(field(std::string("gonial-") + sides[s], a.gonial_angle_deg, side + "gonial_angle_deg"));
    expected.push_back(field(std::string("condyle-") + sides[s], a.condyle_size_mm, side + "condyle_size_mm"));
  }
  check_verb("phantom", expected);
}

// The parser itself: a default with parentheses, a range after it, an option without one.
TEST(HelpDefaults, ParsesCliHelpLayout) {
  const auto d = shown_defaults(
      "Options:\n"
      "  --max-memory SIZE\n      budget (docs) (default: 75 % of this machine's (or cgroup's) memory)\n"
      "  --disk-radius MM\n      radius (default: 2) [0.1 to 10]\n"
      "  --quiet\n      print nothing but errors\n");
  ASSERT_EQ(d.size(), 2u);
  EXPECT_EQ(d.at("max-memory"), "75 % of this machine's (or cgroup's) memory");
  EXPECT_EQ(d.at("disk-radius"), "2");
}
