// SPDX-License-Identifier: Apache-2.0
// Shared helpers of the stability suite (docs/accuracy.md): every case reports what it measured
// next to its bound, and those rows become the table in docs/accuracy.md.
#pragma once

#include <string>

#include "render/render_scene_internal.h"
#include "render/tile_renderer.h"
#include "scene/scene.h"

namespace tessera::stability {

// The full (slow) versions run from bench/stability (compiled with TESSERA_STABILITY_FULL, or
// with the environment variable TESSERA_STABILITY_FULL=1); CI runs the reduced ones.
bool full_mode();
// `reduced` in CI, `full` in the full version.
inline int pick(int reduced, int full) { return full_mode() ? full : reduced; }

// Records one measured quantity against its bound and returns whether the bound holds:
// `measured <= bound` (kAtMost) or `measured >= bound` (kAtLeast). Prints the row and, when
// TESSERA_ACCURACY_OUT names a file, appends it there as tab-separated
// case, quantity, measured, bound, pass (bench/stability/accuracy_table.sh builds the table).
enum class Bound { kAtMost, kAtLeast };
bool check(const std::string& case_id, const std::string& quantity, double measured, Bound kind, double bound);
// A measurement with no pass/fail meaning (timings, fitted values reported for information).
void report(const std::string& case_id, const std::string& quantity, double measured, const std::string& note);

// A double as a JSON number that reads back to the same double (%.17g), for scene text.
std::string num(double v);

Scene scene_from(const std::string& json, const std::string& path = "stability.json");
// A fresh directory under the system temp dir, removed by the caller's fixture.
std::string make_temp_dir(const std::string& tag);
void write_text(const std::string& path, const std::string& text);

// Scenes shared by the convergence (case 10) and error-estimate (case 11) cases: a Whitted-like
// scene full of edges, mirrors and glass, and a plane whose radiance varies smoothly in every pixel.
std::string edge_rich_scene(int w, int h);
std::string smooth_scene(int w, int h);

}  // namespace tessera::stability
