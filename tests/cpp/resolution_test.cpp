// Tests of the sampling-resolution estimates against the AOS paper's figures (Eq. 2, App. A).
#include "aos/metrics/resolution.h"

#include <cmath>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace aos {
namespace {

using ::testing::HasSubstr;

constexpr double kPi = 3.14159265358979323846;

LensCamera Camera(int side, double fov_deg, LensModel model = LensModel::kPinhole) {
  LensCamera camera = LensCamera::FromPinhole(PinholeCamera::FromFov(side, side, fov_deg));
  camera.model = model;
  camera.Finalize("camera");
  return camera;
}

TEST(Resolution, PaperEq2ThreePointFiveMegapixelsAt35Metres) {
  // n = 3.5 MP (1871^2 = 3,500,641 pixels), FOV 80 degrees, h = 35 m: the footprint is
  // (2 h tan 40)^2 = 3450.5 m^2, so n / A = 1014.5 samples/m^2 and p = 3.14 cm.
  ResolutionOptions options;
  options.distance_m = 35.0;
  const ResolutionResult r = SamplingResolution(Camera(1871, 80.0), options);
  const double footprint = std::pow(2.0 * 35.0 * std::tan(40.0 * kPi / 180.0), 2);
  EXPECT_NEAR(r.eq2_samples_per_m2, 1871.0 * 1871.0 / footprint, 1e-6);
  EXPECT_NEAR(r.eq2_samples_per_m2, 1014.0, 1.0);  // the paper's "about 1,014"
  EXPECT_NEAR(r.eq2_sample_size_m, 0.0314, 0.0001);
  // Back-projection of a pinhole covers the same footprint with the same pixels (rounding of
  // the summed quad areas only).
  EXPECT_EQ(r.pixels_on_plane, 1871 * 1871);
  EXPECT_NEAR(r.footprint_m2, footprint, 1e-6 * footprint);
  EXPECT_NEAR(r.samples_per_m2, r.eq2_samples_per_m2, 1e-6 * r.eq2_samples_per_m2);
}

TEST(Resolution, PaperPoseErrorGivesTheEffectiveResolution) {
  // p = 3.18 cm, e = 4.23 cm: p' = p + 2 e = 11.64 cm and 1 / p'^2 = 73.8 samples/m^2 (the
  // paper rounds to 74).
  EXPECT_NEAR(EffectiveSampleSize(0.0318, 0.0423), 0.1164, 1e-12);
  // Through SamplingResolution: a pose error in metres, and the same in pixels.
  ResolutionOptions options;
  options.distance_m = 35.0;
  options.pose_error_m = 0.0423;
  const ResolutionResult metres = SamplingResolution(Camera(1871, 80.0), options);
  EXPECT_NEAR(metres.effective_sample_size_m, metres.sample_size_m + 0.0846, 1e-12);
  EXPECT_NEAR(metres.effective_samples_per_m2,
              1.0 / std::pow(metres.sample_size_m + 0.0846, 2), 1e-9);
  options.pose_error_m = 0.0;
  options.pose_error_px = 0.0423 / metres.sample_size_m;
  const ResolutionResult pixels = SamplingResolution(Camera(1871, 80.0), options);
  EXPECT_NEAR(pixels.pose_error_m, 0.0423, 1e-12);
  EXPECT_NEAR(1.0 / std::pow(0.1164, 2), 73.8, 0.05);
}

TEST(Resolution, AFisheyeCoversMoreGroundPerPixelOffAxis) {
  // Same focal length, equidistant fisheye: off-axis pixels cover more ground than a pinhole's
  // (r = f theta < f tan theta), so the back-projected density is lower than Eq. 2's.
  LensCamera fisheye = Camera(400, 80.0, LensModel::kFisheye);
  ResolutionOptions options;
  options.distance_m = 20.0;
  options.max_off_axis_deg = 89.0;  // every pixel
  const ResolutionResult r = SamplingResolution(fisheye, options);
  EXPECT_EQ(r.pixels_on_plane, 400 * 400);
  EXPECT_EQ(r.pixels_off_axis, 0);
  EXPECT_LT(r.samples_per_m2, 0.9 * r.eq2_samples_per_m2);
  // By default the pixels further than 60 degrees off the axis are left out (their footprints
  // are long slivers); the figure then comes nearer Eq. 2's.
  options.max_off_axis_deg = 60.0;
  const ResolutionResult central = SamplingResolution(fisheye, options);
  EXPECT_GT(central.pixels_off_axis, 0);
  EXPECT_EQ(central.pixels_on_plane + central.pixels_off_axis, 400 * 400);
  EXPECT_GT(central.samples_per_m2, r.samples_per_m2);
}

TEST(Resolution, AFieldOfViewGoesThroughTheLenssRadialMap) {
  // Equidistant fisheye: r = f theta, so a 180-degree field across 1000 pixels has
  // f = 500 / (pi / 2); a pinhole cannot see 180 degrees.
  const LensCamera fisheye =
      LensFromFov(LensModel::kFisheye, 1000, 800, 180.0, {0, 0, 0, 0, 0}, 0.0, "camera");
  EXPECT_NEAR(fisheye.fx, 500.0 / (M_PI / 2.0), 1e-9);
  EXPECT_EQ(fisheye.cx, 500.0);
  const LensCamera pinhole =
      LensFromFov(LensModel::kPinhole, 1000, 800, 90.0, {0, 0, 0, 0, 0}, 0.0, "camera");
  EXPECT_NEAR(pinhole.fx, 500.0, 1e-9);
  try {
    LensFromFov(LensModel::kPinhole, 1000, 800, 180.0, {0, 0, 0, 0, 0}, 0.0, "camera");
    FAIL();
  } catch (const std::invalid_argument& error) {
    EXPECT_THAT(error.what(), testing::HasSubstr("camera.fov_deg: a pinhole lens's field of view"));
  }
}

TEST(Resolution, OptionsAreChecked) {
  ResolutionOptions options;
  options.distance_m = 0.0;
  try {
    SamplingResolution(Camera(10, 60.0), options);
    FAIL();
  } catch (const std::invalid_argument& error) {
    EXPECT_THAT(error.what(), HasSubstr("distance_m"));
  }
  options.distance_m = 10.0;
  options.pose_error_m = 0.1;
  options.pose_error_px = 1.0;
  try {
    SamplingResolution(Camera(10, 60.0), options);
    FAIL();
  } catch (const std::invalid_argument& error) {
    EXPECT_THAT(error.what(), HasSubstr("not both"));
  }
}

}  // namespace
}  // namespace aos
