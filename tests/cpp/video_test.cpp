// Frames and telemetry from a drone video with DJI's SRT (sfm/video.h): the SRT's layouts against
// hand-written values, and a simulated flight made into a video and an SRT, imported and posed:
// the poses are the simulation's and the hidden target renders as from the original frames.
#include "aos/sfm/video.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/videoio.hpp>

#include "aos/geometry/geodesy.h"
#include "aos/lightfield/formats.h"
#include "aos/metrics/quality.h"
#include "aos/render/integral.h"
#include "aos/sfm/telemetry.h"
#include "aos/sim/scene.h"
#include "aos/sim/simulator.h"
#include "error_of.h"
#include "temp_folder.h"

namespace aos {
namespace {

using ::testing::HasSubstr;
using test_util::ErrorOf;

class Video : public testing_util::TempFolderTest {
 protected:
  std::string Write(const std::string& name, const std::string& text) {
    std::ofstream(Path(name)) << text;
    return Path(name);
  }
};

TEST_F(Video, SrtLayoutsOfDjiModelsAreRead) {
  // Mavic 3 style (bracketed keys, gimbal angles), an older style (GPS(lon, lat, alt) and
  // BAROMETER), a block before the GPS fix (0, 0: skipped) and a repeated block.
  const std::string path = Write(
      "a.srt",
      "1\n00:00:00,000 --> 00:00:00,033\n<font size=\"28\">FrameCnt: 1, DiffTime: 33ms\n"
      "2026-06-01 10:00:00.000\n[iso: 100] [shutter: 1/500.0] [latitude: 0.000000] "
      "[longitude: 0.000000] [rel_alt: 0.000 abs_alt: 0.000] </font>\n\n"
      "2\n00:00:00,033 --> 00:00:00,066\n<font size=\"28\">FrameCnt: 2, DiffTime: 33ms\n"
      "[latitude: 48.123456] [longtitude: 15.654321] [rel_alt: 30.500 abs_alt: 380.250] "
      "[gb_yaw: -12.5 gb_pitch: -90.0 gb_roll: 0.3] </font>\n\n"
      "3\n00:00:01,500 --> 00:00:02,000\nHOME(15.6543,48.1234) 2026.06.01 10:00:01\n"
      "GPS (15.654400,48.123500,13) BAROMETER:31.2\nISO:100 Shutter:500 EV: Fnum:F2.8\n\n"
      "4\n00:00:01,500 --> 00:00:02,000\nGPS(15.654400,48.123500,381.0) BAROMETER:31.2\n");
  const SrtLog log = ReadDjiSrt(path);
  EXPECT_EQ(log.skipped_blocks, 1);
  ASSERT_EQ(log.samples.size(), 2u);
  const SrtSample& a = log.samples[0];
  EXPECT_EQ(a.line, 8);  // its time range's line
  EXPECT_NEAR(a.time_s, 0.033, 1e-12);
  EXPECT_EQ(a.latitude_deg, 48.123456);
  EXPECT_EQ(a.longitude_deg, 15.654321);
  EXPECT_EQ(*a.relative_altitude_m, 30.5);
  EXPECT_EQ(*a.absolute_altitude_m, 380.25);
  ASSERT_TRUE(a.gimbal_yaw_pitch_roll_deg.has_value());
  EXPECT_EQ((*a.gimbal_yaw_pitch_roll_deg)[0], -12.5);
  EXPECT_EQ((*a.gimbal_yaw_pitch_roll_deg)[2], 0.3);
  const SrtSample& b = log.samples[1];
  EXPECT_NEAR(b.time_s, 1.5, 1e-12);
  EXPECT_EQ(b.longitude_deg, 15.6544);
  EXPECT_EQ(b.latitude_deg, 48.1235);
  EXPECT_EQ(*b.relative_altitude_m, 31.2);
  EXPECT_FALSE(b.absolute_altitude_m.has_value());  // GPS(...)'s third number is not read
  EXPECT_FALSE(b.gimbal_yaw_pitch_roll_deg.has_value());
  // Bad input: one error naming the file, the line and the field.
  EXPECT_THAT(ErrorOf([&] { ReadDjiSrt(Write("none.srt", "1\n00:00:00,000 --> 00:00:01,000\nhello\n")); }),
              HasSubstr("none.srt: 0 block(s) with a position (1 without)"));
  EXPECT_THAT(ErrorOf([&] {
                ReadDjiSrt(Write("back.srt",
                                 "1\n00:00:02,000 --> 00:00:03,000\n[latitude: 48.1] [longitude: 15.1]\n\n"
                                 "2\n00:00:01,000 --> 00:00:02,000\n[latitude: 48.1] [longitude: 15.1]\n"));
              }),
              HasSubstr("back.srt: line 6: time: 1 s comes before the block before it (2 s)"));
  EXPECT_THAT(ErrorOf([&] {
                ReadDjiSrt(Write("lat.srt", "1\n00:00:02,000 --> 00:00:03,000\n[latitude: 98.1] [longitude: 15.1]\n"));
              }),
              HasSubstr("lat.srt: line 2: latitude: 98.1 is outside [-90, 90]"));
}

// A simulated flight along a line (31 nadir views 1 m apart, 35 m up, under trees, a warm
// target at the centre) recorded as a 10 fps video (one frame per view) with a DJI SRT placing
// the local frame at UTM 33N (500000, 5318000): the imported frames are posed as simulated and
// render the hidden target as the original frames do.
TEST_F(Video, ASimulatedFlightAsVideoAndSrtRendersTheTargetLikeItsFrames) {
  Scene scene = ParseScene(R"({
    "format": "aos-scene", "version": 1, "seed": 5,
    "ground": {"texture": {"type": "noise", "square": 1.0, "colors": [0.2, 0.6]}},
    "targets": [{"center": [0.0, 0.0], "size": [0.6, 1.8], "texture": {"type": "constant", "color": 1.0}}],
    "occluders": {"trees": {"area": [-30.0, -20.0, 30.0, 20.0], "per_hectare": 300, "height": [10.0, 16.0]}},
    "camera": {"width": 96, "height": 96, "fov_deg": 50.0, "channels": 1, "bit_depth": 8},
    "sampling": {"altitude": 35.0, "positions": [[0, 0, 35]]},
    "truth": {"fov_deg": 12.0}
  })", "scene");
  scene.sampling.positions.clear();
  for (int k = 0; k <= 30; ++k) scene.sampling.positions.push_back({-15.0 + k, 0.0, 35.0});
  const SimulationResult simulated = Simulate(scene);
  const LightField& original = simulated.light_field;
  ASSERT_EQ(original.views.size(), 31u);

  // The video: 10 fps, frame k = view k (MJPG at its best quality: near lossless).
  const std::string video = Path("flight.avi");
  {
    cv::VideoWriter writer(video, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 10.0,
                           cv::Size(96, 96), /*isColor=*/false);
    ASSERT_TRUE(writer.isOpened());
    writer.set(cv::VIDEOWRITER_PROP_QUALITY, 100);
    for (const View& view : original.views) {
      cv::Mat frame(96, 96, CV_8UC1);
      for (int y = 0; y < 96; ++y) {
        for (int x = 0; x < 96; ++x) frame.at<uint8_t>(y, x) = view.image.At<uint8_t>(x, y)[0];
      }
      writer.write(frame);
    }
  }
  // The SRT: one block per frame, the simulated positions moved to WGS84.
  std::vector<Vec3d> world;
  for (const View& view : original.views) {
    world.push_back(view.cam_from_world.Center() + Vec3d(500000.0, 5318000.0, 0.0));
  }
  const std::vector<Vec3d> wgs84 = TransformPoints(world, "EPSG:32633", "EPSG:4326", "truth");
  std::string srt;
  for (size_t k = 0; k < world.size(); ++k) {
    char block[512];
    std::snprintf(block, sizeof(block),
                  "%zu\n00:00:%02zu,%03zu --> 00:00:%02zu,%03zu\n<font size=\"28\">FrameCnt: %zu\n"
                  "[latitude: %.9f] [longitude: %.9f] [rel_alt: %.3f abs_alt: 412.000] "
                  "[gb_yaw: 0.0 gb_pitch: -90.0 gb_roll: 0.0] </font>\n\n",
                  k + 1, k / 10, (k % 10) * 100, (k + 1) / 10, ((k + 1) % 10) * 100, k + 1,
                  wgs84[k].y, wgs84[k].x, world[k].z);
    srt += block;
  }
  VideoFramesOptions options;
  options.srt_file = Write("flight.srt", srt);
  options.frame_every_s = 0.1;
  std::filesystem::create_directories(dir_ / "frames");
  const VideoFramesResult frames =
      ExtractVideoFrames(video, Path("frames"), Path("telemetry.csv"), options);
  EXPECT_EQ(frames.video_frames, 31);
  EXPECT_NEAR(frames.fps, 10.0, 1e-9);
  ASSERT_EQ(frames.frames.size(), 31u);
  EXPECT_EQ(frames.frames[12], "000012.png");
  EXPECT_EQ(frames.yaw_from, "SRT gimbal yaw");
  EXPECT_TRUE(frames.warnings.empty());  // the SRT spans the video (3.1 s)
  // Another video's SRT (its first 10 blocks: 1 s of the 3.1 s video) is warned about.
  {
    VideoFramesOptions short_srt = options;
    short_srt.srt_file = Write("short.srt", srt.substr(0, srt.find("11\n00:00:01,000")));
    std::filesystem::create_directories(dir_ / "frames_short");
    const VideoFramesResult partial = ExtractVideoFrames(video, Path("frames_short"),
                                                         Path("telemetry_short.csv"), short_srt);
    EXPECT_EQ(partial.frames.size(), 10u);
    ASSERT_EQ(partial.warnings.size(), 1u);
    EXPECT_THAT(partial.warnings[0], HasSubstr("the video lasts 3.1 s but its SRT"));
    EXPECT_THAT(partial.warnings[0], HasSubstr("is it this video's SRT?"));
  }

  TelemetryOptions telemetry;
  telemetry.telemetry_file = Path("telemetry.csv");
  telemetry.fov_deg = 50.0;
  const TelemetryResult posed = ImportTelemetry(Path("frames"), telemetry);
  EXPECT_EQ(posed.order, "time");
  const LightField& imported = posed.light_field;
  EXPECT_EQ(imported.crs, "EPSG:32633");
  EXPECT_EQ(imported.origin, Vec3d(500000.0, 5318000.0, 0.0));
  ASSERT_EQ(imported.views.size(), 31u);
  for (size_t k = 0; k < 31; ++k) {
    // Positions to the millimetre (the SRT's 1e-9 degrees, 0.1 mm); orientations to the meridian
    // convergence 15 m off the central meridian: 15 m / (6.39e6 m cos 48) sin 48 = 2.6e-6 rad
    // (1.5e-4 degrees).
    EXPECT_NEAR(glm::length(imported.views[k].cam_from_world.Center() -
                            original.views[k].cam_from_world.Center()),
                0.0, 1e-3);
    const Mat3d d = imported.views[k].cam_from_world.rotation *
                    glm::transpose(original.views[k].cam_from_world.rotation);
    const double angle = std::acos(std::clamp((d[0][0] + d[1][1] + d[2][2] - 1.0) / 2.0, -1.0, 1.0));
    EXPECT_LT(angle * 180.0 / 3.141592653589793, 2e-4);
  }

  // Rendered at the truth camera on the ground: the target as from the original frames.
  LoadOptions load;
  load.grey = true;  // OpenCV decodes the grey video as BGR
  WriteLightField(Path("imported.json"), imported);
  const LightField loaded = LoadLightField(Path("imported.json"), load).light_field;
  IntegralOptions render;
  render.cam_from_world = simulated.truth.cam_from_world;
  render.fov_deg = 12.0;
  render.width = simulated.truth.ground.width();
  render.height = simulated.truth.ground.height();
  const Image a = RenderIntegral(original, render).image;
  const Image b = RenderIntegral(loaded, render).image;
  const double psnr_original = CompareImages(a, simulated.truth.ground).psnr_db;
  const double psnr_video = CompareImages(b, simulated.truth.ground).psnr_db;
  EXPECT_NEAR(psnr_video, psnr_original, 0.5);
  std::printf("PSNR against the ground truth: original frames %.3f dB, video frames %.3f dB\n",
              psnr_original, psnr_video);
  EXPECT_GT(psnr_original, 10.0);

  // Frames every 2 m of flight: every second one.
  options.frame_every_m = 2.0;
  std::filesystem::create_directories(dir_ / "frames2");
  const VideoFramesResult by_distance =
      ExtractVideoFrames(video, Path("frames2"), Path("telemetry2.csv"), options);
  ASSERT_EQ(by_distance.frames.size(), 16u);
  EXPECT_EQ(by_distance.frames[1], "000002.png");
  // Without gimbal angles: yaw from the course (east), pitch given.
  std::string no_gimbal = srt;
  for (size_t at; (at = no_gimbal.find("[gb_yaw")) != std::string::npos;) {
    no_gimbal.erase(at, no_gimbal.find(']', at) + 1 - at);
  }
  options.srt_file = Write("no_gimbal.srt", no_gimbal);
  EXPECT_THAT(ErrorOf([&] {
                ExtractVideoFrames(video, Path("frames2"), Path("telemetry3.csv"), options);
              }),
              HasSubstr("no_gimbal.srt: the SRT has no gimbal angles"));
  options.fixed_pitch_deg = -90.0;
  std::filesystem::create_directories(dir_ / "frames3");
  const VideoFramesResult course =
      ExtractVideoFrames(video, Path("frames3"), Path("telemetry3.csv"), options);
  EXPECT_EQ(course.yaw_from, "direction of flight (course over ground)");
  std::ifstream csv(Path("telemetry3.csv"));
  std::string header, row;
  std::getline(csv, header);
  std::getline(csv, row);
  EXPECT_EQ(header, "frame,time,lat,lon,alt,yaw,pitch,roll");
  // Flying east: yaw 90 (true north; the grid's east is within 1e-3 degrees of it here).
  double yaw = 0.0;
  ASSERT_EQ(std::sscanf(row.c_str(), "%*[^,],%*f,%*f,%*f,%*f,%lf", &yaw), 1);
  EXPECT_NEAR(yaw, 90.0, 0.01);
}

}  // namespace
}  // namespace aos
