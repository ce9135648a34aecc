// SPDX-License-Identifier: Apache-2.0
// A cursor over a JSON value that knows its path in the document, so every complaint names
// the file and field precisely ("objects[3].radius: must be > 0, got -1"), and that rejects
// fields it was never asked about (typos must not be silently ignored).
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "math/vec3.h"
#include "scene/scene_error.h"

namespace tessera {

class JsonReader {
 public:
  JsonReader(const nlohmann::json& value, std::string file, std::string path);

  [[noreturn]] void fail(const std::string& what) const;
  const std::string& path() const { return path_; }
  const nlohmann::json& value() const { return value_; }

  bool is_object() const { return value_.is_object(); }
  bool has(const std::string& key) const;
  JsonReader at(const std::string& key) const;  // required member
  std::optional<JsonReader> find(const std::string& key) const;
  std::vector<JsonReader> array() const;        // elements of a required array
  std::vector<std::pair<std::string, JsonReader>> members() const;

  double number() const;  // finite number
  double number_in(double lo, double hi, bool lo_open = false) const;
  int64_t integer_in(int64_t lo, int64_t hi) const;
  bool boolean() const;
  std::string string() const;
  std::string one_of(const std::vector<std::string>& allowed) const;
  Vec3d vec3() const;           // [x, y, z], finite
  Rgb rgb(double max = 1e30) const;  // [r, g, b] or a single number, each in [0, max]

  // Call after reading an object: every member not read is an error naming it.
  void reject_unknown() const;

 private:
  std::string child_path(const std::string& key) const;
  void mark(const std::string& key) const;

  const nlohmann::json& value_;
  std::string file_;
  std::string path_;
  mutable std::set<std::string> read_;
};

}  // namespace tessera
