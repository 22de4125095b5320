#include "aos/render/surface_integral.h"

#include <algorithm>
#include <cmath>
#include <exception>
#include <limits>
#include <string>
#include <vector>

#include <omp.h>

#include "aos/util/error.h"
#include "aos/util/math.h"
#include "aos/util/parallel.h"

// How it works
// Unlike a plane, focal points give no homography, so every (pixel, view) pair is projected on
// its own: the focal point relative to a centre C (the lens centre, or the points' reference for
// a cylinder aperture), X, goes into view i as R_i X + R_i (C - C_i), all in double precision (UTM-sized centres cancel before any rounding).
// The admission tests are integral.h's, evaluated per sample. Rows are split among threads; each
// keeps its own sample buffers for the robust mean.

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
  Sampler sample = nullptr;
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

}  // namespace

void SurfaceIntegralOptions::Check() const {
  if (!(agreement > 0.0 && agreement <= 1.0)) {
    ThrowInvalid("agreement: must be in (0, 1] (got " + FormatNumber(agreement) + ")");
  }
  if (!(min_inlier_fraction >= 0.0 && min_inlier_fraction <= 1.0)) {
    ThrowInvalid("min_inlier_fraction: must be in [0, 1] (got " +
                 FormatNumber(min_inlier_fraction) + ")");
  }
}

void PointIntegralOptions::Check(int view_count) const {
  if (!(aperture_radius >= 0.0)) {
    ThrowInvalid("aperture_radius: must be >= 0 metres or infinity (got " +
                 FormatNumber(aperture_radius) + ")");
  }
  if (!(min_view_angle_deg >= 0.0 && min_view_angle_deg < 90.0)) {
    ThrowInvalid("min_view_angle_deg: must be in [0, 90) degrees (got " +
                 FormatNumber(min_view_angle_deg) + ")");
  }
  for (int i = 0; i < 3; ++i) {
    if (!std::isfinite(lens_center[i]) || !std::isfinite(lens_axis[i]) ||
        !std::isfinite(surface_normal[i])) {
      ThrowInvalid("lens_center/lens_axis/surface_normal: must be finite");
    }
  }
  if (!(glm::length(lens_axis) > 0.0)) ThrowInvalid("lens_axis: must not be zero");
  if (!(glm::length(surface_normal) > 0.0)) ThrowInvalid("surface_normal: must not be zero");
  CheckThreadCount(num_threads);
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
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const double z = depth.At<float>(x, y)[0];
      points.points[static_cast<size_t>(y) * camera.width + x] =
          (z > 0.0 && std::isfinite(z)) ? z * (world_from_pixel * Vec3d(x + 0.5, y + 0.5, 1.0))
                                        : Vec3d(nan);
    }
  }
  PointIntegralOptions at_points;
  at_points.aperture = PointIntegralOptions::Aperture::kLensPlane;
  at_points.aperture_radius = options.aperture_radius;
  at_points.lens_center = points.reference;
  at_points.lens_axis = Row(cam_from_world.rotation, 2);
  at_points.surface_normal = options.focal_plane.normal;
  at_points.min_view_angle_deg = options.min_view_angle_deg;
  at_points.view_indices = options.view_indices;
  at_points.num_threads = options.num_threads;
  at_points.variance = options.variance;
  SurfaceIntegralResult result =
      RenderIntegralAtPoints(light_field, points, at_points, surface, progress);
  result.integral.cam_from_world = cam_from_world;
  return result;
}

SurfaceIntegralResult RenderIntegralAtPoints(const LightField& light_field,
                                             const FocalPoints& points,
                                             const PointIntegralOptions& options,
                                             const SurfaceIntegralOptions& surface,
                                             ProgressSink* progress) {
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
  struct Camera { int width, height; } camera{points.width, points.height};
  // Everything below is relative to the lens centre (kLensPlane) or the reference (kCylinder),
  // in double precision.
  const bool cylinder = options.aperture == PointIntegralOptions::Aperture::kCylinder;
  const Vec3d center = cylinder ? points.reference : options.lens_center;
  const Vec3d shift = points.reference - center;  // point relative to `center` = p + shift
  const Vec3d lens_axis = glm::normalize(options.lens_axis);
  const Vec3d normal = glm::normalize(options.surface_normal);
  const double min_angle = DegToRad(options.min_view_angle_deg);
  const double sin2_min = std::sin(min_angle) * std::sin(min_angle);
  const bool nearest = options.aperture_radius == 0.0;
  const bool finite_aperture = std::isfinite(options.aperture_radius) && !nearest;
  const double r2 = options.aperture_radius * options.aperture_radius;

  std::vector<int> selection = options.view_indices;
  if (selection.empty()) {
    selection.resize(light_field.views.size());
    for (size_t i = 0; i < selection.size(); ++i) selection[i] = static_cast<int>(i);
  }
  std::sort(selection.begin(), selection.end());
  std::vector<ViewSetup> views;
  const int channels = light_field.views[static_cast<size_t>(selection.front())].image.channels();
  const double range =
      PixelTypeFullRange(light_field.views[static_cast<size_t>(selection.front())].image.type());
  for (int index : selection) {
    const View& view = light_field.views[static_cast<size_t>(index)];
    CheckView(view, "view " + std::to_string(index) + (view.name.empty() ? "" : " (" + view.name + ")"));
    if (view.image.channels() != channels) {
      ThrowInvalid("view " + std::to_string(index) + ": has " +
                   std::to_string(view.image.channels()) +
                   " channels but the first selected view has " + std::to_string(channels));
    }
    ViewSetup setup;
    setup.image = &view.image;
    setup.rotation = view.cam_from_world.rotation;
    setup.b = view.cam_from_world.Center() - center;
    setup.offset = setup.rotation * (-setup.b);
    setup.lens_b = glm::dot(lens_axis, setup.b);
    setup.fx = view.camera.fx;
    setup.fy = view.camera.fy;
    setup.cx = view.camera.cx;
    setup.cy = view.camera.cy;
    setup.width = view.camera.width;
    setup.height = view.camera.height;
    if (view.camera.model != LensModel::kPinhole) setup.lens = &view.camera;
    setup.sample = SamplerFor(view.image);
    views.push_back(setup);
  }

  SurfaceIntegralResult result;
  IntegralResult& out = result.integral;
  out.image = Image(camera.width, camera.height, channels, PixelType::kF32);
  out.count = Image(camera.width, camera.height, 1, PixelType::kU32);
  out.views_selected = static_cast<int>(views.size());
  if (surface.robust) result.inliers = Image(camera.width, camera.height, 1, PixelType::kU32);
  if (options.variance) out.variance = Image(camera.width, camera.height, 1, PixelType::kF32);

  const int threads = ResolveThreadCount(options.num_threads);
  ProgressStart(progress, "render on surface", camera.height);
  std::vector<uint8_t> view_used(views.size(), 0);
  int64_t fallback = 0;
  bool cancelled = false;
  std::exception_ptr error;
#pragma omp parallel num_threads(threads) reduction(+ : fallback)
  {
    std::vector<uint8_t> used(views.size(), 0);
    std::vector<double> samples, luminance, sorted;
    std::vector<double> value(static_cast<size_t>(channels));
#pragma omp for schedule(dynamic, 4)
    for (int64_t y = 0; y < camera.height; ++y) {
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
        for (int x = 0; x < camera.width; ++x) {
          float* pixel = out.image.At<float>(x, row);
          const Vec3d& point = points.points[static_cast<size_t>(row) * camera.width + x];
          if (!std::isfinite(point.x) || !std::isfinite(point.y) || !std::isfinite(point.z)) continue;
          const Vec3d focal = point + shift;
          samples.clear();
          luminance.clear();
          double best = std::numeric_limits<double>::infinity();
          size_t chosen = views.size();  // nearest mode: the view kept so far
          for (size_t i = 0; i < views.size(); ++i) {
            const ViewSetup& view = views[i];
            const Vec3d in_cam = view.rotation * focal + view.offset;
            double u, v;
            if (view.lens != nullptr) {
              Vec2d pixel;
              if (!view.lens->Project(in_cam, &pixel)) continue;
              u = pixel.x;
              v = pixel.y;
            } else {
              if (!(in_cam.z > 0.0)) continue;
              u = view.fx * in_cam.x / in_cam.z + view.cx;
              v = view.fy * in_cam.y / in_cam.z + view.cy;
            }
            if (!(u >= 0.0 && u <= view.width && v >= 0.0 && v <= view.height)) continue;
            const Vec3d to_view = view.b - focal;
            const double along = glm::dot(normal, to_view);
            if (along * along < sin2_min * glm::dot(to_view, to_view)) continue;
            if (cylinder && (finite_aperture || nearest)) {
              // Distance of C_i from the line through X along the axis.
              const Vec3d across = to_view - glm::dot(to_view, lens_axis) * lens_axis;
              const double distance2 = glm::dot(across, across);
              if (finite_aperture && distance2 > r2) continue;
              if (nearest) {
                if (!(distance2 < best)) continue;
                best = distance2;
                chosen = i;
                samples.clear();
                luminance.clear();
              }
            } else if (finite_aperture || nearest) {
              // The line X + s (C_i - X) meets the lens plane a . (P - C) = 0 at
              // P - C = ((a.b) X - (a.X) b) / ((a.b) - (a.X)), written as integral.cpp does:
              // exactly b for a view on the lens plane, so symmetric views tie exactly.
              const double a_x = glm::dot(lens_axis, focal);
              const double denominator = view.lens_b - a_x;
              if (denominator == 0.0) continue;
              const Vec3d numerator = view.lens_b * focal - a_x * view.b;
              const double distance2 =
                  glm::dot(numerator, numerator) / (denominator * denominator);
              if (finite_aperture && distance2 > r2) continue;
              if (nearest) {
                if (!(distance2 < best)) continue;
                best = distance2;
                chosen = i;
                samples.clear();
                luminance.clear();
              }
            }
            view.sample(*view.image, u, v, value.data());
            double mean = 0.0;
            for (int c = 0; c < channels; ++c) {
              samples.push_back(value[static_cast<size_t>(c)]);
              mean += value[static_cast<size_t>(c)];
            }
            luminance.push_back(mean / channels);
            if (!nearest) used[i] = 1;
          }
          if (chosen < views.size()) used[chosen] = 1;
          const size_t n = luminance.size();
          out.count.At<uint32_t>(x, row)[0] = static_cast<uint32_t>(n);
          if (n == 0) continue;
          // The inlier set: every sample, or those near the median of the luminance.
          size_t kept = n;
          double lower = -std::numeric_limits<double>::infinity();
          double upper = std::numeric_limits<double>::infinity();
          if (surface.robust && n >= 2) {
            // The densest band [v, v + width] over the sorted luminances (two pointers).
            sorted = luminance;
            std::sort(sorted.begin(), sorted.end());
            const double width = 2.0 * surface.agreement * range;
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
              ++fallback;
            }
          }
          if (surface.robust) result.inliers.At<uint32_t>(x, row)[0] = static_cast<uint32_t>(kept);
          if (options.variance && n >= 2 && !nearest) {
            // Population variance of all the samples, mean over channels (integral.h).
            double variance = 0.0;
            for (int c = 0; c < channels; ++c) {
              double sum = 0.0, squares = 0.0;
              for (size_t k = 0; k < n; ++k) {
                const double value = samples[k * channels + static_cast<size_t>(c)];
                sum += value;
                squares += value * value;
              }
              const double mean = sum / static_cast<double>(n);
              variance += std::max(0.0, squares / static_cast<double>(n) - mean * mean);
            }
            out.variance.At<float>(x, row)[0] = static_cast<float>(variance / channels);
          }
          for (int c = 0; c < channels; ++c) {
            double sum = 0.0;
            for (size_t k = 0; k < n; ++k) {
              if (luminance[k] >= lower && luminance[k] <= upper) {
                sum += samples[k * channels + static_cast<size_t>(c)];
              }
            }
            pixel[c] = static_cast<float>(sum / static_cast<double>(kept));
          }
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
  for (uint8_t u : view_used) out.views_used += u;
  for (int y = 0; y < camera.height; ++y) {
    const uint32_t* count = out.count.At<uint32_t>(0, y);
    for (int x = 0; x < camera.width; ++x) {
      out.samples += count[x];
      out.uncovered_pixels += count[x] == 0;
    }
  }
  return result;
}

}  // namespace aos
