// AVX2 + FMA kernel of the per-sample renderer: one view (a pinhole projection, or a lens view's
// local homography or cubic map) at a tile of focal points, 8 points per step (projection,
// admission tests as masks, bilinear taps, double accumulation). Compiled for the baseline
// CPU; the function carries target attributes and is only handed out after a runtime check of
// the CPU (as integral_kernels_avx2.cpp).
#include <cstdint>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <type_traits>

#include "aos/render/integral_kernels.h"
#include "aos/render/surface_integral_kernels.h"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#define AOS_HAVE_AVX2_POINT_KERNELS 1
#endif

namespace aos::internal {

#ifdef AOS_HAVE_AVX2_POINT_KERNELS
namespace {

// Folds one test into the certain-pass and certain-fail masks: pass where value > bound, fail
// where value < -bound; lanes in between stay undecided (the caller's exact test decides).
__attribute__((target("avx2,fma"), always_inline)) inline void Decide(__m256 value, __m256 bound,
                                                                      __m256 negative_bound,
                                                                      __m256& pass, __m256& fail) {
  pass = _mm256_and_ps(pass, _mm256_cmp_ps(value, bound, _CMP_GT_OQ));
  fail = _mm256_or_ps(fail, _mm256_cmp_ps(value, negative_bound, _CMP_LT_OQ));
}

// One group of 8 lanes with at least one admitted, waiting for its samples.
struct Pending {
  __m256i keep, offset;
  __m256 ax, ay;
  int group;
};

// The taps of one pending group as gathered (the long-latency half of a sample).
struct Taps {
  __m256i top, bottom;        // 8/16-bit views: both horizontal taps of a row in one 32-bit word
  __m256 p00, p01, p10, p11;  // float views
};

template <PixelType kType>
__attribute__((target("avx2,fma"), always_inline)) inline Taps Gather(const Pending& p,
                                                                      const unsigned char* origin,
                                                                      int stride_bytes) {
  Taps t;
  if constexpr (kType == PixelType::kF32) {
    // Both horizontal taps of a row in one 64-bit load per lane (as the 8/16-bit views' 32-bit
    // words): 16 loads instead of four 8-lane vgatherdps (32 elements). Lanes 0, 1, 4, 5 go
    // to `a` and 2, 3, 6, 7 to `b` (two per 128-bit half), so that one shuffle per tap column
    // puts the taps in lane order.
    alignas(32) int32_t offsets[8];
    _mm256_store_si256(reinterpret_cast<__m256i*>(offsets), p.offset);
    const auto pairs = [&](int k0, int k1, int row) {
      const __m128d low = _mm_castsi128_pd(
          _mm_loadl_epi64(reinterpret_cast<const __m128i*>(origin + row + offsets[k0])));
      return _mm_loadh_pd(low, reinterpret_cast<const double*>(origin + row + offsets[k1]));
    };
    for (int row = 0; row < 2; ++row) {
      const int row_bytes = row == 0 ? 0 : stride_bytes;
      const __m256 a = _mm256_castpd_ps(_mm256_insertf128_pd(
          _mm256_castpd128_pd256(pairs(0, 1, row_bytes)), pairs(4, 5, row_bytes), 1));
      const __m256 b = _mm256_castpd_ps(_mm256_insertf128_pd(
          _mm256_castpd128_pd256(pairs(2, 3, row_bytes)), pairs(6, 7, row_bytes), 1));
      (row == 0 ? t.p00 : t.p10) = _mm256_shuffle_ps(a, b, _MM_SHUFFLE(2, 0, 2, 0));
      (row == 0 ? t.p01 : t.p11) = _mm256_shuffle_ps(a, b, _MM_SHUFFLE(3, 1, 3, 1));
    }
  } else {
    // Both horizontal taps of a row in one 32-bit word, read with scalar loads: on Zen 3 16
    // scalar loads cost fewer cycles than two 8-lane vpgatherdd (about 13 cycles each), about
    // 5 % of the F0 mesh render.
    alignas(32) int32_t offsets[8];
    _mm256_store_si256(reinterpret_cast<__m256i*>(offsets), p.offset);
    const auto word = [&](int k, int row) {
      int32_t value;
      std::memcpy(&value, origin + row + offsets[k], sizeof(int32_t));
      return value;
    };
    t.top = _mm256_setr_epi32(word(0, 0), word(1, 0), word(2, 0), word(3, 0), word(4, 0),
                              word(5, 0), word(6, 0), word(7, 0));
    t.bottom = _mm256_setr_epi32(word(0, stride_bytes), word(1, stride_bytes), word(2, stride_bytes),
                                 word(3, stride_bytes), word(4, stride_bytes), word(5, stride_bytes),
                                 word(6, stride_bytes), word(7, stride_bytes));
  }
  return t;
}

// Interpolates one group's taps and adds the samples to the accumulators.
template <PixelType kType>
__attribute__((target("avx2,fma"), always_inline)) inline void Accumulate(
    const Pending& p, const Taps& t, bool variance, double* sum, double* sum_squares,
    uint32_t* count) {
  __m256 p00, p01, p10, p11;
  if constexpr (kType == PixelType::kF32) {
    p00 = t.p00, p01 = t.p01, p10 = t.p10, p11 = t.p11;
  } else {
    constexpr int kBits = kType == PixelType::kU8 ? 8 : 16;
    const __m256i mask = _mm256_set1_epi32((1 << kBits) - 1);
    p00 = _mm256_cvtepi32_ps(_mm256_and_si256(t.top, mask));
    p01 = _mm256_cvtepi32_ps(_mm256_and_si256(_mm256_srli_epi32(t.top, kBits), mask));
    p10 = _mm256_cvtepi32_ps(_mm256_and_si256(t.bottom, mask));
    p11 = _mm256_cvtepi32_ps(_mm256_and_si256(_mm256_srli_epi32(t.bottom, kBits), mask));
  }
  const __m256 upper = _mm256_fmadd_ps(p.ax, _mm256_sub_ps(p01, p00), p00);
  const __m256 lower = _mm256_fmadd_ps(p.ax, _mm256_sub_ps(p11, p10), p10);
  const __m256 value = _mm256_and_ps(_mm256_fmadd_ps(p.ay, _mm256_sub_ps(lower, upper), upper),
                                     _mm256_castsi256_ps(p.keep));
  const __m256d low = _mm256_cvtps_pd(_mm256_castps256_ps128(value));
  const __m256d high = _mm256_cvtps_pd(_mm256_extractf128_ps(value, 1));
  double* out = sum + p.group;
  _mm256_storeu_pd(out, _mm256_add_pd(_mm256_loadu_pd(out), low));
  _mm256_storeu_pd(out + 4, _mm256_add_pd(_mm256_loadu_pd(out + 4), high));
  if (variance) {
    double* squares = sum_squares + p.group;
    _mm256_storeu_pd(squares, _mm256_fmadd_pd(low, low, _mm256_loadu_pd(squares)));
    _mm256_storeu_pd(squares + 4, _mm256_fmadd_pd(high, high, _mm256_loadu_pd(squares + 4)));
  }
  auto* counts = reinterpret_cast<__m256i*>(count + p.group);
  _mm256_storeu_si256(counts, _mm256_sub_epi32(_mm256_loadu_si256(counts), p.keep));
}

// Samples the pending groups and adds them to the accumulators, software-pipelined: the next
// group's taps are fetched before the current group is interpolated (as the span kernels).
template <PixelType kType>
__attribute__((target("avx2,fma"), always_inline)) inline void Flush(
    const Pending* pending, int size, const unsigned char* origin, int stride_bytes,
    bool variance, double* sum, double* sum_squares, uint32_t* count) {
  if (size == 0) return;
  Taps current = Gather<kType>(pending[0], origin, stride_bytes);
  for (int k = 0; k + 1 < size; ++k) {
    const Taps next = Gather<kType>(pending[k + 1], origin, stride_bytes);
    Accumulate<kType>(pending[k], current, variance, sum, sum_squares, count);
    current = next;
  }
  Accumulate<kType>(pending[size - 1], current, variance, sum, sum_squares, count);
}

// c . (1, x, y, x^2, x y, y^2, x^3, x^2 y, x y^2, y^3) in 9 fused multiply-adds (PointKernelArgs::
// cubic): x (c1 + c4 y + x (c3 + c7 y + c6 x)) + y (c2 + y (c5 + c8 x + c9 y)) + c0.
__attribute__((target("avx2,fma"), always_inline)) inline __m256 Cubic(const __m256 c[10], __m256 x,
                                                                       __m256 y) {
  const __m256 xx = _mm256_fmadd_ps(c[6], x, _mm256_fmadd_ps(c[7], y, c[3]));
  const __m256 x_part = _mm256_fmadd_ps(x, xx, _mm256_fmadd_ps(c[4], y, c[1]));
  const __m256 yy = _mm256_fmadd_ps(c[9], y, _mm256_fmadd_ps(c[8], x, c[5]));
  const __m256 y_part = _mm256_fmadd_ps(y, yy, c[2]);
  return _mm256_fmadd_ps(x, x_part, _mm256_fmadd_ps(y, y_part, c[0]));
}

template <PixelType kType, bool kCubic>
__attribute__((target("avx2,fma"))) bool Avx2PointsMap(const Image& image,
                                                       const PointTileArrays& points,
                                                       const PointKernelArgs& args, double* sum,
                                                       double* sum_squares, uint32_t* count) {
  constexpr int kValueSize = kType == PixelType::kU8 ? 1 : (kType == PixelType::kU16 ? 2 : 4);
  const auto* origin = static_cast<const unsigned char*>(image.RawAt(0, 0));
  const int stride_bytes = static_cast<int>(image.row_stride()) * kValueSize;
  __m256 P[3][4];
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) P[r][c] = _mm256_set1_ps(args.P[r][c]);
  }
  const __m256 width = _mm256_set1_ps(args.width), height = _mm256_set1_ps(args.height);
  __m256 bound[5], negative[5];
  for (int k = 0; k < 5; ++k) {
    bound[k] = _mm256_set1_ps(args.bound[k]);
    negative[k] = _mm256_set1_ps(-args.bound[k]);
  }
  const __m256 n0 = _mm256_set1_ps(args.normal[0]), n1 = _mm256_set1_ps(args.normal[1]),
               n2 = _mm256_set1_ps(args.normal[2]);
  const __m256 sin2 = _mm256_set1_ps(args.sin2), grazing_bound = _mm256_set1_ps(args.grazing_bound);
  const __m256 a0 = _mm256_set1_ps(args.axis[0]), a1 = _mm256_set1_ps(args.axis[1]),
               a2 = _mm256_set1_ps(args.axis[2]);
  const __m256 b0 = _mm256_set1_ps(args.b[0]), b1 = _mm256_set1_ps(args.b[1]),
               b2 = _mm256_set1_ps(args.b[2]);
  const __m256 lens_b = _mm256_set1_ps(args.lens_b), r2 = _mm256_set1_ps(args.r2);
  const __m256 aperture_bound = _mm256_set1_ps(args.aperture_bound);
  const __m256 negative_aperture_bound = _mm256_set1_ps(-args.aperture_bound);
  const __m256 negative_grazing_bound = _mm256_set1_ps(-args.grazing_bound);
  const __m256 denominator_bound = _mm256_set1_ps(args.denominator_bound);
  const __m256 abs_mask = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
  const __m256 all = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
  const __m256 one = _mm256_set1_ps(1.0f), half = _mm256_set1_ps(0.5f),
               minus_one = _mm256_set1_ps(-1.0f);
  const __m256 x_max = _mm256_set1_ps(static_cast<float>(image.width()) - 0.5f);
  const __m256 y_max = _mm256_set1_ps(static_cast<float>(image.height()) - 0.5f);
  const __m256i one_i = _mm256_set1_epi32(1);
  const __m256i stride = _mm256_set1_epi32(stride_bytes);
  __m256 cubic[2][10];
  if constexpr (kCubic) {
    for (int r = 0; r < 2; ++r) {
      for (int k = 0; k < 10; ++k) cubic[r][k] = _mm256_set1_ps(args.cubic[r][k]);
    }
  }
  const int image_tests = args.image_tests;
  bool any = false;
  constexpr int kPending = 32;
  Pending pending[kPending];
  int pending_size = 0;
  // The next view's pixels, spread over the groups (a burst would fill the miss queues).
  const int groups_per_row = points.rows > 0 ? points.row_length / 8 : points.size / 8;
  const int groups = points.rows > 0 ? groups_per_row * points.rows : groups_per_row;
  const int prefetch_per_group =
      groups > 0 ? (args.prefetch_count + groups - 1) / groups : 0;
  int prefetched = 0;
  for (int group = 0; group < groups; ++group) {
    const int i = points.rows > 0
                      ? (group / groups_per_row) * points.row_stride + (group % groups_per_row) * 8
                      : group * 8;
    for (int k = 0; k < prefetch_per_group && prefetched < args.prefetch_count; ++k) {
      _mm_prefetch(args.prefetch[prefetched++], _MM_HINT_T0);
    }
    const __m256 x = _mm256_loadu_ps(points.x + i);
    const __m256 y = _mm256_loadu_ps(points.y + i);
    const __m256 z = _mm256_loadu_ps(points.z + i);
    const __m256 valid = _mm256_castsi256_ps(
        _mm256_loadu_si256(reinterpret_cast<const __m256i*>(points.valid + i)));
    const __m256 U = _mm256_fmadd_ps(P[0][0], x, _mm256_fmadd_ps(P[0][1], y, _mm256_fmadd_ps(P[0][2], z, P[0][3])));
    const __m256 V = _mm256_fmadd_ps(P[1][0], x, _mm256_fmadd_ps(P[1][1], y, _mm256_fmadd_ps(P[1][2], z, P[1][3])));
    const __m256 Z = _mm256_fmadd_ps(P[2][0], x, _mm256_fmadd_ps(P[2][1], y, _mm256_fmadd_ps(P[2][2], z, P[2][3])));
    __m256 pass = valid;
    __m256 fail = _mm256_xor_ps(valid, all);
    if (image_tests == 0 && _mm256_movemask_ps(valid) == 0) continue;
    if (image_tests != 0) {
      if (image_tests & 1) Decide(Z, bound[0], negative[0], pass, fail);
      if (image_tests & 2) Decide(U, bound[1], negative[1], pass, fail);
      if (image_tests & 4) Decide(_mm256_fmsub_ps(width, Z, U), bound[2], negative[2], pass, fail);
      if (image_tests & 8) Decide(V, bound[3], negative[3], pass, fail);
      if (image_tests & 16) Decide(_mm256_fmsub_ps(height, Z, V), bound[4], negative[4], pass, fail);
      // Skip the rest when no lane is left undecided-or-passing (the common case at the edge
      // of a view's footprint).
      if (_mm256_movemask_ps(_mm256_andnot_ps(fail, all)) == 0) continue;
    }
    if (args.grazing || args.aperture == 2) {
      const __m256 t0 = _mm256_sub_ps(b0, x), t1 = _mm256_sub_ps(b1, y), t2 = _mm256_sub_ps(b2, z);
      const __m256 t_t = _mm256_fmadd_ps(t0, t0, _mm256_fmadd_ps(t1, t1, _mm256_mul_ps(t2, t2)));
      if (args.grazing) {
        const __m256 along = _mm256_fmadd_ps(n0, t0, _mm256_fmadd_ps(n1, t1, _mm256_mul_ps(n2, t2)));
        Decide(_mm256_fmsub_ps(along, along, _mm256_mul_ps(sin2, t_t)), grazing_bound,
               negative_grazing_bound, pass, fail);
      }
      if (args.aperture == 2) {
        const __m256 t_a = _mm256_fmadd_ps(a0, t0, _mm256_fmadd_ps(a1, t1, _mm256_mul_ps(a2, t2)));
        // |t - (t.a) a|^2 = |t|^2 - (t.a)^2 for a unit axis.
        const __m256 distance2 = _mm256_fnmadd_ps(t_a, t_a, t_t);
        Decide(_mm256_sub_ps(r2, distance2), aperture_bound, negative_aperture_bound, pass, fail);
      }
    }
    if (args.aperture == 1) {
      const __m256 a_x = _mm256_fmadd_ps(a0, x, _mm256_fmadd_ps(a1, y, _mm256_mul_ps(a2, z)));
      const __m256 denominator = _mm256_sub_ps(lens_b, a_x);
      const __m256 m0 = _mm256_fnmadd_ps(a_x, b0, _mm256_mul_ps(lens_b, x));
      const __m256 m1 = _mm256_fnmadd_ps(a_x, b1, _mm256_mul_ps(lens_b, y));
      const __m256 m2 = _mm256_fnmadd_ps(a_x, b2, _mm256_mul_ps(lens_b, z));
      const __m256 m_m = _mm256_fmadd_ps(m0, m0, _mm256_fmadd_ps(m1, m1, _mm256_mul_ps(m2, m2)));
      Decide(_mm256_fmsub_ps(_mm256_mul_ps(r2, denominator), denominator, m_m), aperture_bound,
             negative_aperture_bound, pass, fail);
      pass = _mm256_and_ps(pass, _mm256_cmp_ps(_mm256_and_ps(denominator, abs_mask),
                                               denominator_bound, _CMP_GT_OQ));
    }
    int undecided = _mm256_movemask_ps(_mm256_andnot_ps(_mm256_or_ps(pass, fail), all));
    int admitted = _mm256_movemask_ps(pass);
    while (undecided != 0) {
      const int lane = __builtin_ctz(static_cast<unsigned>(undecided));
      undecided &= undecided - 1;
      if (args.exact(args.exact_context, i + lane)) admitted |= 1 << lane;
    }
    if (admitted == 0) continue;
    any = true;
    // Positions and taps' offsets of the admitted lanes; the taps are read in a second pass, so
    // that their latency overlaps across groups (no load waits on the tests of its group).
    const __m256i lanes = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
    const __m256i keep_i = _mm256_cmpeq_epi32(
        _mm256_and_si256(_mm256_set1_epi32(admitted), lanes), lanes);
    // Bilinear sample, clamped into the bordered image like the span kernels (max_ps returns
    // its second operand, -1, for NaN).
    const __m256 inv_z = _mm256_div_ps(one, Z);
    __m256 sx, sy;  // continuous pixel - 0.5
    if constexpr (kCubic) {
      const __m256 qx = _mm256_mul_ps(U, inv_z), qy = _mm256_mul_ps(V, inv_z);
      sx = Cubic(cubic[0], qx, qy);
      sy = Cubic(cubic[1], qx, qy);
    } else {
      sx = _mm256_fmsub_ps(U, inv_z, half);
      sy = _mm256_fmsub_ps(V, inv_z, half);
    }
    sx = _mm256_min_ps(_mm256_max_ps(sx, minus_one), x_max);
    sy = _mm256_min_ps(_mm256_max_ps(sy, minus_one), y_max);
    const __m256i ix = _mm256_sub_epi32(_mm256_cvttps_epi32(_mm256_add_ps(sx, one)), one_i);
    const __m256i iy = _mm256_sub_epi32(_mm256_cvttps_epi32(_mm256_add_ps(sy, one)), one_i);
    const __m256 fx = _mm256_cvtepi32_ps(ix), fy = _mm256_cvtepi32_ps(iy);
    Pending& p = pending[pending_size++];
    p.group = i;
    p.keep = keep_i;
    p.ax = _mm256_sub_ps(sx, fx);
    p.ay = _mm256_sub_ps(sy, fy);
    constexpr int kShift = kValueSize == 1 ? 0 : (kValueSize == 2 ? 1 : 2);
    p.offset = _mm256_add_epi32(_mm256_mullo_epi32(iy, stride), _mm256_slli_epi32(ix, kShift));
    if (pending_size == kPending) {
      Flush<kType>(pending, pending_size, origin, stride_bytes, args.variance, sum, sum_squares,
                   count);
      pending_size = 0;
    }
  }
  Flush<kType>(pending, pending_size, origin, stride_bytes, args.variance, sum, sum_squares,
               count);
  return any;
}

template <PixelType kType>
__attribute__((target("avx2,fma"))) bool Avx2Points(const Image& image,
                                                    const PointTileArrays& points,
                                                    const PointKernelArgs& args, double* sum,
                                                    double* sum_squares, uint32_t* count) {
  if (args.cubic_map) {
    // On the cubic path (U, V) / Z are tangent-plane coordinates, not pixels: no image bound
    // can be tested on them (LensRoute::FitCubic takes only quads that need none). A broken
    // invariant, checked in every build (one test per quad): the render rethrows it.
    if (args.image_tests != 0) {
      throw std::logic_error("Avx2Points: a cubic map with image bounds to test");
    }
    return Avx2PointsMap<kType, true>(image, points, args, sum, sum_squares, count);
  }
  return Avx2PointsMap<kType, false>(image, points, args, sum, sum_squares, count);
}

// ---- the robust route's exact gather (ExactGather) ----
// AVX2 without FMA: the compiler may not fuse a multiply and an add here, so every operation
// rounds as the scalar reference's does (compiled for the baseline CPU, which has no FMA).
#define AOS_EXACT_TARGET __attribute__((target("avx2"), always_inline)) inline

// glm's dot product of a vec3 with itself or another: (a.x b.x + a.y b.y) + a.z b.z.
AOS_EXACT_TARGET __m256d Dot3(__m256d ax, __m256d ay, __m256d az, __m256d bx, __m256d by,
                              __m256d bz) {
  return _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(ax, bx), _mm256_mul_pd(ay, by)),
                       _mm256_mul_pd(az, bz));
}

AOS_EXACT_TARGET __m256d Broadcast(double v) { return _mm256_set1_pd(v); }

// Row r of R_i focal + offset (glm: (m[0][r] x + m[1][r] y) + m[2][r] z, then + offset).
AOS_EXACT_TARGET __m256d CameraRow(const ExactViewArgs& a, int r, __m256d x, __m256d y,
                                   __m256d z) {
  return _mm256_add_pd(
      Dot3(Broadcast(a.rotation[0][r]), Broadcast(a.rotation[1][r]), Broadcast(a.rotation[2][r]), x, y, z),
      Broadcast(a.offset[r]));
}

// SampleTyped's clamp: min(s > -1 ? s : -1, last), std::min's comparison (last < low).
AOS_EXACT_TARGET __m256d ClampTap(__m256d s, __m256d minus_one, __m256d last) {
  const __m256d low = _mm256_blendv_pd(minus_one, s, _mm256_cmp_pd(s, minus_one, _CMP_GT_OQ));
  return _mm256_blendv_pd(low, last, _mm256_cmp_pd(last, low, _CMP_LT_OQ));
}

template <PixelType kType>
__attribute__((target("avx2"))) bool Avx2Exact(const Image& image, const double* px,
                                               const double* py, const double* pz, int count,
                                               const ExactViewArgs& a, uint8_t* admitted,
                                               double* value) {
  using T = std::conditional_t<kType == PixelType::kU8, uint8_t,
                               std::conditional_t<kType == PixelType::kU16, uint16_t, float>>;
  const __m256d zero = _mm256_setzero_pd();
  const __m256d half = _mm256_set1_pd(0.5), minus_one = _mm256_set1_pd(-1.0);
  const __m256d last_x = Broadcast(image.width() - 0.5), last_y = Broadcast(image.height() - 0.5);
  bool any = false;
  for (int j = 0; j < count; j += 4) {
    const __m256d x = _mm256_loadu_pd(px + j), y = _mm256_loadu_pd(py + j),
                  z = _mm256_loadu_pd(pz + j);
    // in_cam = R_i focal + offset.
    const __m256d cam_x = CameraRow(a, 0, x, y, z), cam_y = CameraRow(a, 1, x, y, z),
                  cam_z = CameraRow(a, 2, x, y, z);
    const __m256d u = _mm256_add_pd(_mm256_div_pd(_mm256_mul_pd(Broadcast(a.fx), cam_x), cam_z),
                                    Broadcast(a.cx));
    const __m256d v = _mm256_add_pd(_mm256_div_pd(_mm256_mul_pd(Broadcast(a.fy), cam_y), cam_z),
                                    Broadcast(a.cy));
    __m256d ok = _mm256_cmp_pd(cam_z, zero, _CMP_GT_OQ);
    ok = _mm256_and_pd(ok, _mm256_cmp_pd(u, zero, _CMP_GE_OQ));
    ok = _mm256_and_pd(ok, _mm256_cmp_pd(u, Broadcast(a.width), _CMP_LE_OQ));
    ok = _mm256_and_pd(ok, _mm256_cmp_pd(v, zero, _CMP_GE_OQ));
    ok = _mm256_and_pd(ok, _mm256_cmp_pd(v, Broadcast(a.height), _CMP_LE_OQ));
    // Grazing: rejected where along^2 < sin2 |to_view|^2, to_view = b - focal.
    const __m256d tx = _mm256_sub_pd(Broadcast(a.b[0]), x), ty = _mm256_sub_pd(Broadcast(a.b[1]), y),
                  tz = _mm256_sub_pd(Broadcast(a.b[2]), z);
    const __m256d along = Dot3(Broadcast(a.normal[0]), Broadcast(a.normal[1]), Broadcast(a.normal[2]), tx, ty, tz);
    ok = _mm256_and_pd(ok, _mm256_cmp_pd(_mm256_mul_pd(along, along),
                                         _mm256_mul_pd(Broadcast(a.sin2), Dot3(tx, ty, tz, tx, ty, tz)),
                                         _CMP_NLT_UQ));
    if (a.aperture == 2) {
      // Cylinder: across = to_view - (to_view . axis) axis; rejected where |across|^2 > r2.
      const __m256d d = Dot3(tx, ty, tz, Broadcast(a.axis[0]), Broadcast(a.axis[1]), Broadcast(a.axis[2]));
      const __m256d qx = _mm256_sub_pd(tx, _mm256_mul_pd(d, Broadcast(a.axis[0])));
      const __m256d qy = _mm256_sub_pd(ty, _mm256_mul_pd(d, Broadcast(a.axis[1])));
      const __m256d qz = _mm256_sub_pd(tz, _mm256_mul_pd(d, Broadcast(a.axis[2])));
      ok = _mm256_and_pd(ok, _mm256_cmp_pd(Dot3(qx, qy, qz, qx, qy, qz), Broadcast(a.r2), _CMP_NGT_UQ));
    } else if (a.aperture == 1) {
      // Lens plane: D = a.b - a.X (rejected where 0), N = (a.b) X - (a.X) b, rejected where
      // |N|^2 / D^2 > r2.
      const __m256d a_x = Dot3(Broadcast(a.axis[0]), Broadcast(a.axis[1]), Broadcast(a.axis[2]), x, y, z);
      const __m256d denominator = _mm256_sub_pd(Broadcast(a.lens_b), a_x);
      ok = _mm256_and_pd(ok, _mm256_cmp_pd(denominator, zero, _CMP_NEQ_UQ));
      const __m256d lens_b = Broadcast(a.lens_b);
      const __m256d nx = _mm256_sub_pd(_mm256_mul_pd(lens_b, x), _mm256_mul_pd(a_x, Broadcast(a.b[0])));
      const __m256d ny = _mm256_sub_pd(_mm256_mul_pd(lens_b, y), _mm256_mul_pd(a_x, Broadcast(a.b[1])));
      const __m256d nz = _mm256_sub_pd(_mm256_mul_pd(lens_b, z), _mm256_mul_pd(a_x, Broadcast(a.b[2])));
      const __m256d distance2 = _mm256_div_pd(Dot3(nx, ny, nz, nx, ny, nz),
                                              _mm256_mul_pd(denominator, denominator));
      ok = _mm256_and_pd(ok, _mm256_cmp_pd(distance2, Broadcast(a.r2), _CMP_NGT_UQ));
    }
    const int mask = _mm256_movemask_pd(ok);
    for (int k = 0; k < 4; ++k) admitted[j + k] = static_cast<uint8_t>((mask >> k) & 1);
    if (mask == 0) continue;
    any = true;
    // SampleTyped: sx = min(max-ish(u - 0.5, -1), width - 0.5) (the reference's comparisons),
    // taps at floor(sx) and floor(sx) + 1, then the same three interpolations. Lanes not
    // admitted sample at (0.5, 0.5) (inside the image; their values are not used).
    const __m256d sx = ClampTap(_mm256_sub_pd(_mm256_blendv_pd(half, u, ok), half), minus_one,
                                last_x);
    const __m256d sy = ClampTap(_mm256_sub_pd(_mm256_blendv_pd(half, v, ok), half), minus_one,
                                last_y);
    const __m256d fx = _mm256_floor_pd(sx), fy = _mm256_floor_pd(sy);
    const __m256d ax = _mm256_sub_pd(sx, fx), ay = _mm256_sub_pd(sy, fy);
    alignas(16) int32_t ix[4], iy[4];
    _mm_store_si128(reinterpret_cast<__m128i*>(ix), _mm256_cvttpd_epi32(fx));
    _mm_store_si128(reinterpret_cast<__m128i*>(iy), _mm256_cvttpd_epi32(fy));
    alignas(32) double p00[4], p01[4], p10[4], p11[4];
    for (int k = 0; k < 4; ++k) {
      const T* top = image.At<T>(ix[k], iy[k]);
      const T* bottom = image.At<T>(ix[k], iy[k] + 1);
      p00[k] = top[0];
      p01[k] = top[1];
      p10[k] = bottom[0];
      p11[k] = bottom[1];
    }
    const __m256d t00 = _mm256_load_pd(p00), t01 = _mm256_load_pd(p01),
                  t10 = _mm256_load_pd(p10), t11 = _mm256_load_pd(p11);
    const __m256d upper = _mm256_add_pd(t00, _mm256_mul_pd(ax, _mm256_sub_pd(t01, t00)));
    const __m256d lower = _mm256_add_pd(t10, _mm256_mul_pd(ax, _mm256_sub_pd(t11, t10)));
    _mm256_storeu_pd(value + j,
                     _mm256_add_pd(upper, _mm256_mul_pd(ay, _mm256_sub_pd(lower, upper))));
  }
  return any;
}

#undef AOS_EXACT_TARGET

bool CpuHasAvx2() {
  static const bool has = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2");
  }();
  return has;
}

bool CpuHasAvx2Fma() {
  static const bool has = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  }();
  return has;
}

}  // namespace

PointKernel Avx2PointKernel(const Image& image) {
  if (!SimdEnabled() || !CpuHasAvx2Fma() || image.channels() != 1 || image.border() < 1) {
    return nullptr;
  }
  // Gather offsets are 32-bit byte offsets.
  if (image.AllocatedBytes() >= static_cast<size_t>(std::numeric_limits<int32_t>::max() / 2)) {
    return nullptr;
  }
  switch (image.type()) {
    case PixelType::kU8: return &Avx2Points<PixelType::kU8>;
    case PixelType::kU16: return &Avx2Points<PixelType::kU16>;
    case PixelType::kF32: return &Avx2Points<PixelType::kF32>;
    case PixelType::kU32: break;
  }
  return nullptr;
}

bool ExactGatherBuilt() {
#ifdef __FMA__
  return false;
#else
  return true;
#endif
}

ExactGather Avx2ExactGather(const Image& image) {
#ifdef __FMA__
  // The scalar reference may fuse multiply-adds in such a build (-march=native): its rounding
  // is then not the kernel's.
  (void)image;
  return nullptr;
#else
  if (!SimdEnabled() || !CpuHasAvx2() || image.channels() != 1 || image.border() < 1) {
    return nullptr;
  }
  switch (image.type()) {
    case PixelType::kU8: return &Avx2Exact<PixelType::kU8>;
    case PixelType::kU16: return &Avx2Exact<PixelType::kU16>;
    case PixelType::kF32: return &Avx2Exact<PixelType::kF32>;
    case PixelType::kU32: break;
  }
  return nullptr;
#endif
}

#else

PointKernel Avx2PointKernel(const Image&) { return nullptr; }
ExactGather Avx2ExactGather(const Image&) { return nullptr; }

#endif

}  // namespace aos::internal
