// The project's JSON text policies on top of nlohmann::json (core/json_text.h).
#include "core/json_text.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

using ms::dump_json;
using ms::Json;
using ms::parse_json;

// Takes text that must fail to parse; returns the error message.
std::string parse_error(const std::string& text) {
  try {
    parse_json(text);
  } catch (const std::exception& e) {
    return e.what();
  }
  ADD_FAILURE() << "no parse error for: " << text.substr(0, 80);
  return "";
}

std::string nested(int depth) { return std::string(depth, '[') + std::string(depth, ']'); }

TEST(JsonText, RoundTripKeepsMemberOrderAndValues) {
  Json v = Json::object();
  v["zeta"] = "mandible \"left\"\n\tside";
  v["alpha"] = 3;
  v["ratio"] = 0.1;
  v["point"] = ms::json_numbers(std::array<double, 3>{1.0, -2.5, 1e300});
  v["unicode"] = "\xC3\xA9\xE2\x82\xAC\xF0\x9F\x98\x80";  // é € 😀
  for (int indent : {-1, 0, 2}) {
    const Json back = parse_json(dump_json(v, indent));
    EXPECT_EQ(back, v) << indent;
    EXPECT_EQ(back.begin().key(), "zeta");
  }
  EXPECT_EQ(dump_json(Json(0.1), -1), "0.1");
  EXPECT_EQ(parse_json(dump_json(Json(1e300), -1)).get<double>(), 1e300);
}

TEST(JsonText, NonFiniteNumbersAreWrittenAsNull) {
  Json v = ms::json_numbers(std::vector<double>{std::nan(""), std::numeric_limits<double>::infinity(), 1.5});
  EXPECT_EQ(dump_json(v, -1), "[null,null,1.5]");
}

TEST(JsonText, InvalidUtf8IsWrittenAsReplacementCharacter) {
  // A file name in Latin-1 ("é" = 0xE9), a truncated sequence and a surrogate.
  const Json v = std::string("caf\xE9 \xE2\x82 \xED\xA0\x80");
  std::string text;
  ASSERT_NO_THROW(text = dump_json(v, -1));
  EXPECT_NE(text.find("caf\xEF\xBF\xBD"), std::string::npos) << text;
  EXPECT_NO_THROW(parse_json(text));
}

TEST(JsonText, DuplicateKeysAreRefusedAtAnyDepth) {
  EXPECT_NE(parse_error(R"({"a": 1, "a": 2})").find("duplicate key \"a\""), std::string::npos);
  EXPECT_NE(parse_error(R"({"x": {"b": 1, "c": 2, "b": 3}})").find("duplicate key \"b\""), std::string::npos);
  // The same key in sibling objects is fine.
  EXPECT_NO_THROW(parse_json(R"([{"a": 1}, {"a": 2}, {"b": {"a": 3}}])"));
}

TEST(JsonText, NestingDepthIsBounded) {
  EXPECT_NO_THROW(parse_json(nested(ms::kMaxJsonDepth)));
  EXPECT_NE(parse_error(nested(ms::kMaxJsonDepth + 1)).find("nesting deeper"), std::string::npos);
  // A hostile file: a million brackets fail fast, without exhausting the stack.
  EXPECT_THROW(parse_json(std::string(1000000, '[')), std::exception);
}

TEST(JsonText, MalformedTextIsRefusedWithItsPosition) {
  for (const char* text : {"", "{", "[1,]", "{\"a\" 1}", "[1] x", "\"\xC3\"", "\"\\uD800\"", "1e400", "nul"}) {
    const std::string msg = parse_error(text);
    EXPECT_FALSE(msg.empty()) << text;
  }
  EXPECT_NE(parse_error("{\n  \"a\": tru\n}").find("line 3"), std::string::npos);
}

TEST(JsonText, MemberLookupAndKinds) {
  const Json v = parse_json(R"({"n": 2, "f": 2.5, "s": "x", "b": true, "z": null, "a": [], "o": {}})");
  ASSERT_NE(ms::find_member(v, "n"), nullptr);
  EXPECT_EQ(ms::find_member(v, "missing"), nullptr);
  EXPECT_EQ(ms::find_member(v.at("a"), "n"), nullptr);  // not an object
  EXPECT_EQ(ms::json_kind(v.at("n")), ms::JsonKind::Number);
  EXPECT_EQ(ms::json_kind(v.at("f")), ms::JsonKind::Number);
  EXPECT_EQ(ms::json_kind(v.at("s")), ms::JsonKind::String);
  EXPECT_EQ(ms::json_kind(v.at("b")), ms::JsonKind::Bool);
  EXPECT_EQ(ms::json_kind(v.at("z")), ms::JsonKind::Null);
  EXPECT_EQ(ms::json_kind(v.at("a")), ms::JsonKind::Array);
  EXPECT_STREQ(ms::json_kind_name(ms::json_kind(v.at("o"))), "object");
  EXPECT_THROW(v.at("s").get<double>(), std::exception);
}

}  // namespace
