#include "aos/render/integral_kernels.h"

#include <algorithm>
#include <atomic>
#include <cstdint>

namespace aos::internal {
namespace {

std::atomic<bool> g_simd_enabled{true};
std::atomic<bool> g_simd_variance_enabled{true};
std::atomic<bool> g_simd_row_loads_enabled{true};

// s clamped to [-1, max]; NaN gives -1.
inline float ClampSample(float s, float max) {
  s = s > -1.0f ? s : -1.0f;
  return s < max ? s : max;
}

// A span re-based at its first column xa, so the float arithmetic works with small magnitudes.
struct ScalarSpan {
  float u_a, v_a, w_a, du, dv, dw, x_max, y_max;
  ScalarSpan(const Image& image, const RowLine& line, int xa)
      : u_a(static_cast<float>(line.u0 + line.du * xa)),
        v_a(static_cast<float>(line.v0 + line.dv * xa)),
        w_a(static_cast<float>(line.w0 + line.dw * xa)),
        du(static_cast<float>(line.du)),
        dv(static_cast<float>(line.dv)),
        dw(static_cast<float>(line.dw)),
        x_max(static_cast<float>(image.width()) - 0.5f),
        y_max(static_cast<float>(image.height()) - 0.5f) {}
};

// Where column xa + i samples the view: the top-left tap (ix, iy) and the weights (ax, ay).
struct ScalarSample {
  int ix, iy;
  float ax, ay;
};
inline ScalarSample LocateScalar(const ScalarSpan& c, int i) {
  const float fi = static_cast<float>(i);
  const float inv_w = 1.0f / (c.w_a + c.dw * fi);
  // Sample position in pixel-index space: continuous coordinate minus the half-pixel offset.
  // Clamped to the bordered image (the span already guarantees it up to rounding; the clamp
  // keeps any rounding, or a NaN, from ever reading outside the image's memory).
  const float sx = ClampSample((c.u_a + c.du * fi) * inv_w - 0.5f, c.x_max);
  const float sy = ClampSample((c.v_a + c.dv * fi) * inv_w - 0.5f, c.y_max);
  // sx, sy >= -0.5 (up to rounding), so truncating s + 1 gives floor(s) + 1.
  ScalarSample s;
  s.ix = static_cast<int>(sx + 1.0f) - 1;
  s.iy = static_cast<int>(sy + 1.0f) - 1;
  s.ax = sx - static_cast<float>(s.ix);
  s.ay = sy - static_cast<float>(s.iy);
  return s;
}

// The scalar kernel; with kSquares it also adds, per column, the sum over channels of the
// squared samples into sum_squares[x - x0] (the variance pass), from the same samples.
template <typename T, int kChannels, bool kSquares>
void AccumulateSpanImpl(const Image& image, const RowLine& line, int xa, int xb, int x0,
                        double* sum, double* sum_squares) {
  const int channels = kChannels > 0 ? kChannels : image.channels();
  const T* origin = image.At<T>(0, 0);
  const ptrdiff_t stride = image.row_stride();
  const ScalarSpan span(image, line, xa);
  double* out = sum + static_cast<ptrdiff_t>(xa - x0) * channels;
  const int n = xb - xa;
  for (int i = 0; i < n; ++i) {
    const auto [ix, iy, ax, ay] = LocateScalar(span, i);
    const T* p = origin + static_cast<ptrdiff_t>(iy) * stride + static_cast<ptrdiff_t>(ix) * channels;
    double squares = 0.0;
    for (int c = 0; c < channels; ++c) {
      const float p00 = static_cast<float>(p[c]);
      const float p01 = static_cast<float>(p[c + channels]);
      const float p10 = static_cast<float>(p[stride + c]);
      const float p11 = static_cast<float>(p[stride + c + channels]);
      const float top = p00 + ax * (p01 - p00);
      const float bottom = p10 + ax * (p11 - p10);
      const double value = static_cast<double>(top + ay * (bottom - top));
      out[static_cast<ptrdiff_t>(i) * channels + c] += value;
      if constexpr (kSquares) squares += value * value;
    }
    if constexpr (kSquares) sum_squares[xa - x0 + i] += squares;
  }
}

template <typename T, int kChannels>
void AccumulateSpan(const Image& image, const RowLine& line, int xa, int xb, int x0,
                    double* sum) {
  AccumulateSpanImpl<T, kChannels, false>(image, line, xa, xb, x0, sum, nullptr);
}

template <typename T, int kChannels>
void AccumulateSpanWithSquares(const Image& image, const RowLine& line, int xa, int xb, int x0,
                               double* sum, double* sum_squares) {
  AccumulateSpanImpl<T, kChannels, true>(image, line, xa, xb, x0, sum, sum_squares);
}

// The scalar quadratic kernel (QuadraticKernel): the positions, taps and weights of
// AccumulateSpanImpl's 1-channel samples.
template <typename T>
void AccumulateSpanQuadratic(const Image& image, const RowLine& line, int xa, int xb, int x0,
                             double* sum, double* quad, float centre, float scale,
                             float floor) {
  const T* origin = image.At<T>(0, 0);
  const ptrdiff_t stride = image.row_stride();
  const ScalarSpan span(image, line, xa);
  double* out = sum + (xa - x0);
  double* out_quad = quad + (xa - x0);
  const int n = xb - xa;
  for (int i = 0; i < n; ++i) {
    const auto [ix, iy, ax, ay] = LocateScalar(span, i);
    const T* p = origin + static_cast<ptrdiff_t>(iy) * stride + ix;
    const float p00 = static_cast<float>(p[0]), p01 = static_cast<float>(p[1]);
    const float p10 = static_cast<float>(p[stride]), p11 = static_cast<float>(p[stride + 1]);
    const float top = p00 + ax * (p01 - p00);
    const float bottom = p10 + ax * (p11 - p10);
    out[i] += static_cast<double>(top + ay * (bottom - top));
    const float d00 = std::max(p00 - centre, floor), d01 = std::max(p01 - centre, floor);
    const float d10 = std::max(p10 - centre, floor), d11 = std::max(p11 - centre, floor);
    const float q00 = d00 * d00, q01 = d01 * d01, q10 = d10 * d10, q11 = d11 * d11;
    const float q_top = q00 + ax * (q01 - q00);
    const float q_bottom = q10 + ax * (q11 - q10);
    out_quad[i] += static_cast<double>(scale * (q_top + ay * (q_bottom - q_top)));
  }
}

template <typename T>
SquaresKernel SquaresForChannels(int channels) {
  switch (channels) {
    case 1: return &AccumulateSpanWithSquares<T, 1>;
    case 3: return &AccumulateSpanWithSquares<T, 3>;
    default: return &AccumulateSpanWithSquares<T, 0>;
  }
}

template <typename T>
SpanKernel ForChannels(int channels) {
  switch (channels) {
    case 1: return &AccumulateSpan<T, 1>;
    case 3: return &AccumulateSpan<T, 3>;
    default: return &AccumulateSpan<T, 0>;
  }
}

}  // namespace

SpanKernel ScalarSpanKernel(const Image& image) {
  switch (image.type()) {
    case PixelType::kU8: return ForChannels<uint8_t>(image.channels());
    case PixelType::kU16: return ForChannels<uint16_t>(image.channels());
    case PixelType::kF32: return ForChannels<float>(image.channels());
    case PixelType::kU32: break;
  }
  return nullptr;
}

SquaresKernel ScalarSquaresKernel(const Image& image) {
  switch (image.type()) {
    case PixelType::kU8: return SquaresForChannels<uint8_t>(image.channels());
    case PixelType::kU16: return SquaresForChannels<uint16_t>(image.channels());
    case PixelType::kF32: return SquaresForChannels<float>(image.channels());
    case PixelType::kU32: break;
  }
  return nullptr;
}

QuadraticKernel ScalarQuadraticKernel(const Image& image) {
  if (image.channels() != 1) return nullptr;
  switch (image.type()) {
    case PixelType::kU8: return &AccumulateSpanQuadratic<uint8_t>;
    case PixelType::kU16: return &AccumulateSpanQuadratic<uint16_t>;
    case PixelType::kF32: return &AccumulateSpanQuadratic<float>;
    case PixelType::kU32: break;
  }
  return nullptr;
}

void SetSimdEnabled(bool enabled) { g_simd_enabled.store(enabled, std::memory_order_relaxed); }
bool SimdEnabled() { return g_simd_enabled.load(std::memory_order_relaxed); }
void SetSimdVarianceEnabled(bool enabled) {
  g_simd_variance_enabled.store(enabled, std::memory_order_relaxed);
}
bool SimdVarianceEnabled() { return g_simd_variance_enabled.load(std::memory_order_relaxed); }
void SetSimdRowLoadsEnabled(bool enabled) {
  g_simd_row_loads_enabled.store(enabled, std::memory_order_relaxed);
}
bool SimdRowLoadsEnabled() { return g_simd_row_loads_enabled.load(std::memory_order_relaxed); }

}  // namespace aos::internal
