// SPDX-License-Identifier: Apache-2.0
#include "color/tonemap.h"

#include <algorithm>
#include <cfloat>
#include <cmath>

#include "color/input_sanitizer.h"

namespace tessera::color {

namespace {

// Every operator works in double: inputs up to FLT_MAX are squared by the rational fits and
// must neither overflow nor turn into Inf / Inf = NaN.
double clamp01(double v) { return v < 0.0 ? 0.0 : v > 1.0 ? 1.0 : v; }

Rgb to_rgb(double r, double g, double b) {
  return {float(clamp01(r)), float(clamp01(g)), float(clamp01(b))};
}

float expose(float v, double scale) {
  const double e = double(sanitize_unsigned(v)) * scale;
  return e > double(FLT_MAX) ? FLT_MAX : float(e);
}

}  // namespace

std::string_view tonemap_name(ToneMapOperator op) {
  switch (op) {
    case ToneMapOperator::kClamp: return "clamp";
    case ToneMapOperator::kReinhard: return "reinhard";
    case ToneMapOperator::kAces: return "aces";
    case ToneMapOperator::kPbrNeutral: return "pbr-neutral";
  }
  return "?";
}

std::optional<ToneMapOperator> parse_tonemap(std::string_view name) {
  for (auto op : {ToneMapOperator::kClamp, ToneMapOperator::kReinhard, ToneMapOperator::kAces,
                  ToneMapOperator::kPbrNeutral}) {
    if (tonemap_name(op) == name) return op;
  }
  return std::nullopt;
}

double exposure_scale(float ev) { return std::exp2(double(ev)); }

Rgb tonemap_clamp(const Rgb& c) { return to_rgb(c.r, c.g, c.b); }

// Extended Reinhard, L_d = L (1 + L / L_white^2) / (1 + L), applied to each channel rather
// than to luminance: per channel it cannot leave the gamut, and very bright colored
// highlights (160.0 lamps) desaturate to white as film does.
Rgb tonemap_reinhard(const Rgb& c, double white) {
  const double w2 = white * white;
  auto f = [&](double x) {
    if (x >= white) return 1.0;  // f(white) = 1 and f grows beyond it: clip exactly there
    return x * (1.0 + x / w2) / (1.0 + x);
  };
  return to_rgb(f(c.r), f(c.g), f(c.b));
}

// The ACES filmic curve as fitted by Stephen Hill (BakingLab, "ACES.hlsl", 2016): linear sRGB
// is taken into the ACES RRT working space by ACESInputMat, through the rational fit of the
// RRT + sRGB 100-nit ODT (RRTAndODTFit), and back by ACESOutputMat. Chosen over Narkowicz's
// 2015 one-line fit because the matrices reproduce ACES's hue shifts and desaturation.
Rgb tonemap_aces_hill(const Rgb& c) {
  static constexpr double kIn[3][3] = {{0.59719, 0.35458, 0.04823},
                                       {0.07600, 0.90834, 0.01566},
                                       {0.02840, 0.13383, 0.83777}};
  static constexpr double kOut[3][3] = {{1.60475, -0.53108, -0.07367},
                                        {-0.10208, 1.10813, -0.00605},
                                        {-0.00327, -0.07276, 1.07602}};
  const double v[3] = {c.r, c.g, c.b};
  double t[3];
  for (int i = 0; i < 3; ++i) {
    const double x = kIn[i][0] * v[0] + kIn[i][1] * v[1] + kIn[i][2] * v[2];
    const double a = x * (x + 0.0245786) - 0.000090537;
    const double b = x * (0.983729 * x + 0.4329510) + 0.238081;
    t[i] = a / b;
  }
  double o[3];
  for (int i = 0; i < 3; ++i) o[i] = kOut[i][0] * t[0] + kOut[i][1] * t[1] + kOut[i][2] * t[2];
  return to_rgb(o[0], o[1], o[2]);
}

// Khronos PBR Neutral, exactly as in the specification (KhronosGroup/ToneMapping,
// PBR_Neutral/README.md): F90 = 0.04, Ks = 0.8 - F90, Kd = 0.15.
//   x = min(R,G,B); f = x - x^2/(4 F90) if x <= 2 F90 else F90
//   p = max(c - f); below Ks the result is c - f (no compression);
//   p_n = 1 - (1-Ks)^2 / (p + 1 - 2 Ks); g = 1 / (Kd (p - p_n) + 1)
//   c_out = (c - f) (p_n / p) g + p_n (1 - g)
Rgb tonemap_pbr_neutral(const Rgb& c) {
  constexpr double kF90 = 0.04;
  constexpr double kKs = 0.8 - kF90;
  constexpr double kKd = 0.15;
  const double x = std::min({double(c.r), double(c.g), double(c.b)});
  const double f = x <= 2.0 * kF90 ? x - x * x / (4.0 * kF90) : kF90;
  const double r = c.r - f, g = c.g - f, b = c.b - f;
  const double p = std::max({r, g, b});
  if (p <= kKs) return to_rgb(r, g, b);
  const double pn = 1.0 - (1.0 - kKs) * (1.0 - kKs) / (p + 1.0 - 2.0 * kKs);
  const double gw = 1.0 / (kKd * (p - pn) + 1.0);
  const double s = pn / p * gw, w = pn * (1.0 - gw);
  return to_rgb(r * s + w, g * s + w, b * s + w);
}

Rgb apply_tonemap(const Rgb& c, ToneMapOperator op, double white) {
  switch (op) {
    case ToneMapOperator::kClamp: return tonemap_clamp(c);
    case ToneMapOperator::kReinhard: return tonemap_reinhard(c, white);
    case ToneMapOperator::kAces: return tonemap_aces_hill(c);
    case ToneMapOperator::kPbrNeutral: return tonemap_pbr_neutral(c);
  }
  return tonemap_clamp(c);
}

double auto_white(const ImageRGB& hdr, double scale) {
  float brightest = 0.0f;
  for (float v : hdr.rgb) {
    if (std::isfinite(v) && v > brightest) brightest = v;
  }
  const double w = double(brightest) * scale;
  return w > 0.0 && std::isfinite(w) ? std::min(w, double(FLT_MAX)) : 1.0;
}

ImageRGB tonemap_image(const ImageRGB& hdr, const ToneMapSettings& settings, double* white_used) {
  const double scale = exposure_scale(settings.exposure_ev);
  double white = 1.0;
  if (settings.op == ToneMapOperator::kReinhard) {
    white = settings.white > 0.0f ? double(settings.white) : auto_white(hdr, scale);
  }
  if (white_used) *white_used = white;
  ImageRGB out(hdr.width, hdr.height);
  for (size_t i = 0; i + 2 < hdr.rgb.size(); i += 3) {
    const Rgb c{expose(hdr.rgb[i], scale), expose(hdr.rgb[i + 1], scale),
                expose(hdr.rgb[i + 2], scale)};
    const Rgb m = apply_tonemap(c, settings.op, white);
    out.rgb[i] = m.r;
    out.rgb[i + 1] = m.g;
    out.rgb[i + 2] = m.b;
  }
  return out;
}

ImageRGB expose_image(const ImageRGB& hdr, float exposure_ev, bool signed_values) {
  const double scale = exposure_scale(exposure_ev);
  ImageRGB out(hdr.width, hdr.height);
  for (size_t i = 0; i < hdr.rgb.size(); ++i) {
    const float v = signed_values ? sanitize_signed(hdr.rgb[i]) : sanitize_unsigned(hdr.rgb[i]);
    const double e = double(v) * scale;
    out.rgb[i] = float(std::clamp(e, -double(FLT_MAX), double(FLT_MAX)));
  }
  return out;
}

}  // namespace tessera::color
