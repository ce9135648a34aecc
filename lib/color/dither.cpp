// SPDX-License-Identifier: Apache-2.0
#include "color/dither.h"

#include <array>
#include <cmath>

namespace tessera::color {

namespace {

constexpr int kN = kBlueNoiseSize;
constexpr int kCount = kN * kN;

// Toroidal energy of a binary pattern under a Gaussian kernel; adding or removing one pixel
// updates every cell with one table look-up.
class EnergyField {
 public:
  EnergyField() {
    constexpr double kSigma = 1.5;
    for (int dy = 0; dy < kN; ++dy) {
      for (int dx = 0; dx < kN; ++dx) {
        const int wx = dx < kN / 2 ? dx : dx - kN, wy = dy < kN / 2 ? dy : dy - kN;
        kernel_[size_t(dy * kN + dx)] = std::exp(-double(wx * wx + wy * wy) / (2 * kSigma * kSigma));
      }
    }
    energy_.fill(0.0);
  }

  void toggle(int p, bool add) {
    const int px = p % kN, py = p / kN;
    const double s = add ? 1.0 : -1.0;
    for (int y = 0; y < kN; ++y) {
      const int dy = (y - py + kN) % kN;
      for (int x = 0; x < kN; ++x) {
        energy_[size_t(y * kN + x)] += s * kernel_[size_t(dy * kN + (x - px + kN) % kN)];
      }
    }
  }

  // Tightest cluster: the set pixel of highest energy. Largest void: the empty pixel of lowest
  // energy. Ties go to the lowest index, so the result is deterministic.
  int tightest_cluster(const std::array<uint8_t, kCount>& bits) const { return extreme(bits, 1, true); }
  int largest_void(const std::array<uint8_t, kCount>& bits) const { return extreme(bits, 0, false); }

 private:
  int extreme(const std::array<uint8_t, kCount>& bits, uint8_t want, bool maximum) const {
    int best = -1;
    for (int p = 0; p < kCount; ++p) {
      if (bits[size_t(p)] != want) continue;
      if (best < 0 || (maximum ? energy_[size_t(p)] > energy_[size_t(best)]
                               : energy_[size_t(p)] < energy_[size_t(best)])) {
        best = p;
      }
    }
    return best;
  }

  std::array<double, kCount> kernel_{};
  std::array<double, kCount> energy_{};
};

std::vector<uint16_t> make_blue_noise() {
  // Initial pattern: 10% of pixels from a fixed-seed xorshift generator.
  std::array<uint8_t, kCount> bits{};
  uint32_t state = 0x2545F491u;
  int ones = 0;
  while (ones < kCount / 10) {
    state ^= state << 13;
    state ^= state >> 17;
    state ^= state << 5;
    const int p = int(state % kCount);
    if (!bits[size_t(p)]) {
      bits[size_t(p)] = 1;
      ++ones;
    }
  }
  EnergyField field;
  for (int p = 0; p < kCount; ++p) {
    if (bits[size_t(p)]) field.toggle(p, true);
  }
  // Move points from the tightest cluster to the largest void until that stops changing.
  for (int guard = 0; guard < 4 * kCount; ++guard) {
    const int cluster = field.tightest_cluster(bits);
    bits[size_t(cluster)] = 0;
    field.toggle(cluster, false);
    const int gap = field.largest_void(bits);
    bits[size_t(gap)] = 1;
    field.toggle(gap, true);
    if (gap == cluster) break;
  }
  std::vector<uint16_t> rank(kCount, 0);
  // Phase 1: remove the prototype's points tightest-first; they get the ranks below `ones`.
  {
    auto proto = bits;
    EnergyField f1 = field;
    for (int r = ones - 1; r >= 0; --r) {
      const int c = f1.tightest_cluster(proto);
      proto[size_t(c)] = 0;
      f1.toggle(c, false);
      rank[size_t(c)] = uint16_t(r);
    }
  }
  // Phases 2 and 3: fill the largest voids. (Past half, Ulichney switches to the tightest
  // cluster of zeros; with a kernel of constant sum that is the same pixel.)
  for (int r = ones; r < kCount; ++r) {
    const int v = field.largest_void(bits);
    bits[size_t(v)] = 1;
    field.toggle(v, true);
    rank[size_t(v)] = uint16_t(r);
  }
  return rank;
}

}  // namespace

std::string_view dither_name(DitherMethod d) {
  switch (d) {
    case DitherMethod::kNone: return "none";
    case DitherMethod::kBayer: return "bayer";
    case DitherMethod::kBlueNoise: return "blue-noise";
    case DitherMethod::kFloydSteinberg: return "floyd-steinberg";
  }
  return "?";
}

std::optional<DitherMethod> parse_dither(std::string_view name) {
  for (auto d : {DitherMethod::kNone, DitherMethod::kBayer, DitherMethod::kBlueNoise,
                 DitherMethod::kFloydSteinberg}) {
    if (dither_name(d) == name) return d;
  }
  return std::nullopt;
}

int bayer_rank(int x, int y) {
  // M_2n(x, y) = 4 M_n(x mod n, y mod n) + M_2(x / n, y / n) with M_2 = [0 2; 3 1]: the finest
  // bit of (x, y) picks the most significant base-4 digit of the rank.
  int rank = 0;
  for (int bit = 0; bit < 3; ++bit) {
    const int bx = (x >> bit) & 1, by = (y >> bit) & 1;
    rank |= (((bx ^ by) << 1) | by) << (2 * (2 - bit));
  }
  return rank;
}

const std::vector<uint16_t>& blue_noise_ranks() {
  static const std::vector<uint16_t> ranks = make_blue_noise();
  return ranks;
}

float ordered_threshold(DitherMethod d, int x, int y) {
  switch (d) {
    case DitherMethod::kBayer:
      return (float(bayer_rank(x & 7, y & 7)) + 0.5f) / 64.0f;
    case DitherMethod::kBlueNoise:
      return (float(blue_noise_ranks()[size_t((y & (kN - 1)) * kN + (x & (kN - 1)))]) + 0.5f) /
             float(kCount);
    default:
      return 0.5f;
  }
}

}  // namespace tessera::color
