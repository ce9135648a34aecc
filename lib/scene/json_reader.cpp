// SPDX-License-Identifier: Apache-2.0
#include "scene/json_reader.h"

#include <cmath>
#include <sstream>

namespace tessera {

namespace {

std::string type_name(const nlohmann::json& v) {
  switch (v.type()) {
    case nlohmann::json::value_t::null: return "null";
    case nlohmann::json::value_t::object: return "an object";
    case nlohmann::json::value_t::array: return "an array";
    case nlohmann::json::value_t::string: return "a string";
    case nlohmann::json::value_t::boolean: return "a boolean";
    default: return "a number";
  }
}

std::string show(double v) {
  std::ostringstream os;
  os.precision(17);
  os << v;
  return os.str();
}

}  // namespace

JsonReader::JsonReader(const nlohmann::json& value, std::string file, std::string path)
    : value_(value), file_(std::move(file)), path_(std::move(path)) {}

void JsonReader::fail(const std::string& what) const {
  throw SceneError(file_ + ": " + (path_.empty() ? std::string("(top level)") : path_) + ": " + what);
}

std::string JsonReader::child_path(const std::string& key) const {
  return path_.empty() ? key : path_ + "." + key;
}

void JsonReader::mark(const std::string& key) const { read_.insert(key); }

bool JsonReader::has(const std::string& key) const {
  mark(key);
  return value_.is_object() && value_.contains(key);
}

JsonReader JsonReader::at(const std::string& key) const {
  if (!value_.is_object()) fail("must be an object, got " + type_name(value_));
  mark(key);
  auto it = value_.find(key);
  if (it == value_.end()) fail("missing required field '" + key + "'");
  return JsonReader(*it, file_, child_path(key));
}

std::optional<JsonReader> JsonReader::find(const std::string& key) const {
  if (!value_.is_object()) fail("must be an object, got " + type_name(value_));
  mark(key);
  auto it = value_.find(key);
  if (it == value_.end()) return std::nullopt;
  return JsonReader(*it, file_, child_path(key));
}

std::vector<JsonReader> JsonReader::array() const {
  if (!value_.is_array()) fail("must be an array, got " + type_name(value_));
  std::vector<JsonReader> out;
  for (size_t i = 0; i < value_.size(); ++i) {
    out.emplace_back(value_[i], file_, path_ + "[" + std::to_string(i) + "]");
  }
  return out;
}

std::vector<std::pair<std::string, JsonReader>> JsonReader::members() const {
  if (!value_.is_object()) fail("must be an object, got " + type_name(value_));
  std::vector<std::pair<std::string, JsonReader>> out;
  for (auto it = value_.begin(); it != value_.end(); ++it) {
    out.emplace_back(it.key(), JsonReader(it.value(), file_, child_path(it.key())));
  }
  return out;
}

double JsonReader::number() const {
  if (!value_.is_number()) fail("must be a number, got " + type_name(value_));
  const double v = value_.get<double>();
  // nlohmann parses 1e999 to inf; NaN cannot be written in JSON but can arrive from elsewhere.
  if (!std::isfinite(v)) fail("must be a finite number, got " + show(v));
  return v;
}

double JsonReader::number_in(double lo, double hi, bool lo_open) const {
  const double v = number();
  if (v < lo || v > hi || (lo_open && v == lo)) {
    fail("must be in " + std::string(lo_open ? "(" : "[") + show(lo) + ", " + show(hi) + "], got " + show(v));
  }
  return v;
}

int64_t JsonReader::integer_in(int64_t lo, int64_t hi) const {
  if (!value_.is_number_integer() && !(value_.is_number_float() && std::isfinite(value_.get<double>()) &&
                                       value_.get<double>() == std::floor(value_.get<double>()))) {
    fail("must be an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], got " +
         (value_.is_number() ? value_.dump() : type_name(value_)));
  }
  if (value_.is_number_unsigned() && value_.get<uint64_t>() > uint64_t(INT64_MAX)) {
    fail("must be an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], got " + value_.dump());
  }
  const double dv = value_.get<double>();
  if (dv < double(lo) || dv > double(hi)) {
    fail("must be an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], got " + value_.dump());
  }
  return value_.is_number_float() ? int64_t(dv) : value_.get<int64_t>();
}

bool JsonReader::boolean() const {
  if (!value_.is_boolean()) fail("must be true or false, got " + type_name(value_));
  return value_.get<bool>();
}

std::string JsonReader::string() const {
  if (!value_.is_string()) fail("must be a string, got " + type_name(value_));
  return value_.get<std::string>();
}

std::string JsonReader::one_of(const std::vector<std::string>& allowed) const {
  const std::string s = string();
  for (const auto& a : allowed) {
    if (a == s) return s;
  }
  std::string list;
  for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + ("'" + a + "'");
  fail("must be one of " + list + ", got '" + s + "'");
}

Vec3d JsonReader::vec3() const {
  if (!value_.is_array() || value_.size() != 3) {
    fail("must be an array of 3 numbers [x, y, z], got " +
         (value_.is_array() ? "an array of " + std::to_string(value_.size()) : type_name(value_)));
  }
  const auto e = array();
  return {e[0].number(), e[1].number(), e[2].number()};
}

Rgb JsonReader::rgb(double max) const {
  if (value_.is_number()) {
    const float v = float(number_in(0.0, max));
    return Rgb(v);
  }
  if (!value_.is_array() || value_.size() != 3) {
    fail("must be a color [r, g, b] or a single number, got " +
         (value_.is_array() ? "an array of " + std::to_string(value_.size()) : type_name(value_)));
  }
  const auto e = array();
  return {float(e[0].number_in(0.0, max)), float(e[1].number_in(0.0, max)), float(e[2].number_in(0.0, max))};
}

void JsonReader::reject_unknown() const {
  if (!value_.is_object()) return;
  for (auto it = value_.begin(); it != value_.end(); ++it) {
    if (!read_.count(it.key())) {
      std::string known;
      for (const auto& k : read_) known += (known.empty() ? "" : ", ") + k;
      throw SceneError(file_ + ": " + child_path(it.key()) + ": unknown field (allowed here: " + known + ")");
    }
  }
}

}  // namespace tessera
