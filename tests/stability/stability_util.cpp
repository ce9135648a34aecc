// SPDX-License-Identifier: Apache-2.0
#include "stability_util.h"

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <stdexcept>

#include "scene/scene_parser.h"

namespace tessera::stability {

std::string num(double v) {
  char b[40];
  std::snprintf(b, sizeof b, "%.17g", v);
  return b;
}

bool full_mode() {
#ifdef TESSERA_STABILITY_FULL
  return true;
#else
  const char* v = std::getenv("TESSERA_STABILITY_FULL");
  return v && std::string(v) == "1";
#endif
}

namespace {

void append_row(const std::string& case_id, const std::string& quantity, double measured,
                const std::string& bound, const std::string& verdict) {
  static std::mutex mutex;
  std::lock_guard lock(mutex);
  std::printf("[accuracy] %-28s %-58s %12.4g  bound %-12s %s\n", case_id.c_str(), quantity.c_str(), measured,
              bound.c_str(), verdict.c_str());
  const char* out = std::getenv("TESSERA_ACCURACY_OUT");
  if (!out || !*out) return;
  std::ofstream f(out, std::ios::app);
  char value[64];
  std::snprintf(value, sizeof value, "%.4g", measured);
  f << case_id << '\t' << quantity << '\t' << value << '\t' << bound << '\t' << verdict << '\n';
}

}  // namespace

bool check(const std::string& case_id, const std::string& quantity, double measured, Bound kind, double bound) {
  const bool pass = kind == Bound::kAtMost ? measured <= bound : measured >= bound;  // NaN fails
  char b[64];
  std::snprintf(b, sizeof b, "%s %.4g", kind == Bound::kAtMost ? "<=" : ">=", bound);
  append_row(case_id, quantity, measured, b, pass ? "pass" : "FAIL");
  return pass;
}

void report(const std::string& case_id, const std::string& quantity, double measured, const std::string& note) {
  append_row(case_id, quantity, measured, note, "info");
}

Scene scene_from(const std::string& json, const std::string& path) { return parse_scene(json, path); }

std::string make_temp_dir(const std::string& tag) {
  const auto dir = std::filesystem::temp_directory_path() /
                   ("tessera_stability_" + tag + "_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  return dir.string();
}

void write_text(const std::string& path, const std::string& text) {
  std::ofstream f(path);
  f << text;
  if (!f) throw std::runtime_error("cannot write " + path);
}

std::string edge_rich_scene(int w, int h) {
  return R"({"camera": {"position": [0, 1.6, 6.5], "look_at": [0, 0.9, 0], "vfov_deg": 40},
    "image": {"width": )" + std::to_string(w) + R"(, "height": )" + std::to_string(h) + R"(, "max_depth": 6},
    "background": [0.25, 0.45, 0.8],
    "lights": [{"type": "point", "position": [-4, 6, 5], "intensity": 160}],
    "materials": {
      "c": {"type": "diffuse", "albedo": [0.85, 0.1, 0.08], "checker": {"albedo2": [0.9, 0.85, 0.15], "scale": 0.5}},
      "mi": {"type": "mirror", "reflectance": 0.9}, "g": {"type": "glass", "ior": 1.5},
      "d": {"type": "diffuse", "albedo": [0.2, 0.5, 0.25]}},
    "objects": [
      {"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "c"},
      {"type": "sphere", "center": [-1.5, 1, -0.8], "radius": 1, "material": "mi"},
      {"type": "sphere", "center": [0.55, 0.8, 1.4], "radius": 0.8, "material": "g"},
      {"type": "sphere", "center": [2, 0.7, -0.6], "radius": 0.7, "material": "d"}]})";
}

// A plane filling the view under a point light: the radiance varies smoothly inside every pixel.
std::string smooth_scene(int w, int h) {
  return R"({"camera": {"position": [0, 2, 0.01], "look_at": [0, 0, 0], "vfov_deg": 60},
    "image": {"width": )" + std::to_string(w) + R"(, "height": )" + std::to_string(h) + R"(, "max_depth": 1},
    "lights": [{"type": "point", "position": [0.4, 0.6, 0.2], "intensity": 5}],
    "materials": {"m": {"type": "diffuse", "albedo": 0.8}},
    "objects": [{"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "m"}]})";
}

}  // namespace tessera::stability
