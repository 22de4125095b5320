// Tests of the integral renderer against analytic truth and a brute-force reference.
#include "aos/render/integral.h"

#include <algorithm>
#include <cmath>
#include <atomic>
#include <random>
#include <set>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "aos/render/integral_kernels.h"
#include "aos/sim/simulator.h"
#include "error_of.h"
#include "plane_scene.h"
#include "render_test_util.h"
#include "aos/util/error.h"

namespace aos {
namespace {

using ::testing::HasSubstr;

using test_util::GridCentres;
using test_util::NadirLightField;

// A small simulated light field: 8-bit grey nadir views of the chart-textured ground under a
// 60 %-density voxel volume, per_side x per_side views 3 m apart at 35 m.
LightField SimulatedLightField(int per_side, int width, int height) {
  Scene scene;
  scene.has_voxels = true;
  scene.voxels.center = {0.0, 0.0, 11.0};
  scene.voxels.size = {30.0, 30.0, 6.0};
  scene.voxels.grid = {60, 60, 12};
  scene.voxels.density = 0.6;
  scene.camera.width = width;
  scene.camera.height = height;
  scene.camera.fov_deg = 50.0;
  scene.sampling.altitude = 35.0;
  scene.sampling.grid = per_side;
  scene.sampling.aperture_diameter = 3.0 * (per_side - 1);
  scene.truth.blocked_fraction = false;
  scene.truth.width = scene.truth.height = 8;
  return Simulate(scene).light_field;
}

// The factor from 8-bit grey levels to `type`'s values: 1 (uint8), 257 (uint16), 1/255 (float).
double ValueScale(PixelType type) {
  return type == PixelType::kU8 ? 1.0 : (type == PixelType::kU16 ? 257.0 : 1.0 / 255.0);
}

// The 8-bit light field with its frames converted to `type` (values times ValueScale).
LightField ConvertedLightField(const LightField& u8, PixelType type) {
  LightField light_field = u8;
  const double scale = ValueScale(type);
  for (View& view : light_field.views) {
    Image converted(view.image.width(), view.image.height(), 1, type, 1);
    for (int y = 0; y < converted.height(); ++y) {
      for (int x = 0; x < converted.width(); ++x) {
        const double value = view.image.Value(x, y) * scale;
        if (type == PixelType::kU16) *converted.At<uint16_t>(x, y) = static_cast<uint16_t>(value);
        if (type == PixelType::kF32) *converted.At<float>(x, y) = static_cast<float>(value);
        if (type == PixelType::kU8) *converted.At<uint8_t>(x, y) = static_cast<uint8_t>(value);
      }
    }
    converted.FillBorder();
    view.image = converted;
  }
  return light_field;
}

// A float image of one value everywhere (views whose value names them).
Image ConstantImage(int width, int height, float value) {
  Image image(width, height, 1, PixelType::kF32);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) *image.At<float>(x, y) = value;
  }
  return image;
}

// Focal point of output pixel (x, y) (pixel centre) of the virtual camera.
Vec3d FocalPoint(const LightField& light_field, const IntegralOptions& options, const Rigid3d& cam_from_world, int x, int y) {
  const PinholeCamera camera = VirtualCamera(light_field, options);
  const Vec3d direction =
      glm::transpose(cam_from_world.rotation) * camera.Unproject(Vec2d(x + 0.5, y + 0.5));
  const Vec3d centre = cam_from_world.Center();
  const Vec3d n = options.focal_surface.plane().normal;
  const double t = glm::dot(n, options.focal_surface.plane().point - centre) / glm::dot(n, direction);
  return centre + t * direction;
}

TEST(Integral, SingleViewFromItsOwnPoseReturnsThatImage) {
  // A random 8-bit image, non-square, seen from its own pose with radius 0 and radius infinity.
  const PinholeCamera camera = PinholeCamera::FromFov(64, 48, 55.0);
  Image image(64, 48, 1, PixelType::kU8);
  std::mt19937 random(7);
  for (int y = 0; y < 48; ++y) {
    for (int x = 0; x < 64; ++x) *image.At<uint8_t>(x, y) = static_cast<uint8_t>(random() % 256);
  }
  LightField light_field;
  const Rigid3d pose = LookAt(Vec3d(3, -2, 25), Vec3d(4, 1, 0), Vec3d(0, 1, 0));
  light_field.views.push_back(MakeView("only", camera, pose, image));
  for (double radius : {0.0, std::numeric_limits<double>::infinity()}) {
    IntegralOptions options;
    options.pose_view = 0;
    options.fov_deg = camera.FovXDeg();
    options.width = 64;
    options.height = 48;
    options.aperture_radius = radius;
    options.focal_surface = FocalSurface::FromPlane(Plane::AtHeight(0.0));
    const IntegralResult result = RenderIntegral(light_field, options);
    ASSERT_EQ(result.image.width(), 64);
    ASSERT_EQ(result.image.height(), 48);
    // The homography is the identity up to double rounding; the float sample position is off by
    // at most ~1e-4 px, so a value moves by at most 1e-4 * 255 (the largest step between
    // neighbours) < 0.03 grey levels.
    for (int y = 0; y < 48; ++y) {
      for (int x = 0; x < 64; ++x) {
        EXPECT_EQ(*result.count.At<uint32_t>(x, y), 1u) << x << "," << y;
        EXPECT_NEAR(*result.image.At<float>(x, y), *image.At<uint8_t>(x, y), 0.03)
            << "radius " << radius << " pixel " << x << "," << y;
      }
    }
    EXPECT_EQ(result.views_used, 1);
    EXPECT_EQ(result.uncovered_pixels, 0);
  }
}

// A smooth texture on a plane, in grey levels, and the bound on bilinear interpolation error.
struct SmoothTexture {
  double a1 = 40.0, k1 = 2.0 * M_PI / 8.0;  // amplitude, wavenumber (8 m wavelength)
  double a2 = 30.0, k2 = 2.0 * M_PI / 10.0;
  double Value(double s, double t) const {
    return 120.0 + a1 * std::sin(k1 * s + 0.3) + a2 * std::cos(k2 * t - 0.7) +
           20.0 * std::sin(0.5 * k1 * (s + t));
  }
  // Bilinear interpolation on a grid of spacing g (metres per view pixel) errs by at most
  // (g^2 / 8) (max|T_ss| + max|T_tt|) plus the mixed-term bound; for this T that is below:
  double InterpolationBound(double g) const {
    const double second = a1 * k1 * k1 + a2 * k2 * k2 + 2.0 * 20.0 * 0.25 * k1 * k1;
    return g * g / 8.0 * second * 2.0;  // factor 2: off-nadir foreshortening of up to sqrt(2)
  }
};

struct PlaneCase {
  const char* name;
  Plane plane;
};

class TexturedPlane : public ::testing::TestWithParam<PlaneCase> {};

TEST_P(TexturedPlane, ComesBackWithinHalfAnEightBitStep) {
  const Plane plane = GetParam().plane;
  const Vec3d n = glm::normalize(plane.normal);
  // In-plane axes (s, t) for the texture.
  const Vec3d s_axis = glm::normalize(glm::cross(Vec3d(0, 1, 0), n));
  const Vec3d t_axis = glm::cross(n, s_axis);
  const SmoothTexture texture;
  SyntheticScene scene;
  scene.layers.push_back(SceneLayer{plane, [&](const Vec3d& p, float* value) {
    const Vec3d d = p - plane.point;
    value[0] = static_cast<float>(texture.Value(glm::dot(d, s_axis), glm::dot(d, t_axis)));
    return true;
  }});
  const PinholeCamera camera = PinholeCamera::FromFov(256, 256, 60.0);
  const double altitude = 30.0;
  const auto centres = GridCentres(9, 2.0, altitude);
  // View pixel size on the ground at nadir, metres.
  const double g = altitude / camera.fx;
  const double bound = texture.InterpolationBound(g);
  ASSERT_LT(bound, 0.5) << "test texture too sharp for the claim";

  IntegralOptions options;
  options.cam_from_world = NadirCamFromWorld(Vec3d(0.3, -0.2, altitude));
  options.fov_deg = 40.0;
  options.width = 128;
  options.height = 96;
  options.focal_surface = FocalSurface::FromPlane(plane);
  for (PixelType type : {PixelType::kF32, PixelType::kU8}) {
    const LightField light_field = NadirLightField(scene, camera, centres, type);
    const IntegralResult result = RenderIntegral(light_field, options);
    double max_error = 0.0, sum_error = 0.0;
    int interior = 0;
    for (int y = 8; y < options.height - 8; ++y) {
      for (int x = 8; x < options.width - 8; ++x) {
        ASSERT_GT(*result.count.At<uint32_t>(x, y), 40u);
        const Vec3d point = FocalPoint(light_field, options, options.cam_from_world, x, y) - plane.point;
        const double truth = texture.Value(glm::dot(point, s_axis), glm::dot(point, t_axis));
        const double error = std::abs(*result.image.At<float>(x, y) - truth);
        max_error = std::max(max_error, error);
        sum_error += error;
        ++interior;
      }
    }
    if (type == PixelType::kF32) {
      // Float views: only interpolation error remains, bounded analytically.
      EXPECT_LT(max_error, bound) << GetParam().name;
    } else {
      // 8-bit views add rounding of up to half a step per view; averaged over many views with
      // independent sub-pixel phases the result must stay within half an 8-bit step.
      EXPECT_LT(max_error, 0.5) << GetParam().name;
      EXPECT_LT(sum_error / interior, 0.1) << GetParam().name;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(
    Planes, TexturedPlane,
    ::testing::Values(PlaneCase{"horizontal", Plane::AtHeight(0.0)},
                      PlaneCase{"tilted", Plane{Vec3d(1.0, 0.5, -2.0), Vec3d(0.25, -0.2, 1.0)}}),
    [](const auto& info) { return std::string(info.param.name); });

// A bright disk of radius `radius` at height `height` over a black ground; float views.
SyntheticScene BrightPointScene(double height, double radius) {
  SyntheticScene scene;
  scene.layers.push_back(SceneLayer{Plane::AtHeight(height), [=](const Vec3d& p, float* value) {
    if (p.x * p.x + p.y * p.y > radius * radius) return false;
    value[0] = 1000.0f;
    return true;
  }});
  scene.layers.push_back(SceneLayer{Plane::AtHeight(0.0), [](const Vec3d&, float* value) {
    value[0] = 0.0f;
    return true;
  }});
  return scene;
}

TEST(Integral, PointOffTheFocalPlaneSpreadsIntoTheGeometricDisk) {
  const double altitude = 30.0, point_height = 10.0;
  const SyntheticScene scene = BrightPointScene(point_height, 0.15);
  const PinholeCamera camera = PinholeCamera::FromFov(64, 64, 32.0);
  // A dense square grid of views; the aperture test picks the disk out of it.
  const LightField light_field =
      NadirLightField(scene, camera, GridCentres(41, 0.25, altitude), PixelType::kF32);
  for (double radius : {4.0, 2.0}) {
    IntegralOptions options;
    options.cam_from_world = NadirCamFromWorld(Vec3d(0, 0, altitude));
    options.fov_deg = 20.0;
    options.width = options.height = 101;
    options.aperture_radius = radius;
    const IntegralResult result = RenderIntegral(light_field, options);
    // Geometry: the point's images on the focal plane fill a disk of diameter
    // aperture diameter x depth offset / distance from the aperture = 2 r h_p / (H - h_p).
    const double diameter_m = 2.0 * radius * point_height / (altitude - point_height);
    const double metres_per_pixel =
        2.0 * altitude * std::tan(0.5 * options.fov_deg * M_PI / 180.0) / options.width;
    const double expected_px = diameter_m / metres_per_pixel;
    // Plateau: mean over the central pixels; the disk is where the value exceeds half of it.
    double plateau = 0.0;
    int central = 0;
    for (int y = 48; y <= 52; ++y) {
      for (int x = 48; x <= 52; ++x) {
        plateau += *result.image.At<float>(x, y);
        ++central;
      }
    }
    plateau /= central;
    ASSERT_GT(plateau, 0.0);
    int above = 0;
    for (int y = 0; y < 101; ++y) {
      for (int x = 0; x < 101; ++x) above += *result.image.At<float>(x, y) > 0.5 * plateau;
    }
    const double measured_px = 2.0 * std::sqrt(above / M_PI);
    EXPECT_NEAR(measured_px, expected_px, 1.0) << "aperture radius " << radius;
  }
}

TEST(Integral, UtmCoordinatesGiveTheSameImageAsTheSceneAtTheOrigin) {
  const LightField near = SimulatedLightField(5, 64, 64);
  // The same light field moved by a UTM-sized offset: x_cam = R (X - O) + t, so t' = t - R O.
  const Vec3d offset(543210.123456, 5432109.876543, 312.5);
  LightField far = near;
  for (View& view : far.views) {
    view.cam_from_world.translation -= view.cam_from_world.rotation * offset;
  }
  IntegralOptions options;
  options.width = options.height = 80;
  options.fov_deg = 45.0;
  options.aperture_radius = 5.0;
  options.cam_from_world = NadirCamFromWorld(Vec3d(0.7, -0.4, 35.0));
  options.focal_surface = FocalSurface::FromPlane(Plane{Vec3d(0, 0, 0.5), Vec3d(0.1, 0.05, 1.0)});
  const IntegralResult reference = RenderIntegral(near, options);
  options.cam_from_world.translation -= options.cam_from_world.rotation * offset;
  options.focal_surface = FocalSurface::FromPlane(
      Plane{options.focal_surface.plane().point + offset, options.focal_surface.plane().normal});
  const IntegralResult moved = RenderIntegral(far, options);
  // Transforms are composed in double relative to the virtual camera: 5e6 m * 2^-52 ~ 1e-9 m,
  // far below a pixel, so the images agree to float rounding.
  double max_difference = 0.0;
  for (int y = 0; y < 80; ++y) {
    for (int x = 0; x < 80; ++x) {
      ASSERT_EQ(*reference.count.At<uint32_t>(x, y), *moved.count.At<uint32_t>(x, y));
      max_difference = std::max(max_difference, double(std::abs(*reference.image.At<float>(x, y) -
                                                                *moved.image.At<float>(x, y))));
    }
  }
  EXPECT_LT(max_difference, 1e-3);
  EXPECT_GT(reference.samples, 0);
}

// Views with constant images (value = view index) make the average reveal exactly which views
// contributed; a brute-force per-pixel reference in double checks counts and values.
struct BruteForce {
  std::vector<uint32_t> count;
  std::vector<double> value;
  std::vector<uint8_t> ambiguous;  // some test was within a hair of its threshold
};

BruteForce BruteForceIntegral(const LightField& light_field, const IntegralOptions& options) {
  const PinholeCamera camera = VirtualCamera(light_field, options);
  const Rigid3d& pose = options.cam_from_world;
  const Vec3d c = pose.Center();
  const Vec3d axis = Row(pose.rotation, 2);
  const Vec3d n = glm::normalize(options.focal_surface.plane().normal);
  const double sin_min = std::sin(options.min_view_angle_deg * M_PI / 180.0);
  BruteForce out;
  const size_t pixels = static_cast<size_t>(options.width) * options.height;
  out.count.assign(pixels, 0);
  out.value.assign(pixels, 0.0);
  out.ambiguous.assign(pixels, 0);
  for (int y = 0; y < options.height; ++y) {
    for (int x = 0; x < options.width; ++x) {
      const size_t p = static_cast<size_t>(y) * options.width + x;
      const Vec3d d = glm::transpose(pose.rotation) * camera.Unproject(Vec2d(x + 0.5, y + 0.5));
      const double t = glm::dot(n, options.focal_surface.plane().point - c) / glm::dot(n, d);
      if (!(t > 0.0)) continue;
      const Vec3d X = c + t * d;
      double sum = 0.0;
      for (size_t i = 0; i < light_field.views.size(); ++i) {
        const View& view = light_field.views[i];
        const Vec3d in_cam = view.cam_from_world * X;
        const double scale = glm::length(X - view.cam_from_world.Center());
        if (std::abs(in_cam.z) < 1e-9 * scale) {
          out.ambiguous[p] = 1;
          continue;
        }
        if (in_cam.z <= 0.0) continue;
        const Vec2d uv = view.camera.Pinhole().Project(in_cam);
        const double margin_uv = std::min(std::min(uv.x, view.camera.width - uv.x),
                                          std::min(uv.y, view.camera.height - uv.y));
        if (std::abs(margin_uv) < 1e-6) out.ambiguous[p] = 1;
        if (margin_uv < 0.0) continue;
        const Vec3d to_view = view.cam_from_world.Center() - X;
        const double sin_angle = std::abs(glm::dot(n, to_view)) / glm::length(to_view);
        if (std::abs(sin_angle - sin_min) < 1e-9) out.ambiguous[p] = 1;
        if (sin_angle < sin_min) continue;
        if (std::isfinite(options.aperture_radius)) {
          // Line X -> C_i meets the lens plane a . (Q - c) = 0 at Q.
          const double denominator = glm::dot(axis, to_view);
          if (denominator == 0.0) continue;
          const double s = glm::dot(axis, c - X) / denominator;
          const double distance = glm::length(X + s * to_view - c);
          if (std::abs(distance - options.aperture_radius) < 1e-7 * (1.0 + distance)) {
            out.ambiguous[p] = 1;
          }
          if (distance > options.aperture_radius) continue;
        }
        ++out.count[p];
        sum += view.image.Value(0, 0);
      }
      out.value[p] = out.count[p] ? sum / out.count[p] : 0.0;
    }
  }
  return out;
}

TEST(Integral, CountsAndValuesMatchBruteForceForGeneralGeometry) {
  // Tilted views at varied heights, a virtual camera above and off the flight "plane", a tilted
  // focal plane, a finite aperture and a steep minimum view angle: every per-row span (linear and
  // conic) is exercised and compared pixel by pixel with the direct per-pixel tests.
  std::mt19937 random(12345);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  const PinholeCamera camera = PinholeCamera::FromFov(40, 30, 70.0);
  LightField light_field;
  for (int i = 0; i < 60; ++i) {
    const Vec3d eye(12.0 * uniform(random), 12.0 * uniform(random), 25.0 + 8.0 * uniform(random));
    const Vec3d target(6.0 * uniform(random), 6.0 * uniform(random), 0.0);
    light_field.views.push_back(MakeView("v" + std::to_string(i), camera,
                                         LookAt(eye, target, Vec3d(0, 1, 0)),
                                         ConstantImage(40, 30, static_cast<float>(i))));
  }
  struct Case {
    double aperture, min_angle;
    Rigid3d pose;
  };
  const Case cases[] = {
      {6.0, 60.0, LookAt(Vec3d(1, 2, 45), Vec3d(0, 0, 0), Vec3d(0, 1, 0))},
      {9.0, 1.0, LookAt(Vec3d(-3, 1, 15), Vec3d(2, 0, 0), Vec3d(0, 1, 0))},
      {std::numeric_limits<double>::infinity(), 70.0, LookAt(Vec3d(0, 0, 30), Vec3d(1, 1, 0), Vec3d(0, 1, 0))},
  };
  for (const Case& test_case : cases) {
    IntegralOptions options;
    options.cam_from_world = test_case.pose;
    options.fov_deg = 65.0;
    options.width = 90;
    options.height = 70;
    options.aperture_radius = test_case.aperture;
    options.min_view_angle_deg = test_case.min_angle;
    options.focal_surface = FocalSurface::FromPlane(Plane{Vec3d(0, 0, 1.0), Vec3d(0.2, -0.3, 1.0)});
    const IntegralResult result = RenderIntegral(light_field, options);
    const BruteForce truth = BruteForceIntegral(light_field, options);
    int compared = 0, partial_views = 0;
    for (int y = 0; y < options.height; ++y) {
      for (int x = 0; x < options.width; ++x) {
        const size_t p = static_cast<size_t>(y) * options.width + x;
        if (truth.ambiguous[p]) continue;
        ++compared;
        ASSERT_EQ(*result.count.At<uint32_t>(x, y), truth.count[p])
            << "pixel " << x << "," << y << " aperture " << test_case.aperture;
        // Values are means of view indices: exact up to float rounding.
        ASSERT_NEAR(*result.image.At<float>(x, y), truth.value[p], 1e-4);
        partial_views += truth.count[p] > 0 && truth.count[p] < light_field.views.size();
      }
    }
    EXPECT_GT(compared, options.width * options.height * 9 / 10);
    EXPECT_GT(partial_views, 100) << "the case should admit views only for some pixels";
  }
}

TEST(Integral, MinViewCountLeavesThinPixelsUncoveredAndTheRestUnchanged) {
  // A finite aperture over scattered views: pixel counts range from 0 to many. With
  // min_view_count = k every pixel seen by fewer than k views is uncovered (image, count and
  // variance 0) and every other pixel is the unthresholded render's, bit for bit; the plane
  // kernel and the lens path (a depth map) both.
  std::mt19937 random(7);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  const PinholeCamera camera = PinholeCamera::FromFov(40, 30, 60.0);
  LightField light_field;
  for (int i = 0; i < 30; ++i) {
    const Vec3d eye(10.0 * uniform(random), 10.0 * uniform(random), 30.0);
    light_field.views.push_back(MakeView("v" + std::to_string(i), camera,
                                         LookAt(eye, Vec3d(eye.x, eye.y, 0.0), Vec3d(0, 1, 0)),
                                         ConstantImage(40, 30, static_cast<float>(i))));
  }
  for (const bool surface : {false, true}) {
    IntegralOptions options;
    options.cam_from_world = LookAt(Vec3d(0, 0, 40), Vec3d(0, 0, 0), Vec3d(0, 1, 0));
    options.fov_deg = 70.0;
    options.width = 64;
    options.height = 48;
    options.aperture_radius = 8.0;
    options.variance = true;
    if (surface) {  // a plane given as a depth map: the per-sample path
      const PinholeCamera virtual_camera = VirtualCamera(light_field, options);
      const Image depth = options.focal_surface.DepthFor(
          virtual_camera, options.cam_from_world,
          ResolveSurfacePlacement(options.focal_surface, light_field, {}, 0.0), 1);
      options.focal_surface =
          FocalSurface::FromDepthMap(depth, virtual_camera, options.cam_from_world);
    }
    const IntegralResult all = RenderIntegral(light_field, options);
    options.min_view_count = 6;
    const IntegralResult thick = RenderIntegral(light_field, options);
    int64_t dropped = 0, kept = 0, samples = 0, uncovered = 0;
    for (int y = 0; y < options.height; ++y) {
      for (int x = 0; x < options.width; ++x) {
        const uint32_t n = *all.count.At<uint32_t>(x, y);
        const uint32_t m = *thick.count.At<uint32_t>(x, y);
        if (n < 6) {
          dropped += n > 0;
          ASSERT_EQ(m, 0u) << x << "," << y;
          ASSERT_EQ(*thick.image.At<float>(x, y), 0.0f);
          ASSERT_EQ(*thick.variance.At<float>(x, y), 0.0f);
        } else {
          ++kept;
          ASSERT_EQ(m, n);
          ASSERT_EQ(*thick.image.At<float>(x, y), *all.image.At<float>(x, y));
          ASSERT_EQ(*thick.variance.At<float>(x, y), *all.variance.At<float>(x, y));
        }
        samples += m;
        uncovered += m == 0;
      }
    }
    EXPECT_GT(dropped, 50) << "the case should have thin pixels";
    EXPECT_GT(kept, 500);
    EXPECT_EQ(thick.samples, samples);
    EXPECT_EQ(thick.uncovered_pixels, uncovered);
    // 0 and 1 keep every pixel; a negative count is refused naming the field.
    options.min_view_count = 1;
    EXPECT_EQ(test_util::MaxAbsDifference(RenderIntegral(light_field, options).image, all.image),
              0.0);
    options.min_view_count = -1;
    EXPECT_THROW(
        {
          try {
            RenderIntegral(light_field, options);
          } catch (const std::invalid_argument& error) {
            EXPECT_NE(std::string(error.what()).find("min_view_count"), std::string::npos);
            throw;
          }
        },
        std::invalid_argument);
  }
}

TEST(Integral, PinholeRadiusZeroPicksTheNearestViewPerPixel) {
  // Views at varied heights (so the lens-plane crossing depends on the pixel) with constant
  // images holding their index: the result names the view chosen for each pixel, which must be
  // the one whose line to the focal point crosses the lens plane nearest to the centre.
  std::mt19937 random(4242);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  const PinholeCamera camera = PinholeCamera::FromFov(48, 40, 75.0);
  LightField light_field;
  for (int i = 0; i < 40; ++i) {
    const Vec3d eye(8.0 * uniform(random), 8.0 * uniform(random), 30.0 + 10.0 * uniform(random));
    light_field.views.push_back(MakeView("v" + std::to_string(i), camera,
                                         LookAt(eye, Vec3d(0, 0, 0), Vec3d(0, 1, 0)),
                                         ConstantImage(48, 40, static_cast<float>(i))));
  }
  IntegralOptions options;
  options.cam_from_world = LookAt(Vec3d(0.5, -0.5, 33.0), Vec3d(0, 0, 0), Vec3d(0, 1, 0));
  options.fov_deg = 40.0;
  options.width = 60;
  options.height = 50;
  options.aperture_radius = 0.0;
  options.focal_surface = FocalSurface::FromPlane(Plane{Vec3d(0, 0, 0.5), Vec3d(0.1, 0.2, 1.0)});
  const IntegralResult result = RenderIntegral(light_field, options);
  const Rigid3d& pose = options.cam_from_world;
  const Vec3d c = pose.Center(), axis = Row(pose.rotation, 2);
  const Vec3d n = glm::normalize(options.focal_surface.plane().normal);
  const double sin_min = std::sin(options.min_view_angle_deg * M_PI / 180.0);
  std::set<int> chosen;
  int compared = 0;
  for (int y = 0; y < options.height; ++y) {
    for (int x = 0; x < options.width; ++x) {
      const Vec3d X = FocalPoint(light_field, options, pose, x, y);
      double best = std::numeric_limits<double>::infinity(), second = best;
      int best_view = -1;
      for (size_t i = 0; i < light_field.views.size(); ++i) {
        const View& view = light_field.views[i];
        const Vec3d in_cam = view.cam_from_world * X;
        if (in_cam.z <= 0.0) continue;
        const Vec2d uv = view.camera.Pinhole().Project(in_cam);
        if (uv.x < 0 || uv.x > 48 || uv.y < 0 || uv.y > 40) continue;
        const Vec3d to_view = view.cam_from_world.Center() - X;
        if (std::abs(glm::dot(n, to_view)) < sin_min * glm::length(to_view)) continue;
        const double s = glm::dot(axis, c - X) / glm::dot(axis, to_view);
        const double distance = glm::length(X + s * to_view - c);
        if (distance < best) {
          second = best;
          best = distance;
          best_view = static_cast<int>(i);
        } else {
          second = std::min(second, distance);
        }
      }
      if (best_view < 0) {
        EXPECT_EQ(*result.count.At<uint32_t>(x, y), 0u);
        continue;
      }
      if (second - best < 1e-9) continue;  // a tie within rounding
      ++compared;
      ASSERT_EQ(*result.count.At<uint32_t>(x, y), 1u);
      ASSERT_EQ(*result.image.At<float>(x, y), static_cast<float>(best_view)) << x << "," << y;
      chosen.insert(best_view);
    }
  }
  EXPECT_GT(compared, options.width * options.height / 2);
  EXPECT_GE(chosen.size(), 3u) << "the nearest view should change across the image";
  EXPECT_EQ(result.views_used, static_cast<int>(chosen.size()));
}

TEST(Integral, PinholeOnTheFlightPlaneTakesTheNearestViewThatSeesEachPixel) {
  // Every view and the virtual camera at the same height (the common case, which takes the
  // sorted fast path): each pixel's view must be the one nearest the virtual centre among the
  // views that see its focal point. Narrow views make the nearest one miss some pixels, and a
  // symmetric grid makes exact ties, which go to the lower index.
  for (const double view_fov : {30.0, 100.0}) {
    // 100 degrees: every view sees every pixel, so tiles are complete early (and stop there).
    const PinholeCamera camera = PinholeCamera::FromFov(32, 32, view_fov);
    LightField light_field;
    std::vector<Vec3d> centres;
    for (int j = 0; j < 7; ++j) {
      for (int i = 0; i < 7; ++i) centres.emplace_back(3.0 * (i - 3), 3.0 * (j - 3), 20.0);
    }
    std::mt19937 random(7);
    std::shuffle(centres.begin(), centres.end(), random);  // index order unrelated to distance
    for (size_t i = 0; i < centres.size(); ++i) {
      light_field.views.push_back(MakeView("v" + std::to_string(i), camera,
                                           NadirCamFromWorld(centres[i]),
                                           ConstantImage(32, 32, static_cast<float>(i))));
    }
    for (const Vec3d& virtual_centre : {Vec3d(1.0, -0.5, 20.0), Vec3d(1.5, 1.5, 20.0)}) {
      IntegralOptions options;
      options.cam_from_world = NadirCamFromWorld(virtual_centre);
      options.fov_deg = 70.0;
      options.width = 40;
      options.height = 40;
      options.aperture_radius = 0.0;
      const IntegralResult result = RenderIntegral(light_field, options);
      int ties = 0, far = 0;
      for (int y = 0; y < options.height; ++y) {
        for (int x = 0; x < options.width; ++x) {
          const Vec3d X = FocalPoint(light_field, options, options.cam_from_world, x, y);
          double best = std::numeric_limits<double>::infinity();
          int best_view = -1, nearest_any = -1;
          double nearest_any_distance = best;
          for (size_t i = 0; i < centres.size(); ++i) {
            const double distance = glm::length(centres[i] - virtual_centre);
            if (distance < nearest_any_distance) {
              nearest_any_distance = distance;
              nearest_any = static_cast<int>(i);
            }
            const Vec2d uv = camera.Project(light_field.views[i].cam_from_world * X);
            if (uv.x < 0 || uv.x > 32 || uv.y < 0 || uv.y > 32) continue;
            ties += distance == best;  // a later index at the same distance loses
            if (distance < best) {
              best = distance;
              best_view = static_cast<int>(i);
            }
          }
          if (best_view < 0) {
            ASSERT_EQ(*result.count.At<uint32_t>(x, y), 0u);
            continue;
          }
          far += best_view != nearest_any;
          ASSERT_EQ(*result.count.At<uint32_t>(x, y), 1u);
          ASSERT_EQ(*result.image.At<float>(x, y), static_cast<float>(best_view)) << x << "," << y;
        }
      }
      if (view_fov < 90.0) EXPECT_GT(far, 100);  // many pixels are outside the nearest frame
      if (virtual_centre.x == 1.5) EXPECT_GT(ties, 0);
      if (view_fov > 90.0) EXPECT_EQ(result.views_used, 1);
    }
  }
}

TEST(Integral, PinholeTiesGoToTheLowerViewIndex) {
  // Two views at the same pose: every pixel is a tie. Listed in reverse order, view 0 must win.
  const PinholeCamera camera = PinholeCamera::FromFov(16, 16, 50.0);
  const Rigid3d pose = NadirCamFromWorld(Vec3d(0, 0, 20));
  LightField light_field;
  light_field.views.push_back(MakeView("a", camera, pose, ConstantImage(16, 16, 10.0f)));
  light_field.views.push_back(MakeView("b", camera, pose, ConstantImage(16, 16, 20.0f)));
  IntegralOptions options;
  options.cam_from_world = pose;
  options.fov_deg = 30.0;
  options.width = options.height = 8;
  options.aperture_radius = 0.0;
  options.view_indices = {1, 0};
  const IntegralResult result = RenderIntegral(light_field, options);
  for (int y = 0; y < 8; ++y) {
    for (int x = 0; x < 8; ++x) EXPECT_EQ(*result.image.At<float>(x, y), 10.0f);
  }
  EXPECT_EQ(result.views_used, 1);
}

TEST(Integral, SimdKernelsWriteOnlyTheirSpanAndThePadding) {
  // Spans of every length 1..17 ending at the last column of an exactly sized accumulator row:
  // the span must match the scalar kernel, values before it must not change, and the kernel may
  // only touch the kSpanPadding values after it (adding +0.0).
  for (PixelType type : {PixelType::kU8, PixelType::kU16, PixelType::kF32}) {
    Image image(24, 6, 1, type, 1);
    for (int y = 0; y < 6; ++y) {
      for (int x = 0; x < 24; ++x) {
        const int value = (x * 37 + y * 11) % 200;
        if (type == PixelType::kU8) *image.At<uint8_t>(x, y) = static_cast<uint8_t>(value);
        if (type == PixelType::kU16) *image.At<uint16_t>(x, y) = static_cast<uint16_t>(value * 300);
        if (type == PixelType::kF32) *image.At<float>(x, y) = static_cast<float>(value) * 0.25f;
      }
    }
    image.FillBorder();
    const internal::SpanKernel simd = internal::Avx2SpanKernel(image);
    const internal::SquaresKernel simd_squares = internal::Avx2SquaresKernel(image);
    if (simd == nullptr || simd_squares == nullptr) GTEST_SKIP() << "no AVX2/FMA on this CPU";
    const internal::SpanKernel scalar = internal::ScalarSpanKernel(image);
    // A slightly rotated, scaled row through the image (stays inside [0, 24] x [0, 6]).
    const internal::RowLine line{0.5, 0.93, 2.2, 0.05, 1.0, 1e-4};
    const int width = 20;
    for (int n = 1; n <= 17; ++n) {
      const int xa = width - n, xb = width;
      std::vector<double> expected(width + internal::kSpanPadding, 7.0), got = expected;
      scalar(image, line, xa, xb, 0, expected.data());
      simd(image, line, xa, xb, 0, got.data());
      for (int x = 0; x < xa; ++x) ASSERT_EQ(got[x], 7.0) << "before the span, n=" << n;
      for (int x = xa; x < xb; ++x) ASSERT_NEAR(got[x], expected[x], 1e-3 * (1 + std::abs(expected[x])));
      for (int x = xb; x < width + internal::kSpanPadding; ++x) ASSERT_EQ(got[x], 7.0) << "padding";
      // The variance kernel: the same for its sums and its squares.
      std::vector<double> sums(width + internal::kSpanPadding, 7.0), squares = sums;
      simd_squares(image, line, xa, xb, 0, sums.data(), squares.data());
      for (int x = 0; x < xa; ++x) ASSERT_EQ(squares[x], 7.0) << "before the span, n=" << n;
      for (int x = xa; x < xb; ++x) ASSERT_EQ(sums[x], got[x]);
      for (int x = xb; x < width + internal::kSpanPadding; ++x) {
        ASSERT_EQ(sums[x], 7.0);
        ASSERT_EQ(squares[x], 7.0) << "padding";
      }
    }
  }
}

// The AVX2 kernels' arithmetic, lane by lane, in scalar code: the same re-basing, FMAs
// (std::fmaf rounds once, as the instructions do), clamps and truncations. The SIMD kernels must
// equal it bit for bit, whichever way they fetch the taps (8-bit views: row loads and shuffles,
// or gathers when a group spans more than 15 columns or more than two rows).
struct FmaModelSample {
  double value;
  double square;
};
FmaModelSample FmaModel(const Image& image, const internal::RowLine& line, int xa, int i) {
  const float ua = static_cast<float>(line.u0 + line.du * xa);
  const float va = static_cast<float>(line.v0 + line.dv * xa);
  const float wa = static_cast<float>(line.w0 + line.dw * xa);
  const float du = static_cast<float>(line.du), dv = static_cast<float>(line.dv),
              dw = static_cast<float>(line.dw);
  const float fi = static_cast<float>(i);
  const float inv_w = 1.0f / std::fmaf(dw, fi, wa);
  const auto clamp = [](float s, float max) {
    s = s > -1.0f ? s : -1.0f;  // NaN -> -1
    return s < max ? s : max;
  };
  const float sx = clamp(std::fmaf(std::fmaf(du, fi, ua), inv_w, -0.5f), image.width() - 0.5f);
  const float sy = clamp(std::fmaf(std::fmaf(dv, fi, va), inv_w, -0.5f), image.height() - 0.5f);
  // The top-left tap by floor (vroundps), the weights in [0, 1) exactly.
  const float fx = std::floor(sx), fy = std::floor(sy);
  const int ix = static_cast<int>(fx), iy = static_cast<int>(fy);
  const float ax = sx - fx, ay = sy - fy;
  const auto p = [&](int dx, int dy) { return static_cast<float>(image.Value(ix + dx, iy + dy, 0)); };
  const float upper = std::fmaf(ax, p(1, 0) - p(0, 0), p(0, 0));
  const float lower = std::fmaf(ax, p(1, 1) - p(0, 1), p(0, 1));
  const double value = std::fmaf(ay, lower - upper, upper);
  return {value, value * value};
}

TEST(Integral, SimdKernelsEqualTheirFmaModelBitForBitOnEveryTapPath) {
  const internal::RowLine lines[] = {
      {0.5, 0.93, 2.2, 0.05, 1.0, 1e-4},    // row loads, groups crossing a row (three rows)
      {63.0, -0.9, 1.5, 0.02, 1.0, 0.0},    // right to left
      {0.5, 2.2, 3.0, 0.01, 1.0, 0.0},      // 2.2 columns a sample: 8 span > 15 columns: gathers
      {5.0, 0.3, 0.5, 0.45, 1.0, 0.0},      // 0.45 rows a sample: > 2 rows a group: gathers
      {2.0, 1.0, 1.0, 0.1, 1.0, 0.012},     // perspective (W varies along the row)
      {60.0, 0.2, 23.4, 0.01, 1.0, 0.0},    // along the bottom-right edge: clamped positions
      {-4.0, 1.0, -3.0, 0.0, 1.0, 0.0},     // left of and above the image: clamped to -1
      {0.5, 2.0, 3.0, 0.0, 1.0, 0.0},       // 8 lanes 14 columns apart: the widest row load
      {0.0, 1.0, 0.0, 0.0, 0.0, 0.0},       // W = 0: NaN (0 x inf) and infinite positions, clamped
  };
  for (PixelType type : {PixelType::kU8, PixelType::kU16, PixelType::kF32}) {
    Image image(64, 24, 1, type, 1);
    for (int y = 0; y < 24; ++y) {
      for (int x = 0; x < 64; ++x) {
        const int value = (x * 37 + y * 101 + x * y * 7) % 251;
        if (type == PixelType::kU8) *image.At<uint8_t>(x, y) = static_cast<uint8_t>(value);
        if (type == PixelType::kU16) *image.At<uint16_t>(x, y) = static_cast<uint16_t>(value * 257);
        if (type == PixelType::kF32) *image.At<float>(x, y) = static_cast<float>(value) * 0.37f;
      }
    }
    image.FillBorder();
    // The 8-bit kernel with row loads, and with gathers only (the benchmarks' baseline).
    internal::SetSimdRowLoadsEnabled(false);
    const internal::SpanKernel gathers = internal::Avx2SpanKernel(image);
    internal::SetSimdRowLoadsEnabled(true);
    const internal::SpanKernel simd = internal::Avx2SpanKernel(image);
    const internal::SquaresKernel simd_squares = internal::Avx2SquaresKernel(image);
    if (simd == nullptr || simd_squares == nullptr) GTEST_SKIP() << "no AVX2/FMA on this CPU";
    EXPECT_EQ(type == PixelType::kU8, gathers != simd);
    for (const internal::RowLine& line : lines) {
      for (int n : {1, 7, 8, 9, 16, 17, 30}) {
        const int xa = 3, xb = xa + n;
        // Accumulators start at 1/3, so a product contracted into an FMA with the old value
        // (one rounding instead of two) would show.
        std::vector<double> sum(xb + internal::kSpanPadding, 1.0 / 3.0), sum2 = sum,
                                                                       squares = sum,
                                                                       gathered = sum;
        simd(image, line, xa, xb, 0, sum.data());
        gathers(image, line, xa, xb, 0, gathered.data());
        simd_squares(image, line, xa, xb, 0, sum2.data(), squares.data());
        for (int i = 0; i < n; ++i) {
          const FmaModelSample expected = FmaModel(image, line, xa, i);
          const double value = 1.0 / 3.0 + expected.value;
          ASSERT_EQ(sum[xa + i], value) << PixelTypeName(type) << " line " << line.u0
                                        << " n=" << n << " i=" << i;
          ASSERT_EQ(sum2[xa + i], value);
          ASSERT_EQ(gathered[xa + i], value);
          ASSERT_EQ(squares[xa + i], 1.0 / 3.0 + expected.square);
        }
        for (int x = xb; x < xb + internal::kSpanPadding; ++x) {
          ASSERT_EQ(sum[x], 1.0 / 3.0);
          ASSERT_EQ(squares[x], 1.0 / 3.0);
        }
      }
    }
  }
}

TEST(Integral, VarianceSimdKernelAgreesWithTheScalarVariance) {
  // The variance pass with the AVX2 kernel against the scalar one on a whole render: equal counts
  // and variances within what the samples' float rounding allows. Samples differ by at most
  // delta = 0.01 grey levels (SimdAndScalarKernelsAgree), so a population variance E[v^2] - E[v]^2
  // of values in [0, range] moves by at most 2 range delta + delta^2.
  const LightField u8 = SimulatedLightField(5, 64, 64);
  for (PixelType type : {PixelType::kU8, PixelType::kU16, PixelType::kF32}) {
    const double scale = ValueScale(type);
    LightField light_field = ConvertedLightField(u8, type);
    if (internal::Avx2SquaresKernel(light_field.views[0].image) == nullptr) {
      GTEST_SKIP() << "no AVX2/FMA on this CPU";
    }
    IntegralOptions options;
    options.cam_from_world = LookAt(Vec3d(1, 2, 35), Vec3d(0, 0, 0), Vec3d(0, 1, 0));
    options.width = 75;  // not a multiple of 8
    options.height = 41;
    options.fov_deg = 40.0;
    options.variance = true;
    internal::SetSimdVarianceEnabled(false);
    const IntegralResult scalar = RenderIntegral(light_field, options);
    internal::SetSimdVarianceEnabled(true);
    const IntegralResult simd = RenderIntegral(light_field, options);
    const double range = 255.0 * scale, delta = 0.01 * scale;
    double max_difference = 0.0, max_variance = 0.0;
    for (int y = 0; y < options.height; ++y) {
      for (int x = 0; x < options.width; ++x) {
        ASSERT_EQ(*scalar.count.At<uint32_t>(x, y), *simd.count.At<uint32_t>(x, y));
        max_variance = std::max<double>(max_variance, *scalar.variance.At<float>(x, y));
        max_difference = std::max<double>(
            max_difference,
            std::abs(double(*scalar.variance.At<float>(x, y)) - *simd.variance.At<float>(x, y)));
      }
    }
    EXPECT_GT(max_variance, 1e-3 * range * range) << PixelTypeName(type);  // not a flat scene
    EXPECT_LE(max_difference, 2.0 * range * delta + delta * delta) << PixelTypeName(type);
  }
}

TEST(Integral, GrazingViewsAndPointsBehindAViewContributeNothing) {
  const PinholeCamera camera = PinholeCamera::FromFov(32, 32, 60.0);
  auto constant_image = [](float value) { return ConstantImage(32, 32, value); };
  LightField light_field;
  // A proper nadir view (value 100).
  light_field.views.push_back(
      MakeView("nadir", camera, NadirCamFromWorld(Vec3d(0, 0, 20)), constant_image(100.0f)));
  // A view skimming the ground from 0.2 m height, 60 m away: 0.19 degrees above the plane.
  light_field.views.push_back(MakeView("grazing", camera,
                                       LookAt(Vec3d(-60, 0, 0.2), Vec3d(0, 0, 0), Vec3d(0, 0, 1)),
                                       constant_image(1e6f)));
  // A view 10 m up looking straight up: every focal point on the ground is behind it.
  light_field.views.push_back(MakeView("upwards", camera,
                                       LookAt(Vec3d(0, 0, 10), Vec3d(0, 0, 30), Vec3d(0, 1, 0)),
                                       constant_image(-1e6f)));
  // A view looking sideways from 5 m: its principal plane (depth 0) crosses the output, points
  // with x < 0 are behind it and those with x > 0 are seen properly (value 100, like the nadir
  // view, so the average stays 100 wherever only legitimate views contribute).
  light_field.views.push_back(MakeView("sideways", camera,
                                       LookAt(Vec3d(0, 0, 5), Vec3d(10, 0, 5), Vec3d(0, 0, 1)),
                                       constant_image(100.0f)));
  IntegralOptions options;
  options.cam_from_world = NadirCamFromWorld(Vec3d(0, 0, 20));
  options.fov_deg = 60.0;
  options.width = options.height = 32;
  const IntegralResult result = RenderIntegral(light_field, options);
  for (int y = 0; y < 32; ++y) {
    for (int x = 0; x < 32; ++x) {
      ASSERT_TRUE(std::isfinite(*result.image.At<float>(x, y)));
      EXPECT_FLOAT_EQ(*result.image.At<float>(x, y), 100.0f) << x << "," << y;
      EXPECT_GE(*result.count.At<uint32_t>(x, y), 1u);
      EXPECT_LE(*result.count.At<uint32_t>(x, y), 2u);
    }
  }
  EXPECT_EQ(result.views_used, 2);
  // With no minimum angle, the grazing view does contribute where it sees the ground.
  options.min_view_angle_deg = 0.0;
  const IntegralResult permissive = RenderIntegral(light_field, options);
  EXPECT_EQ(permissive.views_used, 3);
  for (int y = 0; y < 32; ++y) {
    for (int x = 0; x < 32; ++x) ASSERT_TRUE(std::isfinite(*permissive.image.At<float>(x, y)));
  }
}

TEST(Integral, TenThousandSixteenBitViewsAverageExactly) {
  // 10^4 views of 16-bit data. (a) Constant images at spread poses: the mean of large integers,
  // which a float accumulator gets wrong by far more than 1e-3. (b) Random images at one pose:
  // the per-pixel mean of the frames.
  const int views = 10000;
  const PinholeCamera camera = PinholeCamera::FromFov(12, 12, 40.0);
  std::mt19937 random(99);
  LightField spread, stacked;
  double constant_sum = 0.0;
  std::vector<double> stacked_sum(144, 0.0);
  const Rigid3d common_pose = NadirCamFromWorld(Vec3d(0, 0, 50));
  for (int i = 0; i < views; ++i) {
    const uint16_t constant = static_cast<uint16_t>(60000 + random() % 5536);
    constant_sum += constant;
    Image flat(12, 12, 1, PixelType::kU16);
    Image noisy(12, 12, 1, PixelType::kU16);
    for (int y = 0; y < 12; ++y) {
      for (int x = 0; x < 12; ++x) {
        *flat.At<uint16_t>(x, y) = constant;
        const uint16_t value = static_cast<uint16_t>(random() % 65536);
        *noisy.At<uint16_t>(x, y) = value;
        stacked_sum[static_cast<size_t>(y) * 12 + x] += value;
      }
    }
    const double dx = (i % 100) * 0.01 - 0.5, dy = (i / 100) * 0.01 - 0.5;
    spread.views.push_back(MakeView("", camera, NadirCamFromWorld(Vec3d(dx, dy, 50)), flat));
    stacked.views.push_back(MakeView("", camera, common_pose, noisy));
  }
  IntegralOptions options;
  options.cam_from_world = common_pose;
  options.fov_deg = 20.0;  // well inside every spread view
  options.width = options.height = 12;
  const IntegralResult flat_result = RenderIntegral(spread, options);
  const double expected = constant_sum / views;
  for (int y = 0; y < 12; ++y) {
    for (int x = 0; x < 12; ++x) {
      ASSERT_EQ(*flat_result.count.At<uint32_t>(x, y), static_cast<uint32_t>(views));
      // The output is float32, whose spacing near 6e4 is 2^-8 = 0.004 of a step, so "within
      // 1e-3 of a step" is checked on what the accumulator delivers: the result must be the float
      // nearest to the exact mean (exact sum / count), i.e. the sum lost nothing. A float
      // accumulator is off by whole steps here.
      EXPECT_EQ(*flat_result.image.At<float>(x, y), static_cast<float>(expected));
    }
  }
  options.fov_deg = 40.0;
  const IntegralResult stacked_result = RenderIntegral(stacked, options);
  for (int y = 0; y < 12; ++y) {
    for (int x = 0; x < 12; ++x) {
      // Seen from the frames' own pose, every sample falls exactly on a pixel centre, so again
      // the result must be the float nearest to the exact per-pixel mean.
      const double mean = stacked_sum[static_cast<size_t>(y) * 12 + x] / views;
      EXPECT_EQ(*stacked_result.image.At<float>(x, y), static_cast<float>(mean));
    }
  }
}

TEST(Integral, UncoveredPixelsHaveCountZeroAndValueZero) {
  const LightField light_field = SimulatedLightField(2, 32, 32);
  IntegralOptions options;
  options.cam_from_world = NadirCamFromWorld(Vec3d(0, 0, 35));
  options.fov_deg = 120.0;  // much wider than the views
  options.width = options.height = 64;
  const IntegralResult result = RenderIntegral(light_field, options);
  EXPECT_GT(result.uncovered_pixels, 0);
  EXPECT_EQ(*result.count.At<uint32_t>(0, 0), 0u);
  EXPECT_EQ(*result.image.At<float>(0, 0), 0.0f);
  for (int y = 0; y < 64; ++y) {
    for (int x = 0; x < 64; ++x) ASSERT_TRUE(std::isfinite(*result.image.At<float>(x, y)));
  }
}

TEST(Integral, RgbAndSixteenBitViewsKeepTheirChannels) {
  SyntheticScene scene;
  scene.channels = 3;
  scene.layers.push_back(SceneLayer{Plane::AtHeight(0.0), [](const Vec3d&, float* value) {
    value[0] = 1000.0f;
    value[1] = 2000.0f;
    value[2] = 3000.0f;
    return true;
  }});
  const PinholeCamera camera = PinholeCamera::FromFov(16, 16, 50.0);
  const LightField light_field =
      NadirLightField(scene, camera, GridCentres(3, 1.0, 20.0), PixelType::kU16);
  IntegralOptions options;
  options.cam_from_world = NadirCamFromWorld(Vec3d(0, 0, 20));
  options.fov_deg = 30.0;
  options.width = options.height = 8;
  const IntegralResult result = RenderIntegral(light_field, options);
  ASSERT_EQ(result.image.channels(), 3);
  EXPECT_FLOAT_EQ(result.image.At<float>(4, 4)[0], 1000.0f);
  EXPECT_FLOAT_EQ(result.image.At<float>(4, 4)[1], 2000.0f);
  EXPECT_FLOAT_EQ(result.image.At<float>(4, 4)[2], 3000.0f);
}

TEST(Integral, SimdAndScalarKernelsAgree) {
  // The AVX2 kernels (used when the CPU has them) must give the scalar reference's values up to
  // float rounding: sample positions differ by ~1e-5 px (FMA contraction), i.e. < 0.01 grey
  // levels per sample for 8-bit data with steps of up to 255 between neighbours.
  const LightField u8 = SimulatedLightField(4, 80, 60);
  for (PixelType type : {PixelType::kU8, PixelType::kU16, PixelType::kF32}) {
    const double scale = ValueScale(type);
    LightField light_field = ConvertedLightField(u8, type);
    IntegralOptions options;
    options.cam_from_world = LookAt(Vec3d(1, 2, 35), Vec3d(0, 0, 0), Vec3d(0, 1, 0));
    options.width = 203;  // not a multiple of 8: exercises the masked last group
    options.height = 101;
    options.fov_deg = 40.0;
    options.focal_surface = FocalSurface::FromPlane(Plane{Vec3d(0, 0, 2), Vec3d(0.1, 0.0, 1.0)});
    if (internal::Avx2SpanKernel(light_field.views[0].image) == nullptr) {
      GTEST_SKIP() << "no AVX2/FMA on this CPU: only the scalar kernels exist";
    }
    internal::SetSimdEnabled(false);
    const IntegralResult scalar = RenderIntegral(light_field, options);
    internal::SetSimdEnabled(true);
    const IntegralResult simd = RenderIntegral(light_field, options);
    double max_difference = 0.0;
    for (int y = 0; y < options.height; ++y) {
      for (int x = 0; x < options.width; ++x) {
        ASSERT_EQ(*scalar.count.At<uint32_t>(x, y), *simd.count.At<uint32_t>(x, y));
        max_difference = std::max(max_difference, std::abs(double(*scalar.image.At<float>(x, y)) -
                                                           *simd.image.At<float>(x, y)) / scale);
      }
    }
    EXPECT_LT(max_difference, 0.01) << PixelTypeName(type);
    EXPECT_GT(scalar.samples, 0);
  }
}

TEST(Integral, QuadraticScoresAreTheIntegralOfTheViewsScoreImages) {
  // RenderIntegralWithQuadratic's scores must be what rendering the frames' score images
  // scale_v * (g - centre_v)^2 (float frames, made apart) gives: the same taps and weights, the
  // same float interpolation, the scale applied after it instead of before (a float rounding,
  // relative ~1e-7). Its image and counts must be RenderIntegral's, bit for bit. Both kernels
  // (SIMD and scalar), 8- and 16-bit frames, a tilted plane, a finite aperture.
  const LightField u8 = SimulatedLightField(4, 96, 72);
  for (PixelType type : {PixelType::kU8, PixelType::kU16}) {
    const double value_scale = ValueScale(type);
    const LightField light_field = ConvertedLightField(u8, type);
    std::vector<ViewQuadratic> quadratics(light_field.views.size());
    LightField scores_field = light_field;
    for (size_t v = 0; v < light_field.views.size(); ++v) {
      quadratics[v].centre = static_cast<float>((90.0 + 7.0 * v) * value_scale);
      quadratics[v].scale =
          static_cast<float>(1.0 / ((300.0 + 11.0 * v) * value_scale * value_scale));
      quadratics[v].one_sided = v % 2 == 1;  // both kinds of views in one render
      const Image& frame = light_field.views[v].image;
      Image scores(frame.width(), frame.height(), 1, PixelType::kF32, 1);
      for (int y = 0; y < frame.height(); ++y) {
        for (int x = 0; x < frame.width(); ++x) {
          double d = frame.Value(x, y) - quadratics[v].centre;
          if (quadratics[v].one_sided) d = std::max(d, 0.0);
          *scores.At<float>(x, y) = static_cast<float>(quadratics[v].scale * d * d);
        }
      }
      scores.FillBorder();
      scores_field.views[v].image = scores;
    }
    IntegralOptions options;
    options.cam_from_world = LookAt(Vec3d(1, 2, 35), Vec3d(0, 0, 0), Vec3d(0, 1, 0));
    options.width = 203;  // not a multiple of 8: the masked last group
    options.height = 101;
    options.fov_deg = 40.0;
    options.aperture_radius = 6.0;
    options.focal_surface = FocalSurface::FromPlane(Plane{Vec3d(0, 0, 2), Vec3d(0.1, 0.0, 1.0)});
    ASSERT_TRUE(QuadraticIntegralSupported(light_field, options));
    for (bool simd : {true, false}) {
      internal::SetSimdEnabled(simd);
      const QuadraticIntegralResult both =
          RenderIntegralWithQuadratic(light_field, options, quadratics);
      const IntegralResult plain = RenderIntegral(light_field, options);
      const IntegralResult reference = RenderIntegral(scores_field, options);
      internal::SetSimdEnabled(true);
      const std::string what = std::string(PixelTypeName(type)) + (simd ? ", SIMD" : ", scalar");
      EXPECT_TRUE(test_util::SameImage(both.integral.image, plain.image)) << what;
      EXPECT_TRUE(test_util::SameImage(both.integral.count, plain.count)) << what;
      ASSERT_EQ(both.scores.width(), options.width);
      double largest = 0.0, worst = 0.0;
      int covered = 0;
      for (int y = 0; y < options.height; ++y) {
        for (int x = 0; x < options.width; ++x) {
          largest = std::max(largest, double(*reference.image.At<float>(x, y)));
        }
      }
      for (int y = 0; y < options.height; ++y) {
        for (int x = 0; x < options.width; ++x) {
          const double want = *reference.image.At<float>(x, y);
          const double got = *both.scores.At<float>(x, y);
          worst = std::max(worst, std::abs(got - want));
          covered += *plain.count.At<uint32_t>(x, y) > 0;
          if (*plain.count.At<uint32_t>(x, y) == 0) ASSERT_EQ(got, 0.0) << what;
        }
      }
      EXPECT_GT(covered, options.width * options.height / 2) << what;
      EXPECT_GT(largest, 1.0) << what;
      EXPECT_LE(worst, 2e-6 * largest) << what << ": largest score " << largest;
    }
  }
  // Refused where it does not apply, naming the reason.
  IntegralOptions nearest;
  nearest.pose_view = 0;
  nearest.aperture_radius = 0.0;
  EXPECT_FALSE(QuadraticIntegralSupported(u8, nearest));
  EXPECT_THAT(test_util::ErrorOf([&] {
                RenderIntegralWithQuadratic(u8, nearest,
                                            std::vector<ViewQuadratic>(u8.views.size()));
              }),
              HasSubstr("aperture_radius > 0"));
  IntegralOptions plane;
  plane.pose_view = 0;
  EXPECT_THAT(test_util::ErrorOf([&] { RenderIntegralWithQuadratic(u8, plane, {}); }),
              HasSubstr("per_view: 0 quadratics for"));
}

TEST(Integral, OutputsDoNotDependOnTheThreadCount) {
  // The tiles get shorter with more threads (at least four a thread), which must change no value:
  // each pixel adds its views' samples in view order whichever tile holds it.
  const LightField light_field = SimulatedLightField(6, 64, 48);
  IntegralOptions options;
  options.cam_from_world = LookAt(Vec3d(1, 2, 35), Vec3d(0, 0, 0), Vec3d(0, 1, 0));
  options.width = 131;
  options.height = 257;  // 64, 32, 21 and 8 rows a tile for 1, 2, 3 and 8 threads
  options.fov_deg = 40.0;
  options.variance = true;
  options.num_threads = 1;
  const IntegralResult one = RenderIntegral(light_field, options);
  EXPECT_GT(one.samples, 0);
  for (int threads : {2, 3, 8}) {
    options.num_threads = threads;
    const IntegralResult many = RenderIntegral(light_field, options);
    EXPECT_EQ(many.samples, one.samples);
    for (int y = 0; y < options.height; ++y) {
      for (int x = 0; x < options.width; ++x) {
        ASSERT_EQ(*many.image.At<float>(x, y), *one.image.At<float>(x, y)) << threads;
        ASSERT_EQ(*many.count.At<uint32_t>(x, y), *one.count.At<uint32_t>(x, y)) << threads;
        ASSERT_EQ(*many.variance.At<float>(x, y), *one.variance.At<float>(x, y)) << threads;
      }
    }
  }
}

// Bad input: each names the offending option.
class IntegralBadInput : public ::testing::Test {
 protected:
  void SetUp() override {
    light_field = SimulatedLightField(2, 16, 16);
    options.cam_from_world = NadirCamFromWorld(Vec3d(0, 0, 35));
  }
  std::string ErrorOf(const IntegralOptions& bad) {
    try {
      RenderIntegral(light_field, bad);
    } catch (const std::invalid_argument& error) {
      return error.what();
    }
    return "no error";
  }
  LightField light_field;
  IntegralOptions options;
};

TEST_F(IntegralBadInput, FieldOfView) {
  // 0 is "not given" (the pose view's, else 50 degrees): no error.
  for (double fov : {-5.0, 180.0, 200.0, std::nan("")}) {
    IntegralOptions bad = options;
    bad.fov_deg = fov;
    EXPECT_THAT(ErrorOf(bad), HasSubstr("fov_deg")) << fov;
  }
}

TEST_F(IntegralBadInput, LensTolerance) {
  // Checked for every render, pinhole planes too (where it changes nothing), so a bad value is
  // refused before any frame is sampled.
  for (double bad : {-0.1, 1.5, std::nan("")}) {
    IntegralOptions o = options;
    o.lens_tolerance_px = bad;
    EXPECT_THAT(ErrorOf(o), HasSubstr("lens_tolerance_px"));
  }
}

TEST_F(IntegralBadInput, FocalPlaneBehindOrParallelToTheRays) {
  IntegralOptions bad = options;
  bad.focal_surface = FocalSurface::FromPlane(Plane::AtHeight(50.0));  // above a camera at 35 m that looks down
  EXPECT_THAT(ErrorOf(bad), HasSubstr("lies behind the virtual camera"));
  // A plane through the camera centre contains (is parallel to) the rays that lie in it and
  // meets every other ray only at the centre.
  bad.focal_surface = FocalSurface::FromPlane(Plane{Vec3d(0, 0, 0), Vec3d(1, 0, 0)});  // vertical, through the axis
  EXPECT_THAT(ErrorOf(bad), HasSubstr("contains the virtual camera centre"));
  bad.focal_surface = FocalSurface::FromPlane(Plane{Vec3d(0, 0, 35), Vec3d(0.3, 0, 1)});
  EXPECT_THAT(ErrorOf(bad), HasSubstr("contains the virtual camera centre"));
  // A plane that is no plane cannot be made (the one focal-surface value is always valid).
  const auto plane_error = [](const Plane& plane) -> std::string {
    try {
      FocalSurface::FromPlane(plane);
    } catch (const std::invalid_argument& error) {
      return error.what();
    }
    return "no error";
  };
  EXPECT_THAT(plane_error(Plane{Vec3d(0, 0, 0), Vec3d(0, 0, 0)}),
              HasSubstr("focal_surface: plane: point and normal must be finite and the normal "
                        "non-zero"));
  EXPECT_THAT(plane_error(Plane{Vec3d(0, 0, std::nan("")), Vec3d(0, 0, 1)}),
              HasSubstr("focal_surface: plane: point and normal must be finite"));
}

TEST_F(IntegralBadInput, PlanesSeenByPartOfTheImageAreRendered) {
  // A vertical plane beside a nadir camera, and the ground seen by a camera looking at the
  // horizon: the pixels whose rays meet the plane in front are rendered, the others get count 0.
  IntegralOptions side = options;
  side.focal_surface = FocalSurface::FromPlane(Plane{Vec3d(5, 0, 0), Vec3d(1, 0, 0)});
  IntegralOptions horizon = options;
  horizon.cam_from_world = LookAt(Vec3d(0, 0, 2), Vec3d(10, 0, 2), Vec3d(0, 0, 1));
  horizon.fov_deg = 90.0;
  horizon.min_view_angle_deg = 0.0;
  for (const IntegralOptions& case_options : {side, horizon}) {
    const IntegralResult result = RenderIntegral(light_field, case_options);
    EXPECT_GT(result.uncovered_pixels, 0);
    EXPECT_GT(result.samples, 1000);  // and a good part is rendered
    for (int y = 0; y < result.image.height(); ++y) {
      for (int x = 0; x < result.image.width(); ++x) {
        ASSERT_TRUE(std::isfinite(*result.image.At<float>(x, y)));
      }
    }
  }
  // Looking at the horizon, no pixel above it (top row) sees the ground.
  const IntegralResult result = RenderIntegral(light_field, horizon);
  const int bottom = result.count.height() - 1;
  for (int x = 0; x < result.count.width(); ++x) {
    EXPECT_EQ(*result.count.At<uint32_t>(x, 0), 0u);
    EXPECT_GT(*result.count.At<uint32_t>(x, bottom), 0u);  // the ground just below the camera
  }
}

TEST_F(IntegralBadInput, PoseOfAnUnselectedViewIsChecked) {
  light_field.views[3].cam_from_world.rotation[0][0] = std::nan("");
  IntegralOptions bad = options;
  bad.pose_view = 3;
  bad.view_indices = {0, 1};
  EXPECT_THAT(ErrorOf(bad), HasSubstr("pose_view: view 3"));
}

TEST_F(IntegralBadInput, ViewSelectionAndPose) {
  IntegralOptions bad = options;
  bad.view_indices = {0, 7};
  EXPECT_THAT(ErrorOf(bad), HasSubstr("view_indices: no view 7"));
  bad.view_indices = {1, 1};
  EXPECT_THAT(ErrorOf(bad), HasSubstr("listed twice"));
  bad = options;
  bad.pose_view = 4;
  EXPECT_THAT(ErrorOf(bad), HasSubstr("pose_view"));
  bad = options;
  bad.cam_from_world.rotation[0][0] = std::nan("");
  EXPECT_THAT(ErrorOf(bad), HasSubstr("cam_from_world"));
  bad = options;
  bad.cam_from_world.rotation[1][0] = 0.3;
  EXPECT_THAT(ErrorOf(bad), HasSubstr("not orthonormal"));
  bad = options;
  bad.aperture_radius = -1.0;
  EXPECT_THAT(ErrorOf(bad), HasSubstr("aperture_radius"));
  LightField empty;
  try {
    RenderIntegral(empty, options);
    ADD_FAILURE() << "an empty light field must be refused";
  } catch (const std::invalid_argument& error) {
    EXPECT_THAT(error.what(), HasSubstr("view selection is empty"));
  }
}

TEST(Integral, ProgressIsReportedAndCancellationStops) {
  struct Sink : ProgressSink {
    void Start(const std::string& stage, int64_t total) override {
      this->stage = stage;
      this->total = total;
    }
    void Advance(int64_t units) override { done += units; }
    bool Cancelled() override { return cancel; }
    std::string stage;
    int64_t total = 0;
    std::atomic<int64_t> done{0};
    bool cancel = false;
  };
  const LightField light_field = SimulatedLightField(2, 16, 16);
  IntegralOptions options;
  options.cam_from_world = NadirCamFromWorld(Vec3d(0, 0, 35));
  options.width = options.height = 64;
  Sink sink;
  RenderIntegral(light_field, options, &sink);
  EXPECT_EQ(sink.stage, "render");
  EXPECT_GT(sink.total, 0);
  EXPECT_EQ(sink.done.load(), sink.total);
  Sink cancelling;
  cancelling.cancel = true;
  EXPECT_THROW(RenderIntegral(light_field, options, &cancelling), Cancelled);
}

}  // namespace
}  // namespace aos
