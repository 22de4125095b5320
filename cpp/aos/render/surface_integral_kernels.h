#pragma once
// Internal to the per-sample renderer (surface_integral.cpp): the AVX2 kernel that samples one
// view at a tile of focal points (a pinhole view through its projection, a lens view through a
// quad's local map: a homography or, for wide lenses, a cubic), and the exact scalar route kept
// as the reference. Not part of the public API.
//
// The kernel works in float on points relative to the render's centre (tens of metres on real
// flights): each admission test is a value whose sign decides (U >= 0 for u >= 0, ...), computed
// in float together with a bound on its float error (stated by the caller per view and tile).
// A lane whose value is within that bound of 0 is decided by the caller's exact double-precision
// test (the reference's own arithmetic), so the kernel admits exactly the samples the reference
// admits; only the sample values (bilinear in float, as the plane path's span kernels) differ,
// by float rounding.
#include <cstddef>
#include <cstdint>

#include "aos/image/image.h"
#include "aos/render/surface_integral.h"

namespace aos::internal {

// Points of a tile, structure of arrays, relative to the render's centre; `valid` is all ones
// (as an int32) for a point to render, 0 for a pixel without a focal point and for the padding
// up to a multiple of 8 (such lanes hold 0, 0, 0).
// The points may also be a rectangle of a larger tile: `rows` rows of `row_length` points (a
// multiple of 8), `row_stride` apart (index of point (r, k) = r * row_stride + k, for the arrays,
// the accumulators and the exact test alike); rows = 0 means one run of `size` points.
struct PointTileArrays {
  const float* x;
  const float* y;
  const float* z;
  const int32_t* valid;
  int size;  // a multiple of 8 (rows = 0)
  int rows = 0;
  int row_length = 0;
  int row_stride = 0;
};

// Decides one lane exactly (double precision, the reference's arithmetic): true to admit.
using ExactAdmit = bool (*)(const void* context, int index);

struct PointKernelArgs {
  // Homogeneous view pixel (U, V, Z) = P[r][0..2] . p + P[r][3]; u = U / Z, v = V / Z.
  float P[3][4];
  float width, height;  // the view's image: admitted iff Z > 0, 0 <= U <= width Z, 0 <= V <= height Z
  // Float error bounds of Z, U, width Z - U, V, height Z - V.
  float bound[5];
  // The image bounds to test, bit t for bound[t] (Z, U, width Z - U, V, height Z - V); a bound
  // known to hold at every point of the tile is left out (0: the tile lies inside the image).
  int image_tests = 0x1f;
  // Grazing: admitted iff (n . t)^2 >= sin2 |t|^2, t = b - p; skipped unless `grazing`.
  bool grazing = false;
  float normal[3], sin2, grazing_bound;
  // Aperture: 0 none, 1 lens plane (|N|^2 <= r2 D^2 and D != 0, D = a.b - a.p,
  // N = (a.b) p - (a.p) b), 2 cylinder (|t - (t.a) a|^2 <= r2).
  int aperture = 0;
  float axis[3], b[3], lens_b, r2, aperture_bound, denominator_bound;
  bool variance = false;
  // Lens views (surface_integral.cpp, LensRoute::FitCubic): the pixel is not (U / Z, V / Z) but
  // a cubic polynomial in (x, y) = (U / Z, V / Z), u = sum cubic[0][k] m_k(x, y) and likewise v
  // with cubic[1], monomials m = (1, x, y, x^2, x y, y^2, x^3, x^2 y, x y^2, y^3), the pixel-centre
  // offset 0.5 already subtracted from both constant terms (u - 0.5 = cubic[0] . m). Only with
  // image_tests 0 (the caller has checked that the tile's points lie inside the image).
  bool cubic_map = false;
  float cubic[2][10] = {};
  // Addresses to prefetch while the kernel runs (the next view's pixels), spread over the groups.
  const char* const* prefetch = nullptr;
  int prefetch_count = 0;
  ExactAdmit exact = nullptr;
  const void* exact_context = nullptr;
};

// Adds the admitted lanes' bilinear samples into sum[i] (double), their squares into
// sum_squares[i] when args.variance, and 1 into count[i]; returns whether any lane was admitted.
// `image` is a 1-channel 8-bit, 16-bit or float view with a border >= 1.
using PointKernel = bool (*)(const Image& image, const PointTileArrays& points,
                             const PointKernelArgs& args, double* sum, double* sum_squares,
                             uint32_t* count);

// The AVX2 kernel for this view, or nullptr (no AVX2/FMA, SIMD disabled by SetSimdEnabled,
// or a view type or channel count without one).
PointKernel Avx2PointKernel(const Image& image);

// The robust route's gather (surface_integral.cpp, RenderSampleListsTiled) for one pinhole view
// of one channel: the reference's admission tests (AdmitSample) and bilinear sample
// (SampleTyped), 4 points at a time in double precision with the reference's operations in the
// reference's order and no fused multiply-add, so that the admitted samples and their values
// are the reference's bit for bit (test: surface_integral_test
// RobustTiledRouteEqualsTheReferenceExactly).
struct ExactViewArgs {
  double rotation[3][3];  // glm's column-major R_i: rotation[c][r] = R_i[c][r]
  double offset[3];       // R_i (C - C_i)
  double b[3];            // C_i - C
  double fx, fy, cx, cy, width, height;  // the view's camera
  double normal[3], sin2;                // the grazing test
  // 0: no aperture test (infinite aperture), 1: lens plane, 2: cylinder.
  int aperture = 0;
  double axis[3], lens_b, r2;
};
// Points relative to the centre (structure of arrays, NaN for a pixel without a point), `count`
// a multiple of 4: admitted[j] = 1 and value[j] = the sample where the view admits point j,
// admitted[j] = 0 elsewhere (value[j] then unspecified). Returns whether any was admitted.
using ExactGather = bool (*)(const Image& image, const double* x, const double* y,
                             const double* z, int count, const ExactViewArgs& args,
                             uint8_t* admitted, double* value);

// The AVX2 gather for this view, or nullptr (no AVX2, SIMD disabled by SetSimdEnabled, a view
// type or channel count without one, or a build whose scalar code may fuse multiply-adds).
ExactGather Avx2ExactGather(const Image& image);

// Whether this build compiles the exact gather at all: false where the scalar code may fuse
// multiply-adds (-march=native on an FMA CPU, seen in the library's own flags).
bool ExactGatherBuilt();

// The lens route's work (surface_integral.cpp, LensRoute), summed over every render since the
// last ResetLensRouteCounts(): quads sampled through a local map (homography or cubic) per
// level (0: 64 x 64 output pixels, 1: 32, 2: 16, 3: 8), 8 x 8 quads projected point by point,
// and exact node projections. For tests of the route's choices; the renders' outputs do not
// depend on them.
struct LensRouteCounts {
  int64_t fitted_quads[4] = {0, 0, 0, 0};
  int64_t exact_quads = 0;
  int64_t projected_nodes = 0;
};
LensRouteCounts GetLensRouteCounts();
void ResetLensRouteCounts();

// The per-pixel scalar loop the fast route replaced (pixel-outer, view-inner, double precision):
// the reference the tests compare against; also the route of the robust mean in nearest mode
// (elsewhere the robust mean gathers the same samples tile by tile and equals it bit for bit).
SurfaceIntegralResult RenderIntegralAtPointsReference(const LightField& light_field,
                                                      const FocalPoints& points,
                                                      const PointIntegralOptions& options,
                                                      const SurfaceIntegralOptions& surface,
                                                      ProgressSink* progress);

}  // namespace aos::internal
