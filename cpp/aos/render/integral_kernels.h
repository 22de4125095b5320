#pragma once
// Internal to the integral renderer: the inner loops that sample one view along a span of an
// output row and add the samples to double accumulators. The scalar kernels are the reference;
// AVX2 kernels (8 samples at a time, gathers) are used when the CPU has AVX2 and FMA and give
// the same values up to float rounding (8-bit views: bit-identical samples, whether the taps come
// from row loads or gathers). Not part of the public API.
#include <cstddef>

#include "aos/image/image.h"

namespace aos::internal {

// Homogeneous view coordinates along an output row: U(x) = u0 + du x, likewise V and W.
struct RowLine {
  double u0, du, v0, dv, w0, dw;
};

// Adds samples for columns [xa, xb) into sum[(x - x0) * channels + c]. The caller guarantees
// W > 0 and 0 <= U/W <= width, 0 <= V/W <= height on the whole span, and that `sum` has
// kSpanPadding writable values past the span's end (SIMD kernels add +0.0 there).
constexpr int kSpanPadding = 16;  // 8 lanes x 2 channels (the 2-channel 8-bit kernel)
using SpanKernel = void (*)(const Image& image, const RowLine& line, int xa, int xb, int x0,
                            double* sum);

// A span kernel that also adds the sum over channels of the squared samples into
// sum_squares[x - x0] (the renderer's variance pass), from the same samples as it adds to `sum`;
// `sum_squares` too needs kSpanPadding writable values past the span's end.
// The squares are rounded as the scalar kernel rounds them (double product, then double sum);
// the SIMD samples themselves differ from the scalar ones by float rounding, as for SpanKernel.
using SquaresKernel = void (*)(const Image& image, const RowLine& line, int xa, int xb, int x0,
                               double* sum, double* sum_squares);
SquaresKernel ScalarSquaresKernel(const Image& image);
// The AVX2 variance kernel for 1-channel 8-bit, 16-bit and float views; nullptr otherwise (as
// Avx2SpanKernel).
SquaresKernel Avx2SquaresKernel(const Image& image);

// A span kernel for 1-channel views that also adds, per sample, the bilinear interpolation of its
// four taps' scores scale * max(tap - centre, floor)^2 into quad[x - x0] (the anomaly-imaging
// pass: integral.h RenderIntegralWithQuadratic; floor -inf, or 0 for one-sided scores), with the
// same taps and weights as the sample it adds to `sum`. In float: each tap's d = max(tap -
// centre, floor) and d * d, interpolated as the value is, times scale, added in double. `quad`
// too needs kSpanPadding writable values past the span's end.
using QuadraticKernel = void (*)(const Image& image, const RowLine& line, int xa, int xb, int x0,
                                 double* sum, double* quad, float centre, float scale,
                                 float floor);
// The scalar quadratic kernel for 1-channel 8-bit, 16-bit and float views (nullptr otherwise).
QuadraticKernel ScalarQuadraticKernel(const Image& image);
// The AVX2 quadratic kernel for 1-channel 8-bit (row loads) and 16-bit views; nullptr otherwise.
QuadraticKernel Avx2QuadraticKernel(const Image& image);

// The scalar kernel for the view's pixel type and channel count (nullptr for uint32 views).
SpanKernel ScalarSpanKernel(const Image& image);
// The AVX2 kernel, or nullptr when the CPU lacks AVX2/FMA, SIMD is disabled, or the view's type
// or channel count has none (1-channel 8-bit, 16-bit and float views have one, and 2-channel
// 8-bit views: masked grey frames).
SpanKernel Avx2SpanKernel(const Image& image);

// SIMD kernels are on by default; tests and benchmarks turn them off to compare with the scalar
// reference. SetSimdVarianceEnabled(false) turns off only the SIMD variance kernel (the variance
// pass then runs the scalar kernel, as before it had a SIMD one: tools/bench_merge.py's baseline).
// Not thread-safe: set them before rendering.
void SetSimdEnabled(bool enabled);
bool SimdEnabled();
void SetSimdVarianceEnabled(bool enabled);
bool SimdVarianceEnabled();
// Off: the 8-bit AVX2 kernels (span and variance) fetch every tap with gathers, as before they had
// row loads (tools/bench_integral.py's baseline; the samples are the same). The switches are
// atomic, so flipping one during a render is no data race, but which kernel each view of that
// render gets is then unspecified.
void SetSimdRowLoadsEnabled(bool enabled);
bool SimdRowLoadsEnabled();

// The kernel the renderer uses: AVX2 when available, else scalar.
inline SpanKernel SelectSpanKernel(const Image& image) {
  SpanKernel kernel = SimdEnabled() ? Avx2SpanKernel(image) : nullptr;
  return kernel != nullptr ? kernel : ScalarSpanKernel(image);
}

inline SquaresKernel SelectSquaresKernel(const Image& image) {
  SquaresKernel kernel = SimdEnabled() && SimdVarianceEnabled() ? Avx2SquaresKernel(image) : nullptr;
  return kernel != nullptr ? kernel : ScalarSquaresKernel(image);
}

inline QuadraticKernel SelectQuadraticKernel(const Image& image) {
  QuadraticKernel kernel = SimdEnabled() ? Avx2QuadraticKernel(image) : nullptr;
  return kernel != nullptr ? kernel : ScalarQuadraticKernel(image);
}

}  // namespace aos::internal
