// SPDX-License-Identifier: Apache-2.0
// render/sampler.h's owen_sobol_2d_lanes for each SIMD target (SSSE3, SSE4, AVX2, AVX-512, and
// Highway's one-lane fallback), compiled by Google Highway and picked at run time, as
// render/sphere_roots_simd.cpp is. It is
// sampler.cpp's owen_sobol_2d step for step, in exact arithmetic only: 32-bit multiplies keep the
// low half (as uint32_t arithmetic does), shifts, masks and byte shuffles move bits, and the final
// conversion of a 24-bit integer to float and its scaling by 2^-24 round nothing. So every target
// gives the scalar bits.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "render/sampler_simd.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include "render/sampler.h"

HWY_BEFORE_NAMESPACE();
namespace tessera {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

// At most 8 lanes a vector: one vector a packet on AVX2 and AVX-512, two on SSE4.
using DU = hn::CappedTag<uint32_t, kOwenLanes>;
using VU = hn::Vec<DU>;

// What a bit reversal keeps: all of reverse_bits(w), the shuffled index's low 16 bits
// (reverse_bits(w) & 0xffff), or the 24 bits to_unit_float keeps (reverse_bits(w) >> 8).
enum class Kept { kAll, kLow16, kHigh24 };

#if HWY_TARGET == HWY_SCALAR
// One lane, no byte shuffles (GCC 12 builds Highway's fallback as HWY_SCALAR): sampler.cpp's
// swaps, with its byte swap as two more.
template <int kShift>
HWY_INLINE VU swap_bits(VU w, uint32_t mask) {
  const VU m = hn::Set(DU(), mask);
  return hn::Or(hn::And(hn::ShiftRight<kShift>(w), m), hn::ShiftLeft<kShift>(hn::And(w, m)));
}

template <Kept kKept>
HWY_INLINE VU reverse_bits(VU x) {
  const DU du;
  x = swap_bits<1>(x, 0x55555555u);
  x = swap_bits<2>(x, 0x33333333u);
  x = swap_bits<4>(x, 0x0f0f0f0fu);
  x = swap_bits<8>(x, 0x00ff00ffu);
  x = hn::Or(hn::ShiftRight<16>(x), hn::ShiftLeft<16>(x));
  if constexpr (kKept == Kept::kLow16) return hn::And(x, hn::Set(du, 0xffffu));
  if constexpr (kKept == Kept::kHigh24) return hn::ShiftRight<8>(x);
  return x;
}
#else
using DB = hn::Repartition<uint8_t, DU>;
using VB = hn::Vec<DB>;

// Byte-shuffle indices for each 16-byte block (x86 shuffles bytes within blocks); an index with
// its top bit set gives a zero byte. With each byte's bits already reversed, moving the bytes is
// what is left of a 32-bit reversal, and the mask or shift that follows one is folded into it.
alignas(16) constexpr uint8_t kReverseBytes[16] = {3, 2, 1, 0, 7, 6, 5, 4, 11, 10, 9, 8, 15, 14, 13, 12};
alignas(16) constexpr uint8_t kReverseBytesLow16[16] = {3,  2,  0x80, 0x80, 7,  6,  0x80, 0x80,
                                                        11, 10, 0x80, 0x80, 15, 14, 0x80, 0x80};
alignas(16) constexpr uint8_t kReverseBytesHigh24[16] = {2,  1, 0, 0x80, 6,  5,  4,  0x80,
                                                         10, 9, 8, 0x80, 14, 13, 12, 0x80};
// A nibble's bits reversed, in the low and in the high nibble of a byte.
alignas(16) constexpr uint8_t kNibbleReversed[16] = {0x0, 0x8, 0x4, 0xc, 0x2, 0xa, 0x6, 0xe,
                                                     0x1, 0x9, 0x5, 0xd, 0x3, 0xb, 0x7, 0xf};
alignas(16) constexpr uint8_t kNibbleReversedHigh[16] = {0x00, 0x80, 0x40, 0xc0, 0x20, 0xa0, 0x60, 0xe0,
                                                         0x10, 0x90, 0x50, 0xd0, 0x30, 0xb0, 0x70, 0xf0};

// reverse_bits of sampler.cpp, or the part of it kept: each byte's bits reversed by two 16-entry
// nibble lookups (sampler.cpp's three mask-and-shift swaps take 15 operations a vector; these take
// 6), then the bytes moved. The tables are loaded once a call (the compiler hoists them).
template <Kept kKept>
HWY_INLINE VU reverse_bits(VU w) {
  const DU du;
  const DB db;
  const VB low_nibble = hn::Set(db, uint8_t{0x0f});
  const VB lo = hn::And(hn::BitCast(db, w), low_nibble);
  // Shifted as 32-bit lanes: the bits that cross into a byte from the next one are masked off.
  const VB hi = hn::And(hn::BitCast(db, hn::ShiftRight<4>(w)), low_nibble);
  const VB reversed = hn::Or(hn::TableLookupBytes(hn::LoadDup128(db, kNibbleReversedHigh), lo),
                             hn::TableLookupBytes(hn::LoadDup128(db, kNibbleReversed), hi));
  const uint8_t* order = kKept == Kept::kAll     ? kReverseBytes
                         : kKept == Kept::kLow16 ? kReverseBytesLow16
                                                 : kReverseBytesHigh24;
  return hn::BitCast(du, hn::TableLookupBytesOr0(reversed, hn::LoadDup128(db, order)));
}
#endif

// laine_karras_permutation of sampler.cpp; Mul of uint32_t lanes keeps the low 32 bits.
HWY_INLINE VU laine_karras(VU x, VU seed) {
  const DU du;
  x = hn::Xor(x, hn::Mul(x, hn::Set(du, 0x3d20adeau)));
  x = hn::Add(x, seed);
  x = hn::Mul(x, hn::Or(hn::ShiftRight<16>(seed), hn::Set(du, 1u)));
  x = hn::Xor(x, hn::Mul(x, hn::Set(du, 0x05526c56u)));
  x = hn::Xor(x, hn::Mul(x, hn::Set(du, 0x53a22864u)));
  return x;
}

// The bit-reversed Pascal-matrix dimension of a 16-bit index i, which sampler.cpp looks up in its
// byte tables: the reversed direction number k has bit j set where C(k, j) is odd, that is
// (Lucas) where j's bits are a subset of k's, so bit j of the result is the XOR of the index bits
// k with k a superset of j. That superset sum over the 4-bit positions is four steps, one per
// position bit d: every position j with bit d clear takes in position j + 2^d. Twelve operations
// a vector; a gather from the tables would be fewer instructions, but it is microcoded and slow
// on AMD before Zen 4, and there is none before AVX2.
HWY_INLINE VU sobol_dim1_reversed(VU i) {
  const DU du;
  i = hn::Xor(i, hn::And(hn::ShiftRight<1>(i), hn::Set(du, 0x5555u)));
  i = hn::Xor(i, hn::And(hn::ShiftRight<2>(i), hn::Set(du, 0x3333u)));
  i = hn::Xor(i, hn::And(hn::ShiftRight<4>(i), hn::Set(du, 0x0f0fu)));
  return hn::Xor(i, hn::ShiftRight<8>(i));  // i < 2^16: the mask 0x00ff would keep every bit
}

void OwenSobol2dLanes(const OwenSobolLanes& lanes, float* u, float* v) {
  const DU du;
  const hn::Rebind<float, DU> df;
  const hn::RebindToSigned<DU> di;
  // to_unit_float of bits already shifted down: below 2^24, so the signed conversion is exact,
  // and so is the scaling.
  const auto scale = hn::Set(df, 0x1p-24f);
  auto to_unit = [&](VU bits24) { return hn::Mul(hn::ConvertTo(df, hn::BitCast(di, bits24)), scale); };
  for (size_t k = 0; k < size_t(kOwenLanes); k += hn::Lanes(du)) {
    // The shuffled index, nested_uniform_scramble(index, seeds.index) & 0xffff.
    const VU i = reverse_bits<Kept::kLow16>(
        laine_karras(reverse_bits<Kept::kAll>(hn::Load(du, lanes.index + k)), hn::Load(du, lanes.seed_index + k)));
    // As in sampler.cpp, the Sobol point is scrambled in bit-reversed form: reversed, x is i itself.
    const VU x = laine_karras(i, hn::Load(du, lanes.seed_x + k));
    const VU y = laine_karras(sobol_dim1_reversed(i), hn::Load(du, lanes.seed_y + k));
    hn::StoreU(to_unit(reverse_bits<Kept::kHigh24>(x)), df, u + k);
    hn::StoreU(to_unit(reverse_bits<Kept::kHigh24>(y)), df, v + k);
  }
}

}  // namespace HWY_NAMESPACE
}  // namespace tessera
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace tessera {

HWY_EXPORT(OwenSobol2dLanes);

void owen_sobol_2d_lanes(const OwenSobolLanes& lanes, float u[kOwenLanes], float v[kOwenLanes]) {
  HWY_DYNAMIC_DISPATCH(OwenSobol2dLanes)(lanes, u, v);
}

}  // namespace tessera
#endif  // HWY_ONCE
