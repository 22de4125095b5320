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
  int height;  // of the view, pixels
};

// The span's constants: the row line re-based at its first pixel `xa` (double, then float, as
// the scalar kernel), the view's clamp limits and its rows; `value_size` bytes per sample.
__attribute__((target("avx2,fma"), always_inline)) inline SpanSetup MakeSpanSetup(const Image& image,
                                                                   const RowLine& line, int xa,
                                                                   int value_size) {
  SpanSetup c;
  c.origin = static_cast<const unsigned char*>(image.RawAt(0, 0));
  c.stride_bytes = static_cast<int>(image.row_stride()) * value_size;
  c.ua = _mm256_set1_ps(static_cast<float>(line.u0 + line.du * xa));
  c.va = _mm256_set1_ps(static_cast<float>(line.v0 + line.dv * xa));
  c.wa = _mm256_set1_ps(static_cast<float>(line.w0 + line.dw * xa));
  c.du = _mm256_set1_ps(static_cast<float>(line.du));
  c.dv = _mm256_set1_ps(static_cast<float>(line.dv));
  c.dw = _mm256_set1_ps(static_cast<float>(line.dw));
  c.x_max = _mm256_set1_ps(static_cast<float>(image.width()) - 0.5f);
  c.y_max = _mm256_set1_ps(static_cast<float>(image.height()) - 0.5f);
  c.height = image.height();
  return c;
}

// Where the 8 samples of a group fall in the view: the top-left tap and the weights.
struct Positions {
  __m256 ax, ay;
  __m256i ix, iy;
};

// A group's weights and its taps' raw values (the long-latency part).
struct Fetched {
  __m256 ax, ay;
  __m256i top, bottom;        // 8/16-bit views: both horizontal taps of a row in one 32-bit word
  __m256 p00, p01, p10, p11;  // float views
};

// The clamped sample positions of columns xa + fi (fi: 8 consecutive column offsets, as floats).
struct Samples {
  __m256 sx, sy;
};
__attribute__((target("avx2,fma"), always_inline)) inline Samples LocateSamples(const SpanSetup& c,
                                                                                __m256 fi) {
  const __m256 inv_w = _mm256_div_ps(_mm256_set1_ps(1.0f), _mm256_fmadd_ps(c.dw, fi, c.wa));
  // Clamped to [-1, size - 0.5] as in the scalar kernel (max_ps returns its second operand,
  // -1, for NaN), so no rounding can send a load outside the bordered image.
  const __m256 half = _mm256_set1_ps(0.5f), minus_one = _mm256_set1_ps(-1.0f);
  Samples s;
  s.sx = _mm256_min_ps(
      _mm256_max_ps(_mm256_fmsub_ps(_mm256_fmadd_ps(c.du, fi, c.ua), inv_w, half), minus_one),
      c.x_max);
  s.sy = _mm256_min_ps(
      _mm256_max_ps(_mm256_fmsub_ps(_mm256_fmadd_ps(c.dv, fi, c.va), inv_w, half), minus_one),
      c.y_max);
  return s;
}

// The top-left tap and the weights: floor (exact) and the fraction in [0, 1) (exact too).
__attribute__((target("avx2,fma"), always_inline)) inline Positions Split(const Samples& s) {
  const __m256 fx = _mm256_floor_ps(s.sx), fy = _mm256_floor_ps(s.sy);
  Positions p;
  p.ix = _mm256_cvttps_epi32(fx);
  p.iy = _mm256_cvttps_epi32(fy);
  p.ax = _mm256_sub_ps(s.sx, fx);
  p.ay = _mm256_sub_ps(s.sy, fy);
  return p;
}

// The sample positions of columns xa + fi, split into taps and weights.
__attribute__((target("avx2,fma"), always_inline)) inline Positions Locate(const SpanSetup& c,
                                                                           __m256 fi) {
  return Split(LocateSamples(c, fi));
}

// The 16 bytes at `p`, in both 128-bit halves, shuffled by `control`.
__attribute__((target("avx2,fma"), always_inline)) inline __m256i ShuffleRow(const unsigned char* p,
                                                                             __m256i control) {
  return _mm256_shuffle_epi8(
      _mm256_broadcastsi128_si256(_mm_loadu_si128(reinterpret_cast<const __m128i*>(p))), control);
}

// The taps of a group, by gathers (8-bit views have row loads: Avx2SpanU8Rows).
template <PixelType kType>
__attribute__((target("avx2,fma"), always_inline)) inline Fetched Fetch(const SpanSetup& c,
                                                                        const Positions& p) {
  constexpr int kValueSize = kType == PixelType::kU8 ? 1 : (kType == PixelType::kU16 ? 2 : 4);
  Fetched f;
  f.ax = p.ax;
  f.ay = p.ay;
  const __m256i offset =
      _mm256_add_epi32(_mm256_mullo_epi32(p.iy, _mm256_set1_epi32(c.stride_bytes)),
                       _mm256_mullo_epi32(p.ix, _mm256_set1_epi32(kValueSize)));
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

// Adds the 8 float values to out[0..7] in double; with `squares`, their squares (in double, as
// the scalar kernel: one rounding for the product, one for the sum) to squares[0..7].
__attribute__((target("avx2,fma"), always_inline)) inline void Accumulate(__m256 value, double* out,
                                                                          double* squares) {
  const __m256d low = _mm256_cvtps_pd(_mm256_castps256_ps128(value));
  const __m256d high = _mm256_cvtps_pd(_mm256_extractf128_ps(value, 1));
  _mm256_storeu_pd(out, _mm256_add_pd(_mm256_loadu_pd(out), low));
  _mm256_storeu_pd(out + 4, _mm256_add_pd(_mm256_loadu_pd(out + 4), high));
  if (squares != nullptr) {
    // A separate multiply and add, rounded as the scalar kernel rounds: the empty asm keeps the
    // compiler from contracting them into an FMA.
    __m256d low2 = _mm256_mul_pd(low, low), high2 = _mm256_mul_pd(high, high);
    asm("" : "+x"(low2), "+x"(high2));
    _mm256_storeu_pd(squares, _mm256_add_pd(_mm256_loadu_pd(squares), low2));
    _mm256_storeu_pd(squares + 4, _mm256_add_pd(_mm256_loadu_pd(squares + 4), high2));
  }
}

// The second half: unpack the taps, interpolate, add to the double accumulators.
// The taps' scores scale * (tap - centre)^2, interpolated with the sample's weights (the
// quadratic kernels: integral_kernels.h QuadraticKernel); the scalar kernel's order of operations.
// `floor`: -inf, or 0 for one-sided scores (max(tap - centre, floor)).
__attribute__((target("avx2,fma"), always_inline)) inline __m256 InterpolateQuadratic(
    __m256 p00, __m256 p01, __m256 p10, __m256 p11, __m256 ax, __m256 ay, __m256 centre,
    __m256 scale, __m256 floor) {
  const __m256 d00 = _mm256_max_ps(_mm256_sub_ps(p00, centre), floor);
  const __m256 d01 = _mm256_max_ps(_mm256_sub_ps(p01, centre), floor);
  const __m256 d10 = _mm256_max_ps(_mm256_sub_ps(p10, centre), floor);
  const __m256 d11 = _mm256_max_ps(_mm256_sub_ps(p11, centre), floor);
  const __m256 q00 = _mm256_mul_ps(d00, d00), q01 = _mm256_mul_ps(d01, d01);
  const __m256 q10 = _mm256_mul_ps(d10, d10), q11 = _mm256_mul_ps(d11, d11);
  const __m256 upper = _mm256_fmadd_ps(ax, _mm256_sub_ps(q01, q00), q00);
  const __m256 lower = _mm256_fmadd_ps(ax, _mm256_sub_ps(q11, q10), q10);
  return _mm256_mul_ps(scale, _mm256_fmadd_ps(ay, _mm256_sub_ps(lower, upper), upper));
}

// With `quad` (the quadratic kernels), the taps' scores scale * (tap - centre)^2 interpolated and
// added to quad[0..7] too.
template <PixelType kType, bool kQuad = false>
__attribute__((target("avx2,fma"), always_inline)) inline void Finish(
    const Fetched& f, double* out, double* squares, __m256 keep, double* quad = nullptr,
    __m256 centre = _mm256_setzero_ps(), __m256 scale = _mm256_setzero_ps(),
    __m256 floor = _mm256_setzero_ps()) {
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
  if constexpr (kQuad) {
    Accumulate(_mm256_and_ps(
                   InterpolateQuadratic(p00, p01, p10, p11, f.ax, f.ay, centre, scale, floor),
                   keep),
               quad, nullptr);
  }
  const __m256 upper = _mm256_fmadd_ps(f.ax, _mm256_sub_ps(p01, p00), p00);
  const __m256 lower = _mm256_fmadd_ps(f.ax, _mm256_sub_ps(p11, p10), p10);
  // `keep` zeroes the lanes past the end of the span (adding +0.0 changes nothing).
  const __m256 value = _mm256_and_ps(_mm256_fmadd_ps(f.ay, _mm256_sub_ps(lower, upper), upper), keep);
  Accumulate(value, out, squares);
}

// One span of a 1-channel view; with kSquares also the squared samples (the variance pass).
// Software-pipelined in three stages: while group g is interpolated and added, the taps of group
// g + 1 are loaded and the positions of group g + 2 computed, so the loads' latency (and that of
// the division before them) overlaps useful work. Groups past the span's end are clamped into
// the image, so their loads stay in bounds; the last group's extra lanes add zero to the
// accumulators' padding (see the caller).
// With kQuad, also the quadratic kernel's scores (QuadraticKernel) into `quad`.
template <PixelType kType, bool kSquares, bool kQuad = false>
__attribute__((target("avx2,fma"))) void Avx2SpanImpl(const Image& image, const RowLine& line,
                                                      int xa, int xb, int x0, double* sum,
                                                      double* sum_squares, double* quad = nullptr,
                                                      float centre_value = 0.0f,
                                                      float scale_value = 0.0f,
                                                      float floor_value = 0.0f) {
  const __m256 centre = _mm256_set1_ps(centre_value), scale = _mm256_set1_ps(scale_value);
  const __m256 floor = _mm256_set1_ps(floor_value);
  double* out_quad = kQuad ? quad + (xa - x0) : nullptr;
  constexpr int kValueSize = kType == PixelType::kU8 ? 1 : (kType == PixelType::kU16 ? 2 : 4);
  // Same re-basing and arithmetic order as the scalar kernel.
  const SpanSetup c = MakeSpanSetup(image, line, xa, kValueSize);
  double* out = sum + (xa - x0);
  double* squares = kSquares ? sum_squares + (xa - x0) : nullptr;
  const int n = xb - xa;
  const __m256 all = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
  // Column offsets as floats; adding 8 is exact (integers below 2^24).
  const __m256 eight = _mm256_set1_ps(8.0f);
  __m256 fi = _mm256_setr_ps(0, 1, 2, 3, 4, 5, 6, 7);
  Fetched current = Fetch<kType>(c, Locate(c, fi));
  fi = _mm256_add_ps(fi, eight);
  Positions ahead = Locate(c, fi);
  int i = 0;
  for (; i + 8 < n; i += 8) {
    fi = _mm256_add_ps(fi, eight);
    const Positions after = Locate(c, fi);
    const Fetched next = Fetch<kType>(c, ahead);
    Finish<kType, kQuad>(current, out + i, kSquares ? squares + i : nullptr, all,
                         kQuad ? out_quad + i : nullptr, centre, scale, floor);
    current = next;
    ahead = after;
  }
  const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  const __m256 keep = _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_set1_epi32(n - i), lane));
  Finish<kType, kQuad>(current, out + i, kSquares ? squares + i : nullptr, keep,
                       kQuad ? out_quad + i : nullptr, centre, scale, floor);
}

__attribute__((target("avx2,fma"))) void Avx2SpanU16Quadratic(const Image& image,
                                                              const RowLine& line, int xa, int xb,
                                                              int x0, double* sum, double* quad,
                                                              float centre, float scale,
                                                              float floor) {
  Avx2SpanImpl<PixelType::kU16, false, true>(image, line, xa, xb, x0, sum, nullptr, quad, centre,
                                             scale, floor);
}

// The taps of a group of an 8-bit view: both horizontal taps of the top row in the low 16 bits
// of each lane of `top` ([p00, p01, 0, 0]), likewise `bottom`; the upper bytes are zero.
struct TapsU8 {
  __m256i top, bottom;
};

// 8-bit views: the taps of 8 consecutive samples usually lie in a short stretch of two view rows
// (along an output row the view position moves by about one view pixel per output pixel; on F0
// every group does). Then 16-byte row loads and byte shuffles replace the two gathers, which
// issue 8 loads each. The words built are the gathers' words in their low 16 bits ([p00, p01]
// and [p10, p11]) with the upper bytes zero, so the samples are the gathers'. The base is the
// smaller of the first and last lanes' taps (one lane permute and a min: the exact positions are
// monotonic along the span); since rounding can break that by a pixel, every lane is checked:
// each tap must lie within 15 columns right of the base column and in its row or the next.
// Otherwise the group gathers (the same words, masked to 16 bits).
// Memory: reads 16 bytes from the base column (>= -1, <= width - 1, as positions are clamped to
// [-1, width - 0.5]) in rows y_min .. y_min + 2, the third only where y_min + 2 <= height (the
// bottom border row); so at most 14 bytes past the last border row, in the slack (image.cpp:
// kSlackBytes).
__attribute__((target("avx2,fma"), always_inline)) inline TapsU8 FetchU8(const SpanSetup& c,
                                                                          const Positions& p,
                                                                          __m256i x_lane,
                                                                          __m256i y_lane) {
  // The base: every lane holds the first or the last lane's tap (x_lane, y_lane: all 0 or all 7).
  const __m256i x_base = _mm256_permutevar8x32_epi32(p.ix, x_lane);
  const __m256i y_base = _mm256_permutevar8x32_epi32(p.iy, y_lane);
  const __m256i d = _mm256_sub_epi32(p.ix, x_base);
  const __m256i e = _mm256_sub_epi32(p.iy, y_base);
  const __m256i d_max = _mm256_set1_epi32(14), e_max = _mm256_set1_epi32(1);
  const __m256i fits = _mm256_and_si256(_mm256_cmpeq_epi32(_mm256_max_epu32(d, d_max), d_max),
                                        _mm256_cmpeq_epi32(_mm256_max_epu32(e, e_max), e_max));
  TapsU8 t;
  if (__builtin_expect(_mm256_movemask_epi8(fits) == -1, 1)) {
    const int x0 = _mm256_cvtsi256_si32(x_base), y0 = _mm256_cvtsi256_si32(y_base);
    const unsigned char* row = c.origin + static_cast<ptrdiff_t>(y0) * c.stride_bytes + x0;
    // Per lane, bytes [d, d + 1, zero, zero] (vpshufb zeroes for 0x80).
    const __m256i control = _mm256_add_epi32(_mm256_add_epi32(d, _mm256_slli_epi32(d, 8)),
                                             _mm256_set1_epi32(static_cast<int>(0x80800100u)));
    // Always three rows and a blend (lanes in row y0 + 1 take the lower pair): on F0 about one
    // group in six spans two rows, and the branch it would take costs more than the third load.
    // At the bottom (y0 = height - 1) no lane is in row y0 + 1 and the third is not read.
    const ptrdiff_t third = y0 + 2 <= c.height ? 2 * c.stride_bytes : c.stride_bytes;
    const __m256 row0 = _mm256_castsi256_ps(ShuffleRow(row, control));
    const __m256 row1 = _mm256_castsi256_ps(ShuffleRow(row + c.stride_bytes, control));
    const __m256 row2 = _mm256_castsi256_ps(ShuffleRow(row + third, control));
    // Lanes in row y0 + 1 (e = 1) have the sign bit of the shifted e set.
    const __m256 lower = _mm256_castsi256_ps(_mm256_slli_epi32(e, 31));
    t.top = _mm256_castps_si256(_mm256_blendv_ps(row0, row1, lower));
    t.bottom = _mm256_castps_si256(_mm256_blendv_ps(row1, row2, lower));
    return t;
  }
  const __m256i offset =
      _mm256_add_epi32(_mm256_mullo_epi32(p.iy, _mm256_set1_epi32(c.stride_bytes)), p.ix);
  const __m256i low16 = _mm256_set1_epi32(0xffff);
  t.top = _mm256_and_si256(
      _mm256_i32gather_epi32(reinterpret_cast<const int*>(c.origin), offset, 1), low16);
  t.bottom = _mm256_and_si256(
      _mm256_i32gather_epi32(reinterpret_cast<const int*>(c.origin + c.stride_bytes), offset, 1),
      low16);
  return t;
}

// Finish<kU8>'s arithmetic on TapsU8 (no masks needed above the second byte).
__attribute__((target("avx2,fma"), always_inline)) inline __m256 InterpolateU8(const TapsU8& t,
                                                                              __m256 ax,
                                                                              __m256 ay) {
  const __m256i byte = _mm256_set1_epi32(0xff);
  const __m256 p00 = _mm256_cvtepi32_ps(_mm256_and_si256(t.top, byte));
  const __m256 p01 = _mm256_cvtepi32_ps(_mm256_srli_epi32(t.top, 8));
  const __m256 p10 = _mm256_cvtepi32_ps(_mm256_and_si256(t.bottom, byte));
  const __m256 p11 = _mm256_cvtepi32_ps(_mm256_srli_epi32(t.bottom, 8));
  const __m256 upper = _mm256_fmadd_ps(ax, _mm256_sub_ps(p01, p00), p00);
  const __m256 lower = _mm256_fmadd_ps(ax, _mm256_sub_ps(p11, p10), p10);
  return _mm256_fmadd_ps(ay, _mm256_sub_ps(lower, upper), upper);
}

// InterpolateU8, and with `quad` the taps' interpolated scores (InterpolateQuadratic) added to
// quad[0..7] (masked by `keep`).
__attribute__((target("avx2,fma"), always_inline)) inline __m256 InterpolateU8Quadratic(
    const TapsU8& t, __m256 ax, __m256 ay, __m256 centre, __m256 scale, __m256 floor, __m256 keep,
    double* quad) {
  const __m256i byte = _mm256_set1_epi32(0xff);
  const __m256 p00 = _mm256_cvtepi32_ps(_mm256_and_si256(t.top, byte));
  const __m256 p01 = _mm256_cvtepi32_ps(_mm256_srli_epi32(t.top, 8));
  const __m256 p10 = _mm256_cvtepi32_ps(_mm256_and_si256(t.bottom, byte));
  const __m256 p11 = _mm256_cvtepi32_ps(_mm256_srli_epi32(t.bottom, 8));
  Accumulate(
      _mm256_and_ps(InterpolateQuadratic(p00, p01, p10, p11, ax, ay, centre, scale, floor), keep),
      quad, nullptr);
  const __m256 upper = _mm256_fmadd_ps(ax, _mm256_sub_ps(p01, p00), p00);
  const __m256 lower = _mm256_fmadd_ps(ax, _mm256_sub_ps(p11, p10), p10);
  return _mm256_fmadd_ps(ay, _mm256_sub_ps(lower, upper), upper);
}

// The 8-bit kernel with row loads, software-pipelined in three stages as Avx2SpanImpl (while
// group g is interpolated and added, group g + 1's taps are loaded and group g + 2 located). Its
// critical path per group (division, floor, base, row loads, interpolation, accumulation: about
// 90 cycles of latency on Zen 3) is several times its issue time, so without the stages the
// reorder buffer, not the execution units, bounds it.
// The samples' values; with kQuad, the same taps' scores added to quad[0..7] too.
template <bool kQuad>
__attribute__((target("avx2,fma"), always_inline)) inline __m256 SampleU8(
    const TapsU8& t, const Positions& at, __m256 centre, __m256 scale, __m256 floor, __m256 keep,
    double* quad) {
  if constexpr (kQuad) {
    return InterpolateU8Quadratic(t, at.ax, at.ay, centre, scale, floor, keep, quad);
  } else {
    (void)centre, (void)scale, (void)floor, (void)keep, (void)quad;
    return InterpolateU8(t, at.ax, at.ay);
  }
}

// With kQuad, also the quadratic kernel's scores (QuadraticKernel) into `quad`.
template <bool kSquares, bool kQuad>
__attribute__((target("avx2,fma"), always_inline)) inline void Avx2SpanU8RowsImpl(
    const Image& image, const RowLine& line, int xa, int xb, int x0, double* sum,
    double* sum_squares, double* quad, float centre_value, float scale_value, float floor_value) {
  const SpanSetup c = MakeSpanSetup(image, line, xa, 1);
  double* out = sum + (xa - x0);
  double* squares = kSquares ? sum_squares + (xa - x0) : nullptr;
  double* out_quad = kQuad ? quad + (xa - x0) : nullptr;
  const __m256 centre = _mm256_set1_ps(centre_value), scale = _mm256_set1_ps(scale_value);
  const __m256 floor = _mm256_set1_ps(floor_value);
  const __m256 all = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
  const int n = xb - xa;
  // The view position moves monotonically along the span (W > 0): U/W grows iff
  // du w - u dw >= 0, so the smaller tap is the first lane's or the last lane's for the whole span.
  const double u_a = line.u0 + line.du * xa, v_a = line.v0 + line.dv * xa,
               w_a = line.w0 + line.dw * xa;
  const __m256i x_lane = _mm256_set1_epi32(line.du * w_a - u_a * line.dw >= 0.0 ? 0 : 7);
  const __m256i y_lane = _mm256_set1_epi32(line.dv * w_a - v_a * line.dw >= 0.0 ? 0 : 7);
  const __m256 eight = _mm256_set1_ps(8.0f);
  __m256 fi = _mm256_setr_ps(0, 1, 2, 3, 4, 5, 6, 7);
  Positions p = Locate(c, fi);
  TapsU8 taps = FetchU8(c, p, x_lane, y_lane);
  fi = _mm256_add_ps(fi, eight);
  // Between the first two stages only the clamped positions travel (two registers, not four).
  Samples q = LocateSamples(c, fi);
  int i = 0;
  for (; i + 8 < n; i += 8) {
    fi = _mm256_add_ps(fi, eight);
    const Samples after = LocateSamples(c, fi);
    const Positions split = Split(q);
    const TapsU8 next = FetchU8(c, split, x_lane, y_lane);
    Accumulate(SampleU8<kQuad>(taps, p, centre, scale, floor, all, kQuad ? out_quad + i : nullptr),
               out + i, kSquares ? squares + i : nullptr);
    taps = next;
    p = split;
    q = after;
  }
  const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  const __m256 keep = _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_set1_epi32(n - i), lane));
  Accumulate(_mm256_and_ps(SampleU8<kQuad>(taps, p, centre, scale, floor, keep,
                                           kQuad ? out_quad + i : nullptr),
                           keep),
             out + i, kSquares ? squares + i : nullptr);
}

template <bool kSquares>
__attribute__((target("avx2,fma"))) void Avx2SpanU8Rows(const Image& image, const RowLine& line,
                                                        int xa, int xb, int x0, double* sum,
                                                        double* sum_squares) {
  Avx2SpanU8RowsImpl<kSquares, false>(image, line, xa, xb, x0, sum, sum_squares, nullptr, 0.0f,
                                      0.0f, 0.0f);
}

__attribute__((target("avx2,fma"))) void Avx2SpanU8RowsQuadratic(const Image& image,
                                                                 const RowLine& line, int xa,
                                                                 int xb, int x0, double* sum,
                                                                 double* quad, float centre,
                                                                 float scale, float floor) {
  Avx2SpanU8RowsImpl<false, true>(image, line, xa, xb, x0, sum, nullptr, quad, centre, scale,
                                  floor);
}

template <PixelType kType>
__attribute__((target("avx2,fma"))) void Avx2Span(const Image& image, const RowLine& line,
                                                  int xa, int xb, int x0, double* sum) {
  Avx2SpanImpl<kType, false>(image, line, xa, xb, x0, sum, nullptr);
}

__attribute__((target("avx2,fma"))) void Avx2SpanU8RowsSum(const Image& image, const RowLine& line,
                                                           int xa, int xb, int x0, double* sum) {
  Avx2SpanU8Rows<false>(image, line, xa, xb, x0, sum, nullptr);
}

// 8-bit views with gathers only (no row loads): the kernel before row loads, for benchmarks.
__attribute__((target("avx2,fma"))) void Avx2SpanU8Gathers(const Image& image, const RowLine& line,
                                                           int xa, int xb, int x0, double* sum) {
  Avx2SpanImpl<PixelType::kU8, false>(image, line, xa, xb, x0, sum, nullptr);
}

__attribute__((target("avx2,fma"))) void Avx2SpanSquaresU8Gathers(const Image& image,
                                                                  const RowLine& line, int xa,
                                                                  int xb, int x0, double* sum,
                                                                  double* sum_squares) {
  Avx2SpanImpl<PixelType::kU8, true>(image, line, xa, xb, x0, sum, sum_squares);
}

template <PixelType kType>
__attribute__((target("avx2,fma"))) void Avx2SpanSquares(const Image& image, const RowLine& line,
                                                         int xa, int xb, int x0, double* sum,
                                                         double* sum_squares) {
  Avx2SpanImpl<kType, true>(image, line, xa, xb, x0, sum, sum_squares);
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
  const SpanSetup c = MakeSpanSetup(image, line, xa, 1);
  double* out = sum + 2 * (xa - x0);
  const int n = xb - xa;
  const __m256 all = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
  // A pixel is 2 bytes: Fetch's byte offsets for kU16 (2 bytes a value) are this layout's.
  const __m256 eight = _mm256_set1_ps(8.0f);
  __m256 fi = _mm256_setr_ps(0, 1, 2, 3, 4, 5, 6, 7);
  Fetched current = Fetch<PixelType::kU16>(c, Locate(c, fi));
  int i = 0;
  for (; i + 8 < n; i += 8) {
    fi = _mm256_add_ps(fi, eight);
    const Fetched next = Fetch<PixelType::kU16>(c, Locate(c, fi));
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

// Whether the AVX2 kernels can sample `image` (gather offsets are 32-bit byte offsets).
bool Avx2Usable(const Image& image) {
  return SimdEnabled() && CpuHasAvx2Fma() && image.border() >= 1 &&
         image.AllocatedBytes() < static_cast<size_t>(std::numeric_limits<int32_t>::max() / 2);
}

}  // namespace

SquaresKernel Avx2SquaresKernel(const Image& image) {
  if (!Avx2Usable(image) || image.channels() != 1) return nullptr;
  switch (image.type()) {
    case PixelType::kU8:
      return SimdRowLoadsEnabled() ? &Avx2SpanU8Rows<true> : &Avx2SpanSquaresU8Gathers;
    case PixelType::kU16: return &Avx2SpanSquares<PixelType::kU16>;
    case PixelType::kF32: return &Avx2SpanSquares<PixelType::kF32>;
    case PixelType::kU32: break;
  }
  return nullptr;
}

QuadraticKernel Avx2QuadraticKernel(const Image& image) {
  if (!Avx2Usable(image) || image.channels() != 1) return nullptr;
  switch (image.type()) {
    case PixelType::kU8: return SimdRowLoadsEnabled() ? &Avx2SpanU8RowsQuadratic : nullptr;
    case PixelType::kU16: return &Avx2SpanU16Quadratic;
    default: return nullptr;
  }
}

SpanKernel Avx2SpanKernel(const Image& image) {
  if (!Avx2Usable(image) || image.channels() > 2) return nullptr;
  if (image.channels() == 2) {
    return image.type() == PixelType::kU8 ? &Avx2SpanU8TwoChannels : nullptr;
  }
  switch (image.type()) {
    case PixelType::kU8:
      return SimdRowLoadsEnabled() ? &Avx2SpanU8RowsSum : &Avx2SpanU8Gathers;
    case PixelType::kU16: return &Avx2Span<PixelType::kU16>;
    case PixelType::kF32: return &Avx2Span<PixelType::kF32>;
    case PixelType::kU32: break;
  }
  return nullptr;
}

#else

SpanKernel Avx2SpanKernel(const Image&) { return nullptr; }
SquaresKernel Avx2SquaresKernel(const Image&) { return nullptr; }
QuadraticKernel Avx2QuadraticKernel(const Image&) { return nullptr; }

#endif

}  // namespace aos::internal
