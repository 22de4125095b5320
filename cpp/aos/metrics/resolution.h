#pragma once
// Spatial sampling resolution of a camera looking straight down at a focal plane (the AOS
// paper's Eq. 2 and Appendix A), and the effective resolution under a pose error.
//
// Contract
// - The camera looks along its +z axis at the plane z = distance_m (camera frame), i.e. a nadir
//   view from distance_m above a horizontal focal plane.
// - Eq. 2 (pinhole): samples per square metre = n / A, n = width x height pixels and A the
//   footprint (2 d tan(fov_x / 2)) (2 d tan(fov_y / 2)) = n d^2 / (fx fy), so n / A = fx fy / d^2;
//   sample size p = 1 / sqrt(n / A). For other lens models this is their pinhole part (fx, fy).
//   Eq. 2's sample size is also the sample size at nadir (the image centre) for every model.
// - Appendix A (any model): every pixel's four corners are unprojected and intersected with the
//   plane; samples per square metre = pixels whose corners all meet the plane / the area their
//   footprints cover, over the pixels whose ray lies within max_off_axis_deg of the camera axis
//   (a wide lens's pixels towards the horizon cover long slivers of ground, tens of metres for a
//   fisheye, which AOS does not integrate usefully; without the limit they dominate the figure).
//   For a pinhole within the limit it equals Eq. 2 (to rounding); off-axis pixels of a fisheye
//   cover more ground, so the estimate falls.
// - Pose error: e in pixels is converted to metres at the plane with the back-projected sample
//   size, e_m = e_px p (or given in metres directly); the effective sample size is p' = p + 2 e
//   and the effective resolution 1 / p'^2 samples per square metre.
//
// Throws std::invalid_argument naming the option.
#include <cstdint>

#include "aos/geometry/lens.h"
#include "aos/util/option_fields.h"

namespace aos {

struct ResolutionOptions {
  // Distance from the camera to the focal plane along its axis, metres (> 0).
  double distance_m = 35.0;
  // Pose error in pixels (>= 0); converted to metres with the back-projected sample size.
  double pose_error_px = 0.0;
  // Pose error in metres at the focal plane (>= 0); give at most one of the two.
  double pose_error_m = 0.0;
  // Pixels whose ray is further than this from the camera axis are left out of the
  // back-projected figure, degrees in (0, 90).
  double max_off_axis_deg = 60.0;

  void Check() const;
  // The field table (util/option_fields.h): every field once, in declaration order.
  template <class Visit>
  static void Fields(Visit&& field) {
    using O = ResolutionOptions;
    field(OptionField("distance_m", &O::distance_m, "m", Range::Any(),
                      "Distance from the camera to the focal plane along its axis, metres (> "
                      "0)."));
    field(OptionField("pose_error_px", &O::pose_error_px, "px", Range::Any(),
                      "Pose error in pixels (>= 0), converted to metres with the sample size."));
    field(OptionField("pose_error_m", &O::pose_error_m, "m", Range::Any(),
                      "Pose error in metres at the focal plane (>= 0); at most one of the "
                      "two."));
    field(OptionField("max_off_axis_deg", &O::max_off_axis_deg, "deg", Range::Any(),
                      "The back-projected figure counts pixels whose ray is within this angle "
                      "of the axis, degrees in (0, 90)."));
  }
};

struct ResolutionResult {
  double eq2_samples_per_m2 = 0.0;  // Eq. 2
  double eq2_sample_size_m = 0.0;
  double samples_per_m2 = 0.0;      // Appendix A, back-projected
  double sample_size_m = 0.0;
  int64_t pixels_on_plane = 0;      // pixels whose footprint was counted
  int64_t pixels_off_axis = 0;      // pixels meeting the plane but beyond max_off_axis_deg
  double footprint_m2 = 0.0;        // the area they cover
  double pose_error_m = 0.0;        // e in metres at the plane
  double effective_sample_size_m = 0.0;   // p' = p + 2 e
  double effective_samples_per_m2 = 0.0;  // 1 / p'^2
};

ResolutionResult SamplingResolution(const LensCamera& camera, const ResolutionOptions& options);

// p' = p + 2 e and 1 / p'^2 (metres, samples per square metre).
inline double EffectiveSampleSize(double sample_size_m, double pose_error_m) {
  return sample_size_m + 2.0 * pose_error_m;
}

}  // namespace aos
