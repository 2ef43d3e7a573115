#include "core/json_text.h"

#include <set>
#include <stdexcept>
#include <vector>

namespace ms {

Json parse_json(const std::string& text) {
  // One set of keys per open object, to find duplicates as the parser meets
  // them (nlohmann itself keeps the last value of a duplicate key).
  std::vector<std::set<std::string>> open_objects;
  int open_containers = 0;
  const Json::parser_callback_t check = [&](int /*depth*/, Json::parse_event_t event, Json& parsed) {
    switch (event) {
      case Json::parse_event_t::object_start:
        open_objects.emplace_back();
        [[fallthrough]];
      case Json::parse_event_t::array_start:
        if (++open_containers > kMaxJsonDepth)
          throw std::runtime_error("JSON parse error: nesting deeper than " + std::to_string(kMaxJsonDepth));
        break;
      case Json::parse_event_t::object_end:
        open_objects.pop_back();
        [[fallthrough]];
      case Json::parse_event_t::array_end: --open_containers; break;
      case Json::parse_event_t::key: {
        const std::string& key = parsed.get_ref<const std::string&>();
        if (!open_objects.back().insert(key).second)
          throw std::runtime_error("JSON parse error: duplicate key " + dump_json(Json(key), -1) + " in one object");
        break;
      }
      default: break;
    }
    return true;
  };
  return Json::parse(text, check, /*allow_exceptions=*/true, /*ignore_comments=*/false);
}

std::string dump_json(const Json& j, int indent) {
  return j.dump(indent, ' ', /*ensure_ascii=*/false, Json::error_handler_t::replace);
}

JsonKind json_kind(const Json& v) {
  switch (v.type()) {
    case Json::value_t::null: return JsonKind::Null;
    case Json::value_t::boolean: return JsonKind::Bool;
    case Json::value_t::number_integer:
    case Json::value_t::number_unsigned:
    case Json::value_t::number_float: return JsonKind::Number;
    case Json::value_t::string: return JsonKind::String;
    case Json::value_t::array: return JsonKind::Array;
    case Json::value_t::object: return JsonKind::Object;
    default: return JsonKind::Other;
  }
}

const char* json_kind_name(JsonKind k) {
  switch (k) {
    case JsonKind::Null: return "null";
    case JsonKind::Bool: return "bool";
    case JsonKind::Number: return "number";
    case JsonKind::String: return "string";
    case JsonKind::Array: return "array";
    case JsonKind::Object: return "object";
    default: return "binary value";
  }
}

}  // namespace ms
