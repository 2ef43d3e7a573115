// Writes seed inputs for fuzz_compare (format in fuzz_compare.cpp:
// PRE results.json \0 POST results.json \0 PRE srd.json \0 POST srd.json)
// from the JSON of two real run folders in fuzz/seeds/compare/ (`mandisym run`
// on sample_dicom/symmetric and sample_dicom/ramus_L_plus4mm, docs/fuzzing.md),
// written compact, plus variants that reach each consistency warning and the
// alignment's paths: the same scan twice, POST dated before PRE, a
// de-identified run, a moved ramus, too few common landmarks, srd.json with
// other bins.
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "core/json_text.h"

namespace fs = std::filesystem;
using Value = ms::Json;
using ms::json_numbers;
using ms::parse_json;

namespace {

Value read(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return parse_json(std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>()));
}

// Only the members compare reads: input, landmarks, symmetry_plane, scores.
Value lean_results(const Value& r) {
  Value o = Value::object();
  for (const char* k : {"input", "landmarks", "symmetry_plane", "scores"})
    if (const ms::Json* v = ms::find_member(r, k)) o[k] = *v;
  return o;
}

// The first `n` landmarks' descriptors.
Value lean_srd(const Value& s, std::size_t n) {
  Value o = Value::object();
  for (const auto& [k, v] : s.items()) {
    if (k != "landmarks") {
      o[k] = v;
      continue;
    }
    Value l = Value::object();
    for (const auto& [name, blocks] : v.items())
      if (l.size() < n) l[name] = blocks;
    o[k] = l;
  }
  return o;
}

void write(const fs::path& out, const std::string& name, const Value& pre, const Value* post, const Value* pre_srd,
           const Value* post_srd) {
  std::string bytes = ms::dump_json(pre, 0);
  if (post) bytes += std::string(1, '\0') + post->dump(0);
  if (pre_srd) bytes += std::string(1, '\0') + pre_srd->dump(0);
  if (post_srd) bytes += std::string(1, '\0') + post_srd->dump(0);
  std::ofstream(out / (name + ".seed"), std::ios::binary) << bytes;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) return 2;
  const fs::path out = argv[1], in = MANDISYM_COMPARE_SEEDS;
  fs::create_directories(out);
  const Value pre = read(in / "pre_results.json"), post = read(in / "post_results.json");
  const Value pre_srd = read(in / "pre_srd.json"), post_srd = read(in / "post_srd.json");
  write(out, "full", pre, &post, &pre_srd, &post_srd);
  write(out, "results_only", pre, &post, nullptr, nullptr);
  write(out, "same_run", pre, nullptr, nullptr, nullptr);
  const Value lpre = lean_results(pre), lpost = lean_results(post);
  const Value spre = lean_srd(pre_srd, 2), spost = lean_srd(post_srd, 2);
  write(out, "lean", lpre, &lpost, &spre, &spost);
  write(out, "lean_swapped", lpost, &lpre, &spost, &spre);
  Value v = lpost;
  v["input"]["study_date"] = "20251201";
  write(out, "post_before_pre", lpre, &v, nullptr, nullptr);
  v = lpost;
  v["input"]["path"] = "(removed)";
  write(out, "deidentified", lpre, &v, nullptr, nullptr);
  v = lpost;
  for (const char* n : {"Co_L", "Cr_L", "Go_L"}) v["landmarks"][n][std::size_t{0}] = v["landmarks"][n][std::size_t{0}].get<double>() + 12;
  write(out, "ramus_moved", lpre, &v, &spre, &spost);
  v = lpost;
  Value two = Value::object();
  for (const char* n : {"Me", "Pog"}) {
    const ms::Json* p = ms::find_member(lpost.at("landmarks"), n);
    two[n] = p ? *p : Value();
  }
  v["landmarks"] = two;
  write(out, "two_landmarks", lpre, &v, nullptr, nullptr);
  Value s = spost;
  s["bins"] = 6;
  write(out, "srd_other_bins", lpre, &lpost, &spre, &s);
  return 0;
}
