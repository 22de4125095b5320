#include "aos/render/surface_integral.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <exception>
#include <limits>
#include <string>
#include <vector>

#include <omp.h>

#include "aos/render/integral_kernels.h"
#include "aos/render/masked_mean.h"
#include "aos/render/surface_integral_kernels.h"
#include "aos/util/error.h"
#include "aos/util/math.h"
#include "aos/util/parallel.h"

// How it works
// Unlike a plane, focal points give no homography, so every (pixel, view) pair is projected on
// its own: the focal point relative to a centre C (the lens centre, or the points' reference for
// a cylinder aperture), X, goes into view i as R_i X + R_i (C - C_i), all in double precision
// (UTM-sized centres cancel before any rounding). The admission tests are integral.h's,
// evaluated per sample (AdmitSample).
//
// The plain mean goes tile by tile (64 x 64 pixels), views outer: a view's pixels near the
// tile stay in cache and the tile's accumulators (double sums, uint32 counts) in L1/L2. Per
// view and tile, the bounding box of the tile's focal points is tested first: a box entirely
// outside one of the view's image bounds (each a linear test in the point), or entirely outside
// the aperture (the crossing points of a box's corners bound those of the whole box: the
// crossing is a projective map of the point), skips the view for the tile; on F0 a pixel sees
// about 140 of the 382 views. The image bounds the box satisfies at all eight corners are not
// tested in the kernel (most (view, tile) pairs lie across one edge of the view's image). Pinhole views of one channel then go through the AVX2 kernel
// (surface_integral_avx2.cpp): points relative to C in float (tens of metres on real flights),
// 8 at a time, each test with a bound on its float error; a lane within the bound is decided by
// AdmitSample in double, so exactly the reference's samples are admitted, and only the sample
// values carry float rounding (as the plane path's span kernels), accumulated in double.
// Views with a lens model (LensRoute) take the same kernel quad by quad: per quad of the tile
// (64, split down to 8 pixels) a homography fitted to the lens projection in the tangent plane of
// the quad's centre ray (radtan: of the view's optical axis; affine through the corners, or where
// that misses by less than 4x a full homography by least squares over the nodes, Homography8;
// fisheye and omnidirectional lenses on 64- and 32-pixel quads: a cubic polynomial in the
// tangent-plane coordinates over 5 x 5 nodes, FitCubic, which passes on whole tiles where
// homographies passed at 16 pixels), accepted when it is within lens_tolerance_px of the exact
// projection at the quad's nodes (plus a first-order bound for the surface's departure from the
// bilinear sheet through the corners) and every ray keeps inside the lens's valid field; the exact
// projections of the nodes are cached per view and tile, so children reuse their parent's.
// Nearest mode (aperture 0), other pixel types, far-away points and lens quads that fail at
// 8 x 8 take AdmitSample and the double sampler per point, still tiled and culled (lens views
// are not culled: their projection is not linear). The robust mean needs every sample of a
// pixel at once: it gathers them tile by tile, views outer (RenderSampleListsTiled), with the
// reference's double-precision admission and sampler (for pinhole views of one channel an AVX2
// kernel doing the same double operations in the same order, 4 points at a time, without
// FMA), so it equals the per-pixel reference loop (internal::RenderIntegralAtPointsReference)
// bit for bit; nearest mode keeps that loop.

namespace aos {
namespace {

// Bilinear sampling of one view at continuous pixel coordinates into `out` (one per channel).
using Sampler = void (*)(const Image&, double, double, double*);

struct ViewSetup {
  const Image* image = nullptr;
  Mat3d rotation{1.0};      // R_i
  Vec3d offset{0.0};        // R_i (C - C_i): camera coordinates of the virtual centre
  Vec3d b{0.0};             // C_i - C
  double lens_b = 0.0;      // a . b
  double fx = 0, fy = 0, cx = 0, cy = 0, width = 0, height = 0;
  const LensCamera* lens = nullptr;  // set for views with a lens model (direct sampling)
  // Lens views: the largest angle from the view's optical axis within which every ray
  // projects (LensCamera::ValidAngle), radians.
  double valid_angle = 0.0;
  // cos(valid_angle - kAngleShortcut): a quad's rays within that cosine of the optical axis and
  // a margin below kAngleShortcut are inside the valid field without an acos (LensRoute::Fit).
  double cos_shortcut = 1.0;
  Sampler sample = nullptr;
  internal::PointKernel kernel = nullptr;  // pinhole views with an AVX2 kernel
  // Pinhole views of one channel: the robust route's exact AVX2 gather and its arguments.
  internal::ExactGather exact_gather = nullptr;
  internal::ExactViewArgs exact{};
};

// Bilinear sample at continuous pixel coordinates (u, v), pixel centres at +0.5, clamped into
// the replicated border like the span kernels; typed access (no per-tap type switch).
template <typename T>
void SampleTyped(const Image& image, double u, double v, double* out) {
  double sx = u - 0.5, sy = v - 0.5;
  sx = std::min(sx > -1.0 ? sx : -1.0, image.width() - 0.5);
  sy = std::min(sy > -1.0 ? sy : -1.0, image.height() - 0.5);
  const int ix = static_cast<int>(std::floor(sx));
  const int iy = static_cast<int>(std::floor(sy));
  const double ax = sx - ix, ay = sy - iy;
  const int channels = image.channels();
  const T* top_row = image.At<T>(ix, iy);
  const T* bottom_row = image.At<T>(ix, iy + 1);
  for (int c = 0; c < channels; ++c) {
    const double p00 = top_row[c], p01 = top_row[c + channels];
    const double p10 = bottom_row[c], p11 = bottom_row[c + channels];
    const double top = p00 + ax * (p01 - p00);
    const double bottom = p10 + ax * (p11 - p10);
    out[c] = top + ay * (bottom - top);
  }
}

Sampler SamplerFor(const Image& image) {
  switch (image.type()) {
    case PixelType::kU8: return &SampleTyped<uint8_t>;
    case PixelType::kU16: return &SampleTyped<uint16_t>;
    case PixelType::kU32: return &SampleTyped<uint32_t>;
    default: return &SampleTyped<float>;
  }
}

// Radians; see ViewSetup::cos_shortcut.
constexpr double kAngleShortcut = 0.25;

// What every route shares: the geometry of the admission tests and the selected views.
struct Setup {
  int width = 0, height = 0;
  bool cylinder = false;
  Vec3d center{0.0};
  Vec3d shift{0.0};  // point relative to `center` = p + shift
  Vec3d lens_axis{0.0, 0.0, 1.0};
  Vec3d normal{0.0, 0.0, 1.0};
  double sin2_min = 0.0;
  bool nearest = false;
  bool finite_aperture = false;
  double r2 = 0.0;
  int channels = 1;
  double range = 255.0;
  bool masked = false;  // a masked light field: the last channel is the weight (masked_mean.h)
  double lens_tolerance = 0.0;  // PointIntegralOptions::lens_tolerance_px
  std::vector<ViewSetup> views;
  std::vector<int> view_indices;  // views[i] is light-field view view_indices[i] (ascending)
};

Setup MakeSetup(const LightField& light_field, const FocalPoints& points,
                const PointIntegralOptions& options, const SurfaceIntegralOptions& surface) {
  options.Check(static_cast<int>(light_field.views.size()));
  surface.Check();
  if (points.width <= 0 || points.height <= 0 ||
      points.points.size() != static_cast<size_t>(points.width) * static_cast<size_t>(points.height)) {
    ThrowInvalid("points: must hold width x height points (got " +
                 std::to_string(points.points.size()) + " for " + std::to_string(points.width) +
                 "x" + std::to_string(points.height) + ")");
  }
  for (int i = 0; i < 3; ++i) {
    if (!std::isfinite(points.reference[i])) ThrowInvalid("points: reference must be finite");
  }
  Setup s;
  s.width = points.width;
  s.height = points.height;
  // Everything below is relative to the lens centre (kLensPlane) or the reference (kCylinder),
  // in double precision.
  s.cylinder = options.aperture == PointIntegralOptions::Aperture::kCylinder;
  s.center = s.cylinder ? points.reference : options.lens_center;
  s.shift = points.reference - s.center;
  s.lens_axis = glm::normalize(options.lens_axis);
  s.normal = glm::normalize(options.surface_normal);
  const double min_angle = DegToRad(options.min_view_angle_deg);
  s.sin2_min = std::sin(min_angle) * std::sin(min_angle);
  s.nearest = options.aperture_radius == 0.0;
  s.finite_aperture = std::isfinite(options.aperture_radius) && !s.nearest;
  s.r2 = options.aperture_radius * options.aperture_radius;
  s.lens_tolerance = options.lens_tolerance_px;

  std::vector<int> selection = options.view_indices;
  if (selection.empty()) {
    selection.resize(light_field.views.size());
    for (size_t i = 0; i < selection.size(); ++i) selection[i] = static_cast<int>(i);
  }
  std::sort(selection.begin(), selection.end());
  s.view_indices = selection;
  s.channels = light_field.views[static_cast<size_t>(selection.front())].image.channels();
  s.range =
      PixelTypeFullRange(light_field.views[static_cast<size_t>(selection.front())].image.type());
  s.masked = light_field.masked;
  for (int index : selection) {
    const View& view = light_field.views[static_cast<size_t>(index)];
    CheckView(view, "view " + std::to_string(index) + (view.name.empty() ? "" : " (" + view.name + ")"));
    if (view.image.channels() != s.channels) {
      ThrowInvalid("view " + std::to_string(index) + ": has " +
                   std::to_string(view.image.channels()) +
                   " channels but the first selected view has " + std::to_string(s.channels));
    }
    ViewSetup setup;
    setup.image = &view.image;
    setup.rotation = view.cam_from_world.rotation;
    setup.b = view.cam_from_world.Center() - s.center;
    setup.offset = setup.rotation * (-setup.b);
    setup.lens_b = glm::dot(s.lens_axis, setup.b);
    setup.fx = view.camera.fx;
    setup.fy = view.camera.fy;
    setup.cx = view.camera.cx;
    setup.cy = view.camera.cy;
    setup.width = view.camera.width;
    setup.height = view.camera.height;
    if (!view.camera.IsPinhole()) {
      setup.lens = &view.camera;
      setup.valid_angle = view.camera.ValidAngle();
      setup.cos_shortcut = std::cos(std::max(0.0, setup.valid_angle - kAngleShortcut));
    }
    setup.sample = SamplerFor(view.image);
    setup.kernel = internal::Avx2PointKernel(view.image);
    if (setup.lens == nullptr && !s.nearest) {
      setup.exact_gather = internal::Avx2ExactGather(view.image);
      internal::ExactViewArgs& e = setup.exact;
      for (int c = 0; c < 3; ++c) {
        for (int r = 0; r < 3; ++r) e.rotation[c][r] = setup.rotation[c][r];
        e.offset[c] = setup.offset[c];
        e.b[c] = setup.b[c];
        e.normal[c] = s.normal[c];
        e.axis[c] = s.lens_axis[c];
      }
      e.fx = setup.fx;
      e.fy = setup.fy;
      e.cx = setup.cx;
      e.cy = setup.cy;
      e.width = setup.width;
      e.height = setup.height;
      e.sin2 = s.sin2_min;
      e.aperture = s.finite_aperture ? (s.cylinder ? 2 : 1) : 0;
      e.lens_b = setup.lens_b;
      e.r2 = s.r2;
    }
    s.views.push_back(setup);
  }
  return s;
}

// integral.h's admission of the focal point `focal` (relative to the centre) into `view`, in
// double precision: its pixel (u, v), and the squared aperture distance where there is an
// aperture test or nearest mode (else left alone). False if the sample is not admitted.
inline bool AdmitSample(const Setup& s, const ViewSetup& view, const Vec3d& focal, double* u_out,
                        double* v_out, double* distance2_out) {
  const Vec3d in_cam = view.rotation * focal + view.offset;
  double u, v;
  if (view.lens != nullptr) {
    Vec2d pixel;
    if (!view.lens->Project(in_cam, &pixel)) return false;
    u = pixel.x;
    v = pixel.y;
  } else {
    if (!(in_cam.z > 0.0)) return false;
    u = view.fx * in_cam.x / in_cam.z + view.cx;
    v = view.fy * in_cam.y / in_cam.z + view.cy;
  }
  if (!(u >= 0.0 && u <= view.width && v >= 0.0 && v <= view.height)) return false;
  const Vec3d to_view = view.b - focal;
  const double along = glm::dot(s.normal, to_view);
  if (along * along < s.sin2_min * glm::dot(to_view, to_view)) return false;
  if (s.cylinder && (s.finite_aperture || s.nearest)) {
    // Distance of C_i from the line through X along the axis.
    const Vec3d across = to_view - glm::dot(to_view, s.lens_axis) * s.lens_axis;
    const double distance2 = glm::dot(across, across);
    if (s.finite_aperture && distance2 > s.r2) return false;
    *distance2_out = distance2;
  } else if (s.finite_aperture || s.nearest) {
    // The line X + s (C_i - X) meets the lens plane a . (P - C) = 0 at
    // P - C = ((a.b) X - (a.X) b) / ((a.b) - (a.X)), written as integral.cpp does:
    // exactly b for a view on the lens plane, so symmetric views tie exactly.
    const double a_x = glm::dot(s.lens_axis, focal);
    const double denominator = view.lens_b - a_x;
    if (denominator == 0.0) return false;
    const Vec3d numerator = view.lens_b * focal - a_x * view.b;
    const double distance2 = glm::dot(numerator, numerator) / (denominator * denominator);
    if (s.finite_aperture && distance2 > s.r2) return false;
    *distance2_out = distance2;
  }
  *u_out = u;
  *v_out = v;
  return true;
}

// One admitted sample of `view` at view pixel (u, v) into a pixel's lists: its channels (a
// masked light field's divided by their mask weight: surface_integral.h) and their luminance.
// False, and nothing added, for a masked sample of weight 0. `value` holds the view's channels.
inline bool AddValues(const Setup& s, int channels, bool masked, const double* value,
                      std::vector<double>& samples, std::vector<double>& luminance);
inline bool AddSample(const Setup& s, const ViewSetup& view, double u, double v, int channels,
                      bool masked, double* value, std::vector<double>& samples,
                      std::vector<double>& luminance) {
  view.sample(*view.image, u, v, value);
  return AddValues(s, channels, masked, value, samples, luminance);
}

// AddSample after the sampling: the view's channels `value` into the lists.
inline bool AddValues(const Setup& s, int channels, bool masked, const double* value,
                      std::vector<double>& samples, std::vector<double>& luminance) {
  if (channels == 1 && !masked) {
    // The same values without the divisions by 1: x / 1 = x and (0 + x) / 1 = x + 0 exactly.
    samples.push_back(value[0]);
    luminance.push_back(value[0] + 0.0);
    return true;
  }
  double weight = 1.0;
  if (masked) {
    weight = value[channels] / s.range;
    if (!(weight > 0.0)) return false;
  }
  double mean = 0.0;
  for (int c = 0; c < channels; ++c) {
    samples.push_back(value[c] / weight);
    mean += samples.back();
  }
  luminance.push_back(mean / channels);
  return true;
}

// True if no band [v, v + width] holds `needed` or more of `values` (then the robust mean falls
// back, whatever the sort would find), from a histogram: bins of width / kBandBins from the
// smallest value; a band's values lie in kBandBins + 1 consecutive bins, give or take one bin
// at either end for rounding, so the largest sum over kBandBins + 3 consecutive bins bounds
// every band's count from above. False (undecided: sort) where that bound reaches `needed`,
// or where the values span more than kMaxBandBins bins.
constexpr int kBandBins = 8;
constexpr int kMaxBandBins = 4096;
inline bool NoBandHolds(const std::vector<double>& values, double width, double needed,
                        std::vector<int32_t>& histogram) {
  const auto [lo, hi] = std::minmax_element(values.begin(), values.end());
  const double bin = width / kBandBins;
  if (!(bin > 0.0) || !(*hi - *lo < bin * (kMaxBandBins - 1))) return false;
  const double scale = 1.0 / bin;
  const int bins = static_cast<int>((*hi - *lo) * scale) + 1;
  histogram.assign(static_cast<size_t>(bins + kBandBins + 3), 0);
  for (const double value : values) {
    ++histogram[static_cast<size_t>(std::min(bins - 1, static_cast<int>((value - *lo) * scale)))];
  }
  int32_t window = 0;
  for (int i = 0; i < kBandBins + 3; ++i) window += histogram[static_cast<size_t>(i)];
  int32_t most = window;
  for (int i = kBandBins + 3; i < bins + kBandBins + 3; ++i) {
    window += histogram[static_cast<size_t>(i)] - histogram[static_cast<size_t>(i - kBandBins - 3)];
    most = std::max(most, window);
  }
  return static_cast<double>(most) < needed;
}

// Output pixel (x, y) from its samples (in view order, `channels` values each) and their
// luminances: count, the robust mean's band and inliers, the variance, the (inlier) mean.
// Returns true where the robust mean fell back to the plain mean. With a `histogram` (scratch)
// a pixel that NoBandHolds decides falls back without the sort (the same outputs); without one
// (the reference) every pixel is sorted.
inline bool FinishPixel(const Setup& s, const SurfaceIntegralOptions& surface, bool variance,
                        int channels, const std::vector<double>& samples,
                        const std::vector<double>& luminance, std::vector<double>& sorted,
                        std::vector<int32_t>* histogram, int x, int y,
                        SurfaceIntegralResult& result) {
  IntegralResult& out = result.integral;
  const size_t n = luminance.size();
  out.count.At<uint32_t>(x, y)[0] = static_cast<uint32_t>(n);
  if (n == 0) return false;
  bool fell_back = false;
  // The inlier set: every sample, or those in the densest band of the luminance.
  size_t kept = n;
  double lower = -std::numeric_limits<double>::infinity();
  double upper = std::numeric_limits<double>::infinity();
  if (surface.robust && n >= 2 && histogram != nullptr &&
      NoBandHolds(luminance, 2.0 * surface.agreement * s.range,
                  surface.min_inlier_fraction * static_cast<double>(n), *histogram)) {
    fell_back = true;  // what the search below would find, without sorting
  } else if (surface.robust && n >= 2) {
    // The densest band [v, v + width] over the sorted luminances (two pointers).
    sorted = luminance;
    std::sort(sorted.begin(), sorted.end());
    const double width = 2.0 * surface.agreement * s.range;
    size_t best_begin = 0, best_size = 0;
    for (size_t begin = 0, end = 0; begin < n; ++begin) {
      while (end < n && sorted[end] <= sorted[begin] + width) ++end;
      if (end - begin > best_size) {
        best_size = end - begin;
        best_begin = begin;
      }
    }
    if (static_cast<double>(best_size) >= surface.min_inlier_fraction * static_cast<double>(n)) {
      lower = sorted[best_begin];
      upper = sorted[best_begin + best_size - 1];
      kept = best_size;
    } else {
      fell_back = true;
    }
  }
  if (surface.robust) result.inliers.At<uint32_t>(x, y)[0] = static_cast<uint32_t>(kept);
  if (variance && n >= 2 && !s.nearest) {
    // Population variance of all the samples, mean over channels (integral.h).
    // Two passes (the mean, then the squared deviations from it): no cancellation, so equal
    // samples give exactly 0 whatever their magnitude (16-bit values near 65535).
    double sum_variance = 0.0;
    for (int c = 0; c < channels; ++c) {
      double sum = 0.0;
      for (size_t k = 0; k < n; ++k) sum += samples[k * channels + static_cast<size_t>(c)];
      const double mean = sum / static_cast<double>(n);
      double squares = 0.0;
      for (size_t k = 0; k < n; ++k) {
        const double deviation = samples[k * channels + static_cast<size_t>(c)] - mean;
        squares += deviation * deviation;
      }
      sum_variance += squares / static_cast<double>(n);
    }
    out.variance.At<float>(x, y)[0] = static_cast<float>(sum_variance / channels);
  }
  float* pixel = out.image.At<float>(x, y);
  for (int c = 0; c < channels; ++c) {
    double sum = 0.0;
    for (size_t k = 0; k < n; ++k) {
      if (luminance[k] >= lower && luminance[k] <= upper) {
        sum += samples[k * channels + static_cast<size_t>(c)];
      }
    }
    pixel[c] = static_cast<float>(sum / static_cast<double>(kept));
  }
  return fell_back;
}

// The outputs of a per-sample render of `s` (image with the masked light field's channel
// dropped, count, inliers for the robust mean, variance), sized and zeroed.
SurfaceIntegralResult MakeOutputs(const Setup& s, int channels, bool robust, bool variance) {
  SurfaceIntegralResult result;
  IntegralResult& out = result.integral;
  out.image = Image(s.width, s.height, channels, PixelType::kF32);
  out.count = Image(s.width, s.height, 1, PixelType::kU32);
  out.views_selected = static_cast<int>(s.views.size());
  if (robust) result.inliers = Image(s.width, s.height, 1, PixelType::kU32);
  if (variance) out.variance = Image(s.width, s.height, 1, PixelType::kF32);
  return result;
}

// Views used, samples and uncovered pixels from the counts.
void FinishStatistics(const Setup& s, const std::vector<uint8_t>& view_used,
                      SurfaceIntegralResult& result) {
  IntegralResult& out = result.integral;
  for (size_t i = 0; i < view_used.size(); ++i) {
    if (view_used[i]) result.used_view_indices.push_back(s.view_indices[i]);
  }
  out.views_used = static_cast<int>(result.used_view_indices.size());
  for (int y = 0; y < s.height; ++y) {
    const uint32_t* count = out.count.At<uint32_t>(0, y);
    for (int x = 0; x < s.width; ++x) {
      out.samples += count[x];
      out.uncovered_pixels += count[x] == 0;
    }
  }
}

}  // namespace

namespace internal {

SurfaceIntegralResult RenderIntegralAtPointsReference(const LightField& light_field,
                                                      const FocalPoints& points,
                                                      const PointIntegralOptions& options,
                                                      const SurfaceIntegralOptions& surface,
                                                      ProgressSink* progress) {
  const Setup s = MakeSetup(light_field, points, options, surface);
  const std::vector<ViewSetup>& views = s.views;
  // A masked light field (lightfield.h): each sample's last channel is its mask weight times
  // the full range; a sample of weight 0 is left out, the others are divided by their weight
  // (surface_integral.h), so the output has one channel less.
  const bool masked = light_field.masked;
  if (masked && s.channels < 2) {
    ThrowInvalid("masked light field: the views have 1 channel; a masked view has its values "
                 "and a weight channel");
  }
  const int sampled_channels = s.channels;
  const int channels = s.channels - (masked ? 1 : 0);
  const bool nearest = s.nearest;
  SurfaceIntegralResult result = MakeOutputs(s, channels, surface.robust, options.variance);

  const int threads = ResolveThreadCount(options.num_threads);
  ProgressStart(progress, "render on surface", s.height);
  std::vector<uint8_t> view_used(views.size(), 0);
  int64_t fallback = 0;
  bool cancelled = false;
  std::exception_ptr error;
#pragma omp parallel num_threads(threads) reduction(+ : fallback)
  {
    std::vector<uint8_t> used(views.size(), 0);
    std::vector<double> samples, luminance, sorted;
    std::vector<double> value(static_cast<size_t>(sampled_channels));
#pragma omp for schedule(dynamic, 4)
    for (int64_t y = 0; y < s.height; ++y) {
      bool stop;
#pragma omp atomic read
      stop = cancelled;
      if (stop) continue;
      try {
        if (ProgressCancelled(progress)) {
#pragma omp atomic write
          cancelled = true;
          continue;
        }
        const int row = static_cast<int>(y);
        for (int x = 0; x < s.width; ++x) {
          const Vec3d& point = points.points[static_cast<size_t>(row) * s.width + x];
          if (!std::isfinite(point.x) || !std::isfinite(point.y) || !std::isfinite(point.z)) continue;
          const Vec3d focal = point + s.shift;
          samples.clear();
          luminance.clear();
          double best = std::numeric_limits<double>::infinity();
          size_t chosen = views.size();  // nearest mode: the view kept so far
          for (size_t i = 0; i < views.size(); ++i) {
            const ViewSetup& view = views[i];
            double u, v, distance2 = std::numeric_limits<double>::infinity();
            if (!AdmitSample(s, view, focal, &u, &v, &distance2)) continue;
            if (nearest) {
              if (!(distance2 < best)) continue;
              best = distance2;
              chosen = i;
              samples.clear();
              luminance.clear();
            }
            // Nearest mode keeps the nearest view even where it is masked (uncovered then).
            if (!AddSample(s, view, u, v, channels, masked, value.data(), samples, luminance)) {
              continue;
            }
            if (!nearest) used[i] = 1;
          }
          if (chosen < views.size()) used[chosen] = 1;
          fallback += FinishPixel(s, surface, options.variance, channels, samples, luminance,
                                  sorted, nullptr, x, row, result);
        }
        ProgressAdvance(progress, 1);
      } catch (...) {
#pragma omp critical(aos_surface_error)
        if (!error) error = std::current_exception();
#pragma omp atomic write
        cancelled = true;
      }
    }
#pragma omp critical(aos_surface_merge)
    for (size_t i = 0; i < used.size(); ++i) view_used[i] |= used[i] != 0;
  }
  if (error) std::rethrow_exception(error);
  if (cancelled) throw Cancelled();
  result.fallback_pixels = fallback;
  FinishStatistics(s, view_used, result);
  return result;
}

}  // namespace internal

namespace {

// Output tiles of 64 x 64 pixels (on F0 faster than 32 x 32, 128 x 32, 256 x 16: the cull and
// the share of a view's cache lines each tile reads balance there).
constexpr int kTileWidth = 64;
constexpr int kTileHeight = 64;
constexpr double kFloatRoundoff = 5.9604644775390625e-08;  // 2^-24
// Beyond this (metres) points and view centres are left to double precision.
constexpr double kFloatRange = 1e6;

struct Box {
  Vec3d lo, hi;
  Vec3d Corner(int k) const {
    return Vec3d((k & 1) ? hi.x : lo.x, (k & 2) ? hi.y : lo.y, (k & 4) ? hi.z : lo.z);
  }
};

// True if the pinhole view admits no point of the box: one of its image bounds (each a linear
// test in the point: Z > 0, U >= 0, ..., with (U, V, Z) = K (R X + offset)) fails at all eight
// corners by more than a rounding margin.
// Sets bit t of *tests (t: 0 Z > 0, 1 U >= 0, 2 width Z - U >= 0, 3 V >= 0, 4 height Z - V >= 0)
// unless that bound holds at all eight corners by more than the margin (then at every point of
// the box, so the kernel need not test it): on F0 most (view, tile) pairs lie across one edge
// of the view's image, and one bound of five is tested.
bool OutsideImage(const ViewSetup& view, const Box& box, int* tests) {
  bool negative[5] = {true, true, true, true, true};
  bool positive[5] = {true, true, true, true, true};
  const double size = std::abs(view.fx) + std::abs(view.fy) + std::abs(view.cx) +
                      std::abs(view.cy) + view.width + view.height + 1.0;
  for (int k = 0; k < 8; ++k) {
    const Vec3d in_cam = view.rotation * box.Corner(k) + view.offset;
    const double margin =
        1e-9 * size * (std::abs(in_cam.x) + std::abs(in_cam.y) + std::abs(in_cam.z));
    const double U = view.fx * in_cam.x + view.cx * in_cam.z;
    const double V = view.fy * in_cam.y + view.cy * in_cam.z;
    const double tests[5] = {in_cam.z, U, view.width * in_cam.z - U, V,
                             view.height * in_cam.z - V};
    for (int t = 0; t < 5; ++t) {
      negative[t] = negative[t] && tests[t] < -margin;
      positive[t] = positive[t] && tests[t] > margin;
    }
  }
  *tests = 0;
  for (int t = 0; t < 5; ++t) *tests |= positive[t] ? 0 : 1 << t;
  return negative[0] || negative[1] || negative[2] || negative[3] || negative[4];
}

// True if a finite aperture admits no point of the box. The lens-plane crossing is a
// projective map of the point (one sign of its denominator over the box), the cylinder's
// offset a linear one: either way the images of the corners span those of the whole box, so
// the box is out when the corners' images' bounding box lies further than the radius.
bool OutsideAperture(const Setup& s, const ViewSetup& view, const Box& box) {
  if (!s.finite_aperture) return false;
  const double inf = std::numeric_limits<double>::infinity();
  Vec3d lo(inf), hi(-inf);
  int sign = 0;
  for (int k = 0; k < 8; ++k) {
    const Vec3d corner = box.Corner(k);
    Vec3d image;
    if (s.cylinder) {
      const Vec3d to_view = view.b - corner;
      image = to_view - glm::dot(to_view, s.lens_axis) * s.lens_axis;
    } else {
      const double a_x = glm::dot(s.lens_axis, corner);
      const double denominator = view.lens_b - a_x;
      if (!(std::abs(denominator) > 1e-9 * (std::abs(view.lens_b) + std::abs(a_x)))) return false;
      const int corner_sign = denominator > 0.0 ? 1 : -1;
      if (sign != 0 && corner_sign != sign) return false;
      sign = corner_sign;
      image = (view.lens_b * corner - a_x * view.b) / denominator;
    }
    lo = glm::min(lo, image);
    hi = glm::max(hi, image);
  }
  double distance2 = 0.0;
  for (int i = 0; i < 3; ++i) {
    const double gap = std::max({lo[i], -hi[i], 0.0});
    distance2 += gap * gap;
  }
  return distance2 > s.r2 * (1.0 + 1e-6);
}

// True if no point of the box is seen at a grazing angle from the view: {X : |n.(C_i - X)| >=
// sin(angle) |C_i - X|} is two convex cones, so all eight corners inside one (with a margin)
// put the whole box inside it.
bool NeverGrazing(const Setup& s, const ViewSetup& view, const Box& box) {
  if (s.sin2_min == 0.0) return true;  // (n.t)^2 < 0 never holds
  int sign = 0;
  for (int k = 0; k < 8; ++k) {
    const Vec3d to_view = view.b - box.Corner(k);
    const double along = glm::dot(s.normal, to_view);
    if (!(along * along > s.sin2_min * glm::dot(to_view, to_view) * (1.0 + 1e-6))) return false;
    const int corner_sign = along > 0.0 ? 1 : -1;
    if (sign != 0 && corner_sign != sign) return false;
    sign = corner_sign;
  }
  return true;
}

// The rectangle of view pixels (tap indices, clamped into the bordered image) that the box's
// points project into, from its corners; empty if a corner is not in front of the view.
struct Footprint {
  int x0 = 0, x1 = -1, y0 = 0, y1 = -1;
};
// From the points on the tile's outline (the prefetch only needs to be about right: a surface
// bulging out of its outline's footprint costs cache misses, not results), 2 pixels of margin.
Footprint FootprintOf(const ViewSetup& view, const std::vector<Vec3d>& outline) {
  Footprint f;
  double u_min = std::numeric_limits<double>::infinity(), u_max = -u_min;
  double v_min = u_min, v_max = -u_min;
  for (const Vec3d& point : outline) {
    const Vec3d in_cam = view.rotation * point + view.offset;
    if (!(in_cam.z > 0.0)) return f;
    const double u = view.fx * in_cam.x / in_cam.z + view.cx;
    const double v = view.fy * in_cam.y / in_cam.z + view.cy;
    u_min = std::min(u_min, u - 2.0);
    u_max = std::max(u_max, u + 2.0);
    v_min = std::min(v_min, v - 2.0);
    v_max = std::max(v_max, v + 2.0);
  }
  const Image& image = *view.image;
  // Tap indices ix = floor(u - 0.5) in [-1, width - 1] (and ix + 1), likewise rows.
  f.x0 = static_cast<int>(std::clamp(u_min - 1.5, -1.0, image.width() - 1.0));
  f.x1 = static_cast<int>(std::clamp(u_max + 0.5, -1.0, image.width() - 1.0));
  f.y0 = static_cast<int>(std::clamp(v_min - 1.5, -1.0, image.height() - 1.0));
  f.y1 = static_cast<int>(std::clamp(v_max + 0.5, -1.0, image.height() - 1.0));
  return f;
}

// The same for a lens view: the outline's points through the lens (exactly); empty if one does
// not project.
Footprint LensFootprintOf(const ViewSetup& view, const std::vector<Vec3d>& outline) {
  Footprint f;
  double u_min = std::numeric_limits<double>::infinity(), u_max = -u_min;
  double v_min = u_min, v_max = -u_min;
  for (const Vec3d& point : outline) {
    Vec2d pixel;
    if (!view.lens->Project(view.rotation * point + view.offset, &pixel)) return f;
    u_min = std::min(u_min, pixel.x - 2.0);
    u_max = std::max(u_max, pixel.x + 2.0);
    v_min = std::min(v_min, pixel.y - 2.0);
    v_max = std::max(v_max, pixel.y + 2.0);
  }
  const Image& image = *view.image;
  f.x0 = static_cast<int>(std::clamp(u_min - 1.5, -1.0, image.width() - 1.0));
  f.x1 = static_cast<int>(std::clamp(u_max + 0.5, -1.0, image.width() - 1.0));
  f.y0 = static_cast<int>(std::clamp(v_min - 1.5, -1.0, image.height() - 1.0));
  f.y1 = static_cast<int>(std::clamp(v_max + 0.5, -1.0, image.height() - 1.0));
  return f;
}

// The addresses of the cache lines of a view's pixels that a tile will read (the kernel's
// gathers stall on cache misses otherwise: a view's pixels are read once per tile), at most
// kMaxPrefetch (the rest is left to the hardware).
constexpr int kMaxPrefetch = 1024;
int FootprintLines(const Image& image, const Footprint& f, const char** lines) {
  if (f.x1 < f.x0 || f.y1 < f.y0) return 0;
  const auto* base = static_cast<const char*>(image.RawAt(0, 0));
  const ptrdiff_t pixel_bytes =
      static_cast<ptrdiff_t>(PixelTypeSize(image.type())) * image.channels();
  const ptrdiff_t row_bytes =
      image.row_stride() * static_cast<ptrdiff_t>(PixelTypeSize(image.type()));
  int count = 0;
  for (int y = f.y0; y <= f.y1 + 1; ++y) {
    const char* row = base + y * row_bytes;
    // Whole cache lines from the first tap's to the last tap's (taps x0 .. x1 + 1).
    const auto first = reinterpret_cast<uintptr_t>(row + f.x0 * pixel_bytes) & ~uintptr_t{63};
    const auto last = reinterpret_cast<uintptr_t>(row + (f.x1 + 2) * pixel_bytes - 1);
    for (uintptr_t line = first; line <= last; line += 64) {
      if (count == kMaxPrefetch) return count;
      lines[count++] = reinterpret_cast<const char*>(line);
    }
  }
  return count;
}

struct ExactContext {
  const Setup* setup;
  const ViewSetup* view;
  const Vec3d* focal;
};

bool ExactAdmitLane(const void* context, int index) {
  const auto* c = static_cast<const ExactContext*>(context);
  double u, v, distance2;
  return AdmitSample(*c->setup, *c->view, c->focal[index], &u, &v, &distance2);
}

// The AVX2 kernel's description of `view` on a tile whose points (relative to the centre) lie
// within |x| <= extent.x etc.: the projection in float and the bounds of each test's float error
// (surface_integral_kernels.h; a few times the worst-case rounding of the float arithmetic).
// The projection is (U, V, Z) = rows[r] . p + t[r] for a point p relative to the centre.
internal::PointKernelArgs KernelArgsFor(const Setup& s, const ViewSetup& view, const Vec3d rows[3],
                                        const double t[3], const Vec3d& extent, bool grazing) {
  internal::PointKernelArgs args;
  double magnitude[3];
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) args.P[r][c] = static_cast<float>(rows[r][c]);
    args.P[r][3] = static_cast<float>(t[r]);
    magnitude[r] = glm::dot(glm::abs(rows[r]), extent) + std::abs(t[r]);
  }
  const double g = kFloatRoundoff;
  args.width = static_cast<float>(view.width);
  args.height = static_cast<float>(view.height);
  args.bound[0] = static_cast<float>(16 * g * magnitude[2]);
  args.bound[1] = static_cast<float>(16 * g * magnitude[0]);
  args.bound[2] = static_cast<float>(32 * g * (view.width * magnitude[2] + magnitude[0]));
  args.bound[3] = static_cast<float>(16 * g * magnitude[1]);
  args.bound[4] = static_cast<float>(32 * g * (view.height * magnitude[2] + magnitude[1]));
  const double P = glm::length(extent), B = glm::length(view.b);
  const double D = P + B;
  args.grazing = grazing;
  for (int i = 0; i < 3; ++i) {
    args.normal[i] = static_cast<float>(s.normal[i]);
    args.axis[i] = static_cast<float>(s.lens_axis[i]);
    args.b[i] = static_cast<float>(view.b[i]);
  }
  args.sin2 = static_cast<float>(s.sin2_min);
  args.grazing_bound = static_cast<float>(64 * g * D * D);
  args.lens_b = static_cast<float>(view.lens_b);
  args.r2 = static_cast<float>(s.r2);
  args.aperture = s.finite_aperture ? (s.cylinder ? 2 : 1) : 0;
  if (s.cylinder) {
    args.aperture_bound = static_cast<float>(64 * g * (D * D + s.r2));
  } else {
    const double numerator = std::abs(view.lens_b) * P + P * B;
    const double denominator = std::abs(view.lens_b) + P;
    args.aperture_bound =
        static_cast<float>(128 * g * (numerator * numerator + s.r2 * denominator * denominator));
    args.denominator_bound = static_cast<float>(16 * g * denominator);
  }
  return args;
}

// A pinhole view's projection K (R p + offset).
internal::PointKernelArgs KernelArgs(const Setup& s, const ViewSetup& view, const Vec3d& extent,
                                     bool grazing) {
  const Vec3d r0 = Row(view.rotation, 0), r1 = Row(view.rotation, 1), r2 = Row(view.rotation, 2);
  const Vec3d rows[3] = {view.fx * r0 + view.cx * r2, view.fy * r1 + view.cy * r2, r2};
  const double t[3] = {view.fx * view.offset.x + view.cx * view.offset.z,
                       view.fy * view.offset.y + view.cy * view.offset.z, view.offset.z};
  return KernelArgsFor(s, view, rows, t, extent, grazing);
}

// One thread's working memory for a tile.
struct TileBuffers {
  std::vector<float> x, y, z;
  std::vector<int32_t> valid;
  std::vector<Vec3d> focal;
  std::vector<double> sum, sum_squares, best, value;
  std::vector<uint32_t> count;
  std::vector<int32_t> chosen;
  std::vector<uint8_t> used;
  std::vector<int> views;           // the views the tile's culls leave
  std::vector<uint8_t> image_tests;  // the image bounds the tile's points may fail (OutsideImage)
  std::vector<Footprint> footprints;
  std::vector<const char*> lines;  // the next view's cache lines to prefetch
  std::vector<Vec3d> outline;      // points on the tile's border (footprints)
  std::vector<Vec3d> lens_outline;  // fewer of them, for lens views
  // The lens route: exact projections at quad nodes, valid while node_stamp[j] == generation
  // (one generation per view), and each quad's departure from bilinear (-1 = not computed).
  struct LensNode {
    Vec3d direction;  // unit: the node's focal point in the view's camera frame, normalised
    double distance;  // metres from the view centre
    Vec2d pixel;
    bool valid;
  };
  std::vector<uint32_t> node_stamp;
  std::vector<LensNode> nodes;
  uint32_t generation = 0;
  std::vector<double> deviation;
  internal::LensRouteCounts counts;  // this tile's, added to the totals at its end
};

// Totals of internal::LensRouteCounts (relaxed atomics: one add per field and tile).
std::atomic<int64_t> g_fitted_quads[4];
std::atomic<int64_t> g_exact_quads{0};
std::atomic<int64_t> g_projected_nodes{0};

// Least squares for a homography (u, v) = (a . (x, y, 1), b . (x, y, 1)) / (g . (x, y) + 1)
// from point pairs, linearised (the algebraic error: a . h - u g . p = u, b . h - v g . p = v,
// h = (x, y, 1), p = (x, y)). The normal equations' a and b blocks share N = sum h h^T, so g
// comes from their 2 x 2 Schur complement and a, b from N^-1 (a few hundred flops a fit).
struct Homography8 {
  Mat3d n{0.0};                   // sum h h^T
  Vec3d su{0.0}, sv{0.0};         // sum h u, sum h v
  glm::dmat2x3 mu{0.0}, mv{0.0};  // sum h u p^T, sum h v p^T (3 x 2)
  glm::dmat2 pp{0.0};             // sum (u^2 + v^2) p p^T
  Vec2d rp{0.0};                  // sum (u^2 + v^2) p

  void Add(const Vec2d& p, const Vec2d& uv) {
    const Vec3d h(p.x, p.y, 1.0);
    n += glm::outerProduct(h, h);
    su += uv.x * h;
    sv += uv.y * h;
    mu += glm::outerProduct(uv.x * h, p);
    mv += glm::outerProduct(uv.y * h, p);
    const double r2 = uv.x * uv.x + uv.y * uv.y;
    pp += glm::outerProduct(r2 * p, p);
    rp += r2 * p;
  }

  // Rows (a, b, (g, 1)) of the homography; false if the system is (numerically) singular.
  bool Solve(Vec3d* a, Vec3d* b, Vec2d* g) const {
    if (!(std::abs(glm::determinant(n)) > 1e-300)) return false;
    const Mat3d inverse = glm::inverse(n);
    // [N 0 M_u; 0 N M_v; M_u^T M_v^T P] (a, b, -g) = (s_u, s_v, -r) after negating g's column.
    const glm::dmat2x3 nu = inverse * mu, nv = inverse * mv;
    const glm::dmat2 schur = pp - glm::transpose(mu) * nu - glm::transpose(mv) * nv;
    const Vec2d right = -rp + glm::transpose(mu) * (inverse * su) + glm::transpose(mv) * (inverse * sv);
    const double det = glm::determinant(schur);
    if (!(std::abs(det) > 1e-12 * (std::abs(schur[0][0] * schur[1][1]) + 1e-300))) return false;
    *g = glm::inverse(schur) * right;
    *a = inverse * su + nu * (*g);
    *b = inverse * sv + nv * (*g);
    return std::isfinite(a->x + a->y + a->z + b->x + b->y + b->z + g->x + g->y);
  }
};

// The cubic map of the lens route (LensRoute::FitCubic): its monomials of (x, y) in the kernel's
// order (PointKernelArgs::cubic).
constexpr int kCubicTerms = 10;
inline void CubicMonomials(double x, double y, double m[kCubicTerms]) {
  m[0] = 1.0;
  m[1] = x;
  m[2] = y;
  m[3] = x * x;
  m[4] = x * y;
  m[5] = y * y;
  m[6] = x * x * x;
  m[7] = x * x * y;
  m[8] = x * y * y;
  m[9] = y * y * y;
}

// Solves the normal equations a c = b[r] (a symmetric positive definite, upper triangle used)
// for both right-hand sides by Cholesky, in place (b becomes c); false if a pivot falls below
// 1e-12 of its diagonal entry (the nodes do not determine the map).
inline bool SolveCubicNormalEquations(double a[kCubicTerms][kCubicTerms],
                                      double b[2][kCubicTerms]) {
  constexpr int n = kCubicTerms;
  // a = L L^T with L stored transposed in the upper triangle: a[k][i] = L[i][k], i >= k.
  for (int k = 0; k < n; ++k) {
    double pivot = a[k][k];
    for (int j = 0; j < k; ++j) pivot -= a[j][k] * a[j][k];
    if (!(pivot > 1e-12 * a[k][k])) return false;
    const double root = std::sqrt(pivot);
    a[k][k] = root;
    for (int i = k + 1; i < n; ++i) {
      double value = a[k][i];
      for (int j = 0; j < k; ++j) value -= a[j][k] * a[j][i];
      a[k][i] = value / root;
    }
  }
  for (int r = 0; r < 2; ++r) {
    double* c = b[r];
    for (int i = 0; i < n; ++i) {  // L y = b
      for (int j = 0; j < i; ++j) c[i] -= a[j][i] * c[j];
      c[i] /= a[i][i];
    }
    for (int i = n - 1; i >= 0; --i) {  // L^T c = y
      for (int j = i + 1; j < n; ++j) c[i] -= a[i][j] * c[j];
      c[i] /= a[i][i];
    }
  }
  return true;
}

// Quads of the lens route: 64 (the tile), 32, 16 and 8 pixels on a side; ids per level.
constexpr int kLensQuadLevels = 4;
constexpr int kLensQuadOffset[kLensQuadLevels] = {0, 1, 5, 21};
constexpr int kLensQuadCount = 85;
// Wide lenses (fisheye, omnidirectional): the cubic map on 64- and 32-pixel quads.
constexpr int kCubicLevels = 2;
static_assert(kTileWidth == 64 && kTileHeight == 64, "the lens route's quads tile 64 x 64");

// Lens views on a tile, quad by quad (see the top of this file): a quad whose local homography
// is within the tolerance goes through the AVX2 kernel, others are split, down to 8 x 8 pixels,
// below which `exact` (AdmitSample and the double sampler) takes each point.
template <typename Exact>
struct LensRoute {
  const Setup& s;
  const ViewSetup& view;
  TileBuffers& b;
  int stride, tile_width, tile_height;
  const Vec3d& extent;
  bool variance, grazing;
  const Exact& exact;
  // The next view's cache lines, handed out to the kernel calls a slice at a time.
  const char* const* prefetch;
  int prefetch_count;
  int prefetch_slice;
  int prefetched = 0;
  bool any = false;

  const TileBuffers::LensNode& Node(int tx, int ty) {
    const size_t j = static_cast<size_t>(ty) * stride + tx;
    TileBuffers::LensNode& node = b.nodes[j];
    if (b.node_stamp[j] == b.generation) return node;
    b.node_stamp[j] = b.generation;
    node.valid = false;
    if (b.valid[j] == 0) return node;
    const Vec3d in_cam = view.rotation * b.focal[j] + view.offset;
    ++b.counts.projected_nodes;
    node.valid = view.lens->Project(in_cam, &node.pixel);
    node.distance = glm::length(in_cam);
    node.valid = node.valid && node.distance > 0.0;
    node.direction = in_cam / node.distance;
    return node;
  }

  // The largest distance (metres) of a quad's focal points from the bilinear interpolation of
  // those at its corner nodes; infinity if a corner has none. The same for every view.
  double Deviation(int id, int qx, int qy, int xl, int yl, int x_end, int y_end) {
    double& memo = b.deviation[static_cast<size_t>(id)];
    if (memo >= 0.0) return memo;
    const auto at = [&](int tx, int ty) { return static_cast<size_t>(ty) * stride + tx; };
    for (size_t j : {at(qx, qy), at(xl, qy), at(qx, yl), at(xl, yl)}) {
      if (b.valid[j] == 0) return memo = std::numeric_limits<double>::infinity();
    }
    const Vec3d& p00 = b.focal[at(qx, qy)];
    const Vec3d& p10 = b.focal[at(xl, qy)];
    const Vec3d& p01 = b.focal[at(qx, yl)];
    const Vec3d& p11 = b.focal[at(xl, yl)];
    double worst = 0.0;
    for (int ty = qy; ty < y_end; ++ty) {
      const double fy = static_cast<double>(ty - qy) / (yl - qy);
      const Vec3d left = p00 + fy * (p01 - p00), right = p10 + fy * (p11 - p10);
      for (int tx = qx; tx < x_end; ++tx) {
        const size_t j = at(tx, ty);
        if (b.valid[j] == 0) continue;
        const double fx = static_cast<double>(tx - qx) / (xl - qx);
        const Vec3d error = b.focal[j] - (left + fx * (right - left));
        worst = std::max(worst, glm::dot(error, error));
      }
    }
    return memo = std::sqrt(worst);
  }

  // What a fit within the tolerance at its nodes (`error`, view pixels) must pass besides: the
  // surface's departure from the bilinear sheet through the quad's corners (its rays turn; the
  // fit's `gradient`, pixels per unit q, and the lens's move them), the lens's valid field, and
  // the image bounds the kernel must test (into *image_tests). `node`: the fit's `nodes` nodes;
  // `distance`, `cos_spread`, `cos_angle` as in Fit.
  // `turn_covered`: `error` already holds over every direction the relief can turn the quad's
  // rays to (FitCubic validates its map over them), so the turn costs only the valid-field
  // margin below.
  bool Accept(int id, int qx, int qy, int xl, int yl, int x_end, int y_end,
              const TileBuffers::LensNode* const* node, int nodes, double error,
              double gradient, double q_per_radian, double distance, double cos_spread,
              double cos_angle, int* image_tests, bool turn_covered = false) {
    if (!(error <= s.lens_tolerance)) return false;
    // Points off the bilinear sheet through the corners (a relief, a step in the surface) see
    // their rays turn by at most deviation / (distance - deviation); the fit and the lens each
    // move by at most about their gradient (pixels per unit q, times q_per_radian) times that
    // (2.25 rather than 2 for the lens's gradient, which is the fit's only up to its error).
    const double deviation = Deviation(id, qx, qy, xl, yl, x_end, y_end);
    if (!(deviation < 0.5 * distance)) return false;
    const double turn = deviation / (distance - deviation);
    if (!turn_covered && !(error + 2.25 * q_per_radian * gradient * turn <= s.lens_tolerance)) {
      return false;
    }
    // Every ray of the quad within the lens's valid field, with a margin of half the spread.
    // (acos only where needed: the spread of a quad is small, and for x <= 0.46 rad,
    // x <= sqrt(2 (1 - cos x)) / (1 - x^2 / 12) <= 1.03 sqrt(2 (1 - cos x)), a bound that decides
    // as the exact spread would wherever it passes.)
    // First without any acos: the quad's rays within valid_angle - kAngleShortcut of the axis
    // and a margin below kAngleShortcut (most quads of a render), then as it was.
    const double chord = std::sqrt(2.0 * std::max(0.0, 1.0 - cos_spread));
    const double margin = 1.5 * (1.03 * chord) + turn;
    if (!(chord <= 0.45 && margin < kAngleShortcut - 1e-6 && cos_angle > view.cos_shortcut) &&
        !(chord <= 0.45 &&
          std::acos(std::max(-1.0, cos_angle)) + margin < view.valid_angle)) {
      const double angle = std::acos(std::max(-1.0, cos_angle));
      const double spread = std::acos(std::max(-1.0, std::min(1.0, cos_spread)));
      if (!(angle + 1.5 * spread + turn < view.valid_angle)) return false;
    }
    // The image bounds the kernel must test (PointKernelArgs::image_tests): W = c . X > 0 holds
    // within 60 degrees of c; a bound that every node's pixel keeps by 2 pixels holds for the
    // quad's points too (their fitted pixels lie within the tolerance of the nodes' hull).
    *image_tests = 0;
    double u_min = std::numeric_limits<double>::infinity(), u_max = -u_min;
    double v_min = u_min, v_max = -u_min;
    for (int k = 0; k < nodes; ++k) {
      u_min = std::min(u_min, node[k]->pixel.x);
      u_max = std::max(u_max, node[k]->pixel.x);
      v_min = std::min(v_min, node[k]->pixel.y);
      v_max = std::max(v_max, node[k]->pixel.y);
    }
    constexpr double kMargin = 2.0;
    if (!(u_min >= kMargin)) *image_tests |= 2;
    if (!(u_max <= view.width - kMargin)) *image_tests |= 4;
    if (!(v_min >= kMargin)) *image_tests |= 8;
    if (!(v_max <= view.height - kMargin)) *image_tests |= 16;
    return true;
  }

  // A relief turns the quad's rays: points off the bilinear sheet through its corners by up to
  // `deviation` metres see their rays turn by at most turn = deviation / (distance -
  // deviation) radians, so their q lies within q_per_radian turn of the sheet's, whose q the
  // nodes span (dq / d(angle) <= 1 / cos^2 of the angle from c). A local map is a function of
  // q alone, so where the turn charged at the map's full gradient (Accept's bound) misses the
  // tolerance, the map is validated over the nodes' q box grown by the turn instead. Its error
  // comes from a 5 x 5 grid of exactly projected directions (into `turned`), plus the
  // interpolation estimate between them from the grid's second differences, as at
  // FitCubic's nodes. `map(q / scale)` is the fitted pixel. Infinity where a grid direction is
  // more than 60 degrees from c, outside the lens's field, or beyond |q / scale| <= `reach`
  // per axis (where the map's own bounds stop: a homography's W >= 0.5, a cubic's float
  // rounding). On the lens benchmark's fisheye, a relief of +-5 cm at 20 m took every quad
  // to the exact projection under the gradient charge (about 2 px for a 2.5 mrad turn); over
  // the grown box the 64-pixel cubics pass.
  static constexpr int kTurnedGrid = 5, kTurnedNodes = kTurnedGrid * kTurnedGrid;
  // `closest`: how near the view the sheet between the nodes comes (the nodes' distance times
  // the cosine of the quad's spread); a deviation of half that or more is refused.
  template <class Map>
  double TurnedError(const Vec2d* q, int count, double scale, const Vec3d& c, const Vec3d& e1,
                     const Vec3d& e2, double deviation, double closest, double reach,
                     const Map& map, TileBuffers::LensNode* turned) {
    constexpr double kInfinity = std::numeric_limits<double>::infinity();
    if (!(deviation < 0.5 * closest)) return kInfinity;
    const double turn = deviation / (closest - deviation);
    Vec2d lo(kInfinity), hi(-kInfinity);
    for (int k = 0; k < count; ++k) lo = glm::min(lo, q[k]), hi = glm::max(hi, q[k]);
    // dq / d(angle) <= 1 + |q|^2 (= 1 / cos^2) at the grown box's farthest corner: two passes.
    double grow = 0.0;
    for (int pass = 0; pass < 2; ++pass) {
      const Vec2d far = scale * glm::max(glm::abs(lo - grow), glm::abs(hi + grow));
      grow = (1.0 + glm::dot(far, far)) * turn / scale;
    }
    lo -= grow;
    hi += grow;
    if (!(std::max({-lo.x, -lo.y, hi.x, hi.y}) <= reach)) return kInfinity;
    Vec2d e[kTurnedNodes];
    double error2 = 0.0;
    for (int k = 0; k < kTurnedNodes; ++k) {
      const Vec2d g = lo + (hi - lo) * Vec2d(k % kTurnedGrid, k / kTurnedGrid) /
                               static_cast<double>(kTurnedGrid - 1);
      const Vec3d direction = c + scale * (g.x * e1 + g.y * e2);
      if (!(glm::dot(c, direction) > 0.5 * glm::length(direction))) return kInfinity;
      ++b.counts.projected_nodes;
      turned[k].valid = view.lens->Project(direction, &turned[k].pixel);
      if (!turned[k].valid) return kInfinity;
      e[k] = map(g) - turned[k].pixel;
      error2 = std::max(error2, glm::dot(e[k], e[k]));
    }
    // A regular grid: h^2 max |e''| / 8 is the largest second difference / 8.
    Vec2d exx(0.0), eyy(0.0);
    for (int a = 0; a < kTurnedGrid; ++a) {
      for (int k = 1; k + 1 < kTurnedGrid; ++k) {
        const int row = a * kTurnedGrid, column = a;
        exx = glm::max(exx, glm::abs(e[row + k + 1] - 2.0 * e[row + k] + e[row + k - 1]));
        eyy = glm::max(eyy, glm::abs(e[(k + 1) * kTurnedGrid + column] -
                                     2.0 * e[k * kTurnedGrid + column] +
                                     e[(k - 1) * kTurnedGrid + column]));
      }
    }
    return std::sqrt(error2) + glm::length(exx + eyy) / 8.0;
  }

  // The quad's local homography into `rows`, `t` (KernelArgsFor) if it is within the tolerance.
  bool Fit(int id, int qx, int qy, int xl, int yl, int x_end, int y_end, Vec3d rows[3],
           double t[3], double* fit_error, int* image_tests) {
    *fit_error = std::numeric_limits<double>::infinity();
    const int xs[3] = {qx, (qx + xl) / 2, xl}, ys[3] = {qy, (qy + yl) / 2, yl};
    const TileBuffers::LensNode* node[9];
    for (int k = 0; k < 9; ++k) {
      node[k] = &Node(xs[k % 3], ys[k / 3]);
      if (!node[k]->valid) return false;
    }
    // Tangent-plane coordinates q around a ray c: q = (e1 . X, e2 . X) / (c . X). For a
    // radial-tangential lens the view's own pinhole coordinates (c its optical axis: the lens
    // map is then its distortion, close to affine, and the fit a homography of the view); for
    // wide lenses the centre node's ray (their map is far from projective off the axis).
    const Vec3d& centre = node[4]->direction;
    const bool perspective = view.lens->traits().perspective;
    const Vec3d c = perspective ? Vec3d(0.0, 0.0, 1.0) : centre;
    const Vec3d helper = std::abs(c.x) < 0.9 ? Vec3d(1.0, 0.0, 0.0) : Vec3d(0.0, 1.0, 0.0);
    const Vec3d e1 = perspective ? Vec3d(1.0, 0.0, 0.0) : glm::normalize(glm::cross(helper, c));
    const Vec3d e2 = glm::cross(c, e1);
    Vec2d q[9];
    // The cosines of the largest angles from c, from the centre node's ray (the quad's angular
    // radius) and from the optical axis.
    double cos_c = 1.0, cos_spread = 1.0, cos_angle = 1.0;
    double distance = std::numeric_limits<double>::infinity();
    // (On unit directions: q is the same for any point along the ray.)
    for (int k = 0; k < 9; ++k) {
      const Vec3d& p = node[k]->direction;
      const double w = glm::dot(c, p);
      // Within 60 degrees of c, so that dq / d(angle) <= 1 / cos^2 <= 4.
      if (!(w > 0.5)) return false;
      const double inverse_w = 1.0 / w;
      q[k] = Vec2d(glm::dot(e1, p) * inverse_w, glm::dot(e2, p) * inverse_w);
      cos_c = std::min(cos_c, w);
      cos_angle = std::min(cos_angle, p.z);
      distance = std::min(distance, node[k]->distance);
    }
    // Wide lenses: c is the centre node's ray, so the spread is cos_c.
    if (perspective) {
      for (int k = 0; k < 9; ++k) cos_spread = std::min(cos_spread, glm::dot(centre, node[k]->direction));
    } else {
      cos_spread = cos_c;
    }
    const double q_per_radian = 1.0 / (cos_c * cos_c);
    // The map pixel = (U, V) / W with rows over (q / scale, 1), q / scale of about unit size.
    // First an affine map (W = 1), least squares through the four corners; where it misses the
    // tolerance by less than kProjectiveRescue, a homography (8 parameters, least squares over
    // the nine nodes; pixels relative to the centre node's): its projective row absorbs part of
    // the lens's second-order terms (radial-tangential: 32-pixel quads pass at 0.02 px instead of
    // 16-pixel ones; fisheye and omnidirectional lenses gain little, and pay only the cheap fit).
    double scale = 0.0;
    for (int k = 0; k < 9; ++k) scale = std::max({scale, std::abs(q[k].x), std::abs(q[k].y)});
    if (!(scale > 0.0)) return false;
    for (int k = 0; k < 9; ++k) q[k] /= scale;
    Vec3d u_row, v_row, w_row(0.0, 0.0, 1.0);
    // Its error at the nine nodes (corners, edge midpoints, centre) against the exact projection,
    // and the largest gradient there (pixels per unit q / scale).
    double error2 = 0.0, gradient2 = 0.0;
    const auto measure = [&] {
      error2 = 0.0;
      gradient2 = 0.0;
      if (w_row == Vec3d(0.0, 0.0, 1.0)) {  // affine: no division, one gradient
        for (int k = 0; k < 9; ++k) {
          const Vec3d hq(q[k].x, q[k].y, 1.0);
          const double du = glm::dot(u_row, hq) - node[k]->pixel.x;
          const double dv = glm::dot(v_row, hq) - node[k]->pixel.y;
          error2 = std::max(error2, du * du + dv * dv);
        }
        gradient2 = u_row.x * u_row.x + u_row.y * u_row.y + v_row.x * v_row.x + v_row.y * v_row.y;
        return;
      }
      for (int k = 0; k < 9; ++k) {
        const Vec3d hq(q[k].x, q[k].y, 1.0);
        const double w = glm::dot(w_row, hq);
        const double u = glm::dot(u_row, hq) / w, v = glm::dot(v_row, hq) / w;
        const double du = u - node[k]->pixel.x, dv = v - node[k]->pixel.y;
        error2 = std::max(error2, du * du + dv * dv);
        const double ux = (u_row.x - u * w_row.x) / w, uy = (u_row.y - u * w_row.y) / w;
        const double vx = (v_row.x - v * w_row.x) / w, vy = (v_row.y - v * w_row.y) / w;
        gradient2 = std::max(gradient2, ux * ux + uy * uy + vx * vx + vy * vy);
      }
    };
    {
      Mat3d normal(0.0);
      Vec3d bu(0.0), bv(0.0);
      for (int k : {0, 2, 6, 8}) {
        const Vec3d h(q[k].x, q[k].y, 1.0);
        normal += glm::outerProduct(h, h);
        bu += node[k]->pixel.x * h;
        bv += node[k]->pixel.y * h;
      }
      if (!(std::abs(glm::determinant(normal)) > 1e-300)) return false;
      const Mat3d inverse = glm::inverse(normal);
      u_row = inverse * bu;
      v_row = inverse * bv;
      measure();
    }
    constexpr double kProjectiveRescue = 4.0;
    if (!(std::sqrt(error2) <= s.lens_tolerance) &&
        std::sqrt(error2) <= kProjectiveRescue * s.lens_tolerance) {
      const Vec2d origin = node[4]->pixel;
      Homography8 fit;
      for (int k = 0; k < 9; ++k) fit.Add(q[k], node[k]->pixel - origin);
      Vec3d a, b;
      Vec2d g;
      // W = 1 + g . q / scale stays >= 0.5 while |q / scale| <= 2 (the quad's points lie within
      // about its nodes' hull, |q / scale| <= 1): the sign of W is c . X's.
      if (fit.Solve(&a, &b, &g) && std::abs(g.x) + std::abs(g.y) <= 0.25) {
        const double affine_error2 = error2, affine_gradient2 = gradient2;
        const Vec3d affine_u = u_row, affine_v = v_row;
        w_row = Vec3d(g.x, g.y, 1.0);
        u_row = a + origin.x * w_row;
        v_row = b + origin.y * w_row;
        measure();
        if (!(error2 < affine_error2)) {  // keep the better of the two
          error2 = affine_error2;
          gradient2 = affine_gradient2;
          u_row = affine_u;
          v_row = affine_v;
          w_row = Vec3d(0.0, 0.0, 1.0);
        }
      }
    }
    double error = std::sqrt(error2);
    *fit_error = error;
    // A relief: the map validated over the turned rays where needed (TurnedError; W >= 0.5
    // holds within |q / scale| <= 2), and the image bounds taken from their pixels too.
    const double deviation = Deviation(id, qx, qy, xl, yl, x_end, y_end);
    if (!(deviation < 0.5 * distance)) return false;
    const double turn = deviation / (distance - deviation);
    const double gradient = std::sqrt(gradient2) / scale;
    TileBuffers::LensNode turned[kTurnedNodes];
    const TileBuffers::LensNode* hull[9 + kTurnedNodes];
    std::copy(node, node + 9, hull);
    int hull_nodes = 9;
    if (turn > 0.0 && error <= s.lens_tolerance &&
        !(error + 2.25 * q_per_radian * gradient * turn <= s.lens_tolerance)) {
      const auto homography_at = [&](const Vec2d& g) {
        const Vec3d hq(g.x, g.y, 1.0);
        return Vec2d(glm::dot(u_row, hq), glm::dot(v_row, hq)) / glm::dot(w_row, hq);
      };
      // (*fit_error stays the nodes' error: what the children's is predicted from.)
      const double turned_error = TurnedError(q, 9, scale, c, e1, e2, deviation,
                                              distance * cos_spread, 2.0, homography_at, turned);
      if (!(turned_error <= s.lens_tolerance)) return false;  // NaN too
      error = std::max(error, turned_error);
      for (int k = 0; k < kTurnedNodes; ++k) hull[hull_nodes++] = &turned[k];
    }
    if (!Accept(id, qx, qy, xl, yl, x_end, y_end, hull, hull_nodes, error, gradient,
                q_per_radian, distance, cos_spread, cos_angle, image_tests,
                /*turn_covered=*/hull_nodes > 9)) {
      return false;
    }
    // (U, V, W) = H diag(1 / scale, 1 / scale, 1) (e1, e2, c)^T (R p + offset): u = U / W.
    const Vec3d h_rows[3] = {Vec3d(u_row.x / scale, u_row.y / scale, u_row.z),
                             Vec3d(v_row.x / scale, v_row.y / scale, v_row.z),
                             Vec3d(w_row.x / scale, w_row.y / scale, w_row.z)};
    const Mat3d cam_from_world_t = glm::transpose(view.rotation);
    for (int r = 0; r < 3; ++r) {
      const Vec3d in_cam_row = h_rows[r].x * e1 + h_rows[r].y * e2 + h_rows[r].z * c;
      rows[r] = cam_from_world_t * in_cam_row;
      t[r] = glm::dot(in_cam_row, view.offset);
    }
    return true;
  }

  // Wide lenses (fisheye, omnidirectional) on quads of 64 and 32 pixels: a cubic polynomial in
  // the tangent-plane coordinates q of the quad's centre ray (PointKernelArgs::cubic), least
  // squares over a 5 x 5 grid of nodes. A homography cannot take up the equidistant (or Mei)
  // map's second-order term, which holds those lenses at 16-pixel quads; the cubic's residual
  // is fourth order (on the lens benchmark about 3e-4 px at 64 pixels against 0.02). The error
  // estimate (not a strict bound): the largest error e at the nodes plus the error of
  // interpolating e bilinearly between them, |e - I e| <= (h_x^2 max |e_xx| + h_y^2 max |e_yy|)
  // / 8 per component over a cell of h_x x h_y output pixels, with e_xx and e_yy taken as the
  // largest second divided differences of e along the grid's rows and columns (each equals e_xx
  // somewhere within its two cells: the estimate holds up to the third derivative of e times
  // the cell, an order smaller again), plus a bound on the kernel's float rounding.
  // Only where the kernel need not test any image bound (*image_tests 0): false otherwise.
  bool FitCubic(int id, int qx, int qy, int xl, int yl, int x_end, int y_end, Vec3d rows[3],
                double t[3], float cubic[2][kCubicTerms], double* fit_error, int* image_tests) {
    *fit_error = std::numeric_limits<double>::infinity();
    constexpr int kGrid = 5, kNodes = kGrid * kGrid;
    // Nodes at quarters of the quad, rounded to pixels: on a 64-pixel tile 0, 16, 32, 47, 63
    // (its last node is the tile's last pixel, 63), of which all but 47 are nodes of the 32- and
    // 16-pixel quads below (their nodes there: 0, 8, 16, 24, 32 and 32, 40, 48, 55, 63).
    int xs[kGrid], ys[kGrid];
    for (int k = 0; k < kGrid; ++k) {
      xs[k] = qx + ((xl - qx) * k + 2) / 4;
      ys[k] = qy + ((yl - qy) * k + 2) / 4;
    }
    const TileBuffers::LensNode* node[kNodes];
    for (int k = 0; k < kNodes; ++k) {
      node[k] = &Node(xs[k % kGrid], ys[k / kGrid]);
      if (!node[k]->valid) return false;
    }
    // Tangent-plane coordinates around the centre node's ray c, as Fit's for wide lenses.
    const Vec3d& c = node[kNodes / 2]->direction;
    const Vec3d helper = std::abs(c.x) < 0.9 ? Vec3d(1.0, 0.0, 0.0) : Vec3d(0.0, 1.0, 0.0);
    const Vec3d e1 = glm::normalize(glm::cross(helper, c));
    const Vec3d e2 = glm::cross(c, e1);
    Vec2d q[kNodes];
    double cos_c = 1.0, cos_angle = 1.0;
    double distance = std::numeric_limits<double>::infinity();
    for (int k = 0; k < kNodes; ++k) {
      const Vec3d& p = node[k]->direction;
      const double w = glm::dot(c, p);
      if (!(w > 0.5)) return false;  // within 60 degrees of c, as Fit
      q[k] = Vec2d(glm::dot(e1, p) / w, glm::dot(e2, p) / w);
      cos_c = std::min(cos_c, w);
      cos_angle = std::min(cos_angle, p.z);
      distance = std::min(distance, node[k]->distance);
    }
    const double q_per_radian = 1.0 / (cos_c * cos_c);
    double scale = 0.0;
    for (int k = 0; k < kNodes; ++k) scale = std::max({scale, std::abs(q[k].x), std::abs(q[k].y)});
    if (!(scale > 0.0)) return false;
    for (int k = 0; k < kNodes; ++k) q[k] /= scale;
    // Least squares, pixels relative to the centre node's.
    const Vec2d origin = node[kNodes / 2]->pixel;
    double normal[kCubicTerms][kCubicTerms] = {};
    double coefficients[2][kCubicTerms] = {};
    double m[kNodes][kCubicTerms];
    for (int k = 0; k < kNodes; ++k) {
      CubicMonomials(q[k].x, q[k].y, m[k]);
      const Vec2d pixel = node[k]->pixel - origin;
      for (int i = 0; i < kCubicTerms; ++i) {
        for (int j = i; j < kCubicTerms; ++j) normal[i][j] += m[k][i] * m[k][j];
        coefficients[0][i] += m[k][i] * pixel.x;
        coefficients[1][i] += m[k][i] * pixel.y;
      }
    }
    if (!SolveCubicNormalEquations(normal, coefficients)) return false;
    coefficients[0][0] += origin.x;
    coefficients[1][0] += origin.y;
    // The error at the nodes, and the largest gradient there (pixels per unit q / scale).
    Vec2d e[kNodes];
    double error2 = 0.0, gradient2 = 0.0;
    for (int k = 0; k < kNodes; ++k) {
      double u = 0.0, v = 0.0;
      for (int i = 0; i < kCubicTerms; ++i) {
        u += coefficients[0][i] * m[k][i];
        v += coefficients[1][i] * m[k][i];
      }
      e[k] = Vec2d(u, v) - node[k]->pixel;
      error2 = std::max(error2, glm::dot(e[k], e[k]));
      const double x = q[k].x, y = q[k].y;
      double gradient = 0.0;
      for (const double* a : {coefficients[0], coefficients[1]}) {
        const double dx = a[1] + 2.0 * a[3] * x + a[4] * y + 3.0 * a[6] * x * x +
                          2.0 * a[7] * x * y + a[8] * y * y;
        const double dy = a[2] + a[4] * x + 2.0 * a[5] * y + a[7] * x * x +
                          2.0 * a[8] * x * y + 3.0 * a[9] * y * y;
        gradient += dx * dx + dy * dy;
      }
      gradient2 = std::max(gradient2, gradient);
    }
    // Between the nodes (see above): second divided differences along rows (x) and columns (y),
    // per component, in pixels per output pixel squared.
    Vec2d exx(0.0), eyy(0.0);
    double hx = 0.0, hy = 0.0;
    for (int k = 0; k + 1 < kGrid; ++k) {
      hx = std::max(hx, static_cast<double>(xs[k + 1] - xs[k]));
      hy = std::max(hy, static_cast<double>(ys[k + 1] - ys[k]));
    }
    for (int a = 0; a < kGrid; ++a) {
      for (int k = 1; k + 1 < kGrid; ++k) {
        const double left = xs[k] - xs[k - 1], right = xs[k + 1] - xs[k];
        const double below = ys[k] - ys[k - 1], above = ys[k + 1] - ys[k];
        const Vec2d along_x =
            2.0 * ((e[a * kGrid + k + 1] - e[a * kGrid + k]) / right -
                   (e[a * kGrid + k] - e[a * kGrid + k - 1]) / left) / (left + right);
        const Vec2d along_y =
            2.0 * ((e[(k + 1) * kGrid + a] - e[k * kGrid + a]) / above -
                   (e[k * kGrid + a] - e[(k - 1) * kGrid + a]) / below) / (below + above);
        exx = glm::max(exx, glm::abs(along_x));
        eyy = glm::max(eyy, glm::abs(along_y));
      }
    }
    // (E1, E2, W) = diag(1 / scale, 1 / scale, 1) (e1, e2, c)^T (R p + offset): q / scale =
    // (E1, E2) / W, the kernel's (U, V) / Z.
    const Vec3d in_cam_rows[3] = {e1 / scale, e2 / scale, c};
    const Mat3d cam_from_world_t = glm::transpose(view.rotation);
    for (int r = 0; r < 3; ++r) {
      rows[r] = cam_from_world_t * in_cam_rows[r];
      t[r] = glm::dot(in_cam_rows[r], view.offset);
    }
    // Float rounding, outside the double-precision estimate (eps = 2^-24). The kernel forms
    // (U, V, Z) from float points (|p| <= extent per axis) by three multiply-adds each: U
    // within 3 eps (|rows[0]| . extent + |t[0]|), and so V and Z; with Z >= cos_c distance and
    // |q / scale| <= about 1 (the nodes' hull), q / scale = U / Z (one more rounding) within
    // dq, which moves the pixel by dq times the gradient. It then evaluates the cubic in float:
    // the constant, the absolute pixel position, rounds by eps |c0|, every other coefficient by
    // eps |c_i| (|monomial| <= 1), and each of the 10 multiply-adds (Cubic in the kernel) by eps
    // times its result, at most |c0| + sum |c_i|: within eps (3 |c0| + 12 sum |c_i|) per
    // component. About 3e-4 px on the lens benchmark (1024-pixel frames from 20 m; the cubic's
    // residual there is as much again), some 8x that at 8192-pixel frames: a small share of
    // the default 0.02.
    constexpr double kEps = 0x1.0p-24;
    double size[3];
    for (int r = 0; r < 3; ++r) {
      size[r] = std::abs(rows[r].x) * extent.x + std::abs(rows[r].y) * extent.y +
                std::abs(rows[r].z) * extent.z + std::abs(t[r]);
    }
    const double z_min = cos_c * distance;
    const double dq = kEps * (3.0 * std::max(size[0], size[1]) + 3.0 * size[2] + z_min) / z_min;
    Vec2d rounding(0.0);
    for (int r = 0; r < 2; ++r) {
      double sum = 0.0;
      for (int i = 1; i < kCubicTerms; ++i) sum += std::abs(coefficients[r][i]);
      rounding[r] = kEps * (3.0 * (std::abs(coefficients[r][0]) + 0.5) + 12.0 * sum);
    }
    const double float_error = glm::length(rounding) + dq * std::sqrt(gradient2);
    double error =
        std::sqrt(error2) + glm::length(hx * hx * exx + hy * hy * eyy) / 8.0 + float_error;
    *fit_error = error;  // the nodes' error: what the children's is predicted from
    // A relief: the map validated over the turned rays where needed (TurnedError), and the
    // image bounds taken from their pixels too.
    const double deviation = Deviation(id, qx, qy, xl, yl, x_end, y_end);
    if (!(deviation < 0.5 * distance)) return false;
    const double turn = deviation / (distance - deviation);
    TileBuffers::LensNode turned[kTurnedNodes];
    const TileBuffers::LensNode* hull[kNodes + kTurnedNodes];
    std::copy(node, node + kNodes, hull);
    int hull_nodes = kNodes;
    // Where the turn charged at the map's gradient (Accept's bound without turn_covered) keeps
    // the tolerance, as on a plane, nothing more is projected.
    const double gradient = std::sqrt(gradient2) / scale;
    const bool charged = error + 2.25 * q_per_radian * gradient * turn <= s.lens_tolerance;
    if (turn > 0.0 && !charged && error <= s.lens_tolerance) {
      // Within |q / scale| <= 1.25: the float rounding above took monomials <= 1, now <= 2.
      const auto cubic_at = [&](const Vec2d& g) {
        double mono[kCubicTerms];
        CubicMonomials(g.x, g.y, mono);
        Vec2d pixel(0.0);
        for (int i = 0; i < kCubicTerms; ++i) {
          pixel += Vec2d(coefficients[0][i], coefficients[1][i]) * mono[i];
        }
        return pixel;
      };
      const double turned_error = TurnedError(q, kNodes, scale, c, e1, e2, deviation,
                                              distance * cos_c, 1.25, cubic_at, turned) +
                                  2.0 * float_error;
      if (!(turned_error <= s.lens_tolerance)) return false;  // NaN too
      error = std::max(error, turned_error);
      for (int k = 0; k < kTurnedNodes; ++k) hull[hull_nodes++] = &turned[k];
    }
    if (!Accept(id, qx, qy, xl, yl, x_end, y_end, hull, hull_nodes, error, gradient,
                q_per_radian, distance, cos_c, cos_angle, image_tests,
                /*turn_covered=*/hull_nodes > kNodes) ||
        *image_tests != 0) {
      return false;
    }
    for (int r = 0; r < 2; ++r) {
      for (int i = 0; i < kCubicTerms; ++i) cubic[r][i] = static_cast<float>(coefficients[r][i]);
      cubic[r][0] = static_cast<float>(coefficients[r][0] - 0.5);  // PointKernelArgs::cubic
    }
    return true;
  }

  // `parent_error`: the parent quad's fit error at its nodes (infinity if unknown). A smooth
  // map's affine fit error scales with the square of the quad's side, a cubic's with the fourth
  // power: a quad whose predicted error (a quarter of its parent's for an affine fit, a
  // sixteenth for a cubic) is above twice the tolerance is split without a fit. Not
  // for radial-tangential lenses: their homography takes up most of the second-order terms, so
  // a parent far outside the tolerance says little about its children (on the lens benchmark
  // nearly every 32-pixel quad passes below a 64-pixel tile that missed by 8x and more).
  void Quad(int level, int qx, int qy, double parent_error) {
    const int side = kTileWidth >> level;
    if (qx >= tile_width || qy >= tile_height) return;
    const int x_end = std::min(qx + side, tile_width), y_end = std::min(qy + side, tile_height);
    // The fit's nodes: the quad's first pixels and the next quad's (clamped into the tile), so
    // that a quad's children share its nodes.
    const int xl = std::min(qx + side, tile_width - 1), yl = std::min(qy + side, tile_height - 1);
    const int id = kLensQuadOffset[level] + (qy / side) * (kTileWidth / side) + qx / side;
    Vec3d rows[3];
    double t[3];
    double error = std::numeric_limits<double>::infinity();
    int image_tests = 0x1f;
    // Wide lenses take the cubic map on the upper levels (FitCubic), whose error falls with the
    // fourth power of the side (a sixteenth of the parent's for a child).
    const bool cubic = !view.lens->traits().perspective && level < kCubicLevels;
    const double predicted = cubic ? parent_error / 16.0 : 0.25 * parent_error;
    const bool hopeless = !view.lens->traits().perspective && std::isfinite(parent_error) &&
                          predicted > 2.0 * s.lens_tolerance && level + 1 < kLensQuadLevels;
    if (hopeless) error = predicted;
    float cubic_map[2][kCubicTerms];
    const int fewest = cubic ? 8 : 2;  // the 5 x 5 grid's nodes at least 2 pixels apart
    if (!hopeless && xl - qx >= fewest && yl - qy >= fewest &&
        (cubic ? FitCubic(id, qx, qy, xl, yl, x_end, y_end, rows, t, cubic_map, &error,
                          &image_tests)
               : Fit(id, qx, qy, xl, yl, x_end, y_end, rows, t, &error, &image_tests))) {
      internal::PointKernelArgs args = KernelArgsFor(s, view, rows, t, extent, grazing);
      ++b.counts.fitted_quads[level];
      args.variance = variance;
      args.image_tests = image_tests;
      if (cubic) {
        args.cubic_map = true;
        std::copy(&cubic_map[0][0], &cubic_map[0][0] + 2 * kCubicTerms, &args.cubic[0][0]);
      }
      const int origin = qy * stride + qx;
      internal::PointTileArrays arrays{b.x.data() + origin, b.y.data() + origin,
                                       b.z.data() + origin, b.valid.data() + origin, 0};
      arrays.rows = y_end - qy;
      arrays.row_length = (x_end - qx + 7) / 8 * 8;
      arrays.row_stride = stride;
      const ExactContext context{&s, &view, b.focal.data() + origin};
      args.exact = &ExactAdmitLane;
      args.exact_context = &context;
      args.prefetch = prefetch + prefetched;
      // A slice per 16 x 16 pixels.
      args.prefetch_count =
          std::min(prefetch_slice * std::max(1, (side / 16) * (side / 16)),
                   prefetch_count - prefetched);
      prefetched += args.prefetch_count;
      if (view.kernel(*view.image, arrays, args, b.sum.data() + origin,
                      variance ? b.sum_squares.data() + origin : nullptr, b.count.data() + origin)) {
        any = true;
      }
      return;
    }
    if (level + 1 < kLensQuadLevels) {
      const int half = side / 2;
      // A cubic's error does not predict an affine fit's.
      const double passed =
          cubic && level + 1 >= kCubicLevels ? std::numeric_limits<double>::infinity() : error;
      for (int k = 0; k < 4; ++k) Quad(level + 1, qx + (k % 2) * half, qy + (k / 2) * half, passed);
      return;
    }
    ++b.counts.exact_quads;
    for (int ty = qy; ty < y_end; ++ty) {
      for (int tx = qx; tx < x_end; ++tx) exact(ty * stride + tx);
    }
  }
};

void RenderPointTile(const Setup& s, const FocalPoints& points, bool variance, int x0, int y0,
                     int x1, int y1, TileBuffers& b, IntegralResult& out) {
  const int tile_width = x1 - x0;
  // Rows padded to a multiple of 8 points (the padding lanes invalid), so that every rectangle
  // of the tile starting at a multiple of 8 is whole groups of the kernel (the lens route).
  const int stride = (tile_width + 7) / 8 * 8;
  const int size = stride * (y1 - y0);
  const int padded = size;
  const int channels = s.channels;
  b.x.assign(static_cast<size_t>(padded), 0.0f);
  b.y.assign(static_cast<size_t>(padded), 0.0f);
  b.z.assign(static_cast<size_t>(padded), 0.0f);
  b.valid.assign(static_cast<size_t>(padded), 0);
  b.focal.resize(static_cast<size_t>(size));
  const double inf = std::numeric_limits<double>::infinity();
  Box box{Vec3d(inf), Vec3d(-inf)};
  Vec3d extent(0.0);
  bool any = false;
  // Rows and columns as loops (an index's j / stride and j % stride were integer divisions per
  // point, several per pixel of the render).
  for (int ty = 0; ty < y1 - y0; ++ty) {
    const Vec3d* row = points.points.data() + static_cast<size_t>(y0 + ty) * s.width + x0;
    for (int tx = 0; tx < tile_width; ++tx) {
      const Vec3d& point = row[tx];
      if (!std::isfinite(point.x) || !std::isfinite(point.y) || !std::isfinite(point.z)) continue;
      const size_t j = static_cast<size_t>(ty) * stride + tx;
      const Vec3d focal = point + s.shift;
      b.focal[j] = focal;
      b.x[j] = static_cast<float>(focal.x);
      b.y[j] = static_cast<float>(focal.y);
      b.z[j] = static_cast<float>(focal.z);
      b.valid[j] = -1;
      box.lo = glm::min(box.lo, focal);
      box.hi = glm::max(box.hi, focal);
      extent = glm::max(extent, glm::abs(focal));
      any = true;
    }
  }
  if (!any) return;  // the outputs stay 0
  b.sum.assign(static_cast<size_t>(padded) * channels, 0.0);
  if (variance) b.sum_squares.assign(static_cast<size_t>(padded) * channels, 0.0);
  b.count.assign(static_cast<size_t>(padded), 0);
  b.value.resize(static_cast<size_t>(channels));
  if (s.lens_tolerance > 0.0) {
    b.node_stamp.assign(static_cast<size_t>(size), 0);
    b.nodes.resize(static_cast<size_t>(size));
    b.generation = 0;
    b.deviation.assign(kLensQuadCount, -1.0);
    b.counts = internal::LensRouteCounts{};
  }
  if (s.nearest) {
    b.best.assign(static_cast<size_t>(size), inf);
    b.chosen.assign(static_cast<size_t>(size), -1);
  }
  const bool float_points = std::max({extent.x, extent.y, extent.z}) < kFloatRange &&
                            (!s.finite_aperture || s.r2 < kFloatRange * kFloatRange);
  const internal::PointTileArrays arrays{b.x.data(), b.y.data(), b.z.data(), b.valid.data(),
                                         padded};
  // The tile's outline: its valid points on the border, every 16 pixels, and the last ones
  // (about 16 points; each is projected into every view the culls leave). Lens views take every
  // 32 pixels (corners and edge midpoints, 8 points): their exact projections are dearer, and
  // every view is projected (no cull).
  b.outline.clear();
  b.lens_outline.clear();
  const int tile_height = y1 - y0;
  for (int ty = 0; ty < tile_height; ++ty) {
    if (!(ty % 16 == 0 || ty == tile_height - 1)) continue;
    const bool border_row = ty == 0 || ty == tile_height - 1;
    for (int tx = 0; tx < tile_width; ++tx) {
      const bool on_border = border_row || tx == 0 || tx == tile_width - 1;
      const bool sampled = tx % 16 == 0 || tx == tile_width - 1;
      const size_t j = static_cast<size_t>(ty) * stride + tx;
      if (!(on_border && sampled && b.valid[j] != 0)) continue;
      b.outline.push_back(b.focal[j]);
      if ((tx % 32 == 0 || tx == tile_width - 1) && (ty % 32 == 0 || ty == tile_height - 1)) {
        b.lens_outline.push_back(b.focal[j]);
      }
    }
  }
  if (b.outline.empty()) {
    for (int k = 0; k < 8; ++k) b.outline.push_back(box.Corner(k));
  }
  if (b.lens_outline.empty()) b.lens_outline = b.outline;
  b.views.clear();
  b.image_tests.clear();
  b.footprints.clear();
  for (size_t i = 0; i < s.views.size(); ++i) {
    const ViewSetup& view = s.views[i];
    int image_tests = 0x1f;
    if (view.lens == nullptr && OutsideImage(view, box, &image_tests)) continue;
    if (OutsideAperture(s, view, box)) continue;
    b.views.push_back(static_cast<int>(i));
    b.image_tests.push_back(static_cast<uint8_t>(image_tests));
    b.footprints.push_back(view.lens == nullptr ? FootprintOf(view, b.outline)
                                                : LensFootprintOf(view, b.lens_outline));
  }
  b.lines.resize(kMaxPrefetch);
  if (!b.views.empty()) {
    const int count =
        FootprintLines(*s.views[static_cast<size_t>(b.views[0])].image, b.footprints[0], b.lines.data());
    for (int k = 0; k < count; ++k) __builtin_prefetch(b.lines[static_cast<size_t>(k)], 0, 3);
  }
  for (size_t k = 0; k < b.views.size(); ++k) {
    const size_t i = static_cast<size_t>(b.views[k]);
    const ViewSetup& view = s.views[i];
    // The next view's lines, prefetched while this one runs.
    const int prefetch_count =
        k + 1 < b.views.size()
            ? FootprintLines(*s.views[static_cast<size_t>(b.views[k + 1])].image,
                             b.footprints[k + 1], b.lines.data())
            : 0;
    if (view.lens == nullptr && view.kernel != nullptr && float_points && !s.nearest &&
        glm::length(view.b) < kFloatRange) {
      internal::PointKernelArgs args = KernelArgs(s, view, extent, !NeverGrazing(s, view, box));
      args.variance = variance;
      args.image_tests = b.image_tests[k];
      args.prefetch = b.lines.data();
      args.prefetch_count = prefetch_count;
      const ExactContext context{&s, &view, b.focal.data()};
      args.exact = &ExactAdmitLane;
      args.exact_context = &context;
      if (view.kernel(*view.image, arrays, args, b.sum.data(), b.sum_squares.data(),
                      b.count.data())) {
        b.used[i] = 1;
      }
      continue;
    }
    // Exact per-point route: AdmitSample and the double sampler, in view order per pixel as
    // the reference.
    const auto exact = [&](int j) {
      if (b.valid[static_cast<size_t>(j)] == 0) return;
      double u, v, distance2 = inf;
      if (!AdmitSample(s, view, b.focal[static_cast<size_t>(j)], &u, &v, &distance2)) return;
      double* sum = b.sum.data() + static_cast<size_t>(j) * channels;
      if (s.nearest) {
        if (!(distance2 < b.best[static_cast<size_t>(j)])) return;
        b.best[static_cast<size_t>(j)] = distance2;
        b.chosen[static_cast<size_t>(j)] = static_cast<int32_t>(i);
        view.sample(*view.image, u, v, sum);
        b.count[static_cast<size_t>(j)] = 1;
        return;
      }
      view.sample(*view.image, u, v, b.value.data());
      for (int c = 0; c < channels; ++c) sum[c] += b.value[static_cast<size_t>(c)];
      if (variance) {
        double* squares = b.sum_squares.data() + static_cast<size_t>(j) * channels;
        for (int c = 0; c < channels; ++c) {
          squares[c] += b.value[static_cast<size_t>(c)] * b.value[static_cast<size_t>(c)];
        }
      }
      ++b.count[static_cast<size_t>(j)];
      b.used[i] = 1;
    };
    if (view.lens != nullptr && view.kernel != nullptr && float_points && !s.nearest &&
        s.lens_tolerance > 0.0 && glm::length(view.b) < kFloatRange) {
      // Lens views: local maps per quad, within the tolerance of the exact projection.
      ++b.generation;
      // The next view's lines go out with the quads' kernel calls (about 16 of them at the
      // default tolerance), the rest at the end.
      LensRoute<decltype(exact)> route{s, view, b, stride, tile_width, tile_height, extent,
                                       variance, !NeverGrazing(s, view, box), exact,
                                       b.lines.data(), prefetch_count, (prefetch_count + 15) / 16};
      route.Quad(0, 0, 0, std::numeric_limits<double>::infinity());
      for (int line = route.prefetched; line < prefetch_count; ++line) {
        __builtin_prefetch(b.lines[static_cast<size_t>(line)], 0, 3);
      }
      if (route.any) b.used[i] = 1;
      continue;
    }
    for (int line = 0; line < prefetch_count; ++line) {
      __builtin_prefetch(b.lines[static_cast<size_t>(line)], 0, 3);
    }
    for (int j = 0; j < size; ++j) exact(j);
  }
  if (s.lens_tolerance > 0.0) {
    for (int level = 0; level < 4; ++level) {
      g_fitted_quads[level].fetch_add(b.counts.fitted_quads[level], std::memory_order_relaxed);
    }
    g_exact_quads.fetch_add(b.counts.exact_quads, std::memory_order_relaxed);
    g_projected_nodes.fetch_add(b.counts.projected_nodes, std::memory_order_relaxed);
  }
  for (int ty = 0; ty < tile_height; ++ty) {
    const int y = y0 + ty;
    uint32_t* count_row = out.count.At<uint32_t>(x0, y);
    float* image_row = out.image.At<float>(x0, y);
    for (int tx = 0; tx < tile_width; ++tx) {
      const size_t j = static_cast<size_t>(ty) * stride + tx;
      if (s.nearest && b.chosen[j] >= 0) b.used[static_cast<size_t>(b.chosen[j])] = 1;
      const uint32_t n = b.count[j];
      count_row[tx] = n;
      if (n == 0) continue;
      const double* sum = b.sum.data() + j * channels;
      if (variance && n >= 2 && !s.nearest) {
        // Population variance, mean over channels (integral.h), as the reference.
        const double* squares = b.sum_squares.data() + j * channels;
        double total = 0.0;
        if (s.masked) {
          // The valid samples' variance (masked_mean.h), the weight channel's squares left out.
          double value_squares = 0.0;
          for (int c = 0; c + 1 < channels; ++c) value_squares += squares[c];
          total = internal::MaskedVariance(sum, value_squares, channels, s.range) * channels;
        } else {
          for (int c = 0; c < channels; ++c) {
            const double mean = sum[c] / static_cast<double>(n);
            total += std::max(0.0, squares[c] / static_cast<double>(n) - mean * mean);
          }
        }
        out.variance.At<float>(x0 + tx, y)[0] = static_cast<float>(total / channels);
      }
      float* pixel = image_row + static_cast<size_t>(tx) * channels;
      for (int c = 0; c < channels; ++c) pixel[c] = static_cast<float>(sum[c] / static_cast<double>(n));
    }
  }
}

// The plain mean, tile by tile (see the top of this file).
SurfaceIntegralResult RenderTiled(const Setup& s, const FocalPoints& points,
                                  const PointIntegralOptions& options, ProgressSink* progress) {
  SurfaceIntegralResult result;
  IntegralResult& out = result.integral;
  out.image = Image(s.width, s.height, s.channels, PixelType::kF32);
  out.count = Image(s.width, s.height, 1, PixelType::kU32);
  out.views_selected = static_cast<int>(s.views.size());
  if (options.variance) out.variance = Image(s.width, s.height, 1, PixelType::kF32);
  const int tiles_x = (s.width + kTileWidth - 1) / kTileWidth;
  const int tiles_y = (s.height + kTileHeight - 1) / kTileHeight;
  const int64_t tiles = static_cast<int64_t>(tiles_x) * tiles_y;

  const int threads = ResolveThreadCount(options.num_threads);
  ProgressStart(progress, "render on surface", tiles);
  std::vector<TileBuffers> buffers(static_cast<size_t>(threads));  // one per thread
  ParallelForPerThread(tiles, threads, progress, [&](int64_t t, int thread) {
    TileBuffers& mine = buffers[static_cast<size_t>(thread)];
    if (mine.used.empty()) mine.used.assign(s.views.size(), 0);
    const int x0 = static_cast<int>(t % tiles_x) * kTileWidth;
    const int y0 = static_cast<int>(t / tiles_x) * kTileHeight;
    RenderPointTile(s, points, options.variance, x0, y0, std::min(s.width, x0 + kTileWidth),
                    std::min(s.height, y0 + kTileHeight), mine, out);
  });
  std::vector<uint8_t> view_used(s.views.size(), 0);
  for (const TileBuffers& mine : buffers) {
    for (size_t i = 0; i < mine.used.size(); ++i) view_used[i] |= mine.used[i];
  }
  FinishStatistics(s, view_used, result);
  return result;
}


// The robust mean (and any render with a masked light field's per-sample division), tile by
// tile: the reference's per-pixel work on the same samples, gathered views outer. Per tile of
// kRobustTile x kRobustTile pixels the views are culled by the bounding box of its focal points
// (OutsideImage for pinhole views, OutsideAperture: conservative, so only views that admit no
// point of the tile are skipped), and each remaining view's admitted samples (AdmitSample and
// the double sampler, as the reference, or for a pinhole view of one channel the exact AVX2
// gather, internal::ExactGather: the same tests and sample, 4 points at a time, about twice as
// fast on F0) are appended to their pixels' lists in ascending view order: every pixel gets the reference's samples in the reference's order, and FinishPixel
// makes the same arithmetic of them, so the outputs equal the reference's bit for bit. A view's
// samples for one tile lie in a small patch of its image (the reference, pixel outer, walks
// every view's image for every pixel). Not for nearest mode (aperture 0: one sample a pixel).
constexpr int kRobustTile = 16;

SurfaceIntegralResult RenderSampleListsTiled(const LightField& light_field, const Setup& s,
                                             const FocalPoints& points,
                                             const PointIntegralOptions& options,
                                             const SurfaceIntegralOptions& surface,
                                             ProgressSink* progress) {
  const bool masked = light_field.masked;
  if (masked && s.channels < 2) {
    ThrowInvalid("masked light field: the views have 1 channel; a masked view has its values "
                 "and a weight channel");
  }
  const int channels = s.channels - (masked ? 1 : 0);
  SurfaceIntegralResult result = MakeOutputs(s, channels, surface.robust, options.variance);
  const int tiles_x = (s.width + kRobustTile - 1) / kRobustTile;
  const int tiles_y = (s.height + kRobustTile - 1) / kRobustTile;
  const int64_t tiles = static_cast<int64_t>(tiles_x) * tiles_y;
  const int threads = ResolveThreadCount(options.num_threads);
  ProgressStart(progress, "render on surface", tiles);
  // Per-thread scratch: the tile's sample lists and the views it used.
  struct Scratch {
    std::vector<uint8_t> used;
    std::vector<std::vector<double>> samples, luminance;
    std::vector<double> sorted, value;
    std::vector<int32_t> histogram;
    std::vector<Vec3d> focal;
    std::vector<uint8_t> valid;
    std::vector<double> x, y, z, gathered;  // the exact gather's points and samples
    std::vector<uint8_t> admitted;
    int64_t fallback = 0;
  };
  constexpr int kPixels = kRobustTile * kRobustTile;
  std::vector<Scratch> scratch(static_cast<size_t>(threads));
  ParallelForPerThread(tiles, threads, progress, [&](int64_t t, int thread) {
    Scratch& mine = scratch[static_cast<size_t>(thread)];
    if (mine.used.empty()) {
      mine.used.assign(s.views.size(), 0);
      mine.samples.resize(kPixels);
      mine.luminance.resize(kPixels);
      mine.value.resize(static_cast<size_t>(s.channels));
      mine.focal.resize(kPixels);
      mine.valid.resize(kPixels);
      for (std::vector<double>* array : {&mine.x, &mine.y, &mine.z, &mine.gathered}) {
        array->resize(kPixels);
      }
      mine.admitted.resize(kPixels);
    }
    const int x0 = static_cast<int>(t % tiles_x) * kRobustTile;
    const int y0 = static_cast<int>(t / tiles_x) * kRobustTile;
    const int x1 = std::min(s.width, x0 + kRobustTile), y1 = std::min(s.height, y0 + kRobustTile);
    const int tile_width = x1 - x0, size = tile_width * (y1 - y0);
    const double inf = std::numeric_limits<double>::infinity();
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const int padded = (size + 3) / 4 * 4;
    for (int j = size; j < padded; ++j) {
      mine.x[static_cast<size_t>(j)] = mine.y[static_cast<size_t>(j)] =
          mine.z[static_cast<size_t>(j)] = nan;
    }
    Box box{Vec3d(inf), Vec3d(-inf)};
    bool any = false;
    for (int j = 0; j < size; ++j) {
      mine.samples[static_cast<size_t>(j)].clear();
      mine.luminance[static_cast<size_t>(j)].clear();
      const Vec3d& point =
          points.points[static_cast<size_t>(y0 + j / tile_width) * s.width + x0 + j % tile_width];
      mine.valid[static_cast<size_t>(j)] =
          std::isfinite(point.x) && std::isfinite(point.y) && std::isfinite(point.z);
      // The exact gather's arrays: NaN (admitted by no view) where there is no point.
      mine.x[static_cast<size_t>(j)] = mine.y[static_cast<size_t>(j)] =
          mine.z[static_cast<size_t>(j)] = nan;
      if (!mine.valid[static_cast<size_t>(j)]) continue;
      mine.focal[static_cast<size_t>(j)] = point + s.shift;
      mine.x[static_cast<size_t>(j)] = mine.focal[static_cast<size_t>(j)].x;
      mine.y[static_cast<size_t>(j)] = mine.focal[static_cast<size_t>(j)].y;
      mine.z[static_cast<size_t>(j)] = mine.focal[static_cast<size_t>(j)].z;
      box.lo = glm::min(box.lo, mine.focal[static_cast<size_t>(j)]);
      box.hi = glm::max(box.hi, mine.focal[static_cast<size_t>(j)]);
      any = true;
    }
    for (size_t i = 0; any && i < s.views.size(); ++i) {
      const ViewSetup& view = s.views[i];
      int image_tests = 0;
      if (view.lens == nullptr && OutsideImage(view, box, &image_tests)) continue;
      if (OutsideAperture(s, view, box)) continue;
      if (view.exact_gather != nullptr && !masked) {
        // Pinhole, one channel: the reference's tests and sampler, 4 points at a time.
        if (!view.exact_gather(*view.image, mine.x.data(), mine.y.data(), mine.z.data(),
                               padded, view.exact, mine.admitted.data(), mine.gathered.data())) {
          continue;
        }
        for (int j = 0; j < size; ++j) {
          if (!mine.admitted[static_cast<size_t>(j)]) continue;
          if (AddValues(s, channels, masked, &mine.gathered[static_cast<size_t>(j)],
                        mine.samples[static_cast<size_t>(j)],
                        mine.luminance[static_cast<size_t>(j)])) {
            mine.used[i] = 1;
          }
        }
        continue;
      }
      for (int j = 0; j < size; ++j) {
        if (!mine.valid[static_cast<size_t>(j)]) continue;
        double u, v, distance2 = inf;
        if (!AdmitSample(s, view, mine.focal[static_cast<size_t>(j)], &u, &v, &distance2)) continue;
        if (AddSample(s, view, u, v, channels, masked, mine.value.data(),
                      mine.samples[static_cast<size_t>(j)], mine.luminance[static_cast<size_t>(j)])) {
          mine.used[i] = 1;
        }
      }
    }
    for (int j = 0; j < size; ++j) {
      if (!mine.valid[static_cast<size_t>(j)]) continue;
      mine.fallback += FinishPixel(s, surface, options.variance, channels,
                              mine.samples[static_cast<size_t>(j)],
                              mine.luminance[static_cast<size_t>(j)], mine.sorted, &mine.histogram,
                              x0 + j % tile_width,
                              y0 + j / tile_width, result);
    }
  });
  std::vector<uint8_t> view_used(s.views.size(), 0);
  int64_t fallback = 0;
  for (const Scratch& mine : scratch) {
    for (size_t i = 0; i < mine.used.size(); ++i) view_used[i] |= mine.used[i];
    fallback += mine.fallback;
  }
  result.fallback_pixels = fallback;
  FinishStatistics(s, view_used, result);
  return result;
}

}  // namespace

void SurfaceIntegralOptions::Check() const {
  CheckFieldRanges(*this);  // the table's ranges (surface_integral.h)
}

void PointIntegralOptions::Check(int view_count) const {
  CheckFieldRanges(static_cast<const ApertureOptions&>(*this));  // aperture.h's ranges
  for (int i = 0; i < 3; ++i) {
    if (!std::isfinite(lens_center[i]) || !std::isfinite(lens_axis[i]) ||
        !std::isfinite(surface_normal[i])) {
      ThrowInvalid("lens_center/lens_axis/surface_normal: must be finite");
    }
  }
  if (!(glm::length(lens_axis) > 0.0)) ThrowInvalid("lens_axis: must not be zero");
  if (!(glm::length(surface_normal) > 0.0)) ThrowInvalid("surface_normal: must not be zero");
  if (view_count <= 0) ThrowInvalid("view selection is empty: the light field has no views");
  std::vector<uint8_t> seen(static_cast<size_t>(view_count), 0);
  for (int index : view_indices) {
    if (index < 0 || index >= view_count) {
      ThrowInvalid("view_indices: no view " + std::to_string(index) + " (the light field has " +
                   std::to_string(view_count) + " views)");
    }
    if (seen[static_cast<size_t>(index)]++) {
      ThrowInvalid("view_indices: view " + std::to_string(index) + " is listed twice");
    }
  }
}

SurfaceIntegralResult RenderIntegralOnDepth(const LightField& light_field,
                                            const IntegralOptions& options, const Image& depth,
                                            const SurfaceIntegralOptions& surface,
                                            ProgressSink* progress) {
  options.Check(static_cast<int>(light_field.views.size()));
  surface.Check();
  const PinholeCamera camera = VirtualCamera(light_field, options);
  if (depth.empty() || depth.width() != camera.width || depth.height() != camera.height ||
      depth.channels() != 1 || depth.type() != PixelType::kF32) {
    ThrowInvalid("depth: must be a 1-channel float32 image of the virtual camera's size " +
                 std::to_string(camera.width) + "x" + std::to_string(camera.height) + " (got " +
                 (depth.empty() ? std::string("none")
                                : std::to_string(depth.width()) + "x" +
                                      std::to_string(depth.height()) + "x" +
                                      std::to_string(depth.channels())) +
                 ")");
  }
  const Rigid3d cam_from_world = VirtualCamFromWorld(light_field, options);
  const Mat3d world_from_pixel = glm::transpose(cam_from_world.rotation) * glm::inverse(camera.K());
  FocalPoints points;
  points.width = camera.width;
  points.height = camera.height;
  points.reference = cam_from_world.Center();
  points.points.resize(static_cast<size_t>(camera.width) * static_cast<size_t>(camera.height));
  const double nan = std::numeric_limits<double>::quiet_NaN();
#pragma omp parallel for schedule(static) num_threads(ResolveThreadCount(options.num_threads))
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const double z = depth.At<float>(x, y)[0];
      points.points[static_cast<size_t>(y) * camera.width + x] =
          (z > 0.0 && std::isfinite(z)) ? z * (world_from_pixel * Vec3d(x + 0.5, y + 0.5, 1.0))
                                        : Vec3d(nan);
    }
  }
  PointIntegralOptions at_points;
  static_cast<ApertureOptions&>(at_points) = options;  // the aperture, whole
  at_points.aperture = PointIntegralOptions::Aperture::kLensPlane;
  at_points.lens_center = points.reference;
  at_points.lens_axis = Row(cam_from_world.rotation, 2);
  at_points.surface_normal = GrazingNormal(light_field, options);
  at_points.variance = options.variance;
  SurfaceIntegralResult result =
      RenderIntegralAtPoints(light_field, points, at_points, surface, progress);
  result.integral.cam_from_world = cam_from_world;
  if (options.min_view_count > 1 && !result.inliers.empty()) {  // the dropped pixels' too
    for (int y = 0; y < camera.height; ++y) {
      for (int x = 0; x < camera.width; ++x) {
        if (result.integral.count.At<uint32_t>(x, y)[0] <
            static_cast<uint32_t>(options.min_view_count)) {
          result.inliers.At<uint32_t>(x, y)[0] = 0;
        }
      }
    }
  }
  DropThinPixels(options.min_view_count, &result.integral);
  return result;
}


SurfaceIntegralResult RenderIntegralAtPoints(const LightField& light_field,
                                             const FocalPoints& points,
                                             const PointIntegralOptions& options,
                                             const SurfaceIntegralOptions& surface,
                                             ProgressSink* progress) {
  const Setup s = MakeSetup(light_field, points, options, surface);
  if (surface.robust) {
    // Masked light fields are divided per sample there (surface_integral.h). Nearest mode keeps
    // one sample a pixel: the reference loop.
    if (s.nearest) {
      return internal::RenderIntegralAtPointsReference(light_field, points, options, surface,
                                                       progress);
    }
    return RenderSampleListsTiled(light_field, s, points, options, surface, progress);
  }
  SurfaceIntegralResult result = RenderTiled(s, points, options, progress);
  // A masked light field's mean over valid samples (masked_mean.h), for every route here.
  if (light_field.masked) {
    internal::DivideByMaskWeight(result.integral, PixelTypeFullRange(s.views.front().image->type()));
  }
  return result;
}

namespace internal {

LensRouteCounts GetLensRouteCounts() {
  LensRouteCounts counts;
  for (int level = 0; level < 4; ++level) counts.fitted_quads[level] = g_fitted_quads[level].load();
  counts.exact_quads = g_exact_quads.load();
  counts.projected_nodes = g_projected_nodes.load();
  return counts;
}

void ResetLensRouteCounts() {
  for (auto& count : g_fitted_quads) count.store(0);
  g_exact_quads.store(0);
  g_projected_nodes.store(0);
}

}  // namespace internal

}  // namespace aos
