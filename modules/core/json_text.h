// JSON for MandiSym's files (results.json, compare.json, manifests, Slicer
// markups): nlohmann::json (Debian nlohmann-json3-dev) with insertion-ordered
// objects, plus the project's two text policies:
//  - parse_json: strict reading of files that may be hostile or hand-edited
//    (compare inputs, batch manifests);
//  - dump_json: writing that never throws on text from the outside world
//    (file names or DICOM strings in another encoding).
#pragma once

#include <nlohmann/json.hpp>

#include <string>
#include <type_traits>

namespace ms {

using Json = nlohmann::ordered_json;

// Deepest nesting parse_json accepts. MandiSym's files nest at most 5 deep;
// 256 leaves room for any hand-edited file and bounds the parser's work on a
// hostile one.
constexpr int kMaxJsonDepth = 256;

// Parses a complete RFC 8259 JSON text (nlohmann's parser: invalid UTF-8,
// lone surrogate escapes, trailing text and numbers overflowing a double are
// errors). In addition rejects nesting deeper than kMaxJsonDepth and
// duplicate object keys (a file that says two things about one field is not
// read at all). Throws std::runtime_error (nlohmann's parse_error, or one of
// ours for depth/duplicates) whose message names the position or the key.
Json parse_json(const std::string& text);

// Serialises: indent < 0 gives one line; otherwise `indent` spaces per
// level. Bytes that are not well-formed UTF-8 are written as U+FFFD, so the
// output is always valid JSON; NaN and infinities are written as null.
std::string dump_json(const Json& j, int indent = 2);

// The member `key` of `obj`, or nullptr when obj is not an object or has no
// such member.
inline const Json* find_member(const Json& obj, const std::string& key) {
  if (!obj.is_object()) return nullptr;
  const auto it = obj.find(key);
  return it == obj.end() ? nullptr : &*it;
}

// The JSON type of a value as RFC 8259 names it (integers and floats are both
// numbers), for strict readers and their messages.
enum class JsonKind { Null, Bool, Number, String, Array, Object, Other };
JsonKind json_kind(const Json& v);
// "null", "bool", "number", "string", "array", "object" (or "binary value").
const char* json_kind_name(JsonKind k);

// An array of numbers from any iterable of arithmetic values, e.g.
// std::array<double, 3> or std::vector<int>: integers stay integers ("140"),
// everything else is written as a double.
template <class T>
Json json_numbers(const T& container) {
  Json a = Json::array();
  for (const auto& x : container) {
    if constexpr (std::is_integral_v<std::decay_t<decltype(x)>>)
      a.push_back(static_cast<long long>(x));
    else
      a.push_back(static_cast<double>(x));
  }
  return a;
}

}  // namespace ms
