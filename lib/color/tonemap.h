// SPDX-License-Identifier: Apache-2.0
// Tone mapping: scene-referred linear light -> display-referred linear light in [0, 1].
// Everything here stays linear; the sRGB transfer function (srgb.h) is the last step, applied
// by the encoders. Exposure is a power-of-two scale applied first.
#pragma once

#include <optional>
#include <string_view>

#include "color/rgb.h"
#include "image/image.h"

namespace tessera::color {

enum class ToneMapOperator {
  kClamp,       // exposure, then clip to [0, 1]
  kReinhard,    // extended Reinhard (2002, eq. 4) per channel with a white point
  kAces,        // Stephen Hill's fit of the ACES RRT + sRGB ODT (see tonemap.cpp)
  kPbrNeutral,  // Khronos PBR Neutral (2024), the published specification
};

std::string_view tonemap_name(ToneMapOperator op);
std::optional<ToneMapOperator> parse_tonemap(std::string_view name);

struct ToneMapSettings {
  ToneMapOperator op = ToneMapOperator::kClamp;
  float exposure_ev = 0.0f;  // scale by 2^EV before the operator
  float white = 0.0f;        // Reinhard white point after exposure; <= 0: the brightest value
};

// 2^ev.
double exposure_scale(float ev);

// The operators on one already-exposed, non-negative, finite color. Each returns [0, 1].
Rgb tonemap_clamp(const Rgb& c);
Rgb tonemap_reinhard(const Rgb& c, double white);  // white > 0; white itself maps to exactly 1
Rgb tonemap_aces_hill(const Rgb& c);
Rgb tonemap_pbr_neutral(const Rgb& c);
Rgb apply_tonemap(const Rgb& c, ToneMapOperator op, double white);

// The brightest finite channel value of the image after exposure (the Reinhard default white
// point, so the brightest pixel maps to exactly 1). 1 for an image with no positive value.
double auto_white(const ImageRGB& hdr, double scale);

// Sanitizes (input_sanitizer.h, unsigned policy), exposes and tone maps a whole image.
// Returns display-referred linear light in [0, 1]. *white_used receives the white point.
ImageRGB tonemap_image(const ImageRGB& hdr, const ToneMapSettings& settings,
                       double* white_used = nullptr);

// Sanitizes and exposes without tone mapping: the reference of the HDR formats.
// signed_values keeps negatives (EXR); otherwise they become 0 (RGBE, RGB9E5).
ImageRGB expose_image(const ImageRGB& hdr, float exposure_ev, bool signed_values);

}  // namespace tessera::color
