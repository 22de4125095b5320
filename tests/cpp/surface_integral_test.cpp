// Tests of the per-sample renderer's fast route (surface_integral.cpp: tiles, views outer,
// culls, the AVX2 kernel) against the per-pixel reference loop it replaced
// (internal::RenderIntegralAtPointsReference), and of the cylinder aperture against analytic
// truth.
#include "aos/render/surface_integral.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "aos/render/integral_kernels.h"
#include "aos/render/surface_integral_kernels.h"
#include "aos/util/math.h"
#include "render_test_util.h"

namespace aos {
namespace {

using test_util::ConstantImage;

// A random texture (every pixel independent: the steepest image there is for bilinear
// interpolation, so the float positions' error shows fully), with its border filled.
Image RandomImage(int width, int height, int channels, PixelType type, std::mt19937& rng) {
  Image image(width, height, channels, type, 1);
  std::uniform_real_distribution<float> value(0.0f, 255.0f);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      for (int c = 0; c < channels; ++c) {
        const float v = value(rng);
        switch (type) {
          case PixelType::kU8: image.At<uint8_t>(x, y)[c] = static_cast<uint8_t>(v); break;
          case PixelType::kU16: image.At<uint16_t>(x, y)[c] = static_cast<uint16_t>(v); break;
          case PixelType::kU32: image.At<uint32_t>(x, y)[c] = static_cast<uint32_t>(v); break;
          case PixelType::kF32: image.At<float>(x, y)[c] = v; break;
        }
      }
    }
  }
  image.FillBorder();
  return image;
}

// Views 18-26 m up at random positions within 14 m of the axis, each looking at a random
// ground point within 8 m of the origin (tilted up to ~35 degrees), 40 x 32 pixels, 60 degrees:
// each sees a 28 m wide patch, so the focal points below are partly outside most views.
LightField RandomLightField(int views, int channels, PixelType type, std::mt19937& rng,
                            const Vec3d& origin = Vec3d(0.0), bool lens = false) {
  std::uniform_real_distribution<double> across(-14.0, 14.0), up(18.0, 26.0), target(-8.0, 8.0);
  const PinholeCamera pinhole = PinholeCamera::FromFov(40, 32, 60.0);
  LightField light_field;
  for (int i = 0; i < views; ++i) {
    const Vec3d eye = origin + Vec3d(across(rng), across(rng), up(rng));
    const Vec3d look = origin + Vec3d(target(rng), target(rng), 0.0);
    const Rigid3d pose = LookAt(eye, look);
    const Image image = RandomImage(40, 32, channels, type, rng);
    if (lens && i % 2 == 0) {
      LensCamera camera = LensCamera::FromPinhole(pinhole);
      camera.model = LensModel::kRadTan;
      camera.distortion = {-0.05, 0.01, 0.001, -0.001, 0.0};
      camera.Finalize("test");
      light_field.views.push_back(MakeView("lens" + std::to_string(i), camera, pose, image));
    } else {
      light_field.views.push_back(MakeView("v" + std::to_string(i), pinhole, pose, image));
    }
  }
  return light_field;
}

// Focal points of a bumpy surface (heights within +-3 m) over a 36 x 30 m patch, relative to
// `reference`; a few pixels without a point; and, so that lanes land exactly on the float
// tests' edges, points on the image borders of the views (their pixel (0, v), (w, v), (u, 0),
// (u, h) back-projected) and on a cylinder of radius `radius` around view 0's vertical.
FocalPoints RandomPoints(const LightField& light_field, int width, int height,
                         const Vec3d& reference, double radius, std::mt19937& rng) {
  FocalPoints points;
  points.width = width;
  points.height = height;
  points.reference = reference;
  points.points.resize(static_cast<size_t>(width) * height);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const double phase = 6.0 * unit(rng);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const double wx = -18.0 + 36.0 * (x + 0.5) / width, wy = -15.0 + 30.0 * (y + 0.5) / height;
      const double wz = 3.0 * std::sin(0.3 * wx + phase) * std::cos(0.25 * wy);
      points.points[static_cast<size_t>(y) * width + x] = Vec3d(wx, wy, wz);
    }
  }
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (int k = 0; k < width * height / 50; ++k) {
    points.points[static_cast<size_t>(unit(rng) * width * height)] = Vec3d(nan, 0.0, 0.0);
  }
  // Border points: every 7th pixel gets one, of a random view, at a random depth.
  for (size_t k = 0; k < points.points.size(); k += 7) {
    const View& view = light_field.views[static_cast<size_t>(unit(rng) * light_field.views.size())];
    const PinholeCamera camera = view.camera.Pinhole();
    const double t = unit(rng);
    Vec2d pixel;
    switch (static_cast<int>(unit(rng) * 5)) {
      case 0: pixel = Vec2d(0.0, t * camera.height); break;
      case 1: pixel = Vec2d(camera.width, t * camera.height); break;
      case 2: pixel = Vec2d(t * camera.width, 0.0); break;
      case 3: pixel = Vec2d(t * camera.width, camera.height); break;
      default: {
        // On the cylinder of `radius` around view 0's centre's vertical.
        const Vec3d c = light_field.views[0].cam_from_world.Center();
        const double angle = 6.283185307179586 * t;
        points.points[k] = Vec3d(c.x + radius * std::cos(angle), c.y + radius * std::sin(angle),
                                 2.0 * unit(rng)) - reference;
        continue;
      }
    }
    const Vec3d ray((pixel.x - camera.cx) / camera.fx, (pixel.y - camera.cy) / camera.fy, 1.0);
    const Vec3d world = view.cam_from_world.Center() +
                        (10.0 + 15.0 * unit(rng)) * (glm::transpose(view.cam_from_world.rotation) * ray);
    points.points[k] = world - reference;
  }
  return points;
}

// The fast route agrees with the reference: the same samples (counts, views used, samples,
// uncovered pixels exactly), values to the float rounding of the kernel's positions.
//
// Tolerance: the kernel computes (U, V, Z) in float from points and a projection both rounded
// to float; on these scenes (points within 30 m of the centre, f = 35 px, depths >= 5 m) that
// moves a sample position by at most ~ 16 * 2^-24 * (f |X| + f |C_i - C|) / Z ~ 2e-4 px, and a
// bilinear sample by at most 255 * 2 * 2e-4 ~ 0.1 grey levels on a texture of independent
// pixels (the steepest possible), plus float interpolation (255 * 4 * 2^-24). The mean of the
// samples inherits that bound. Variance = E[x^2] - mean^2 moves by at most 2 * 255 * 0.1.
void ExpectSameRender(const SurfaceIntegralResult& fast, const SurfaceIntegralResult& reference,
                      double value_tolerance, const std::string& what) {
  const IntegralResult& a = fast.integral;
  const IntegralResult& b = reference.integral;
  ASSERT_EQ(a.image.width(), b.image.width()) << what;
  ASSERT_EQ(a.image.channels(), b.image.channels()) << what;
  EXPECT_EQ(a.samples, b.samples) << what;
  EXPECT_EQ(a.views_used, b.views_used) << what;
  EXPECT_EQ(a.views_selected, b.views_selected) << what;
  EXPECT_EQ(a.uncovered_pixels, b.uncovered_pixels) << what;
  int failures = 0;
  for (int y = 0; y < a.image.height() && failures < 5; ++y) {
    for (int x = 0; x < a.image.width() && failures < 5; ++x) {
      const uint32_t count = *a.count.At<uint32_t>(x, y);
      if (count != *b.count.At<uint32_t>(x, y)) {
        ADD_FAILURE() << what << ": count at " << x << "," << y << ": " << count << " vs "
                      << *b.count.At<uint32_t>(x, y);
        ++failures;
        continue;
      }
      for (int c = 0; c < a.image.channels(); ++c) {
        const double difference = std::abs(a.image.At<float>(x, y)[c] - b.image.At<float>(x, y)[c]);
        if (!(difference <= value_tolerance)) {
          ADD_FAILURE() << what << ": value at " << x << "," << y << " channel " << c << ": "
                        << a.image.At<float>(x, y)[c] << " vs " << b.image.At<float>(x, y)[c];
          ++failures;
        }
      }
      if (!a.variance.empty()) {
        const double difference =
            std::abs(a.variance.At<float>(x, y)[0] - b.variance.At<float>(x, y)[0]);
        if (!(difference <= 2.0 * 255.0 * value_tolerance + 1e-3 * b.variance.At<float>(x, y)[0])) {
          ADD_FAILURE() << what << ": variance at " << x << "," << y << ": "
                        << a.variance.At<float>(x, y)[0] << " vs " << b.variance.At<float>(x, y)[0];
          ++failures;
        }
      }
    }
  }
}

struct Case {
  PointIntegralOptions::Aperture aperture;
  double radius;
  double min_angle_deg;
};

std::string Describe(const Case& c, PixelType type, int channels) {
  return std::string(c.aperture == PointIntegralOptions::Aperture::kCylinder ? "cylinder"
                                                                              : "lens plane") +
         " r=" + std::to_string(c.radius) + " angle=" + std::to_string(c.min_angle_deg) +
         " type=" + std::to_string(static_cast<int>(type)) + " channels=" + std::to_string(channels);
}

std::vector<Case> Cases() {
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<Case> cases;
  for (auto aperture : {PointIntegralOptions::Aperture::kLensPlane,
                        PointIntegralOptions::Aperture::kCylinder}) {
    for (double radius : {inf, 6.0, 0.0}) {
      // 1 degree: the default; 50 degrees: the grazing test rejects views in most tiles.
      for (double angle : {1.0, 50.0}) cases.push_back(Case{aperture, radius, angle});
    }
  }
  return cases;
}

PointIntegralOptions OptionsFor(const Case& c, const Vec3d& reference) {
  PointIntegralOptions options;
  options.aperture = c.aperture;
  options.aperture_radius = c.radius;
  // A lens plane 22 m up, tilted a little; the cylinder's axis vertical.
  options.lens_center = reference + Vec3d(0.5, -0.3, 22.0);
  options.lens_axis = c.aperture == PointIntegralOptions::Aperture::kCylinder
                          ? Vec3d(0.0, 0.0, 1.0)
                          : glm::normalize(Vec3d(0.1, -0.05, -1.0));
  options.surface_normal = glm::normalize(Vec3d(0.05, 0.02, 1.0));
  options.min_view_angle_deg = c.min_angle_deg;
  options.num_threads = 2;
  return options;
}

TEST(RenderIntegralAtPoints, FastRouteAdmitsTheReferencesSamplesAndAgreesToFloatRounding) {
  std::mt19937 rng(1234);
  for (const auto& [type, channels] : std::vector<std::pair<PixelType, int>>{
           {PixelType::kU8, 1}, {PixelType::kF32, 1}, {PixelType::kU16, 1}, {PixelType::kU8, 3}}) {
    const LightField light_field = RandomLightField(24, channels, type, rng);
    // 150 x 90 pixels: partial tiles at the right and bottom, rows not a multiple of 8.
    const FocalPoints points = RandomPoints(light_field, 150, 90, Vec3d(0.0), 6.0, rng);
    for (const Case& c : Cases()) {
      PointIntegralOptions options = OptionsFor(c, Vec3d(0.0));
      for (bool variance : {false, true}) {
        options.variance = variance;
        const SurfaceIntegralResult fast = RenderIntegralAtPoints(light_field, points, options);
        const SurfaceIntegralResult reference =
            internal::RenderIntegralAtPointsReference(light_field, points, options, {}, nullptr);
        ASSERT_GT(reference.integral.samples, 0);
        ExpectSameRender(fast, reference, 0.1,
                         Describe(c, type, channels) + (variance ? " variance" : ""));
      }
    }
  }
}

TEST(RenderIntegralAtPoints, ScalarTileRouteEqualsTheReferenceExactly) {
  // Without SIMD every view takes the tiled route's double-precision path: the same samples
  // added in the same (view) order per pixel, so the images are bit-identical.
  std::mt19937 rng(99);
  const LightField light_field = RandomLightField(16, 1, PixelType::kU8, rng);
  const FocalPoints points = RandomPoints(light_field, 70, 67, Vec3d(0.0), 6.0, rng);
  internal::SetSimdEnabled(false);
  for (const Case& c : Cases()) {
    PointIntegralOptions options = OptionsFor(c, Vec3d(0.0));
    options.variance = true;
    const SurfaceIntegralResult fast = RenderIntegralAtPoints(light_field, points, options);
    const SurfaceIntegralResult reference =
        internal::RenderIntegralAtPointsReference(light_field, points, options, {}, nullptr);
    ExpectSameRender(fast, reference, 0.0, Describe(c, PixelType::kU8, 1) + " scalar");
    EXPECT_TRUE(test_util::SameImage(fast.integral.image, reference.integral.image));
  }
  internal::SetSimdEnabled(true);
}

TEST(RenderIntegralAtPoints, LensViewsAndAFarReferenceAgreeWithTheReference) {
  // Half the views through a radial-tangential lens (projected by LensCamera::Project, not
  // culled), and the whole scene 500 km from the origin of its frame (points relative to a
  // UTM-sized reference): admission still exact, values to float rounding.
  std::mt19937 rng(7);
  const Vec3d origin(512345.25, 5298765.5, 310.0);
  const LightField light_field = RandomLightField(20, 1, PixelType::kU8, rng, origin, true);
  const FocalPoints points = RandomPoints(light_field, 96, 80, origin, 6.0, rng);
  for (const Case& c : Cases()) {
    const PointIntegralOptions options = OptionsFor(c, origin);
    const SurfaceIntegralResult fast = RenderIntegralAtPoints(light_field, points, options);
    const SurfaceIntegralResult reference =
        internal::RenderIntegralAtPointsReference(light_field, points, options, {}, nullptr);
    ASSERT_GT(reference.integral.samples, 0);
    ExpectSameRender(fast, reference, 0.1, Describe(c, PixelType::kU8, 1) + " lens, far");
  }
}

// The robust mean's tiled route (views outer, culled per 16 x 16 tile) equals the per-pixel
// reference loop bit for bit: the same samples, appended in the same (view) order, and the same
// per-pixel arithmetic (image, count, inliers, variance, fallback pixels, views used).
void ExpectIdentical(const SurfaceIntegralResult& a, const SurfaceIntegralResult& b,
                     const std::string& what) {
  EXPECT_EQ(a.integral.samples, b.integral.samples) << what;
  EXPECT_EQ(a.integral.views_used, b.integral.views_used) << what;
  EXPECT_EQ(a.integral.uncovered_pixels, b.integral.uncovered_pixels) << what;
  EXPECT_EQ(a.used_view_indices, b.used_view_indices) << what;
  EXPECT_EQ(a.fallback_pixels, b.fallback_pixels) << what;
  EXPECT_TRUE(test_util::SameImage(a.integral.image, b.integral.image)) << what;
  EXPECT_TRUE(test_util::SameImage(a.integral.count, b.integral.count)) << what;
  EXPECT_TRUE(test_util::SameImage(a.inliers, b.inliers)) << what;
  EXPECT_EQ(a.integral.variance.empty(), b.integral.variance.empty()) << what;
  if (!a.integral.variance.empty()) {
    EXPECT_TRUE(test_util::SameImage(a.integral.variance, b.integral.variance)) << what;
  }
}

TEST(RenderIntegralAtPoints, RobustRouteGathersOneChannelPinholeViewsThroughTheExactKernel) {
  // The robust route's AVX2 gather (ExactGather) is handed out for one-channel 8-bit, 16-bit
  // and float views wherever the CPU has AVX2 and the build's scalar code does not fuse
  // multiply-adds, so that RobustTiledRouteEqualsTheReferenceExactly compares it (and not only
  // the scalar route) with the reference on this machine.
#if !defined(__x86_64__)
  GTEST_SKIP() << "no exact AVX2 gather in this build";
#else
  // The library's flags decide (AOS_NATIVE compiles the library, not this test, with FMA).
  if (!internal::ExactGatherBuilt()) GTEST_SKIP() << "no exact AVX2 gather in this build";
  __builtin_cpu_init();
  if (!__builtin_cpu_supports("avx2")) GTEST_SKIP() << "no AVX2";
  for (PixelType type : {PixelType::kU8, PixelType::kU16, PixelType::kF32}) {
    EXPECT_NE(internal::Avx2ExactGather(Image(8, 8, 1, type, 1)), nullptr);
  }
  EXPECT_EQ(internal::Avx2ExactGather(Image(8, 8, 3, PixelType::kU8, 1)), nullptr);
  EXPECT_EQ(internal::Avx2ExactGather(Image(8, 8, 1, PixelType::kU32, 1)), nullptr);
  internal::SetSimdEnabled(false);
  EXPECT_EQ(internal::Avx2ExactGather(Image(8, 8, 1, PixelType::kU8, 1)), nullptr);
  internal::SetSimdEnabled(true);
#endif
}

TEST(RenderIntegralAtPoints, RobustTiledRouteEqualsTheReferenceExactly) {
  // One-channel pinhole views take the exact AVX2 gather (where the CPU has one), three
  // channels and lens views the scalar tests and sampler.
  std::mt19937 rng(4321);
  int compared = 0;
  for (const auto& [type, channels] : std::vector<std::pair<PixelType, int>>{
           {PixelType::kU8, 1}, {PixelType::kU16, 1}, {PixelType::kF32, 1}, {PixelType::kU8, 3}}) {
    const LightField light_field = RandomLightField(24, channels, type, rng);
    // 75 x 41: partial tiles at the right and bottom.
    const FocalPoints points = RandomPoints(light_field, 75, 41, Vec3d(0.0), 6.0, rng);
    for (const Case& c : Cases()) {
      PointIntegralOptions options = OptionsFor(c, Vec3d(0.0));
      for (bool variance : {false, true}) {
        // agreement 0.3: a band of 153 grey levels on the random texture holds about half the
        // samples, so both outcomes (inliers, fallback) occur.
        for (double agreement : {0.02, 0.3}) {
          options.variance = variance;
          SurfaceIntegralOptions surface;
          surface.robust = true;
          surface.agreement = agreement;
          const SurfaceIntegralResult tiled =
              RenderIntegralAtPoints(light_field, points, options, surface);
          const SurfaceIntegralResult reference = internal::RenderIntegralAtPointsReference(
              light_field, points, options, surface, nullptr);
          ASSERT_GT(reference.integral.samples, 0);
          ExpectIdentical(tiled, reference,
                          Describe(c, type, channels) + (variance ? " variance" : "") +
                              " agreement " + std::to_string(agreement));
          compared += reference.fallback_pixels > 0;
        }
      }
    }
  }
  EXPECT_GT(compared, 0);  // some cases had fallback pixels
  // Lens views (not culled by the image bounds) and a UTM-sized frame.
  const Vec3d origin(512345.25, 5298765.5, 310.0);
  const LightField light_field = RandomLightField(20, 1, PixelType::kU8, rng, origin, true);
  const FocalPoints points = RandomPoints(light_field, 40, 37, origin, 6.0, rng);
  for (const Case& c : Cases()) {
    const PointIntegralOptions options = OptionsFor(c, origin);
    SurfaceIntegralOptions surface;
    surface.robust = true;
    ExpectIdentical(RenderIntegralAtPoints(light_field, points, options, surface),
                    internal::RenderIntegralAtPointsReference(light_field, points, options,
                                                              surface, nullptr),
                    Describe(c, PixelType::kU8, 1) + " lens, far");
  }
}

TEST(RenderIntegralAtPoints, CylinderAdmitsAViewIffItsHorizontalDistanceIsAtMostTheRadius) {
  // Views straight down at horizontal distances d = 1, 2, ..., 8 m from the focal point (and a
  // second view at d = 5 m, the other side); each view's image is its own index + 1. A
  // cylinder of radius r admits exactly the views with d <= r (d = r included), whatever the
  // views' heights; radius 0 takes the nearest view (d = 1), ties to the lower index.
  const PinholeCamera camera = PinholeCamera::FromFov(32, 32, 120.0);
  LightField light_field;
  std::vector<double> distances;
  for (int k = 1; k <= 8; ++k) distances.push_back(k);
  distances.push_back(5.0);
  for (size_t i = 0; i < distances.size(); ++i) {
    const double side = i + 1 == distances.size() ? -1.0 : 1.0;
    const Vec3d centre(100.0 + side * distances[i], 200.0, 20.0 + static_cast<double>(i));
    light_field.views.push_back(MakeView("v" + std::to_string(i), camera, NadirCamFromWorld(centre),
                                         ConstantImage(32, 32, {static_cast<float>(i + 1)})));
  }
  FocalPoints points;
  points.width = points.height = 1;
  points.reference = Vec3d(100.0, 200.0, 3.0);
  points.points = {Vec3d(0.0)};
  PointIntegralOptions options;
  options.aperture = PointIntegralOptions::Aperture::kCylinder;
  options.min_view_angle_deg = 0.0;
  for (double radius : {0.5, 1.0, 2.5, 5.0, 5.5, 7.999, 8.0, 100.0}) {
    options.aperture_radius = radius;
    double sum = 0.0;
    uint32_t count = 0;
    for (size_t i = 0; i < distances.size(); ++i) {
      if (distances[i] <= radius) {
        sum += static_cast<double>(i + 1);
        ++count;
      }
    }
    const SurfaceIntegralResult result = RenderIntegralAtPoints(light_field, points, options);
    EXPECT_EQ(*result.integral.count.At<uint32_t>(0, 0), count) << "r = " << radius;
    if (count > 0) {
      EXPECT_FLOAT_EQ(*result.integral.image.At<float>(0, 0), static_cast<float>(sum / count))
          << "r = " << radius;
    }
    EXPECT_EQ(result.integral.views_used, static_cast<int>(count)) << "r = " << radius;
  }
  options.aperture_radius = 0.0;
  const SurfaceIntegralResult nearest = RenderIntegralAtPoints(light_field, points, options);
  EXPECT_EQ(*nearest.integral.count.At<uint32_t>(0, 0), 1u);
  EXPECT_EQ(*nearest.integral.image.At<float>(0, 0), 1.0f);
  // Without the d = 1..4 views, the two at d = 5 tie: the lower index (4, value 5) wins.
  options.view_indices = {4, 5, 6, 7, 8};
  const SurfaceIntegralResult tie = RenderIntegralAtPoints(light_field, points, options);
  EXPECT_EQ(*tie.integral.image.At<float>(0, 0), 5.0f);
  EXPECT_EQ(tie.integral.views_used, 1);
}

TEST(RenderIntegralAtPoints, ViewsOutsideEveryTileAreNotUsedAndPixelsWithoutPointsAreUncovered) {
  // A view looking away from the points contributes nothing (culled); NaN points count 0.
  std::mt19937 rng(5);
  LightField light_field = RandomLightField(6, 1, PixelType::kU8, rng);
  FocalPoints points = RandomPoints(light_field, 20, 20, Vec3d(0.0), 6.0, rng);
  light_field.views.push_back(MakeView("away", PinholeCamera::FromFov(40, 32, 60.0),
                                       LookAt(Vec3d(0, 0, 20), Vec3d(0, 0, 40)),
                                       ConstantImage(40, 32, {255.0f}, PixelType::kU8)));
  for (int x = 0; x < 20; ++x) points.points[static_cast<size_t>(x)] = Vec3d(std::nan(""));
  PointIntegralOptions options;
  options.min_view_angle_deg = 0.0;
  const SurfaceIntegralResult fast = RenderIntegralAtPoints(light_field, points, options);
  const SurfaceIntegralResult reference =
      internal::RenderIntegralAtPointsReference(light_field, points, options, {}, nullptr);
  ExpectSameRender(fast, reference, 0.1, "culled view");
  for (int x = 0; x < 20; ++x) EXPECT_EQ(*fast.integral.count.At<uint32_t>(x, 0), 0u);
  EXPECT_LE(fast.integral.views_used, 6);
}

// A smooth texture (sums of sines): its largest step between neighbouring pixels bounds how much
// a bilinear sample moves when its position moves (Lipschitz), so the lens route's sample error
// can be bounded tightly from its position tolerance.
Image SmoothImage(int width, int height, double phase) {
  Image image(width, height, 1, PixelType::kF32, 1);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      image.At<float>(x, y)[0] = static_cast<float>(
          128.0 + 60.0 * std::sin(0.35 * x + 0.2 * y + phase) + 40.0 * std::cos(0.27 * y - 0.1 * x));
    }
  }
  image.FillBorder();
  return image;
}

// Gx + Gy, the largest steps between horizontal and between vertical neighbours: a bilinear
// sample moves by at most |du| Gx + |dv| Gy <= |(du, dv)| (Gx + Gy).
double LargestSteps(const Image& image) {
  double gx = 0.0, gy = 0.0;
  for (int y = 0; y + 1 < image.height(); ++y) {
    for (int x = 0; x + 1 < image.width(); ++x) {
      const float v = image.At<float>(x, y)[0];
      gx = std::max(gx, static_cast<double>(std::abs(image.At<float>(x + 1, y)[0] - v)));
      gy = std::max(gy, static_cast<double>(std::abs(image.At<float>(x, y + 1)[0] - v)));
    }
  }
  return gx + gy;
}

// 3 x 3 views 16 m up, 6 m apart, through `lens`: eight look straight down, the centre one looks
// sideways (towards +x, 10 degrees below the horizon), so that half of the ground lies behind
// it and the edge of its valid field (or image) crosses the output's tiles.
LightField LensLightField(const LensCamera& lens) {
  LightField light_field;
  for (int i = 0; i < 9; ++i) {
    const Vec3d eye(6.0 * (i % 3 - 1), 6.0 * (i / 3 - 1), 16.0);
    const Rigid3d pose = i == 4 ? LookAt(eye, eye + Vec3d(1.0, 0.0, -0.176), Vec3d(0.0, 0.0, 1.0))
                                : NadirCamFromWorld(eye);
    light_field.views.push_back(
        MakeView("lens" + std::to_string(i), lens, pose, SmoothImage(lens.width, lens.height, i)));
  }
  return light_field;
}

TEST(RenderIntegral, LensViewsThroughLocalHomographiesAgreeWithTheExactProjection) {
  // Fisheye (180 degrees, and its valid field ending inside the frame by a folding distortion),
  // omnidirectional (200 degrees: rays up to 100 degrees off the axis, behind the camera) and
  // radial-tangential lenses; a virtual camera 30 m up with a 110-degree field over the ground
  // plane (partial tiles at the right and bottom): the fast route (default tolerance) against
  // lens_tolerance_px = 0 (every sample through LensCamera::Project). A sample position within
  // tolerance t of the exact one changes a bilinear sample by at most t (Gx + Gy) (the largest
  // neighbour steps); the tolerance is checked at each quad's nodes, not everywhere, so the
  // bound allows twice that, plus float rounding (the kernel samples in float).
  struct LensCase {
    const char* name;
    LensCamera lens;
  };
  const std::vector<LensCase> cases = {
      {"fisheye 180", LensFromFov(LensModel::kFisheye, 160, 120, 180.0, {0.01, -0.002, 0, 0, 0},
                                  0.0, "test")},
      // k1 = -0.3 folds at 60 degrees: the image circle ends inside the frame's corners and,
      // seen from 16 m, on a circle of 27.7 m radius on the ground, inside the output.
      {"fisheye folding", LensFromFov(LensModel::kFisheye, 64, 64, 110.0,
                                      {-0.3, 0.0, 0, 0, 0}, 0.0, "test")},
      {"omnidir 200", LensFromFov(LensModel::kOmnidir, 160, 120, 200.0, {-0.05, 0.01, 0, 0, 0},
                                  1.2, "test")},
      {"radtan 100", LensFromFov(LensModel::kRadTan, 160, 120, 100.0,
                                 {-0.05, 0.01, 0.001, -0.001, 0.0}, 0.0, "test")},
  };
  for (const LensCase& c : cases) {
    SCOPED_TRACE(c.name);
    const LightField light_field = LensLightField(c.lens);
    IntegralOptions options;
    options.cam_from_world = NadirCamFromWorld(Vec3d(0.3, -0.2, 30.0));
    options.fov_deg = 110.0;
    options.width = 200;
    options.height = 150;
    options.lens_tolerance_px = 0.0;
    const IntegralResult exact = RenderIntegral(light_field, options);
    options.lens_tolerance_px = 0.02;
    const IntegralResult fast = RenderIntegral(light_field, options);
    ASSERT_GT(exact.samples, 0);
    double steps = 0.0;
    for (const View& view : light_field.views) steps = std::max(steps, LargestSteps(view.image));
    const double bound = 2.0 * options.lens_tolerance_px * steps + 1e-3;
    int64_t count_mismatches = 0, compared = 0;
    double largest = 0.0;
    for (int y = 0; y < options.height; ++y) {
      for (int x = 0; x < options.width; ++x) {
        const uint32_t n = fast.count.At<uint32_t>(x, y)[0];
        if (n != exact.count.At<uint32_t>(x, y)[0]) {
          ++count_mismatches;
          continue;
        }
        if (n == 0) continue;
        ++compared;
        largest = std::max(largest, static_cast<double>(std::abs(fast.image.At<float>(x, y)[0] -
                                                                 exact.image.At<float>(x, y)[0])));
      }
    }
    EXPECT_LE(largest, bound) << "largest difference against the exact projection";
    // The route was taken: the values are not the exact route's (they differ by more than the
    // float rounding of the kernel).
    EXPECT_GT(largest, 1e-3);
    // Admission is decided on the fitted position: counts may differ only where a sample lies
    // within the tolerance of a view's image edge.
    EXPECT_LE(count_mismatches, compared / 500) << count_mismatches << " of " << compared;
    EXPECT_EQ(fast.views_used, exact.views_used);
  }
}

TEST(RenderIntegral, LensViewsDoNotDependOnTheThreadCount) {
  // Tiles are independent (their node cache, quads and fits are per tile and view), so the
  // lens route's output is the same bit for bit with any number of threads.
  for (const LensCamera& lens :
       {LensFromFov(LensModel::kFisheye, 160, 120, 180.0, {0.01, -0.002, 0, 0, 0}, 0.0, "test"),
        LensFromFov(LensModel::kOmnidir, 160, 120, 200.0, {-0.05, 0.01, 0, 0, 0}, 1.2, "test"),
        LensFromFov(LensModel::kRadTan, 160, 120, 100.0, {-0.05, 0.01, 0.001, -0.001, 0.0}, 0.0,
                    "test")}) {
    SCOPED_TRACE(LensModelName(lens.model));
    const LightField light_field = LensLightField(lens);
    IntegralOptions options;
    options.cam_from_world = NadirCamFromWorld(Vec3d(0.3, -0.2, 30.0));
    options.fov_deg = 110.0;
    options.width = 200;
    options.height = 150;
    options.num_threads = 1;
    const IntegralResult one = RenderIntegral(light_field, options);
    ASSERT_GT(one.samples, 0);
    for (int threads : {2, 3}) {
      options.num_threads = threads;
      const IntegralResult many = RenderIntegral(light_field, options);
      EXPECT_EQ(many.samples, one.samples) << threads << " threads";
      int64_t differing = 0;
      for (int y = 0; y < options.height; ++y) {
        for (int x = 0; x < options.width; ++x) {
          differing += many.image.At<float>(x, y)[0] != one.image.At<float>(x, y)[0] ||
                       many.count.At<uint32_t>(x, y)[0] != one.count.At<uint32_t>(x, y)[0];
        }
      }
      EXPECT_EQ(differing, 0) << threads << " threads";
    }
  }
}

// Whether the lens route's point kernel runs on this machine (AVX2 and FMA, SIMD enabled): without
// it every sample takes the exact projection and the route's quad counts stay 0.
bool PointKernelRuns() {
  return internal::Avx2PointKernel(Image(8, 8, 1, PixelType::kF32, 1)) != nullptr;
}

TEST(RenderIntegral, RadialTangentialQuadsAreFittedBelowA64PixelTileThatMissed) {
  // The lens benchmark's radial-tangential case (tools/bench_lens.py: 1024 x 1024 frames, 100
  // degrees, from 20 m; a 512 x 512 60-degree output), 3 x 3 views: a 64-pixel tile's affine
  // fit misses the 0.02 px tolerance by far more than 8x, yet nearly every 32-pixel quad passes
  // through the homography. A quarter of the tile's error (the split-without-fit rule of affine
  // fits) must not send them down to 16 pixels (4x the fits and nodes).
  if (!PointKernelRuns()) GTEST_SKIP() << "no AVX2 point kernel: the lens route is not taken";
  const LensCamera lens = LensFromFov(LensModel::kRadTan, 1024, 1024, 100.0,
                                      {-0.05, 0.01, 0.001, -0.001, 0.0}, 0.0, "test");
  LightField light_field;
  for (int i = 0; i < 9; ++i) {
    const Vec3d eye(4.0 * (i % 3 - 1), 4.0 * (i / 3 - 1), 20.0);
    light_field.views.push_back(MakeView("radtan" + std::to_string(i), lens, NadirCamFromWorld(eye),
                                         SmoothImage(lens.width, lens.height, i)));
  }
  IntegralOptions options;
  options.cam_from_world = NadirCamFromWorld(Vec3d(0.0, 0.0, 20.0));
  options.fov_deg = 60.0;
  options.width = options.height = 512;
  options.lens_tolerance_px = 0.0;
  const IntegralResult exact = RenderIntegral(light_field, options);
  options.lens_tolerance_px = 0.02;
  internal::ResetLensRouteCounts();
  const IntegralResult fast = RenderIntegral(light_field, options);
  const internal::LensRouteCounts counts = internal::GetLensRouteCounts();
  EXPECT_GT(counts.fitted_quads[1], 0);
  EXPECT_LE(counts.fitted_quads[2] + counts.fitted_quads[3] + counts.exact_quads,
            counts.fitted_quads[1] / 20)
      << "16-pixel quads " << counts.fitted_quads[2] << ", 32-pixel quads "
      << counts.fitted_quads[1];
  // Within the same bound as the other lens cases (LensViewsThroughLocalHomographies...).
  double steps = 0.0;
  for (const View& view : light_field.views) steps = std::max(steps, LargestSteps(view.image));
  const double bound = 2.0 * options.lens_tolerance_px * steps + 1e-3;
  double largest = 0.0;
  int64_t count_mismatches = 0;
  for (int y = 0; y < options.height; ++y) {
    for (int x = 0; x < options.width; ++x) {
      const uint32_t n = fast.count.At<uint32_t>(x, y)[0];
      if (n != exact.count.At<uint32_t>(x, y)[0]) ++count_mismatches;
      if (n == 0 || n != exact.count.At<uint32_t>(x, y)[0]) continue;
      largest = std::max(largest, static_cast<double>(std::abs(fast.image.At<float>(x, y)[0] -
                                                               exact.image.At<float>(x, y)[0])));
    }
  }
  EXPECT_LE(largest, bound);
  EXPECT_LE(count_mismatches, options.width * options.height / 500);
}

// A ramp: pixel (x, y) holds x + 0.5 (along_x) or y + 0.5, the continuous coordinate of its
// centre, so that a bilinear sample inside the image is its position u (or v) exactly.
Image RampImage(int width, int height, bool along_x) {
  Image image(width, height, 1, PixelType::kF32, 1);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      image.At<float>(x, y)[0] = static_cast<float>((along_x ? x : y) + 0.5);
    }
  }
  image.FillBorder();
  return image;
}

// The fast lens route's render against the exact one's (lens_tolerance_px 0), one channel:
// the largest difference where both sampled the pixel equally often, the pixels whose counts
// differ, the pixels compared and those of them with fewer than `partial_below` samples.
struct RouteDifference {
  double largest = 0.0;
  int64_t count_mismatches = 0;
  int64_t compared = 0;
  int64_t partial = 0;
};
RouteDifference CompareWithExactRoute(const IntegralResult& fast, const IntegralResult& exact,
                                      uint32_t partial_below = 0) {
  RouteDifference out;
  for (int y = 0; y < fast.count.height(); ++y) {
    for (int x = 0; x < fast.count.width(); ++x) {
      const uint32_t n = fast.count.At<uint32_t>(x, y)[0];
      if (n != exact.count.At<uint32_t>(x, y)[0]) ++out.count_mismatches;
      if (n == 0 || n != exact.count.At<uint32_t>(x, y)[0]) continue;
      ++out.compared;
      out.partial += n < partial_below;
      out.largest = std::max(out.largest, static_cast<double>(std::abs(
                                              fast.image.At<float>(x, y)[0] -
                                              exact.image.At<float>(x, y)[0])));
    }
  }
  return out;
}

// The lens benchmark's wide lenses (tools/bench_lens.py): 1024 x 1024 frames through a
// fisheye of 180 degrees and an omnidirectional (Mei) lens of 200 degrees.
struct WideLensCase {
  const char* name;
  LensCamera lens;
};
std::vector<WideLensCase> BenchLensWideLenses() {
  return {{"fisheye 180", LensFromFov(LensModel::kFisheye, 1024, 1024, 180.0,
                                      {0.01, -0.002, 0, 0, 0}, 0.0, "test")},
          {"omnidir 200", LensFromFov(LensModel::kOmnidir, 1024, 1024, 200.0,
                                      {-0.05, 0.01, 0, 0, 0}, 1.2, "test")}};
}

TEST(RenderIntegral, WideLensesAreSampledThroughCubicMapsOn64PixelQuads) {
  // The lens benchmark's fisheye and omnidirectional cases (tools/bench_lens.py: 1024 x 1024
  // frames, 180 and 200 degrees, from 20 m; a 512 x 512 60-degree output), 3 x 3 views 4 m
  // apart: the cubic map (LensRoute::FitCubic) passes the 0.02 px tolerance on whole 64-pixel
  // tiles (its residual there is about 3e-4 px), where homographies passed only at 16 pixels.
  // The frames are ramps (RampImage), so each output pixel is the mean over the views of the
  // sample positions u (or v): the fast render differs from lens_tolerance_px = 0's by at most
  // the tolerance (the fit's error bound at every point of the quad, on a plane), plus the
  // kernel's float rounding (positions of about 1000 pixels: 1e-4). A wrong cubic (a
  // coefficient, the pixel-centre offset) or a bound that lets a worse fit through fails here.
  if (!PointKernelRuns()) GTEST_SKIP() << "no AVX2 point kernel: the lens route is not taken";
  const std::vector<WideLensCase> cases = BenchLensWideLenses();
  for (const WideLensCase& c : cases) {
    for (const bool along_x : {true, false}) {
      SCOPED_TRACE(std::string(c.name) + (along_x ? ", u" : ", v"));
      LightField light_field;
      const Image ramp = RampImage(c.lens.width, c.lens.height, along_x);
      for (int i = 0; i < 9; ++i) {
        const Vec3d eye(4.0 * (i % 3 - 1), 4.0 * (i / 3 - 1), 20.0);
        light_field.views.push_back(
            MakeView("lens" + std::to_string(i), c.lens, NadirCamFromWorld(eye), ramp));
      }
      IntegralOptions options;
      options.cam_from_world = NadirCamFromWorld(Vec3d(0.0, 0.0, 20.0));
      options.fov_deg = 60.0;
      options.width = options.height = 512;
      options.lens_tolerance_px = 0.0;
      const IntegralResult exact = RenderIntegral(light_field, options);
      options.lens_tolerance_px = 0.02;
      internal::ResetLensRouteCounts();
      const IntegralResult fast = RenderIntegral(light_field, options);
      const internal::LensRouteCounts counts = internal::GetLensRouteCounts();
      // 64 tiles x 9 views, each through one cubic map on 25 exactly projected nodes.
      EXPECT_EQ(counts.fitted_quads[0], 64 * 9);
      EXPECT_EQ(counts.fitted_quads[1] + counts.fitted_quads[2] + counts.fitted_quads[3] +
                    counts.exact_quads,
                0);
      EXPECT_LE(counts.projected_nodes, 64 * 9 * 25);
      const RouteDifference d = CompareWithExactRoute(fast, exact);
      EXPECT_LE(d.largest, options.lens_tolerance_px + 1e-4) << "pixels";
      EXPECT_EQ(d.count_mismatches, 0);  // every view covers the output with a margin
    }
  }
}

// Ramp frames (RampImage, along x or y) through `lens` from nadir views at `eyes`, rendered on
// the depth map depth_at(x, y) (metres) of a 256 x 256, 60-degree camera 20 m over the origin,
// with the exact projection and with lens_tolerance_px 0.02: how far the fast render is from
// the exact one (view pixels: each output pixel is the mean of its views' sample positions),
// and the fast render's lens-route counts.
struct OnDepthRoutes {
  RouteDifference difference;
  internal::LensRouteCounts counts;
};
OnDepthRoutes RenderOnDepthBothRoutes(const LensCamera& lens, const std::vector<Vec3d>& eyes,
                                      bool along_x,
                                      const std::function<double(int, int)>& depth_at) {
  LightField light_field;
  const Image ramp = RampImage(lens.width, lens.height, along_x);
  for (size_t i = 0; i < eyes.size(); ++i) {
    light_field.views.push_back(
        MakeView("lens" + std::to_string(i), lens, NadirCamFromWorld(eyes[i]), ramp));
  }
  IntegralOptions options;
  options.cam_from_world = NadirCamFromWorld(Vec3d(0.0, 0.0, 20.0));
  options.fov_deg = 60.0;
  options.width = options.height = 256;
  Image depth(options.width, options.height, 1, PixelType::kF32);
  for (int y = 0; y < options.height; ++y) {
    for (int x = 0; x < options.width; ++x) {
      depth.At<float>(x, y)[0] = static_cast<float>(depth_at(x, y));
    }
  }
  options.lens_tolerance_px = 0.0;
  const SurfaceIntegralResult exact = RenderIntegralOnDepth(light_field, options, depth);
  options.lens_tolerance_px = 0.02;
  internal::ResetLensRouteCounts();
  const SurfaceIntegralResult fast = RenderIntegralOnDepth(light_field, options, depth);
  return {CompareWithExactRoute(fast.integral, exact.integral), internal::GetLensRouteCounts()};
}

// 3 x 3 views 4 m apart, 20 m up.
std::vector<Vec3d> NineEyes() {
  std::vector<Vec3d> eyes;
  for (int i = 0; i < 9; ++i) eyes.emplace_back(4.0 * (i % 3 - 1), 4.0 * (i / 3 - 1), 20.0);
  return eyes;
}

double Waves(int x, int y) {  // a 128-pixel sine in x times one in y
  return std::sin(2.0 * kPi * x / 128.0) * std::cos(2.0 * kPi * y / 128.0);
}

TEST(RenderIntegralOnDepth, WideLensCubicMapsHoldTheToleranceOnReliefTiltsAndSteps) {
  // The cubic map's tolerance where the focal points are not a plane's bilinear grid. The map
  // is a function of a ray's direction (q, the tangent-plane coordinates the kernel forms from
  // each focal point), so a relief only matters through the directions its rays turn to:
  // FitCubic validates the map over the nodes' q box grown by the largest turn (the relief's
  // departure from the bilinear sheet through the quad's corners, over the distance), at a
  // 5 x 5 grid of exact projections. Surfaces, depth in metres below views 20 m up:
  //  - a relief of +-5 cm over 128 pixels, on a depth that grows by 0.02 mm per pixel: a turn of
  //    about 3e-3 rad, which the old bound (the turn at the map's full gradient: about 2 px)
  //    sent to the exact projection everywhere; now the 64-pixel cubics pass;
  //  - a 1 m step along a diagonal: the tiles across it are split (to 32- and 16-pixel maps);
  //  - a 6 m step: the turn (about 0.4 rad) grows the box past what a cubic holds, so the quads
  //    along the step are split down to the exact projection;
  //  - an 8 m pillar of 4 x 4 pixels near each tile's corner, between the nodes: its rays turn
  //    outside the nodes' q, where the cubic extrapolates. Validated on the nodes alone (the box
  //    not grown) the 64-pixel maps pass and the pillar's pixels miss by far more than the
  //    tolerance (checked by hand: this test then fails here); with the grown box they are
  //    split.
  // Ramp frames (RampImage): the fast render differs from lens_tolerance_px = 0's by at most the
  // tolerance, plus float rounding, as on the plane.
  if (!PointKernelRuns()) GTEST_SKIP() << "no AVX2 point kernel: the lens route is not taken";
  const LensCamera lens =
      LensFromFov(LensModel::kFisheye, 1024, 1024, 180.0, {0.01, -0.002, 0, 0, 0}, 0.0, "test");
  struct Surface {
    const char* name;
    double relief_m, step_m, pillar_m;
  };
  for (const Surface& surface :
       {Surface{"relief", 0.05, 0.0, 0.0}, Surface{"1 m step", 0.0, 1.0, 0.0},
        Surface{"6 m step", 0.0, 6.0, 0.0}, Surface{"8 m pillar", 0.0, 0.0, 8.0}}) {
    for (const bool along_x : {true, false}) {
      SCOPED_TRACE(std::string(surface.name) + (along_x ? ", u" : ", v"));
      const OnDepthRoutes r = RenderOnDepthBothRoutes(lens, NineEyes(), along_x, [&](int x, int y) {
        // The pillar: 4 x 4 pixels near a tile's corner, between the cubic's nodes (0, 16, 32,
        // 47, 63), so no node sees it.
        const bool pillar = x % 64 >= 56 && x % 64 < 60 && y % 64 >= 56 && y % 64 < 60;
        return 20.0 + 2e-5 * x + surface.relief_m * Waves(x, y) -
               (x + y > 300 ? surface.step_m : 0.0) - (pillar ? surface.pillar_m : 0.0);
      });
      if (surface.relief_m > 0.0) {
        // 16 tiles x 9 views, every one through one cubic map.
        EXPECT_EQ(r.counts.fitted_quads[0], 16 * 9);
        EXPECT_EQ(r.counts.exact_quads, 0);
      } else if (surface.step_m > 0.0) {
        EXPECT_GT(r.counts.fitted_quads[0], 0);  // away from the step
        if (surface.step_m > 2.0) EXPECT_GT(r.counts.exact_quads, 0);  // along it
      } else {
        EXPECT_EQ(r.counts.fitted_quads[0], 0);  // every tile holds a pillar
      }
      EXPECT_LE(r.difference.largest, 0.02 + 1e-4) << "pixels";
      EXPECT_EQ(r.difference.count_mismatches, 0);
    }
  }
}

TEST(RenderIntegralOnDepth, RadialTangentialHomographiesHoldTheToleranceOnARelief) {
  // The same +-5 cm relief through the lens benchmark's radial-tangential lens: its local
  // homographies are validated over the turned rays too (LensRoute::TurnedError), so the
  // relief's quads are fitted (most at 16 pixels, as on the plane) instead of projected
  // exactly. A
  // homography is checked at its nodes and that grid, not between them, so the bound is twice
  // the tolerance as for the other radial-tangential cases, plus float rounding.
  if (!PointKernelRuns()) GTEST_SKIP() << "no AVX2 point kernel: the lens route is not taken";
  const LensCamera lens = LensFromFov(LensModel::kRadTan, 1024, 1024, 100.0,
                                      {-0.05, 0.01, 0.001, -0.001, 0.0}, 0.0, "test");
  for (const bool along_x : {true, false}) {
    SCOPED_TRACE(along_x ? "u" : "v");
    const OnDepthRoutes r = RenderOnDepthBothRoutes(
        lens, NineEyes(), along_x, [](int x, int y) { return 20.0 + 0.05 * Waves(x, y); });
    // None projected exactly, and most quads as large as on the plane through the relief's
    // mean (there: 37 of 32 pixels, 2156 of 16, none of 8; here 14, 2152 and 384).
    EXPECT_EQ(r.counts.exact_quads, 0);
    EXPECT_LE(r.counts.fitted_quads[3], r.counts.fitted_quads[2] / 4);
    EXPECT_LE(r.difference.largest, 2.0 * 0.02 + 1e-4) << "pixels";
    EXPECT_EQ(r.difference.count_mismatches, 0);
  }
}

TEST(RenderIntegralOnDepth, OneViewThroughAReliefKeepsTheToleranceWherePillarsTurnItsRays) {
  // One radial-tangential view 6 m aside (no mean over views to dilute one view's error) and
  // 4 m pillars of 2 x 2 pixels between the nodes of every 64-pixel tile: their rays turn by
  // about 0.1 rad, past the nodes' q. With the grid check of LensRoute::TurnedError skipped
  // (the map accepted on its nodes), this misses by 0.09-0.12 px (checked by hand); with it,
  // the quads that hold a pillar are validated over the turned rays or split.
  // Homographies are checked at nodes and grid points, not between them, so the bound is twice
  // the tolerance, plus float rounding (as the other radial-tangential cases).
  if (!PointKernelRuns()) GTEST_SKIP() << "no AVX2 point kernel: the lens route is not taken";
  const LensCamera lens = LensFromFov(LensModel::kRadTan, 1024, 1024, 100.0,
                                      {-0.05, 0.01, 0.001, -0.001, 0.0}, 0.0, "test");
  for (const bool along_x : {true, false}) {
    SCOPED_TRACE(along_x ? "u" : "v");
    const OnDepthRoutes r =
        RenderOnDepthBothRoutes(lens, {Vec3d(6.0, -3.0, 20.0)}, along_x, [](int x, int y) {
          const bool pillar = x % 64 >= 20 && x % 64 < 22 && y % 64 >= 20 && y % 64 < 22;
          return pillar ? 16.0 : 20.0;
        });
    EXPECT_GT(r.difference.compared, 256 * 256 / 2);
    EXPECT_LE(r.difference.largest, 2.0 * 0.02 + 1e-4) << "pixels";
    EXPECT_EQ(r.difference.count_mismatches, 0);
  }
}

TEST(RenderIntegral, WideLensCubicMapsOnClippedTilesAndAcrossAFrameEdgeAgreeWithTheExactRoute) {
  // A fisheye frame of 1024 x 768 pixels, 120 degrees across: its edges are 60 degrees off the
  // axis left and right and about 45 above and below, inside the lens's valid field. Three
  // views 20 m up: one over the output's centre, one 16 m aside in y (rays up to 48 degrees
  // off its axis towards -y: its frame's edge crosses the output) and one 24 m aside in x (up to
  // 61 degrees: likewise). On the cubic path the kernel's (U, V) / Z are tangent-plane
  // coordinates, not pixels, so quads that need an image bound tested (*image_tests != 0) must
  // be refused there and split down to the homographies, which test them. The output, 486 x 260
  // over 60 degrees, clips the tiles: the right column is 38 pixels wide, the bottom row 4
  // pixels high, fewer than the cubic's 8 (the 5 x 5 nodes 2 pixels apart), so its quads are
  // fitted by homographies from 16 pixels down. Ramp frames (RampImage): each output pixel is
  // the mean of its views' sample positions. The cubic's error estimate is checked everywhere
  // on its quad, a homography's only at its 3 x 3 nodes, which the other lens cases
  // (LensViewsThroughLocalHomographies...) allow twice the tolerance for; plus float rounding:
  // the kernel's bilinear sample and the two renders' float outputs, 4 x 2^-24 x 1024 px.
  if (!PointKernelRuns()) GTEST_SKIP() << "no AVX2 point kernel: the lens route is not taken";
  const LensCamera lens =
      LensFromFov(LensModel::kFisheye, 1024, 768, 120.0, {0.01, -0.002, 0, 0, 0}, 0.0, "test");
  for (const bool along_x : {true, false}) {
    SCOPED_TRACE(along_x ? "u" : "v");
    LightField light_field;
    const Image ramp = RampImage(lens.width, lens.height, along_x);
    for (const Vec3d& eye :
         {Vec3d(0.0, 0.0, 20.0), Vec3d(0.0, 16.0, 20.0), Vec3d(24.0, 0.0, 20.0)}) {
      light_field.views.push_back(MakeView("lens" + std::to_string(light_field.views.size()), lens,
                                           NadirCamFromWorld(eye), ramp));
    }
    IntegralOptions options;
    options.cam_from_world = NadirCamFromWorld(Vec3d(0.0, 0.0, 20.0));
    options.fov_deg = 60.0;
    options.width = 486;
    options.height = 260;
    options.lens_tolerance_px = 0.0;
    const IntegralResult exact = RenderIntegral(light_field, options);
    options.lens_tolerance_px = 0.02;
    internal::ResetLensRouteCounts();
    const IntegralResult fast = RenderIntegral(light_field, options);
    const internal::LensRouteCounts counts = internal::GetLensRouteCounts();
    EXPECT_GT(counts.fitted_quads[0], 0);
    EXPECT_GT(counts.fitted_quads[2], 0);  // the bottom row's, and across the frames' edges
    ASSERT_GT(exact.samples, 0);
    const double rounding = 4.0 * 0x1.0p-24 * 1024.0;
    const RouteDifference d = CompareWithExactRoute(fast, exact, 3);
    EXPECT_LE(d.largest, 2.0 * options.lens_tolerance_px + rounding) << "pixels";
    // Both aside views' frames end inside the output.
    EXPECT_GT(d.partial, d.compared / 10);
    EXPECT_LT(d.partial, d.compared);
    // Admission is decided on the fitted position: counts may differ only where a sample lies
    // within the tolerance of a frame's edge (a band of about 0.02 output pixels along some
    // 750 pixels of edges: about 15 pixels; 13 on this machine).
    EXPECT_LE(d.count_mismatches, 50);
  }
}

// One view of the lens benchmark's 3 x 3 layout (4 m apart, 20 m up) rendered alone over
// ramp frames (RampImage: the output is the view's sample position u or v), by the fast route
// and by the exact one (lens_tolerance_px = 0): the lens route's counts and the largest
// difference where both sampled.
struct AloneRender {
  internal::LensRouteCounts counts;
  double largest = 0.0;
  int64_t count_mismatches = 0;
};
AloneRender RenderAlone(const LensCamera& lens, int view, bool along_x, int size,
                        double tolerance) {
  LightField light_field;
  const Vec3d eye(4.0 * (view % 3 - 1), 4.0 * (view / 3 - 1), 20.0);
  light_field.views.push_back(MakeView("lens", lens, NadirCamFromWorld(eye),
                                       RampImage(lens.width, lens.height, along_x)));
  IntegralOptions options;
  options.cam_from_world = NadirCamFromWorld(Vec3d(0.0, 0.0, 20.0));
  options.fov_deg = 60.0;
  options.width = options.height = size;
  options.lens_tolerance_px = 0.0;
  const IntegralResult exact = RenderIntegral(light_field, options);
  options.lens_tolerance_px = tolerance;
  internal::ResetLensRouteCounts();
  const IntegralResult fast = RenderIntegral(light_field, options);
  AloneRender out;
  out.counts = internal::GetLensRouteCounts();
  const RouteDifference d = CompareWithExactRoute(fast, exact);
  out.largest = d.largest;
  out.count_mismatches = d.count_mismatches;
  return out;
}

TEST(RenderIntegral, WideLensCubicMapsStraddlingTheToleranceAreRefusedOrHoldIt) {
  // The lens benchmark's fisheye and omnidirectional views rendered coarser: 144 x 144 output
  // pixels over 60 degrees, so that a 64-pixel quad spans about 27 degrees, 3.6x the
  // benchmark's, and the cubic's residual (fourth order in the quad's angle: 3e-4 px x 3.6^4,
  // about 0.05 px, varying over the field) straddles a tolerance of 0.01 px: some 64-pixel cubic
  // fits are accepted, the others refused and their 32-pixel quads (a sixteenth of the
  // residual) fitted. Each view is rendered alone (RenderAlone), so the difference from the
  // exact route is that view's sample position error: within the tolerance where the fit's
  // error estimate (at and between the nodes, float rounding in the kernel included) holds,
  // plus the float rounding of the bilinear sample and of the two renders' outputs, 4 x 2^-24
  // x 1024 px (positions up to 1024 pixels). Checked at the nodes only (the estimate without
  // its term between them), more 64-pixel fits pass and the error reaches about 0.015 px.
  if (!PointKernelRuns()) GTEST_SKIP() << "no AVX2 point kernel: the lens route is not taken";
  const std::vector<WideLensCase> cases = BenchLensWideLenses();
  const double tolerance = 0.01, rounding = 4.0 * 0x1.0p-24 * 1024.0;
  for (const WideLensCase& c : cases) {
    SCOPED_TRACE(c.name);
    internal::LensRouteCounts total;
    double largest = 0.0;
    for (int view = 0; view < 9; ++view) {
      for (const bool along_x : {true, false}) {
        const AloneRender r = RenderAlone(c.lens, view, along_x, 144, tolerance);
        for (int level = 0; level < 4; ++level) {
          total.fitted_quads[level] += r.counts.fitted_quads[level];
        }
        total.exact_quads += r.counts.exact_quads;
        largest = std::max(largest, r.largest);
        EXPECT_EQ(r.count_mismatches, 0);  // the view covers the output with a margin
      }
    }
    // 9 tiles (the last row and column 16 pixels) per render, 18 renders.
    EXPECT_GT(total.fitted_quads[0], 0) << "some 64-pixel cubics accepted";
    EXPECT_LT(total.fitted_quads[0], 9 * 18) << "some refused";
    EXPECT_GT(total.fitted_quads[1], 0);
    EXPECT_EQ(total.fitted_quads[2] + total.fitted_quads[3] + total.exact_quads, 0);
    EXPECT_LE(largest, tolerance + rounding) << "pixels";
  }
  // A 64-pixel cubic that misses by more than 8x has a sixteenth of its error predicted for its
  // 32-pixel quads, which are fitted (not split down to homographies without a fit, as a
  // quarter would): the omnidirectional views at 96 x 96 output pixels and 0.02 px.
  internal::LensRouteCounts total;
  for (int view = 0; view < 9; ++view) {
    const AloneRender r = RenderAlone(cases[1].lens, view, true, 96, 0.02);
    for (int level = 0; level < 4; ++level) {
      total.fitted_quads[level] += r.counts.fitted_quads[level];
    }
    total.exact_quads += r.counts.exact_quads;
  }
  EXPECT_LT(total.fitted_quads[0], 4 * 9);
  EXPECT_GT(total.fitted_quads[1], 0);
  EXPECT_EQ(total.fitted_quads[2] + total.fitted_quads[3] + total.exact_quads, 0)
      << "16-pixel quads " << total.fitted_quads[2] << ", 8-pixel quads "
      << total.fitted_quads[3] << ", exact " << total.exact_quads;
}

TEST(RenderIntegral, LensToleranceIsValidated) {
  const LensCamera lens =
      LensFromFov(LensModel::kFisheye, 64, 48, 180.0, {0, 0, 0, 0, 0}, 0.0, "test");
  const LightField light_field = LensLightField(lens);
  IntegralOptions options;
  options.cam_from_world = NadirCamFromWorld(Vec3d(0.0, 0.0, 30.0));
  options.fov_deg = 60.0;
  options.width = options.height = 32;
  for (double bad : {-0.01, 1.5, std::numeric_limits<double>::quiet_NaN()}) {
    options.lens_tolerance_px = bad;
    try {
      RenderIntegral(light_field, options);
      ADD_FAILURE() << "lens_tolerance_px " << bad << " was accepted";
    } catch (const std::invalid_argument& error) {
      EXPECT_NE(std::string(error.what()).find("lens_tolerance_px"), std::string::npos)
          << error.what();
    }
  }
}

}  // namespace
}  // namespace aos
