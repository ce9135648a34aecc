// SPDX-License-Identifier: Apache-2.0
#include "color/image_metrics.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "color/color_error.h"

namespace tessera::color {

namespace {

void check_same_size(const ImageRGB& a, const ImageRGB& b) {
  if (a.width != b.width || a.height != b.height || a.rgb.size() != b.rgb.size()) {
    throw ColorError("images to compare differ in size");
  }
}

}  // namespace

double psnr_from_mse(double mse) {
  if (mse <= 0.0) return std::numeric_limits<double>::infinity();
  return 10.0 * std::log10(255.0 * 255.0 / mse);
}

LdrError ldr_error(const ImageRGB& ref, const ImageRGB& dec, const std::vector<uint8_t>* include) {
  check_same_size(ref, dec);
  LdrError e;
  double sum = 0.0;
  size_t count = 0;
  for (size_t i = 0; i < ref.rgb.size(); ++i) {
    if (include && !(*include)[i / 3]) continue;
    const double d = (double(dec.rgb[i]) - double(ref.rgb[i])) * 255.0;
    sum += d * d;
    e.max_abs = std::max(e.max_abs, std::abs(d));
    ++count;
  }
  const double mse = count == 0 ? 0.0 : sum / double(count);
  e.rmse = std::sqrt(mse);
  e.psnr_db = psnr_from_mse(mse);
  return e;
}

HdrError hdr_relative_error(const ImageRGB& ref, const ImageRGB& dec,
                            const std::vector<uint8_t>* include) {
  check_same_size(ref, dec);
  HdrError e;
  double sum = 0.0;
  size_t count = 0;
  for (size_t p = 0; p < ref.pixel_count(); ++p) {
    if (include && !(*include)[p]) continue;
    ++count;
    const float* r = &ref.rgb[3 * p];
    const float* d = &dec.rgb[3 * p];
    double peak = 0.0, diff = 0.0;
    for (int c = 0; c < 3; ++c) {
      peak = std::max(peak, std::abs(double(r[c])));
      diff = std::max(diff, std::abs(double(d[c]) - double(r[c])));
    }
    const double rel = diff / std::max(peak, kRelativeErrorFloor);
    e.max_rel = std::max(e.max_rel, rel);
    sum += rel;
  }
  e.mean_rel = count ? sum / double(count) : 0.0;
  return e;
}

double low_frequency_error(const ImageRGB& ref, const ImageRGB& dec, int radius) {
  check_same_size(ref, dec);
  const int w = ref.width, h = ref.height;
  if (w == 0 || h == 0) return 0.0;
  // Summed-area table of the difference, per channel.
  std::vector<double> sat(size_t(w + 1) * size_t(h + 1) * 3, 0.0);
  auto at = [&](int x, int y, int c) -> double& { return sat[(size_t(y) * size_t(w + 1) + size_t(x)) * 3 + size_t(c)]; };
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      for (int c = 0; c < 3; ++c) {
        const double d = double(dec.at(x, y)[c]) - double(ref.at(x, y)[c]);
        at(x + 1, y + 1, c) = d + at(x, y + 1, c) + at(x + 1, y, c) - at(x, y, c);
      }
    }
  }
  double sum = 0.0;
  for (int y = 0; y < h; ++y) {
    const int y0 = std::max(0, y - radius), y1 = std::min(h, y + radius + 1);
    for (int x = 0; x < w; ++x) {
      const int x0 = std::max(0, x - radius), x1 = std::min(w, x + radius + 1);
      const double area = double((x1 - x0) * (y1 - y0));
      for (int c = 0; c < 3; ++c) {
        const double m = (at(x1, y1, c) - at(x0, y1, c) - at(x1, y0, c) + at(x0, y0, c)) / area;
        sum += m * m;
      }
    }
  }
  return std::sqrt(sum / (double(w) * double(h) * 3.0));
}

}  // namespace tessera::color
