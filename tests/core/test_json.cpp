#include "core/json.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

using ms::json::ParseError;
using ms::json::Value;

Value sample() {
  Value v;
  v["name"] = "mandible \"left\"\n\tside";
  v["count"] = 3;
  v["ratio"] = 0.1;
  v["negative"] = -2.5e-8;
  v["flag"] = true;
  v["off"] = false;
  v["nothing"] = nullptr;
  v["point"] = Value::array_of(std::array<double, 3>{1.0, -2.5, 1e300});
  v["ints"] = Value::array_of(std::vector<int>{1, 2, 3});
  v["empty_arr"] = Value::array();
  v["empty_obj"] = Value::object();
  Value list = Value::array();
  list.push_back("a");
  list.push_back(Value::array_of(std::vector<double>{}));
  Value inner;
  inner["deep"]["deeper"] = "x";
  inner["unicode"] = "\xC3\xA9\xE2\x82\xAC\xF0\x9F\x98\x80";  // é € 😀
  list.push_back(inner);
  list.push_back(nullptr);
  v["list"] = list;
  return v;
}

// Takes text that must fail to parse; returns the ParseError message.
std::string parse_error(const std::string& text) {
  try {
    Value::parse(text);
  } catch (const ParseError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no ParseError for: " << text;
  return "";
}

bool has_location(const std::string& msg) {
  return msg.find("line ") != std::string::npos && msg.find("column ") != std::string::npos;
}

TEST(Json, RoundTripIndentedAndCompact) {
  const Value v = sample();
  for (int indent : {-1, 0, 2, 4}) {
    const std::string text = v.dump(indent);
    const Value back = Value::parse(text);
    EXPECT_EQ(back, v) << text;
    EXPECT_EQ(back.dump(indent), text);
  }
  EXPECT_EQ(v.dump(-1).find('\n'), std::string::npos);
}

TEST(Json, DumpLayout) {
  Value v;
  v["a"] = 1;
  v["p"] = Value::array_of(std::vector<double>{1, 2.5});
  Value mixed = Value::array();
  mixed.push_back(1);
  mixed.push_back(nullptr);
  mixed.push_back(true);
  v["m"] = mixed;
  Value strs = Value::array();
  strs.push_back("x");
  v["s"] = strs;
  v["e"] = Value::object();
  EXPECT_EQ(v.dump(),
            "{\n"
            "  \"a\": 1,\n"
            "  \"p\": [1, 2.5],\n"
            "  \"m\": [1, null, true],\n"
            "  \"s\": [\n"
            "    \"x\"\n"
            "  ],\n"
            "  \"e\": {}\n"
            "}");
  EXPECT_EQ(v.dump(-1), "{\"a\":1,\"p\":[1,2.5],\"m\":[1,null,true],\"s\":[\"x\"],\"e\":{}}");
}

TEST(Json, NumberFormatting) {
  EXPECT_EQ(Value(0.1).dump(), "0.1");
  EXPECT_EQ(Value(3).dump(), "3");
  EXPECT_EQ(Value(3.0).dump(), "3");
  EXPECT_EQ(Value(-17L).dump(), "-17");
  EXPECT_EQ(Value(123456789012LL).dump(), "123456789012");
  EXPECT_EQ(Value(1e300).dump(), "1e+300");
  EXPECT_EQ(Value(-0.0).dump(), "-0");
  EXPECT_EQ(Value(std::nan("")).dump(), "null");
  EXPECT_EQ(Value(std::numeric_limits<double>::infinity()).dump(), "null");
  EXPECT_EQ(Value(-std::numeric_limits<double>::infinity()).dump(), "null");
  EXPECT_EQ(Value::parse("1e300").as_number(), 1e300);
  EXPECT_TRUE(std::signbit(Value::parse("-0").as_number()));
  EXPECT_TRUE(std::signbit(Value::parse("-0.0").as_number()));

  // Shortest round-trip text for awkward doubles.
  for (double d : {0.1, 1.0 / 3.0, 2.0 / 3.0, 1e-300, 5e-324, 1.7976931348623157e308,
                   123.456, -9.87654321e-5, 9007199254740993.0}) {
    EXPECT_EQ(Value::parse(Value(d).dump()).as_number(), d) << Value(d).dump();
  }
}

TEST(Json, NumberParsing) {
  EXPECT_EQ(Value::parse("0").as_number(), 0.0);
  EXPECT_EQ(Value::parse("-12.5e2").as_number(), -1250.0);
  EXPECT_EQ(Value::parse("1E+2").as_number(), 100.0);
  EXPECT_EQ(Value::parse("  42  ").as_number(), 42.0);
  EXPECT_EQ(Value::parse("1e-400").as_number(), 0.0);  // underflow -> 0
  EXPECT_TRUE(std::signbit(Value::parse("-1e-400").as_number()));
  EXPECT_EQ(Value::parse("0e99999999999999999999").as_number(), 0.0);
  for (const char* bad : {"01", "-", "+1", ".5", "1.", "1e", "1e+", "0x10", "1e400", "-1e400",
                          "NaN", "Infinity", "- 1"}) {
    EXPECT_TRUE(has_location(parse_error(bad))) << bad;
  }
}

TEST(Json, StringEscapes) {
  Value s(std::string("q\" b\\ n\n t\t r\r ctl\x01\x1f del\x7f / \xC3\xA9"));
  EXPECT_EQ(s.dump(), "\"q\\\" b\\\\ n\\n t\\t r\\r ctl\\u0001\\u001f del\x7f / \xC3\xA9\"");
  EXPECT_EQ(Value::parse(s.dump()), s);

  EXPECT_EQ(Value::parse(R"("\"\\\/\b\f\n\r\t")").as_string(), "\"\\/\b\f\n\r\t");
  EXPECT_EQ(Value::parse(R"("\u0041\u00e9\u20AC")").as_string(), "A\xC3\xA9\xE2\x82\xAC");
  EXPECT_EQ(Value::parse(R"("\u0000")").as_string(), std::string(1, '\0'));
  // Surrogate pair U+1F600 -> F0 9F 98 80; U+10FFFF -> F4 8F BF BF.
  EXPECT_EQ(Value::parse(R"("\ud83d\ude00")").as_string(), "\xF0\x9F\x98\x80");
  EXPECT_EQ(Value::parse(R"("\uDBFF\uDFFF")").as_string(), "\xF4\x8F\xBF\xBF");
  // Raw UTF-8 passes through unchanged.
  EXPECT_EQ(Value::parse("\"\xF0\x9F\x98\x80\"").as_string(), "\xF0\x9F\x98\x80");
  EXPECT_EQ(Value(std::string("\xF0\x9F\x98\x80")).dump(), "\"\xF0\x9F\x98\x80\"");
}

TEST(Json, ObjectOrderPreserved) {
  const Value v = Value::parse(R"({"z": 1, "a": 2, "m": {"y": 1, "b": 2}})");
  std::vector<std::string> keys;
  for (const auto& kv : v.items()) keys.push_back(kv.first);
  EXPECT_EQ(keys, (std::vector<std::string>{"z", "a", "m"}));
  EXPECT_EQ(v.dump(-1), R"({"z":1,"a":2,"m":{"y":1,"b":2}})");

  Value w;
  w["third"] = 3;
  w["first"] = 1;
  w["second"] = 2;
  w["first"] = 10;  // overwrite keeps position
  EXPECT_EQ(w.dump(-1), R"({"third":3,"first":10,"second":2})");
}

TEST(Json, EqualityIgnoresMemberOrder) {
  EXPECT_EQ(Value::parse(R"({"a":1,"b":[1,2]})"), Value::parse(R"({"b":[1,2],"a":1})"));
  EXPECT_NE(Value::parse(R"([1,2])"), Value::parse(R"([2,1])"));
  EXPECT_NE(Value(1), Value("1"));
  EXPECT_NE(Value(), Value(false));
  EXPECT_NE(Value(std::nan("")), Value(std::nan("")));
}

TEST(Json, Accessors) {
  const Value v = Value::parse(R"({"a": [10, 20], "s": "x", "b": false, "n": null})");
  EXPECT_TRUE(v.is_object());
  EXPECT_EQ(v.size(), 4u);
  EXPECT_TRUE(v.contains("a"));
  EXPECT_FALSE(v.contains("zz"));
  EXPECT_EQ(v.find("zz"), nullptr);
  ASSERT_NE(v.find("s"), nullptr);
  EXPECT_EQ(v.find("s")->as_string(), "x");
  EXPECT_EQ(v.at("a").size(), 2u);
  EXPECT_EQ(v.at("a")[1].as_number(), 20.0);
  EXPECT_EQ(v.at("a").elements().size(), 2u);
  EXPECT_FALSE(v.at("b").as_bool());
  EXPECT_TRUE(v.at("n").is_null());
  EXPECT_EQ(v.at("n").type(), Value::Type::Null);
  EXPECT_EQ(Value(5).size(), 0u);
  EXPECT_FALSE(Value(5).contains("a"));
  EXPECT_EQ(Value(5).find("a"), nullptr);
  EXPECT_TRUE(Value(static_cast<const char*>(nullptr)).is_null());
  EXPECT_TRUE(Value(7u).is_number());
  EXPECT_TRUE(Value(7ul).is_number());
  EXPECT_TRUE(Value(7ull).is_number());
}

TEST(Json, TypeErrorsThrow) {
  Value num(1.5);
  EXPECT_THROW(num["k"], std::logic_error);
  EXPECT_THROW(num.push_back(1), std::logic_error);
  EXPECT_THROW(num.as_string(), std::logic_error);
  EXPECT_THROW(num.as_bool(), std::logic_error);
  EXPECT_THROW(num.items(), std::logic_error);
  EXPECT_THROW(num.elements(), std::logic_error);
  EXPECT_THROW(num.at("k"), std::logic_error);
  EXPECT_THROW(Value("s").as_number(), std::logic_error);
  EXPECT_THROW(Value::object()[size_t{0}], std::logic_error);

  Value arr = Value::array();
  arr.push_back(1);
  EXPECT_THROW(arr["k"], std::logic_error);
  EXPECT_THROW(arr[1], std::out_of_range);
  arr[0] = "changed";  // mutable element access, literal 0 not ambiguous
  EXPECT_EQ(arr[0].as_string(), "changed");

  const Value obj = Value::parse(R"({"present": 1})");
  try {
    obj.at("missing_key");
    FAIL() << "expected out_of_range";
  } catch (const std::out_of_range& e) {
    EXPECT_NE(std::string(e.what()).find("missing_key"), std::string::npos);
  }

  // null converts to object / array on first use.
  Value n1;
  n1["k"] = 1;
  EXPECT_TRUE(n1.is_object());
  Value n2;
  n2.push_back(1);
  EXPECT_TRUE(n2.is_array());
}

TEST(Json, ParseErrorsCarryLocation) {
  const std::string msg = parse_error("{\n  \"a\": 1,\n  \"b\": tru\n}");
  EXPECT_NE(msg.find("line 3, column 8"), std::string::npos) << msg;

  const char* bad_inputs[] = {
      "",                      // empty
      "   ",                   // only whitespace
      "[1, 2,]",               // trailing comma in array
      "{\"a\": 1,}",           // trailing comma in object
      "\"unterminated",        // unterminated string
      "[\"abc",                // unterminated string in array
      R"("bad \x escape")",    // bad escape
      R"("\u12G4")",           // bad hex
      R"("\ud83d")",           // lone high surrogate
      R"("\ud83d\u0041")",     // high surrogate + non-low
      R"("\ude00")",           // lone low surrogate
      "\"tab\there\"",         // raw control char
      "\"\xC3\"",              // truncated UTF-8
      "\"\xC0\xAF\"",          // overlong UTF-8
      "\"\xED\xA0\x80\"",      // UTF-8 encoded surrogate
      "{} x",                  // trailing garbage
      "[1] [2]",               // two values
      "1 2",                   // two values
      "{\"a\" 1}",             // missing colon
      "{1: 2}",                // non-string key
      "{\"a\": 1, \"a\": 2}",  // duplicate key
      "[1 2]",                 // missing comma
      "nul",                   // bad literal
      "True",                  // bad literal
      "[",                     // unexpected end
      "{",                     // unexpected end
      "'single'",              // single quotes
  };
  for (const char* text : bad_inputs) {
    const std::string m = parse_error(text);
    EXPECT_TRUE(has_location(m)) << "input: " << text << " message: " << m;
  }
}

TEST(Json, NestingDepthLimit) {
  const std::string ok = std::string(256, '[') + std::string(256, ']');
  EXPECT_NO_THROW(Value::parse(ok));
  const std::string too_deep = std::string(257, '[') + std::string(257, ']');
  EXPECT_TRUE(has_location(parse_error(too_deep)));
  std::string objs;
  for (int i = 0; i < 300; ++i) objs += "{\"k\":";
  objs += "1";
  objs += std::string(300, '}');
  EXPECT_TRUE(has_location(parse_error(objs)));
  // Far deeper input must not blow the stack either.
  EXPECT_THROW(Value::parse(std::string(1000000, '[')), ParseError);
}

TEST(Json, WhitespaceAndBom) {
  EXPECT_EQ(Value::parse(" \t\r\n[ 1 ,\n 2 ] \n"), Value::array_of(std::vector<int>{1, 2}));
  EXPECT_EQ(Value::parse("\xEF\xBB\xBF{\"a\":true}").at("a").as_bool(), true);
  EXPECT_TRUE(Value::parse("null").is_null());
  EXPECT_EQ(Value::parse("\"top\"").as_string(), "top");
}

}  // namespace
