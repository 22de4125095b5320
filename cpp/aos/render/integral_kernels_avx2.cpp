// AVX2 + FMA span kernels for 1-channel views (and 2-channel 8-bit ones: masked grey frames):
// 8 output pixels per step. For 8- and 16-bit
// views one 32-bit gather fetches both horizontal taps of a row (p00 and p01 are adjacent), so a
// bilinear sample costs two gathers; float views need four. The functions carry target
// attributes, so this file is compiled for the baseline CPU and the kernels are only handed out
// after a runtime check of the CPU.
#include "aos/render/integral_kernels.h"

#include <cstdint>
#include <limits>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#define AOS_HAVE_AVX2_KERNELS 1
#endif

namespace aos::internal {

#ifdef AOS_HAVE_AVX2_KERNELS
namespace {

// Constants of one span, broadcast.
struct SpanSetup {
  __m256 du, dv, dw, ua, va, wa;
  __m256 x_max, y_max;
  const unsigned char* origin;
  int stride_bytes;
};

// The first half of a group of 8 samples: positions, weights, and the taps' raw values as
// gathered (the long-latency part).
struct Fetched {
  __m256 ax, ay;
  __m256i top, bottom;        // 8/16-bit views: both horizontal taps of a row in one 32-bit word
  __m256 p00, p01, p10, p11;  // float views
};

template <PixelType kType>
__attribute__((target("avx2,fma"), always_inline)) inline Fetched Fetch(const SpanSetup& c, int i) {
  constexpr int kValueSize = kType == PixelType::kU8 ? 1 : (kType == PixelType::kU16 ? 2 : 4);
  const __m256 one = _mm256_set1_ps(1.0f);
  const __m256 fi = _mm256_add_ps(_mm256_set1_ps(static_cast<float>(i)),
                                  _mm256_setr_ps(0, 1, 2, 3, 4, 5, 6, 7));
  const __m256 inv_w = _mm256_div_ps(one, _mm256_fmadd_ps(c.dw, fi, c.wa));
  // Clamped to [-1, size - 0.5] as in the scalar kernel (max_ps returns its second operand,
  // -1, for NaN), so no rounding can send a gather outside the bordered image.
  const __m256 half = _mm256_set1_ps(0.5f), minus_one = _mm256_set1_ps(-1.0f);
  const __m256 sx = _mm256_min_ps(
      _mm256_max_ps(_mm256_fmsub_ps(_mm256_fmadd_ps(c.du, fi, c.ua), inv_w, half), minus_one),
      c.x_max);
  const __m256 sy = _mm256_min_ps(
      _mm256_max_ps(_mm256_fmsub_ps(_mm256_fmadd_ps(c.dv, fi, c.va), inv_w, half), minus_one),
      c.y_max);
  // sx, sy >= -1, so truncating s + 1 gives floor(s) + 1.
  const __m256i one_i = _mm256_set1_epi32(1);
  const __m256i ix = _mm256_sub_epi32(_mm256_cvttps_epi32(_mm256_add_ps(sx, one)), one_i);
  const __m256i iy = _mm256_sub_epi32(_mm256_cvttps_epi32(_mm256_add_ps(sy, one)), one_i);
  Fetched f;
  f.ax = _mm256_sub_ps(sx, _mm256_cvtepi32_ps(ix));
  f.ay = _mm256_sub_ps(sy, _mm256_cvtepi32_ps(iy));
  const __m256i offset = _mm256_add_epi32(_mm256_mullo_epi32(iy, _mm256_set1_epi32(c.stride_bytes)),
                                          _mm256_mullo_epi32(ix, _mm256_set1_epi32(kValueSize)));
  if constexpr (kType == PixelType::kF32) {
    const auto* base = reinterpret_cast<const float*>(c.origin);
    const auto* below = reinterpret_cast<const float*>(c.origin + c.stride_bytes);
    f.p00 = _mm256_i32gather_ps(base, offset, 1);
    f.p01 = _mm256_i32gather_ps(base + 1, offset, 1);
    f.p10 = _mm256_i32gather_ps(below, offset, 1);
    f.p11 = _mm256_i32gather_ps(below + 1, offset, 1);
  } else {
    f.top = _mm256_i32gather_epi32(reinterpret_cast<const int*>(c.origin), offset, 1);
    f.bottom = _mm256_i32gather_epi32(reinterpret_cast<const int*>(c.origin + c.stride_bytes),
                                      offset, 1);
  }
  return f;
}

// The second half: unpack the taps, interpolate, add to the double accumulators.
template <PixelType kType>
__attribute__((target("avx2,fma"), always_inline)) inline void Finish(const Fetched& f,
                                                                      double* out,
                                                                      __m256 keep) {
  __m256 p00, p01, p10, p11;
  if constexpr (kType == PixelType::kF32) {
    p00 = f.p00, p01 = f.p01, p10 = f.p10, p11 = f.p11;
  } else {
    constexpr int kBits = kType == PixelType::kU8 ? 8 : 16;
    const __m256i mask = _mm256_set1_epi32((1 << kBits) - 1);
    p00 = _mm256_cvtepi32_ps(_mm256_and_si256(f.top, mask));
    p01 = _mm256_cvtepi32_ps(_mm256_and_si256(_mm256_srli_epi32(f.top, kBits), mask));
    p10 = _mm256_cvtepi32_ps(_mm256_and_si256(f.bottom, mask));
    p11 = _mm256_cvtepi32_ps(_mm256_and_si256(_mm256_srli_epi32(f.bottom, kBits), mask));
  }
  const __m256 upper = _mm256_fmadd_ps(f.ax, _mm256_sub_ps(p01, p00), p00);
  const __m256 lower = _mm256_fmadd_ps(f.ax, _mm256_sub_ps(p11, p10), p10);
  // `keep` zeroes the lanes past the end of the span (adding +0.0 changes nothing).
  const __m256 value = _mm256_and_ps(_mm256_fmadd_ps(f.ay, _mm256_sub_ps(lower, upper), upper), keep);
  _mm256_storeu_pd(out, _mm256_add_pd(_mm256_loadu_pd(out),
                                      _mm256_cvtps_pd(_mm256_castps256_ps128(value))));
  _mm256_storeu_pd(out + 4, _mm256_add_pd(_mm256_loadu_pd(out + 4),
                                          _mm256_cvtps_pd(_mm256_extractf128_ps(value, 1))));
}

template <PixelType kType>
__attribute__((target("avx2,fma"))) void Avx2Span(const Image& image, const RowLine& line,
                                                  int xa, int xb, int x0, double* sum) {
  constexpr int kValueSize = kType == PixelType::kU8 ? 1 : (kType == PixelType::kU16 ? 2 : 4);
  SpanSetup c;
  c.origin = static_cast<const unsigned char*>(image.RawAt(0, 0));
  c.stride_bytes = static_cast<int>(image.row_stride()) * kValueSize;
  // Same re-basing and arithmetic order as the scalar kernel.
  c.ua = _mm256_set1_ps(static_cast<float>(line.u0 + line.du * xa));
  c.va = _mm256_set1_ps(static_cast<float>(line.v0 + line.dv * xa));
  c.wa = _mm256_set1_ps(static_cast<float>(line.w0 + line.dw * xa));
  c.du = _mm256_set1_ps(static_cast<float>(line.du));
  c.dv = _mm256_set1_ps(static_cast<float>(line.dv));
  c.dw = _mm256_set1_ps(static_cast<float>(line.dw));
  c.x_max = _mm256_set1_ps(static_cast<float>(image.width()) - 0.5f);
  c.y_max = _mm256_set1_ps(static_cast<float>(image.height()) - 0.5f);
  double* out = sum + (xa - x0);
  const int n = xb - xa;
  const __m256 all = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
  // Software-pipelined: the gathers of the next group are issued before the current group is
  // interpolated, so their latency overlaps useful work (about 15% faster on Zen 3). The last
  // group may extend past the span: its positions are clamped into the image, so its gathers
  // stay in bounds, and its extra lanes add zero to the accumulators' padding (see caller).
  Fetched current = Fetch<kType>(c, 0);
  int i = 0;
  for (; i + 8 < n; i += 8) {
    const Fetched next = Fetch<kType>(c, i + 8);
    Finish<kType>(current, out + i, all);
    current = next;
  }
  const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  const __m256 keep = _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_set1_epi32(n - i), lane));
  Finish<kType>(current, out + i, keep);
}

// 8-bit views of 2 channels (masked grey frames: value x mask, weight; lightfield/mask.h): one
// 32-bit gather per row fetches both channels of both horizontal taps
// [p00 c0, p00 c1, p01 c0, p01 c1], so a sample of both channels costs two gathers, as the
// 1-channel kernel's. The sums are interleaved per pixel (c0, c1), as the scalar kernel's.
__attribute__((target("avx2,fma"), always_inline)) inline __m256 Bilinear(__m256 ax, __m256 ay,
                                                                          __m256 p00, __m256 p01,
                                                                          __m256 p10, __m256 p11) {
  const __m256 upper = _mm256_fmadd_ps(ax, _mm256_sub_ps(p01, p00), p00);
  const __m256 lower = _mm256_fmadd_ps(ax, _mm256_sub_ps(p11, p10), p10);
  return _mm256_fmadd_ps(ay, _mm256_sub_ps(lower, upper), upper);
}

__attribute__((target("avx2,fma"), always_inline)) inline __m256 Byte(__m256i word, int shift) {
  return _mm256_cvtepi32_ps(
      _mm256_and_si256(_mm256_srli_epi32(word, shift), _mm256_set1_epi32(0xff)));
}

// Adds 4 pixels' (c0, c1) from the 128-bit halves `v0`, `v1` to out[0..7].
__attribute__((target("avx2,fma"), always_inline)) inline void AddInterleaved(__m128 v0, __m128 v1,
                                                                              double* out) {
  const __m256d d0 = _mm256_cvtps_pd(v0), d1 = _mm256_cvtps_pd(v1);
  const __m256d low = _mm256_unpacklo_pd(d0, d1);   // p0c0 p0c1 p2c0 p2c1
  const __m256d high = _mm256_unpackhi_pd(d0, d1);  // p1c0 p1c1 p3c0 p3c1
  _mm256_storeu_pd(out, _mm256_add_pd(_mm256_loadu_pd(out), _mm256_permute2f128_pd(low, high, 0x20)));
  _mm256_storeu_pd(out + 4,
                   _mm256_add_pd(_mm256_loadu_pd(out + 4), _mm256_permute2f128_pd(low, high, 0x31)));
}

__attribute__((target("avx2,fma"), always_inline)) inline void FinishTwoChannels(const Fetched& f,
                                                                                 double* out,
                                                                                 __m256 keep) {
  const __m256 v0 = _mm256_and_ps(
      Bilinear(f.ax, f.ay, Byte(f.top, 0), Byte(f.top, 16), Byte(f.bottom, 0), Byte(f.bottom, 16)),
      keep);
  const __m256 v1 = _mm256_and_ps(
      Bilinear(f.ax, f.ay, Byte(f.top, 8), Byte(f.top, 24), Byte(f.bottom, 8), Byte(f.bottom, 24)),
      keep);
  AddInterleaved(_mm256_castps256_ps128(v0), _mm256_castps256_ps128(v1), out);
  AddInterleaved(_mm256_extractf128_ps(v0, 1), _mm256_extractf128_ps(v1, 1), out + 8);
}

__attribute__((target("avx2,fma"))) void Avx2SpanU8TwoChannels(const Image& image,
                                                               const RowLine& line, int xa, int xb,
                                                               int x0, double* sum) {
  SpanSetup c;
  c.origin = static_cast<const unsigned char*>(image.RawAt(0, 0));
  c.stride_bytes = static_cast<int>(image.row_stride());
  c.ua = _mm256_set1_ps(static_cast<float>(line.u0 + line.du * xa));
  c.va = _mm256_set1_ps(static_cast<float>(line.v0 + line.dv * xa));
  c.wa = _mm256_set1_ps(static_cast<float>(line.w0 + line.dw * xa));
  c.du = _mm256_set1_ps(static_cast<float>(line.du));
  c.dv = _mm256_set1_ps(static_cast<float>(line.dv));
  c.dw = _mm256_set1_ps(static_cast<float>(line.dw));
  c.x_max = _mm256_set1_ps(static_cast<float>(image.width()) - 0.5f);
  c.y_max = _mm256_set1_ps(static_cast<float>(image.height()) - 0.5f);
  double* out = sum + 2 * (xa - x0);
  const int n = xb - xa;
  const __m256 all = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
  // A pixel is 2 bytes: Fetch's byte offsets for kU16 (2 bytes a value) are this layout's.
  Fetched current = Fetch<PixelType::kU16>(c, 0);
  int i = 0;
  for (; i + 8 < n; i += 8) {
    const Fetched next = Fetch<PixelType::kU16>(c, i + 8);
    FinishTwoChannels(current, out + 2 * i, all);
    current = next;
  }
  const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  const __m256 keep = _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_set1_epi32(n - i), lane));
  FinishTwoChannels(current, out + 2 * i, keep);
}

bool CpuHasAvx2Fma() {
  static const bool has = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  }();
  return has;
}

}  // namespace

SpanKernel Avx2SpanKernel(const Image& image) {
  if (!SimdEnabled() || !CpuHasAvx2Fma() || image.channels() > 2 || image.border() < 1) {
    return nullptr;
  }
  // Gather offsets are 32-bit byte offsets.
  if (image.AllocatedBytes() >= static_cast<size_t>(std::numeric_limits<int32_t>::max() / 2)) {
    return nullptr;
  }
  if (image.channels() == 2) {
    return image.type() == PixelType::kU8 ? &Avx2SpanU8TwoChannels : nullptr;
  }
  switch (image.type()) {
    case PixelType::kU8: return &Avx2Span<PixelType::kU8>;
    case PixelType::kU16: return &Avx2Span<PixelType::kU16>;
    case PixelType::kF32: return &Avx2Span<PixelType::kF32>;
    case PixelType::kU32: break;
  }
  return nullptr;
}

#else

SpanKernel Avx2SpanKernel(const Image&) { return nullptr; }

#endif

}  // namespace aos::internal
