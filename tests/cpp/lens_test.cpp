// Tests of the lens models: agreement with OpenCV's projections, project/unproject round trips
// over the whole valid field, and the refusal of non-invertible parameters.
#include "aos/geometry/lens.h"

#include <cmath>
#include <functional>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/ccalib/omnidir.hpp>

#include "aos/util/error.h"

#include "error_of.h"

namespace aos {
namespace {

using ::testing::HasSubstr;

constexpr double kPi = 3.14159265358979323846;

LensCamera Lens(LensModel model, std::array<double, 5> distortion, double xi = 0.0,
                double skew = 0.0, int width = 640, int height = 480, double f = 300.0) {
  LensCamera lens;
  lens.model = model;
  lens.width = width;
  lens.height = height;
  lens.fx = f;
  lens.fy = 1.02 * f;
  lens.cx = 0.5 * width + 3.25;
  lens.cy = 0.5 * height - 2.5;
  lens.skew = skew;
  lens.xi = xi;
  lens.distortion = distortion;
  lens.Finalize("test lens");
  return lens;
}

// OpenCV's intrinsic matrix for `lens` (pixel centres at integers: cx - 0.5).
cv::Matx33d OpenCvK(const LensCamera& lens) {
  return cv::Matx33d(lens.fx, lens.skew, lens.cx - 0.5, 0, lens.fy, lens.cy - 0.5, 0, 0, 1);
}

// Points in the camera frame at angles up to `max_theta` off-axis, all azimuths.
std::vector<Vec3d> Rays(double max_theta, int rings = 40, int per_ring = 36) {
  std::vector<Vec3d> rays{Vec3d(0, 0, 1)};
  for (int i = 1; i <= rings; ++i) {
    const double theta = max_theta * i / rings;
    for (int j = 0; j < per_ring; ++j) {
      const double phi = 2.0 * kPi * (j + 0.37) / per_ring;
      rays.emplace_back(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi),
                        std::cos(theta));
    }
  }
  return rays;
}

TEST(Lens, RadTanProjectsAsOpenCv) {
  const LensCamera lens = Lens(LensModel::kRadTan, {-0.21, 0.05, 0.001, -0.0015, -0.004});
  std::vector<cv::Point3d> points;
  for (const Vec3d& ray : Rays(0.8)) points.emplace_back(2.0 * ray.x, 2.0 * ray.y, 2.0 * ray.z);
  std::vector<cv::Point2d> expected;
  cv::projectPoints(points, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), OpenCvK(lens),
                    std::vector<double>(lens.distortion.begin(), lens.distortion.end()), expected);
  for (size_t i = 0; i < points.size(); ++i) {
    Vec2d pixel;
    ASSERT_TRUE(lens.Project(Vec3d(points[i].x, points[i].y, points[i].z), &pixel));
    // Same formula in double precision: agreement to rounding (1e-9 px at ~1000 px).
    EXPECT_NEAR(pixel.x - 0.5, expected[i].x, 1e-9) << i;
    EXPECT_NEAR(pixel.y - 0.5, expected[i].y, 1e-9) << i;
  }
}

TEST(Lens, FisheyeProjectsAsOpenCv) {
  const LensCamera lens = Lens(LensModel::kFisheye, {0.02, -0.01, 0.002, -0.0003, 0.0});
  // cv::fisheye::projectPoints takes theta = atan(r / z), front hemisphere only: rays up to 85
  // degrees (aos uses atan2, which continues past 90; the round-trip tests go there).
  std::vector<cv::Point3d> points;
  for (const Vec3d& ray : Rays(85.0 * kPi / 180.0)) points.emplace_back(ray.x, ray.y, ray.z);
  std::vector<cv::Point2d> expected;
  cv::fisheye::projectPoints(points, expected, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0),
                             OpenCvK(lens), cv::Vec4d(0.02, -0.01, 0.002, -0.0003));
  for (size_t i = 0; i < points.size(); ++i) {
    Vec2d pixel;
    ASSERT_TRUE(lens.Project(Vec3d(points[i].x, points[i].y, points[i].z), &pixel)) << i;
    EXPECT_NEAR(pixel.x - 0.5, expected[i].x, 1e-7) << i;
    EXPECT_NEAR(pixel.y - 0.5, expected[i].y, 1e-7) << i;
  }
}

TEST(Lens, OmnidirProjectsAsOpenCv) {
  const LensCamera lens = Lens(LensModel::kOmnidir, {-0.25, 0.06, 0.0008, -0.0004, 0.0}, 1.3,
                               0.4, 1280, 960, 400.0);
  std::vector<cv::Point3d> points;
  for (const Vec3d& ray : Rays(95.0 * kPi / 180.0)) points.emplace_back(3.0 * ray.x, 3.0 * ray.y, 3.0 * ray.z);
  cv::Mat expected;
  cv::omnidir::projectPoints(cv::Mat(points), expected, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0),
                             OpenCvK(lens), lens.xi, cv::Vec4d(-0.25, 0.06, 0.0008, -0.0004));
  for (size_t i = 0; i < points.size(); ++i) {
    Vec2d pixel;
    ASSERT_TRUE(lens.Project(Vec3d(points[i].x, points[i].y, points[i].z), &pixel)) << i;
    const cv::Vec2d e = expected.at<cv::Vec2d>(static_cast<int>(i));
    EXPECT_NEAR(pixel.x - 0.5, e[0], 1e-7) << i;
    EXPECT_NEAR(pixel.y - 0.5, e[1], 1e-7) << i;
  }
}

// Unproject then project every pixel (and sub-pixel offsets) of the frame that unprojects;
// project then unproject rays up to the edge of the valid field.
void ExpectRoundTrips(const LensCamera& lens, double max_theta, int* unprojected) {
  *unprojected = 0;
  double worst_pixel = 0.0, worst_angle = 0.0;
  for (int y = 0; y <= lens.height; y += 3) {
    for (int x = 0; x <= lens.width; x += 3) {
      const Vec2d pixel(x + 0.123, y + 0.877);
      Vec3d ray;
      if (!lens.Unproject(pixel, &ray)) continue;
      ++*unprojected;
      ASSERT_NEAR(glm::length(ray), 1.0, 1e-12);
      Vec2d back;
      ASSERT_TRUE(lens.Project(ray, &back)) << x << "," << y;
      worst_pixel = std::max(worst_pixel, glm::length(back - pixel));
    }
  }
  for (const Vec3d& ray : Rays(max_theta)) {
    Vec2d pixel;
    ASSERT_TRUE(lens.Project(ray, &pixel)) << ray.x << "," << ray.y << "," << ray.z;
    Vec3d back;
    ASSERT_TRUE(lens.Unproject(pixel, &back)) << pixel.x << "," << pixel.y;
    worst_angle = std::max(worst_angle, std::acos(std::min(1.0, glm::dot(back, ray))));
  }
  // The bound: round trips below 1e-6 pixels; rays back within 1e-7 rad.
  EXPECT_LT(worst_pixel, 1e-6);
  EXPECT_LT(worst_angle, 1e-7);
}

TEST(Lens, RoundTripsOverTheWholeValidField) {
  int count = 0;
  ExpectRoundTrips(Lens(LensModel::kPinhole, {0, 0, 0, 0, 0}), 0.9, &count);
  EXPECT_GT(count, 10000);
  // A 640x480 thermal camera with radial and tangential distortion.
  ExpectRoundTrips(Lens(LensModel::kRadTan, {-0.21, 0.05, 0.001, -0.0015, -0.004}), 0.8, &count);
  EXPECT_GT(count, 10000);
  ExpectRoundTrips(Lens(LensModel::kFisheye, {0.02, -0.01, 0.002, -0.0003, 0.0}, 0.0, 0.0, 640,
                        480, 150.0),
                   100.0 * kPi / 180.0, &count);
  EXPECT_GT(count, 10000);
}

TEST(Lens, OmnidirectionalLensNear178DegreesAndRaysBeyond90) {
  // xi < 1: the field ends where cos(theta) = -xi; 0.9 gives 154 degrees off-axis at most.
  int count = 0;
  const LensCamera wide = Lens(LensModel::kOmnidir, {-0.1, 0.01, 0.0005, 0.0002, 0.0}, 0.9, 0.0,
                               1024, 1024, 250.0);
  ExpectRoundTrips(wide, 89.0 * kPi / 180.0, &count);  // a 178-degree lens
  EXPECT_GT(count, 10000);
  ExpectRoundTrips(wide, 0.999 * wide.theta_max, &count);
  EXPECT_GT(wide.theta_max, 0.5 * kPi);
  // xi > 1: injective where cos(theta) > -1/xi (120 degrees for xi = 2).
  const LensCamera beyond = Lens(LensModel::kOmnidir, {0, 0, 0, 0, 0}, 2.0, 0.0, 1024, 1024, 300.0);
  EXPECT_NEAR(beyond.theta_max, 2.0 * kPi / 3.0, 1e-12);
  ExpectRoundTrips(beyond, 0.999 * beyond.theta_max, &count);
  Vec2d pixel;
  EXPECT_FALSE(beyond.Project(Vec3d(0, std::sin(2.2), std::cos(2.2)), &pixel));  // 126 degrees
}

TEST(Lens, PixelsOutsideTheImageCircleDoNotUnproject) {
  // A fisheye whose distortion folds at some angle outside the frame: pixels beyond that
  // angle's radius have no ray.
  const LensCamera lens = Lens(LensModel::kFisheye, {-0.05, 0.0, 0.0, 0.0, 0.0}, 0.0, 0.0, 200,
                               200, 40.0);
  ASSERT_LT(lens.theta_max, kPi);
  Vec3d ray;
  EXPECT_TRUE(lens.Unproject(Vec2d(lens.cx, lens.cy), &ray));
  EXPECT_FALSE(lens.Unproject(Vec2d(lens.cx + 1e4, lens.cy), &ray));
  EXPECT_FALSE(lens.Unproject(Vec2d(std::nan(""), lens.cy), &ray));
}

using test_util::ErrorOf;

TEST(Lens, NonInvertibleParametersAreRefused) {
  EXPECT_THAT(ErrorOf([] { Lens(LensModel::kOmnidir, {0, 0, 0, 0, 0}, -0.5); }),
              HasSubstr("xi: must be >= 0"));
  // k1 = -0.5: r (1 - 0.5 r^2) stops increasing at r = 0.816, inside a frame reaching r = 1.07.
  EXPECT_THAT(ErrorOf([] { Lens(LensModel::kRadTan, {-0.5, 0, 0, 0, 0}); }),
              HasSubstr("distortion: folds the image"));
  // A fisheye (or omni) fold is the edge of its image circle: masked, not an error (see
  // PixelsOutsideTheImageCircleDoNotUnproject).
  EXPECT_THAT(ErrorOf([] { Lens(LensModel::kRadTan, {0, 0, 0, 0, 0}, 0.0, 0.0, 640, 480, -1.0); }),
              HasSubstr("fx/fy"));
  EXPECT_THAT(ErrorOf([] { Lens(LensModel::kRadTan, {std::nan(""), 0, 0, 0, 0}); }),
              HasSubstr("finite"));
  EXPECT_THAT(ErrorOf([] { ParseLensModel("kannala", "camera cam0: model"); }),
              HasSubstr("camera cam0: model: unknown lens model 'kannala'"));
}

}  // namespace
}  // namespace aos
