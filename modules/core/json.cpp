#include "core/json.h"

#include <charconv>
#include <cmath>
#include <cstdint>
#include <limits>
#include <system_error>

namespace ms::json {

namespace {

constexpr int kMaxDepth = 256;

// Takes a type and the operation attempted; returns a std::logic_error
// describing the mismatch.
std::logic_error type_error(const char* op, Value::Type actual) {
  return std::logic_error(std::string("json: ") + op + " on a " + type_name(actual) +
                          " value");
}

// ---------------------------------------------------------------- writing

// Takes a double and appends its JSON text to `out`: shortest round-trip
// form, "null" for NaN/inf.
void write_number(std::string& out, double d) {
  if (!std::isfinite(d)) {
    out += "null";
    return;
  }
  char buf[64];
  auto res = std::to_chars(buf, buf + sizeof(buf), d);
  out.append(buf, res.ptr);
}

// Length of the well-formed UTF-8 sequence starting at s[i] (RFC 3629:
// shortest form, no surrogates, at most U+10FFFF), or 0 when it is not one.
std::size_t utf8_sequence(const std::string& s, std::size_t i) {
  const auto b = [&](std::size_t k) { return static_cast<unsigned char>(s[k]); };
  const unsigned char c = b(i);
  if (c < 0x80) return 1;
  std::size_t n = c >= 0xC2 && c <= 0xDF ? 2 : c >= 0xE0 && c <= 0xEF ? 3 : c >= 0xF0 && c <= 0xF4 ? 4 : 0;
  if (n == 0 || i + n > s.size()) return 0;
  for (std::size_t k = 1; k < n; ++k)
    if ((b(i + k) & 0xC0) != 0x80) return 0;
  if (c == 0xE0 && b(i + 1) < 0xA0) return 0;   // overlong
  if (c == 0xED && b(i + 1) >= 0xA0) return 0;  // surrogate
  if (c == 0xF0 && b(i + 1) < 0x90) return 0;   // overlong
  if (c == 0xF4 && b(i + 1) >= 0x90) return 0;  // beyond U+10FFFF
  return n;
}

// Takes a string and appends it quoted and escaped to `out` (", \ and control
// characters escaped; well-formed UTF-8 copied as is; any other byte, e.g.
// of a file name in another encoding, written as U+FFFD, so that the output
// is always valid JSON text).
void write_string(std::string& out, const std::string& s) {
  static const char kHex[] = "0123456789abcdef";
  out += '"';
  for (std::size_t i = 0; i < s.size();) {
    const std::size_t n = utf8_sequence(s, i);
    if (n == 0) {
      out += "\xEF\xBF\xBD";
      ++i;
      continue;
    }
    if (n > 1) {
      out.append(s, i, n);
      i += n;
      continue;
    }
    const char ch = s[i++];
    const auto c = static_cast<unsigned char>(ch);
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\b': out += "\\b"; break;
      case '\f': out += "\\f"; break;
      case '\n': out += "\\n"; break;
      case '\r': out += "\\r"; break;
      case '\t': out += "\\t"; break;
      default:
        if (c < 0x20) {
          out += "\\u00";
          out += kHex[c >> 4];
          out += kHex[c & 0xF];
        } else {
          out += ch;
        }
    }
  }
  out += '"';
}

// Takes a newline flag and depth; appends a newline plus indentation
// (nothing when compact).
void newline(std::string& out, int indent, int depth) {
  if (indent < 0) return;
  out += '\n';
  out.append(static_cast<size_t>(indent) * static_cast<size_t>(depth), ' ');
}

// Takes a value, indent setting and current depth; appends its text to out.
void write_value(std::string& out, const Value& v, int indent, int depth) {
  switch (v.type()) {
    case Value::Type::Null: out += "null"; return;
    case Value::Type::Bool: out += v.as_bool() ? "true" : "false"; return;
    case Value::Type::Number: write_number(out, v.as_number()); return;
    case Value::Type::String: write_string(out, v.as_string()); return;
    case Value::Type::Array: {
      const auto& el = v.elements();
      if (el.empty()) {
        out += "[]";
        return;
      }
      bool flat = true;
      for (const auto& e : el) {
        if (e.is_array() || e.is_object() || e.is_string()) {
          flat = false;
          break;
        }
      }
      out += '[';
      for (size_t i = 0; i < el.size(); ++i) {
        if (i > 0) out += (flat && indent >= 0) ? ", " : ",";
        if (!flat) newline(out, indent, depth + 1);
        write_value(out, el[i], indent, depth + 1);
      }
      if (!flat) newline(out, indent, depth);
      out += ']';
      return;
    }
    case Value::Type::Object: {
      const auto& items = v.items();
      if (items.empty()) {
        out += "{}";
        return;
      }
      out += '{';
      for (size_t i = 0; i < items.size(); ++i) {
        if (i > 0) out += ',';
        newline(out, indent, depth + 1);
        write_string(out, items[i].first);
        out += indent >= 0 ? ": " : ":";
        write_value(out, items[i].second, indent, depth + 1);
      }
      newline(out, indent, depth);
      out += '}';
      return;
    }
  }
}

// ---------------------------------------------------------------- parsing

// Recursive-descent parser over a byte string. Each parse_* method consumes
// one production starting at pos_ and returns its value; errors throw
// ParseError located at the offending byte.
class Parser {
 public:
  explicit Parser(const std::string& text) : s_(text) {}

  // Parses the whole text; returns the single top-level value.
  Value parse_document() {
    if (s_.compare(0, 3, "\xEF\xBB\xBF") == 0) pos_ = 3;
    skip_ws();
    Value v = parse_value(0);
    skip_ws();
    if (pos_ != s_.size()) fail("unexpected trailing characters");
    return v;
  }

 private:
  const std::string& s_;
  size_t pos_ = 0;

  // Takes a message; throws ParseError with the line/column of `at`.
  [[noreturn]] void fail_at(size_t at, const std::string& what) const {
    size_t line = 1, col = 1;
    for (size_t i = 0; i < at && i < s_.size(); ++i) {
      if (s_[i] == '\n') {
        ++line;
        col = 1;
      } else {
        ++col;
      }
    }
    throw ParseError("JSON parse error at line " + std::to_string(line) + ", column " +
                     std::to_string(col) + ": " + what);
  }
  [[noreturn]] void fail(const std::string& what) const { fail_at(pos_, what); }

  bool at_end() const { return pos_ >= s_.size(); }
  char peek() const { return at_end() ? '\0' : s_[pos_]; }

  void skip_ws() {
    while (!at_end()) {
      char c = s_[pos_];
      if (c == ' ' || c == '\t' || c == '\n' || c == '\r') {
        ++pos_;
      } else {
        break;
      }
    }
  }

  // Takes the expected literal text; consumes it or fails.
  void expect_literal(const char* lit) {
    size_t start = pos_;
    for (const char* p = lit; *p; ++p) {
      if (at_end() || s_[pos_] != *p) fail_at(start, "invalid literal");
      ++pos_;
    }
  }

  Value parse_value(int depth) {
    if (at_end()) fail("unexpected end of input, expected a value");
    char c = s_[pos_];
    switch (c) {
      case '{': return parse_object(depth + 1);
      case '[': return parse_array(depth + 1);
      case '"': return Value(parse_string());
      case 't': expect_literal("true"); return Value(true);
      case 'f': expect_literal("false"); return Value(false);
      case 'n': expect_literal("null"); return Value();
      default:
        if (c == '-' || (c >= '0' && c <= '9')) return Value(parse_number());
        fail(std::string("unexpected character '") + printable(c) + "'");
    }
  }

  // Takes a byte; returns a printable rendering for error messages.
  static std::string printable(char c) {
    const auto u = static_cast<unsigned char>(c);
    if (u >= 0x20 && u < 0x7F) return std::string(1, c);
    static const char kHex[] = "0123456789ABCDEF";
    return std::string("\\x") + kHex[u >> 4] + kHex[u & 0xF];
  }

  Value parse_array(int depth) {
    if (depth > kMaxDepth) fail("nesting deeper than 256 levels");
    ++pos_;  // '['
    Value arr = Value::array();
    skip_ws();
    if (peek() == ']') {
      ++pos_;
      return arr;
    }
    for (;;) {
      skip_ws();
      arr.push_back(parse_value(depth));
      skip_ws();
      char c = peek();
      if (c == ',') {
        ++pos_;
        skip_ws();
        if (peek() == ']') fail("trailing comma in array");
        continue;
      }
      if (c == ']') {
        ++pos_;
        return arr;
      }
      if (at_end()) fail("unexpected end of input in array");
      fail("expected ',' or ']' in array");
    }
  }

  Value parse_object(int depth) {
    if (depth > kMaxDepth) fail("nesting deeper than 256 levels");
    ++pos_;  // '{'
    Value obj = Value::object();
    skip_ws();
    if (peek() == '}') {
      ++pos_;
      return obj;
    }
    for (;;) {
      skip_ws();
      if (peek() != '"') {
        if (at_end()) fail("unexpected end of input in object");
        fail(peek() == '}' ? "trailing comma in object" : "expected a string key");
      }
      size_t key_pos = pos_;
      std::string key = parse_string();
      if (obj.contains(key)) fail_at(key_pos, "duplicate key \"" + key + "\"");
      skip_ws();
      if (peek() != ':') fail("expected ':' after object key");
      ++pos_;
      skip_ws();
      Value member = parse_value(depth);
      obj[key] = std::move(member);
      skip_ws();
      char c = peek();
      if (c == ',') {
        ++pos_;
        continue;
      }
      if (c == '}') {
        ++pos_;
        return obj;
      }
      if (at_end()) fail("unexpected end of input in object");
      fail("expected ',' or '}' in object");
    }
  }

  // Reads 4 hex digits at pos_; returns their value.
  unsigned parse_hex4() {
    unsigned v = 0;
    for (int i = 0; i < 4; ++i) {
      if (at_end()) fail("unterminated \\u escape");
      char c = s_[pos_];
      v <<= 4;
      if (c >= '0' && c <= '9') {
        v |= static_cast<unsigned>(c - '0');
      } else if (c >= 'a' && c <= 'f') {
        v |= static_cast<unsigned>(c - 'a' + 10);
      } else if (c >= 'A' && c <= 'F') {
        v |= static_cast<unsigned>(c - 'A' + 10);
      } else {
        fail("invalid hex digit in \\u escape");
      }
      ++pos_;
    }
    return v;
  }

  // Takes a code point; appends its UTF-8 encoding to out.
  static void append_utf8(std::string& out, uint32_t cp) {
    if (cp < 0x80) {
      out += static_cast<char>(cp);
    } else if (cp < 0x800) {
      out += static_cast<char>(0xC0 | (cp >> 6));
      out += static_cast<char>(0x80 | (cp & 0x3F));
    } else if (cp < 0x10000) {
      out += static_cast<char>(0xE0 | (cp >> 12));
      out += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
      out += static_cast<char>(0x80 | (cp & 0x3F));
    } else {
      out += static_cast<char>(0xF0 | (cp >> 18));
      out += static_cast<char>(0x80 | ((cp >> 12) & 0x3F));
      out += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
      out += static_cast<char>(0x80 | (cp & 0x3F));
    }
  }

  // Validates one UTF-8 multi-byte sequence whose lead byte is at pos_ and
  // copies it to out (utf8_sequence: rejects overlong forms, surrogates,
  // > U+10FFFF).
  void copy_utf8_sequence(std::string& out) {
    const std::size_t len = utf8_sequence(s_, pos_);
    if (len == 0) fail("invalid UTF-8 sequence in string");
    out.append(s_, pos_, len);
    pos_ += len;
  }

  // Parses a quoted string at pos_; returns its decoded UTF-8 contents.
  std::string parse_string() {
    const size_t start = pos_;
    ++pos_;  // opening quote
    std::string out;
    for (;;) {
      if (at_end()) fail_at(start, "unterminated string");
      const auto c = static_cast<unsigned char>(s_[pos_]);
      if (c == '"') {
        ++pos_;
        return out;
      }
      if (c < 0x20) fail("unescaped control character in string");
      if (c >= 0x80) {
        copy_utf8_sequence(out);
        continue;
      }
      if (c != '\\') {
        out += static_cast<char>(c);
        ++pos_;
        continue;
      }
      const size_t esc_pos = pos_;
      ++pos_;
      if (at_end()) fail_at(start, "unterminated string");
      const char e = s_[pos_++];
      switch (e) {
        case '"': out += '"'; break;
        case '\\': out += '\\'; break;
        case '/': out += '/'; break;
        case 'b': out += '\b'; break;
        case 'f': out += '\f'; break;
        case 'n': out += '\n'; break;
        case 'r': out += '\r'; break;
        case 't': out += '\t'; break;
        case 'u': {
          uint32_t cp = parse_hex4();
          if (cp >= 0xDC00 && cp <= 0xDFFF) fail_at(esc_pos, "lone low surrogate in \\u escape");
          if (cp >= 0xD800 && cp <= 0xDBFF) {
            if (s_.compare(pos_, 2, "\\u") != 0) {
              fail_at(esc_pos, "high surrogate not followed by a low surrogate");
            }
            pos_ += 2;
            const uint32_t lo = parse_hex4();
            if (lo < 0xDC00 || lo > 0xDFFF) {
              fail_at(esc_pos, "high surrogate not followed by a low surrogate");
            }
            cp = 0x10000 + ((cp - 0xD800) << 10) + (lo - 0xDC00);
          }
          append_utf8(out, cp);
          break;
        }
        default: fail_at(esc_pos, std::string("invalid escape '\\") + printable(e) + "'");
      }
    }
  }

  // Parses an RFC 8259 number at pos_; returns it as a double. Overflow is
  // an error, underflow yields (signed) zero.
  double parse_number() {
    const size_t start = pos_;
    bool negative = false;
    if (peek() == '-') {
      negative = true;
      ++pos_;
    }
    auto is_digit = [this] { return !at_end() && s_[pos_] >= '0' && s_[pos_] <= '9'; };
    if (!is_digit()) fail("invalid number: expected a digit");
    // Decimal exponent of the leading significant digit, used to tell
    // overflow from underflow when from_chars reports out of range.
    long long magnitude = 0;
    bool seen_significant = false;
    if (s_[pos_] == '0') {
      ++pos_;
      if (is_digit()) fail_at(start, "invalid number: leading zero");
    } else {
      seen_significant = true;
      while (is_digit()) {
        ++pos_;
        ++magnitude;
      }
      magnitude -= 1;
    }
    if (peek() == '.') {
      ++pos_;
      if (!is_digit()) fail("invalid number: expected a digit after '.'");
      long long frac_index = 0;
      while (is_digit()) {
        --frac_index;
        if (!seen_significant && s_[pos_] != '0') {
          seen_significant = true;
          magnitude = frac_index;
        }
        ++pos_;
      }
    }
    if (peek() == 'e' || peek() == 'E') {
      ++pos_;
      bool exp_negative = false;
      if (peek() == '+' || peek() == '-') {
        exp_negative = peek() == '-';
        ++pos_;
      }
      if (!is_digit()) fail("invalid number: expected a digit in exponent");
      long long exp = 0;
      while (is_digit()) {
        if (exp < 1000000000LL) exp = exp * 10 + (s_[pos_] - '0');
        ++pos_;
      }
      magnitude += exp_negative ? -exp : exp;
    }
    double d = 0.0;
    const char* first = s_.data() + start;
    const char* last = s_.data() + pos_;
    auto res = std::from_chars(first, last, d);
    if (res.ec == std::errc::result_out_of_range) {
      if (seen_significant && magnitude >= 0) fail_at(start, "number out of range");
      return negative ? -0.0 : 0.0;
    }
    if (res.ec != std::errc() || res.ptr != last) fail_at(start, "invalid number");
    return d;
  }
};

}  // namespace

const char* type_name(Value::Type t) {
  switch (t) {
    case Value::Type::Null: return "null";
    case Value::Type::Bool: return "bool";
    case Value::Type::Number: return "number";
    case Value::Type::String: return "string";
    case Value::Type::Array: return "array";
    case Value::Type::Object: return "object";
  }
  return "unknown";
}

Value::Value() = default;
Value::Value(std::nullptr_t) {}
Value::Value(bool b) : type_(Type::Bool), bool_(b) {}
Value::Value(double d) : type_(Type::Number), number_(d) {}
Value::Value(int i) : Value(static_cast<double>(i)) {}
Value::Value(long i) : Value(static_cast<double>(i)) {}
Value::Value(long long i) : Value(static_cast<double>(i)) {}
Value::Value(unsigned i) : Value(static_cast<double>(i)) {}
Value::Value(unsigned long i) : Value(static_cast<double>(i)) {}
Value::Value(unsigned long long i) : Value(static_cast<double>(i)) {}
Value::Value(const char* s) {
  if (s != nullptr) {
    type_ = Type::String;
    string_ = s;
  }
}
Value::Value(std::string s) : type_(Type::String), string_(std::move(s)) {}

Value Value::array() {
  Value v;
  v.type_ = Type::Array;
  return v;
}

Value Value::object() {
  Value v;
  v.type_ = Type::Object;
  return v;
}

Value& Value::operator[](const std::string& key) {
  if (type_ == Type::Null) type_ = Type::Object;
  if (type_ != Type::Object) throw type_error("operator[](key)", type_);
  for (auto& kv : object_) {
    if (kv.first == key) return kv.second;
  }
  object_.emplace_back(key, Value());
  return object_.back().second;
}

const Value& Value::at(const std::string& key) const {
  if (type_ != Type::Object) throw type_error("at(key)", type_);
  if (const Value* v = find(key)) return *v;
  throw std::out_of_range("json: object has no key \"" + key + "\"");
}

bool Value::contains(const std::string& key) const { return find(key) != nullptr; }

const Value* Value::find(const std::string& key) const {
  if (type_ != Type::Object) return nullptr;
  for (const auto& kv : object_) {
    if (kv.first == key) return &kv.second;
  }
  return nullptr;
}

void Value::push_back(Value v) {
  if (type_ == Type::Null) type_ = Type::Array;
  if (type_ != Type::Array) throw type_error("push_back", type_);
  array_.push_back(std::move(v));
}

size_t Value::size() const {
  if (type_ == Type::Array) return array_.size();
  if (type_ == Type::Object) return object_.size();
  return 0;
}

const Value& Value::operator[](size_t i) const {
  if (type_ != Type::Array) throw type_error("operator[](index)", type_);
  if (i >= array_.size()) {
    throw std::out_of_range("json: index " + std::to_string(i) + " out of range (size " +
                            std::to_string(array_.size()) + ")");
  }
  return array_[i];
}

Value& Value::operator[](size_t i) {
  return const_cast<Value&>(static_cast<const Value&>(*this)[i]);
}

bool Value::as_bool() const {
  if (type_ != Type::Bool) throw type_error("as_bool", type_);
  return bool_;
}

double Value::as_number() const {
  if (type_ != Type::Number) throw type_error("as_number", type_);
  return number_;
}

const std::string& Value::as_string() const {
  if (type_ != Type::String) throw type_error("as_string", type_);
  return string_;
}

const std::vector<std::pair<std::string, Value>>& Value::items() const {
  if (type_ != Type::Object) throw type_error("items", type_);
  return object_;
}

const std::vector<Value>& Value::elements() const {
  if (type_ != Type::Array) throw type_error("elements", type_);
  return array_;
}

std::string Value::dump(int indent) const {
  std::string out;
  write_value(out, *this, indent, 0);
  return out;
}

Value Value::parse(const std::string& text) { return Parser(text).parse_document(); }

bool Value::operator==(const Value& other) const {
  if (type_ != other.type_) return false;
  switch (type_) {
    case Type::Null: return true;
    case Type::Bool: return bool_ == other.bool_;
    case Type::Number: return number_ == other.number_;
    case Type::String: return string_ == other.string_;
    case Type::Array: return array_ == other.array_;
    case Type::Object: {
      if (object_.size() != other.object_.size()) return false;
      for (const auto& kv : object_) {
        const Value* o = other.find(kv.first);
        if (o == nullptr || !(kv.second == *o)) return false;
      }
      return true;
    }
  }
  return false;
}

}  // namespace ms::json
