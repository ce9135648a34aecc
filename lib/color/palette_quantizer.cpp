// SPDX-License-Identifier: Apache-2.0
#include "color/palette_quantizer.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>

#include "color/color_error.h"
#include "color/srgb.h"

namespace tessera::color {

namespace {

uint32_t key_of(const Srgb8& c) { return uint32_t(c.r) << 16 | uint32_t(c.g) << 8 | c.b; }
Srgb8 color_of(uint32_t key) { return {uint8_t(key >> 16), uint8_t(key >> 8), uint8_t(key)}; }

Oklab oklab_of(const Srgb8& c) { return linear_srgb_to_oklab(srgb8_to_linear(c)); }

Srgb8 srgb8_of(const Oklab& c) {
  const Rgb lin = oklab_to_linear_srgb(c);
  return linear_to_srgb8(lin);  // srgb_encode clamps out-of-gamut values to [0, 1]
}

// A distinct color of the image and how many pixels have it.
struct Sample {
  Oklab lab;
  double weight;
  uint32_t key;
};

float axis(const Oklab& c, int a) { return a == 0 ? c.L : a == 1 ? c.a : c.b; }

// Weighted first and second moments of a run of samples.
struct Moments {
  double w = 0, s[3] = {0, 0, 0}, s2[3] = {0, 0, 0};

  void add(const Sample& x) {
    w += x.weight;
    for (int a = 0; a < 3; ++a) {
      const double v = axis(x.lab, a);
      s[a] += x.weight * v;
      s2[a] += x.weight * v * v;
    }
  }
  double variance_sum(int a) const { return w > 0 ? s2[a] - s[a] * s[a] / w : 0.0; }
  double sse() const { return variance_sum(0) + variance_sum(1) + variance_sum(2); }
  Oklab mean() const { return {float(s[0] / w), float(s[1] / w), float(s[2] / w)}; }
};

struct Box {
  size_t begin, end;
  Moments m;
};

Moments moments_of(const std::vector<Sample>& v, size_t b, size_t e) {
  Moments m;
  for (size_t i = b; i < e; ++i) m.add(v[i]);
  return m;
}

// Median cut with Wu's split rule: returns the boxes' weighted means.
std::vector<Oklab> median_cut(std::vector<Sample>& samples, int k) {
  std::vector<Box> boxes{{0, samples.size(), moments_of(samples, 0, samples.size())}};
  while (int(boxes.size()) < k) {
    size_t pick = 0;
    for (size_t i = 1; i < boxes.size(); ++i) {
      if (boxes[i].m.sse() > boxes[pick].m.sse()) pick = i;
    }
    Box& box = boxes[pick];
    if (box.end - box.begin < 2 || box.m.sse() <= 0.0) break;  // nothing left to split
    int ax = 0;
    for (int a = 1; a < 3; ++a) {
      if (box.m.variance_sum(a) > box.m.variance_sum(ax)) ax = a;
    }
    std::sort(samples.begin() + std::ptrdiff_t(box.begin), samples.begin() + std::ptrdiff_t(box.end),
              [ax](const Sample& x, const Sample& y) { return axis(x.lab, ax) < axis(y.lab, ax); });
    // Best split: minimum sse(left) + sse(right) over all cut positions, from prefix moments.
    Moments left;
    double best = std::numeric_limits<double>::infinity();
    size_t best_cut = box.begin + 1;
    Moments best_left;
    for (size_t i = box.begin; i + 1 < box.end; ++i) {
      left.add(samples[i]);
      Moments right;
      right.w = box.m.w - left.w;
      for (int a = 0; a < 3; ++a) {
        right.s[a] = box.m.s[a] - left.s[a];
        right.s2[a] = box.m.s2[a] - left.s2[a];
      }
      const double cost = left.sse() + right.sse();
      if (cost < best) {
        best = cost;
        best_cut = i + 1;
        best_left = left;
      }
    }
    Box right_box{best_cut, box.end, moments_of(samples, best_cut, box.end)};
    box = Box{box.begin, best_cut, best_left};
    boxes.push_back(right_box);
  }
  std::vector<Oklab> centers;
  for (const Box& b : boxes) centers.push_back(b.m.mean());
  return centers;
}

// Weighted Lloyd iterations; an emptied cluster is re-seeded at the sample that is currently
// worst represented, so no palette entry is wasted.
void kmeans(const std::vector<Sample>& samples, std::vector<Oklab>& centers, int iterations) {
  const size_t k = centers.size();
  std::vector<int> assign(samples.size(), 0);
  double previous = std::numeric_limits<double>::infinity();
  for (int it = 0; it < iterations; ++it) {
    const OklabNearest search(centers);
    std::vector<Moments> acc(k);
    double total = 0.0;
    size_t worst = 0;
    double worst_err = -1.0;
    for (size_t i = 0; i < samples.size(); ++i) {
      const int c = search.nearest(samples[i].lab);
      assign[i] = c;
      acc[size_t(c)].add(samples[i]);
      const double err = samples[i].weight * oklab_distance2(samples[i].lab, centers[size_t(c)]);
      total += err;
      if (err > worst_err) {
        worst_err = err;
        worst = i;
      }
    }
    for (size_t c = 0; c < k; ++c) {
      if (acc[c].w > 0) {
        centers[c] = acc[c].mean();
      } else {
        centers[c] = samples[worst].lab;
      }
    }
    if (previous - total <= 1e-5 * total) break;  // converged
    previous = total;
  }
}

// How much of the diffused error each pixel takes, from 0 to 1 (libimagequant's "dither map"
// idea): where the undithered mapping already changes index among a pixel's neighbors
// (edges, texture, render noise) banding cannot show and dither would only add noise; inside
// a flat run of one index (a band) the error is applied in full.
std::vector<float> dither_strength(const ImageRGB& img, const OklabNearest& search) {
  const int w = img.width, h = img.height;
  std::vector<int> plain(img.pixel_count());
  for (size_t i = 0; i < plain.size(); ++i) {
    plain[i] = search.nearest(linear_srgb_to_oklab({img.rgb[3 * i], img.rgb[3 * i + 1], img.rgb[3 * i + 2]}));
  }
  std::vector<float> strength(plain.size(), 1.0f);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const int me = plain[size_t(y) * size_t(w) + size_t(x)];
      int same = 0, total = 0;
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          const int nx = x + dx, ny = y + dy;
          if ((dx == 0 && dy == 0) || nx < 0 || ny < 0 || nx >= w || ny >= h) continue;
          ++total;
          same += plain[size_t(ny) * size_t(w) + size_t(nx)] == me;
        }
      }
      // Squared: a pixel with 6 of 8 like neighbors (a band's edge) still takes half the error,
      // one in texture or noise (3 of 8) almost none.
      const float f = total > 0 ? float(same) / float(total) : 1.0f;  // 1x1 image
      strength[size_t(y) * size_t(w) + size_t(x)] = f * f;
    }
  }
  return strength;
}

}  // namespace

OklabNearest::OklabNearest(const std::vector<Oklab>& colors) {
  original_index_.resize(colors.size());
  std::iota(original_index_.begin(), original_index_.end(), 0);
  std::sort(original_index_.begin(), original_index_.end(),
            [&](int x, int y) { return colors[size_t(x)].L < colors[size_t(y)].L; });
  for (int i : original_index_) sorted_.push_back(colors[size_t(i)]);
}

int OklabNearest::nearest(const Oklab& q) const {
  const size_t n = sorted_.size();
  size_t hi = size_t(std::lower_bound(sorted_.begin(), sorted_.end(), q.L,
                                      [](const Oklab& c, float l) { return c.L < l; }) -
                     sorted_.begin());
  size_t lo = hi;  // candidates: [.., lo) going down, [hi, ..) going up
  float best = std::numeric_limits<float>::infinity();
  size_t best_i = 0;
  bool up = hi < n, down = lo > 0;
  while (up || down) {
    if (up) {
      const float dl = sorted_[hi].L - q.L;
      if (dl * dl >= best) {
        up = false;
      } else {
        const float d = oklab_distance2(sorted_[hi], q);
        if (d < best) {
          best = d;
          best_i = hi;
        }
        up = ++hi < n;
      }
    }
    if (down) {
      const float dl = q.L - sorted_[lo - 1].L;
      if (dl * dl >= best) {
        down = false;
      } else {
        const float d = oklab_distance2(sorted_[lo - 1], q);
        if (d < best) {
          best = d;
          best_i = lo - 1;
        }
        down = --lo > 0;
      }
    }
  }
  return original_index_[best_i];
}

std::vector<Srgb8> to_srgb8_pixels(const ImageRGB& img) {
  std::vector<Srgb8> out(img.pixel_count());
  for (size_t i = 0; i < out.size(); ++i) {
    out[i] = linear_to_srgb8(Rgb{img.rgb[3 * i], img.rgb[3 * i + 1], img.rgb[3 * i + 2]});
  }
  return out;
}

std::vector<Srgb8> build_palette(const std::vector<Srgb8>& pixels, int max_colors,
                                 int kmeans_iterations) {
  if (max_colors < 2 || max_colors > 256) throw ColorError("palette size must be 2..256");
  // Histogram of distinct colors by sorting their 24-bit keys.
  std::vector<uint32_t> keys(pixels.size());
  std::transform(pixels.begin(), pixels.end(), keys.begin(), key_of);
  std::sort(keys.begin(), keys.end());
  std::vector<Sample> samples;
  for (size_t i = 0; i < keys.size();) {
    size_t j = i;
    while (j < keys.size() && keys[j] == keys[i]) ++j;
    samples.push_back({oklab_of(color_of(keys[i])), double(j - i), keys[i]});
    i = j;
  }
  if (samples.empty()) return {Srgb8{}};
  if (int(samples.size()) <= max_colors) {
    std::vector<Srgb8> exact;
    for (const Sample& s : samples) exact.push_back(color_of(s.key));
    return exact;
  }
  std::vector<Oklab> centers = median_cut(samples, max_colors);
  kmeans(samples, centers, kmeans_iterations);
  // Round to 8 bits; two centers may round to one color, so deduplicate.
  std::vector<uint32_t> out_keys;
  for (const Oklab& c : centers) out_keys.push_back(key_of(srgb8_of(c)));
  std::sort(out_keys.begin(), out_keys.end());
  out_keys.erase(std::unique(out_keys.begin(), out_keys.end()), out_keys.end());
  std::vector<Srgb8> palette;
  for (uint32_t k : out_keys) palette.push_back(color_of(k));
  return palette;
}

std::vector<uint8_t> map_to_palette(const std::vector<Srgb8>& pixels,
                                    const std::vector<Srgb8>& palette) {
  std::vector<Oklab> labs;
  for (const Srgb8& c : palette) labs.push_back(oklab_of(c));
  const OklabNearest search(labs);
  // Distinct colors are looked up once: sort (key, pixel) pairs and walk them.
  std::vector<uint64_t> order(pixels.size());
  for (size_t i = 0; i < pixels.size(); ++i) order[i] = uint64_t(key_of(pixels[i])) << 32 | i;
  std::sort(order.begin(), order.end());
  std::vector<uint8_t> indices(pixels.size(), 0);
  uint32_t last_key = 0xffffffffu;
  uint8_t last_index = 0;
  for (uint64_t o : order) {
    const uint32_t key = uint32_t(o >> 32);
    if (key != last_key) {
      last_key = key;
      last_index = uint8_t(search.nearest(oklab_of(color_of(key))));
    }
    indices[size_t(o & 0xffffffffu)] = last_index;
  }
  return indices;
}

std::vector<uint8_t> map_floyd_steinberg(const ImageRGB& img, const std::vector<Srgb8>& palette) {
  // Bound on the diffused error per channel, in linear light, growing with the pixel's own
  // value (palette steps are wider in linear light where the image is bright). Where a
  // region's color lies outside the palette's convex hull no mix of entries reaches it and
  // the error would grow without bound; capped, the picks settle on the nearest reachable mix.
  auto cap = [](float pixel, float error) {
    const float limit = 0.03f + 0.25f * std::max(pixel, 0.0f);
    return std::clamp(error, -limit, limit);
  };
  std::vector<Oklab> labs;
  std::vector<Rgb> linear;
  for (const Srgb8& c : palette) {
    labs.push_back(oklab_of(c));
    linear.push_back(srgb8_to_linear(c));
  }
  const OklabNearest search(labs);
  const int w = img.width;
  std::vector<uint8_t> indices(img.pixel_count(), 0);
  const std::vector<float> strength = dither_strength(img, search);
  // Error rows with one guard cell on each side.
  std::vector<Rgb> cur(size_t(w) + 2), next(size_t(w) + 2);
  for (int y = 0; y < img.height; ++y) {
    std::fill(next.begin(), next.end(), Rgb{});
    const bool forward = (y % 2) == 0;
    const int dir = forward ? 1 : -1;
    for (int i = 0; i < w; ++i) {
      const int x = forward ? i : w - 1 - i;
      const float* p = img.at(x, y);
      // The accumulated error is clamped per channel, not the wanted color: clamping the
      // color at 0 would silently drop the debt of every pick with too much of a channel, and
      // a saturated color outside the palette's hull would drift toward gray.
      const Rgb& e = cur[size_t(x + 1)];
      const float s = strength[size_t(y) * size_t(w) + size_t(x)];
      const Rgb want{p[0] + s * cap(p[0], e.r), p[1] + s * cap(p[1], e.g),
                     p[2] + s * cap(p[2], e.b)};
      const int k = search.nearest(linear_srgb_to_oklab(want));
      indices[size_t(y) * size_t(w) + size_t(x)] = uint8_t(k);
      const Rgb& got = linear[size_t(k)];
      for (int c = 0; c < 3; ++c) {
        const float err = want[c] - got[c];
        cur[size_t(x + 1 + dir)][c] += err * (7.0f / 16.0f);
        next[size_t(x + 1 - dir)][c] += err * (3.0f / 16.0f);
        next[size_t(x + 1)][c] += err * (5.0f / 16.0f);
        next[size_t(x + 1 + dir)][c] += err * (1.0f / 16.0f);
      }
    }
    std::swap(cur, next);
  }
  return indices;
}

IndexedImage quantize_palette(const ImageRGB& display_linear, const QuantizerOptions& options) {
  if (options.dither != DitherMethod::kNone && options.dither != DitherMethod::kFloydSteinberg) {
    throw ColorError("palette output supports --dither none or floyd-steinberg");
  }
  IndexedImage out;
  out.width = display_linear.width;
  out.height = display_linear.height;
  const std::vector<Srgb8> pixels = to_srgb8_pixels(display_linear);
  out.palette = build_palette(pixels, options.max_colors, options.kmeans_iterations);
  out.indices = options.dither == DitherMethod::kFloydSteinberg
                    ? map_floyd_steinberg(display_linear, out.palette)
                    : map_to_palette(pixels, out.palette);
  return out;
}

}  // namespace tessera::color
