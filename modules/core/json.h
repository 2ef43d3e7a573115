// Minimal, dependency-free JSON value type for MandiSym (reports, manifests,
// configuration). Objects keep insertion order; numbers are IEEE doubles
// (integers above 2^53 lose precision).
#pragma once

#include <cstddef>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace ms::json {

// Thrown by Value::parse. The message has the form
// "JSON parse error at line L, column C: what" (line and column 1-based,
// column counted in bytes).
struct ParseError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

class Value {
 public:
  enum class Type { Null, Bool, Number, String, Array, Object };

  // Construction. Every integer type is stored as a double.
  Value();
  Value(std::nullptr_t);
  Value(bool b);
  Value(double d);
  Value(int i);
  Value(long i);
  Value(long long i);
  Value(unsigned i);
  Value(unsigned long i);
  Value(unsigned long long i);
  Value(const char* s);  // nullptr gives a null Value
  Value(std::string s);

  // Empty array / empty object.
  static Value array();
  static Value object();

  // Takes any iterable of arithmetic values (std::array<double,3>,
  // std::vector<int>, ...) and returns an array of numbers.
  template <class T>
  static Value array_of(const T& container) {
    Value v = array();
    for (const auto& x : container) v.push_back(Value(static_cast<double>(x)));
    return v;
  }

  // Type queries.
  Type type() const { return type_; }
  bool is_null() const { return type_ == Type::Null; }
  bool is_bool() const { return type_ == Type::Bool; }
  bool is_number() const { return type_ == Type::Number; }
  bool is_string() const { return type_ == Type::String; }
  bool is_array() const { return type_ == Type::Array; }
  bool is_object() const { return type_ == Type::Object; }

  // Object member access by key. Inserts a null member if absent; a null
  // Value first becomes an empty object. Throws std::logic_error on other
  // types. Returns a reference valid until the next insertion.
  Value& operator[](const std::string& key);

  // Object member by key; throws std::out_of_range naming the key if absent,
  // std::logic_error if this is not an object.
  const Value& at(const std::string& key) const;

  // True if this is an object with member `key` (false for non-objects).
  bool contains(const std::string& key) const;

  // Pointer to member `key`, or nullptr if absent or not an object.
  const Value* find(const std::string& key) const;

  // Appends to an array; a null Value first becomes an empty array.
  // Throws std::logic_error on other types.
  void push_back(Value v);

  // Number of array elements or object members; 0 for scalars.
  size_t size() const;

  // Array element i; throws std::out_of_range if i >= size(),
  // std::logic_error if this is not an array. (The non-const overload also
  // keeps v[0] on a mutable Value from being ambiguous with the key form.)
  const Value& operator[](size_t i) const;
  Value& operator[](size_t i);

  // Scalar accessors; throw std::logic_error on a type mismatch.
  bool as_bool() const;
  double as_number() const;
  const std::string& as_string() const;

  // Object members in insertion order / array elements; throw
  // std::logic_error on a type mismatch.
  const std::vector<std::pair<std::string, Value>>& items() const;
  const std::vector<Value>& elements() const;

  // Serialises to text. indent < 0: compact, one line. indent >= 0: members
  // on their own lines indented by `indent` spaces per level, except arrays
  // containing only numbers/bools/nulls, which stay on one line
  // ("[1, 2.5, null]"). Non-finite numbers are written as null; numbers use
  // the shortest text that round-trips. No trailing newline.
  std::string dump(int indent = 2) const;

  // Parses a complete RFC 8259 JSON text (a leading UTF-8 BOM is skipped).
  // Rejects trailing non-whitespace, nesting deeper than 256, invalid
  // UTF-8, lone surrogate escapes, numbers overflowing a double (underflow
  // gives 0) and duplicate object keys. Throws ParseError.
  static Value parse(const std::string& text);

  // Deep equality. Numbers compare as doubles (NaN != NaN, 0 == -0);
  // objects compare as key->value maps, independent of member order.
  bool operator==(const Value& other) const;
  bool operator!=(const Value& other) const { return !(*this == other); }

 private:
  Type type_ = Type::Null;
  bool bool_ = false;
  double number_ = 0.0;
  std::string string_;
  std::vector<Value> array_;
  std::vector<std::pair<std::string, Value>> object_;
};

// Name of a type ("null", "bool", "number", "string", "array", "object").
const char* type_name(Value::Type t);

}  // namespace ms::json
