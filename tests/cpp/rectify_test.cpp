// Tests of rectification (raw lens frames -> perspective frames) and camera files.
#include "aos/render/rectify.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "aos/lightfield/camera_file.h"
#include "aos/lightfield/lightfield.h"
#include "aos/render/integral.h"
#include "aos/util/error.h"
#include "temp_folder.h"

#include "error_of.h"

namespace aos {
namespace {

using ::testing::HasSubstr;

// A smooth pattern over ray directions (grey levels), so bilinear resampling is accurate.
double Pattern(const Vec3d& ray) {
  const Vec3d d = glm::normalize(ray);
  return 128.0 + 90.0 * d.x * std::cos(2.0 * d.y) + 20.0 * d.y;
}

LensCamera Fisheye() {
  LensCamera lens;
  lens.model = LensModel::kFisheye;
  lens.width = 640;
  lens.height = 480;
  lens.fx = lens.fy = 200.0;
  lens.cx = 321.5;
  lens.cy = 238.0;
  lens.distortion = {0.03, -0.01, 0.001, 0.0, 0.0};
  lens.Finalize("fisheye");
  return lens;
}

// The raw frame: every pixel centre's ray, through the lens, gets the pattern.
Image RawFrame(const LensCamera& lens) {
  Image raw(lens.width, lens.height, 1, PixelType::kF32);
  for (int y = 0; y < lens.height; ++y) {
    for (int x = 0; x < lens.width; ++x) {
      Vec3d ray;
      raw.At<float>(x, y)[0] =
          lens.Unproject(Vec2d(x + 0.5, y + 0.5), &ray) ? static_cast<float>(Pattern(ray)) : 0.0f;
    }
  }
  return raw;
}

TEST(Rectify, MatchesTheAnalyticPerspectiveImage) {
  const LensCamera lens = Fisheye();
  RectifyOptions options;
  options.fov_deg = 80.0;
  options.width = 320;
  options.height = 240;
  options.yaw_deg = 12.0;
  options.pitch_deg = -5.0;
  const Rectifier rectifier = MakeRectifier(lens, options);
  const Image rectified = Rectify(rectifier, RawFrame(lens));
  ASSERT_EQ(rectified.width(), 320);
  ASSERT_EQ(rectified.type(), PixelType::kF32);
  double worst = 0.0, worst_unturned = 0.0;
  for (int y = 0; y < 240; ++y) {
    for (int x = 0; x < 320; ++x) {
      const Vec3d ray = rectifier.camera.Unproject(Vec2d(x + 0.5, y + 0.5));
      const double value = rectified.At<float>(x, y)[0];
      worst = std::max(worst, std::abs(value - Pattern(rectifier.lens_from_rectified * ray)));
      worst_unturned = std::max(worst_unturned, std::abs(value - Pattern(ray)));
    }
  }
  // Bilinear interpolation of the smooth pattern: its second derivative is below ~0.05 grey per
  // raw pixel^2 here, so the error bound |f''| h^2 / 8 with h = 1 px is ~0.01; allow 0.1.
  EXPECT_LT(worst, 0.1);
  // The orientation matters (the test would catch an ignored yaw/pitch).
  EXPECT_GT(worst_unturned, 5.0);
}

TEST(Rectify, KeepsTypeAndChannels) {
  const LensCamera lens = Fisheye();
  const Rectifier rectifier = MakeRectifier(lens, RectifyOptions{});
  Image u16(640, 480, 3, PixelType::kU16);
  for (int y = 0; y < 480; ++y) {
    for (int x = 0; x < 640; ++x) {
      for (int c = 0; c < 3; ++c) u16.At<uint16_t>(x, y)[c] = static_cast<uint16_t>(1000 * (c + 1));
    }
  }
  const Image out = Rectify(rectifier, u16);
  EXPECT_EQ(out.type(), PixelType::kU16);
  EXPECT_EQ(out.channels(), 3);
  EXPECT_EQ(out.At<uint16_t>(100, 100)[2], 3000);
}

using test_util::ErrorOf;

TEST(Rectify, AViewTheLensDoesNotCoverIsAnError) {
  LensCamera radtan;
  radtan.model = LensModel::kRadTan;
  radtan.width = 640;
  radtan.height = 480;
  radtan.fx = radtan.fy = 500.0;  // about 65 degrees across
  radtan.cx = 320.0;
  radtan.cy = 240.0;
  radtan.distortion = {-0.1, 0.01, 0.0, 0.0, 0.0};
  radtan.Finalize("radtan");
  RectifyOptions options;
  options.fov_deg = 120.0;
  EXPECT_THAT(ErrorOf([&] { MakeRectifier(radtan, options); }),
              HasSubstr("fov_deg: the lens does not cover the requested view"));
  options.fov_deg = 50.0;
  EXPECT_EQ(ErrorOf([&] { MakeRectifier(radtan, options); }), "no error");
  options.fov_deg = 180.0;
  EXPECT_THAT(ErrorOf([&] { MakeRectifier(radtan, options); }), HasSubstr("fov_deg: must be in"));
  // The error offers the fill option.
  options.fov_deg = 120.0;
  EXPECT_THAT(ErrorOf([&] { MakeRectifier(radtan, options); }), HasSubstr("or fill to make"));

  // fill: the same view, black where the lens does not reach, the lens's image elsewhere.
  options.fill = true;
  const Rectifier filled = MakeRectifier(radtan, options);
  ASSERT_GT(filled.uncovered, 0);
  ASSERT_LT(filled.uncovered, static_cast<int64_t>(640) * 480);
  Image raw(640, 480, 3, PixelType::kU16);
  for (int y = 0; y < 480; ++y) {
    for (int x = 0; x < 640; ++x) {
      for (int c = 0; c < 3; ++c) raw.At<uint16_t>(x, y)[c] = static_cast<uint16_t>(1000 + c);
    }
  }
  const Image out = Rectify(filled, raw);
  int64_t black = 0;
  for (int y = 0; y < 480; ++y) {
    for (int x = 0; x < 640; ++x) {
      const bool is_black = out.Value(x, y, 0) == 0.0;
      black += is_black;
      for (int c = 0; c < 3; ++c) {
        // A constant image resamples to itself wherever the lens covers the pixel.
        ASSERT_EQ(out.Value(x, y, c), is_black ? 0.0 : 1000.0 + c) << x << "," << y;
      }
    }
  }
  EXPECT_EQ(black, filled.uncovered);
  EXPECT_EQ(out.Value(320, 240, 0), 1000.0);  // the centre is covered
  EXPECT_EQ(out.Value(0, 0, 0), 0.0);         // a corner at ~63 degrees off the axis is not
  // A covered view with fill is the same as without it.
  options.fov_deg = 50.0;
  const Rectifier covered = MakeRectifier(radtan, options);
  EXPECT_EQ(covered.uncovered, 0);
}

using CameraFile = testing_util::TempFolderTest;

TEST_F(CameraFile, RoundTripAndErrorsNameTheFileAndField) {
  const std::string path = Path("camera.json");
  const LensCamera lens = Fisheye();
  WriteCameraFile(path, lens, "{\"rms_px\": 0.21}");
  const LensCamera back = ReadCameraFile(path);
  EXPECT_EQ(back.model, LensModel::kFisheye);
  EXPECT_EQ(back.fx, lens.fx);
  EXPECT_EQ(back.cx, lens.cx);
  EXPECT_EQ(back.distortion, lens.distortion);
  std::ofstream(Path("bad.json"))
      << R"({"format": "aos-camera", "version": 1, "model": "radtan", "width": 64, "height": 64,
             "fx": 50, "fy": 50, "cx": 32, "cy": 32, "k1": 0.1})";
  EXPECT_THAT(ErrorOf([&] { ReadCameraFile(Path("bad.json")); }),
              HasSubstr("bad.json: /k1: unknown key"));
  std::ofstream(Path("xi.json"))
      << R"({"format": "aos-camera", "version": 1, "model": "omnidir", "width": 64, "height": 64,
             "fx": 50, "fy": 50, "cx": 32, "cy": 32, "xi": -0.5})";
  EXPECT_THAT(ErrorOf([&] { ReadCameraFile(Path("xi.json")); }),
              HasSubstr("xi.json: xi: must be >= 0"));
  // A pinhole camera file may give its field of view, as a light field's camera may (the shared
  // codec, json_codec.h; camera files refused fov_deg before).
  std::ofstream(Path("fov.json"))
      << R"({"format": "aos-camera", "version": 1, "model": "pinhole", "width": 64, "height": 48,
             "fov_deg": 60})";
  const LensCamera fov = ReadCameraFile(Path("fov.json"));
  const PinholeCamera expected = PinholeCamera::FromFov(64, 48, 60.0);
  EXPECT_EQ(fov.model, LensModel::kPinhole);
  EXPECT_EQ(fov.fx, expected.fx);
  EXPECT_EQ(fov.cx, expected.cx);
  // A pinhole camera file of the previous version (distortion, xi and skew written as zeros)
  // still reads; non-zero distortion on a pinhole is refused (it was silently ignored).
  std::ofstream(Path("old.json"))
      << R"({"format": "aos-camera", "version": 1, "model": "pinhole", "width": 64, "height": 48,
             "fx": 50, "fy": 50, "cx": 32, "cy": 24, "distortion": [0, 0, 0, 0, 0], "xi": 0,
             "skew": 0, "calibration": {"rms_px": 0.3}})";
  EXPECT_EQ(ReadCameraFile(Path("old.json")).fx, 50.0);
  std::ofstream(Path("k1.json"))
      << R"({"format": "aos-camera", "version": 1, "model": "pinhole", "width": 64, "height": 48,
             "fx": 50, "fy": 50, "cx": 32, "cy": 24, "distortion": [0.1]})";
  EXPECT_THAT(ErrorOf([&] { ReadCameraFile(Path("k1.json")); }),
              HasSubstr("k1.json: distortion/xi/skew: a pinhole camera has none"));
}

}  // namespace
}  // namespace aos

namespace aos {
namespace {

// Direct sampling: fisheye views of a textured ground plane, integrated on that plane from a
// pinhole virtual camera, give the texture back; rectify-then-render resamples twice.
double Texture(double x, double y) { return 128.0 + 80.0 * std::sin(0.9 * x) * std::cos(0.7 * y); }

LightField FisheyeGroundViews(const LensCamera& lens) {
  LightField light_field;
  for (int j = 0; j < 3; ++j) {
    for (int i = 0; i < 3; ++i) {
      const Vec3d centre(2.0 * (i - 1), 2.0 * (j - 1), 10.0);
      const Rigid3d pose = NadirCamFromWorld(centre);
      const Mat3d world_from_cam = glm::transpose(pose.rotation);
      Image image(lens.width, lens.height, 1, PixelType::kF32);
      for (int y = 0; y < lens.height; ++y) {
        for (int x = 0; x < lens.width; ++x) {
          Vec3d ray;
          float value = 0.0f;
          if (lens.Unproject(Vec2d(x + 0.5, y + 0.5), &ray)) {
            const Vec3d d = world_from_cam * ray;
            if (d.z < 0.0) {
              const Vec3d p = centre - (centre.z / d.z) * d;
              value = static_cast<float>(Texture(p.x, p.y));
            }
          }
          image.At<float>(x, y)[0] = value;
        }
      }
      light_field.views.push_back(MakeView("v" + std::to_string(3 * j + i), lens, pose, image));
    }
  }
  return light_field;
}

TEST(DirectSampling, FisheyeViewsGiveTheTexturedPlaneBack) {
  LensCamera lens = Fisheye();
  const LightField light_field = FisheyeGroundViews(lens);
  IntegralOptions options;
  options.cam_from_world = NadirCamFromWorld(Vec3d(0, 0, 10));
  options.fov_deg = 60.0;
  options.width = options.height = 96;
  const IntegralResult direct = RenderIntegral(light_field, options);
  const PinholeCamera camera = VirtualCamera(light_field, options);
  double worst = 0.0;
  int64_t checked = 0;
  for (int y = 0; y < 96; ++y) {
    for (int x = 0; x < 96; ++x) {
      if (direct.count.At<uint32_t>(x, y)[0] == 0) continue;
      const Vec3d d = glm::transpose(options.cam_from_world.rotation) *
                      camera.Unproject(Vec2d(x + 0.5, y + 0.5));
      const Vec3d p = Vec3d(0, 0, 10) - (10.0 / d.z) * d;
      worst = std::max(worst, std::abs(direct.image.At<float>(x, y)[0] - Texture(p.x, p.y)));
      ++checked;
    }
  }
  EXPECT_GT(checked, 96 * 96 * 9 / 10);
  // One bilinear resampling of the raw frames (texture curvature x (1 px at ~2.5 cm)^2 / 8)
  // plus the raw frames' own point sampling: well under a grey level.
  EXPECT_LT(worst, 1.0);
  // The same views as pinholes (lens ignored) would be wrong by far more.
  LightField as_pinholes = light_field;
  for (View& view : as_pinholes.views) view.camera = LensCamera::FromPinhole(view.camera.Pinhole());
  const IntegralResult wrong = RenderIntegral(as_pinholes, options);
  double worst_wrong = 0.0;
  for (int y = 40; y < 56; ++y) {
    for (int x = 0; x < 96; ++x) {
      worst_wrong = std::max<double>(worst_wrong, std::abs(wrong.image.At<float>(x, y)[0] -
                                                   direct.image.At<float>(x, y)[0]));
    }
  }
  EXPECT_GT(worst_wrong, 10.0);
}

}  // namespace
}  // namespace aos
