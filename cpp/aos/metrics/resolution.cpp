#include "aos/metrics/resolution.h"

#include <cmath>
#include <vector>

#include "aos/util/error.h"
#include "aos/util/math.h"

namespace aos {

void ResolutionOptions::Check() const {
  if (!(distance_m > 0.0) || !std::isfinite(distance_m)) {
    ThrowInvalid("distance_m: must be a finite number > 0 metres (got " + FormatNumber(distance_m) + ")");
  }
  if (!(pose_error_px >= 0.0) || !std::isfinite(pose_error_px)) {
    ThrowInvalid("pose_error_px: must be >= 0 pixels (got " + FormatNumber(pose_error_px) + ")");
  }
  if (!(pose_error_m >= 0.0) || !std::isfinite(pose_error_m)) {
    ThrowInvalid("pose_error_m: must be >= 0 metres (got " + FormatNumber(pose_error_m) + ")");
  }
  if (!(max_off_axis_deg > 0.0 && max_off_axis_deg < 90.0)) {
    ThrowInvalid("max_off_axis_deg: must be in (0, 90) degrees (got " +
                 FormatNumber(max_off_axis_deg) + ")");
  }
  if (pose_error_px > 0.0 && pose_error_m > 0.0) {
    ThrowInvalid("pose_error_px/pose_error_m: give the pose error in pixels or in metres, not both");
  }
}

ResolutionResult SamplingResolution(const LensCamera& camera, const ResolutionOptions& options) {
  options.Check();
  LensCamera lens = camera;
  lens.Finalize("camera");
  ResolutionResult result;
  const double d = options.distance_m;
  result.eq2_samples_per_m2 = lens.fx * lens.fy / (d * d);
  result.eq2_sample_size_m = 1.0 / std::sqrt(result.eq2_samples_per_m2);

  // Corners of every pixel on the plane z = d (NaN where the corner's ray misses it).
  const int w = lens.width, h = lens.height;
  std::vector<Vec2d> corners(static_cast<size_t>(w + 1) * (h + 1));
  for (int y = 0; y <= h; ++y) {
    for (int x = 0; x <= w; ++x) {
      Vec3d ray;
      Vec2d on_plane(std::nan(""), std::nan(""));
      if (lens.Unproject(Vec2d(x, y), &ray) && ray.z > 0.0) {
        on_plane = Vec2d(ray.x * d / ray.z, ray.y * d / ray.z);
      }
      corners[static_cast<size_t>(y) * (w + 1) + x] = on_plane;
    }
  }
  double area = 0.0;
  int64_t pixels = 0;
  const double min_cos_off_axis = std::cos(DegToRad(options.max_off_axis_deg));
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const Vec2d q[4] = {corners[static_cast<size_t>(y) * (w + 1) + x],
                          corners[static_cast<size_t>(y) * (w + 1) + x + 1],
                          corners[static_cast<size_t>(y + 1) * (w + 1) + x + 1],
                          corners[static_cast<size_t>(y + 1) * (w + 1) + x]};
      bool valid = true;
      for (const Vec2d& c : q) valid = valid && std::isfinite(c.x);
      if (!valid) continue;
      Vec3d centre_ray;
      if (!lens.Unproject(Vec2d(x + 0.5, y + 0.5), &centre_ray) ||
          centre_ray.z < min_cos_off_axis * glm::length(centre_ray)) {
        ++result.pixels_off_axis;
        continue;
      }
      double twice = 0.0;  // shoelace
      for (int k = 0; k < 4; ++k) twice += q[k].x * q[(k + 1) % 4].y - q[(k + 1) % 4].x * q[k].y;
      area += 0.5 * std::abs(twice);
      ++pixels;
    }
  }
  result.pixels_on_plane = pixels;
  result.footprint_m2 = area;
  if (pixels == 0 || !(area > 0.0)) {
    ThrowInvalid("camera: no pixel's footprint within max_off_axis_deg of the axis meets the focal "
                 "plane in front of the camera");
  }
  result.samples_per_m2 = static_cast<double>(pixels) / area;
  result.sample_size_m = 1.0 / std::sqrt(result.samples_per_m2);
  result.pose_error_m =
      options.pose_error_m > 0.0 ? options.pose_error_m : options.pose_error_px * result.sample_size_m;
  result.effective_sample_size_m = EffectiveSampleSize(result.sample_size_m, result.pose_error_m);
  result.effective_samples_per_m2 = 1.0 / (result.effective_sample_size_m * result.effective_sample_size_m);
  return result;
}

}  // namespace aos
