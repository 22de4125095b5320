// Live integration (live/live.h): the window's image equals the batch render of the same views
// at every step, the window stays bounded, and tracks merge repeated sightings.
#include <random>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "aos/geometry/rigid.h"
#include "aos/live/live.h"
#include "error_of.h"

namespace aos {
namespace {

using testing::HasSubstr;
using test_util::ErrorOf;

// A flight of `n` nadir views 20 m up along x, 1 m apart, random 8-bit frames (64 x 48) with a
// bright 4 x 4 patch at the ground point (10, 0, 0) where a view sees it.
LightField Flight(int n) {
  LightField lf;
  const PinholeCamera camera = PinholeCamera::FromFov(64, 48, 60.0);
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> noise(90, 110);
  for (int i = 0; i < n; ++i) {
    const Rigid3d pose = NadirCamFromWorld(Vec3d(i * 1.0, 0.0, 20.0));
    Image image(64, 48, 1, PixelType::kU8, 1);
    for (int y = 0; y < 48; ++y) {
      for (int x = 0; x < 64; ++x) *image.At<uint8_t>(x, y) = static_cast<uint8_t>(noise(rng));
    }
    const Vec2d target = camera.Project(pose * Vec3d(10.0, 0.0, 0.0));
    for (int y = -2; y < 2; ++y) {
      for (int x = -2; x < 2; ++x) {
        const int px = static_cast<int>(target.x) + x, py = static_cast<int>(target.y) + y;
        if (px >= 0 && px < 64 && py >= 0 && py < 48) *image.At<uint8_t>(px, py) = 250;
      }
    }
    image.FillBorder();
    lf.views.push_back(MakeView("frame" + std::to_string(i), camera, pose, image));
  }
  return lf;
}

void ExpectSameImage(const Image& a, const Image& b, const std::string& where) {
  ASSERT_EQ(a.width(), b.width()) << where;
  ASSERT_EQ(a.height(), b.height()) << where;
  for (int y = 0; y < a.height(); ++y) {
    for (int x = 0; x < a.width(); ++x) {
      ASSERT_EQ(*a.At<float>(x, y), *b.At<float>(x, y)) << where << " pixel " << x << ", " << y;
    }
  }
}

TEST(Live, EveryStepEqualsTheBatchRenderOfTheWindow) {
  const LightField flight = Flight(14);
  IntegralOptions render;
  render.width = 48;
  render.height = 40;
  LiveOptions live;
  live.window_frames = 5;
  live.detect = false;
  LiveIntegrator integrator(flight, render, DetectOptions(), live);
  std::vector<int> window;  // the flight's indices in the live window
  for (int i = 0; i < static_cast<int>(flight.views.size()); ++i) {
    const std::vector<std::string> dropped = integrator.Add(flight.views[static_cast<size_t>(i)]);
    window.push_back(i);
    if (window.size() > 5) {
      ASSERT_EQ(dropped, std::vector<std::string>{"frame" + std::to_string(window.front())});
      window.erase(window.begin());
    }
    if (i == 9) {  // take one out of the middle
      ASSERT_TRUE(integrator.Remove("frame7"));
      window.erase(std::find(window.begin(), window.end(), 7));
    }
    ASSERT_EQ(integrator.window().views.size(), window.size());
    // The batch render: the whole flight, the window's views selected, the newest's pose.
    IntegralOptions batch = render;
    batch.view_indices = window;
    batch.pose_view = window.back();
    const IntegralResult expected = RenderIntegral(flight, batch);
    ExpectSameImage(integrator.result().render.image, expected.image, "step " + std::to_string(i));
    EXPECT_EQ(integrator.result().render.views_used, expected.views_used);
  }
  EXPECT_FALSE(integrator.Remove("frame0"));
  EXPECT_EQ(integrator.updates(), 15);
}

TEST(Live, TracksMergeRepeatedSightingsOfOnePlace) {
  const LightField flight = Flight(20);
  IntegralOptions render;
  render.width = 64;
  render.height = 48;
  DetectOptions detect;
  detect.detector = "rx";
  detect.min_score = 100.0;  // the patch: (250 - 100) / 5.8 ~ 26 sigma at full coverage
  detect.min_area_px = 1;
  LiveOptions live;
  live.window_frames = 6;
  LiveIntegrator integrator(flight, render, detect, live);
  for (const View& view : flight.views) integrator.Add(view);
  ASSERT_EQ(integrator.tracks().size(), 1u);
  const LiveTrack track = integrator.tracks().front();
  EXPECT_NEAR(track.detection.local.x, 10.0, 0.5);
  EXPECT_NEAR(track.detection.local.y, 0.0, 0.5);
  EXPECT_GT(track.sightings, 3);
  EXPECT_LE(track.first_update, track.last_update);
  const DetectResult written = integrator.TracksResult();
  ASSERT_EQ(written.detections.size(), 1u);
  EXPECT_EQ(written.detections[0].sightings, track.sightings);
  EXPECT_EQ(written.detections[0].first_seen, track.first_frame);
}

// A distance window: views farther than window_m from the newest (horizontally) leave it too.
TEST(Live, TheDistanceWindowDropsFarViews) {
  const LightField flight = Flight(10);  // 1 m apart along x
  IntegralOptions render;
  LiveOptions live;
  live.detect = false;
  live.window_m = 2.5;
  LiveIntegrator integrator(flight, render, DetectOptions(), live);
  for (const View& view : flight.views) integrator.Add(view);
  const LightField window = integrator.window();
  ASSERT_EQ(window.views.size(), 3u);  // 7, 8, 9: 2 m and 1 m from 9; 6 is 3 m away
  EXPECT_EQ(window.views.front().name, "frame7");
  EXPECT_EQ(integrator.path().size(), 10u);
}

// A time window: views added more than window_s before the newest leave it.
TEST(Live, TheTimeWindowDropsOldViews) {
  const LightField flight = Flight(6);
  LiveOptions live;
  live.detect = false;
  live.window_s = 2.5;
  LiveIntegrator integrator(flight, IntegralOptions(), DetectOptions(), live);
  for (int i = 0; i < 6; ++i) integrator.Add(flight.views[static_cast<size_t>(i)], true, nullptr, i * 1.0);
  const LightField window = integrator.window();
  ASSERT_EQ(window.views.size(), 3u);  // times 3, 4, 5: 2 s and 1 s before 5; 2 is 3 s before
  EXPECT_EQ(window.views.front().name, "frame3");
  EXPECT_TRUE(integrator.Remove("frame4"));
  integrator.Add(flight.views[0], true, nullptr, 5.5);  // a later frame named like an old one
  EXPECT_EQ(integrator.window().views.size(), 3u);  // 3 (2.5 s before), 5, 0
}

// A view whose update fails is not kept: the window is as it was. Here the detector finds no
// pixel to score (the focal plane lies above the cameras, so no view sees it).
TEST(Live, AFailedUpdateLeavesTheWindowAsItWas) {
  const LightField flight = Flight(3);
  IntegralOptions render;
  render.focal_surface = FocalSurface::FromPlane(Plane::AtHeight(50.0));
  LiveOptions live;
  LiveIntegrator integrator(flight, render, DetectOptions(), live);
  EXPECT_THROW(integrator.Add(flight.views[0]), std::invalid_argument);
  EXPECT_TRUE(integrator.window().views.empty());
  EXPECT_TRUE(integrator.path().empty());
  EXPECT_NO_THROW(integrator.Add(flight.views[1], /*update=*/false));
  EXPECT_EQ(integrator.window().views.size(), 1u);
}

TEST(Live, BadInputIsRefusedNamingTheField) {
  const LightField flight = Flight(2);
  IntegralOptions render;
  LiveOptions live;
  live.detect = false;
  LiveIntegrator integrator(flight, render, DetectOptions(), live);
  integrator.Add(flight.views[0]);
  EXPECT_THAT(ErrorOf([&] { integrator.Add(flight.views[0]); }), HasSubstr("name: already"));
  const PinholeCamera other = PinholeCamera::FromFov(32, 24, 60.0);
  Image small(32, 24, 1, PixelType::kU8, 1);
  EXPECT_THAT(ErrorOf([&] {
                integrator.Add(MakeView("small", other, flight.views[1].cam_from_world, small));
              }),
              HasSubstr("camera: 32 x 24 pixels"));
  IntegralOptions selected = render;
  selected.view_indices = {0};
  EXPECT_THAT(ErrorOf([&] { LiveIntegrator(flight, selected, DetectOptions(), live); }),
              HasSubstr("view_indices"));
  LiveOptions fixed = live;
  fixed.follow = "fixed";
  IntegralOptions posed = render;
  posed.pose_view = 0;
  EXPECT_THAT(ErrorOf([&] { LiveIntegrator(flight, posed, DetectOptions(), fixed); }),
              HasSubstr("pose_view"));
  LiveOptions zero = live;
  zero.window_frames = 0;
  EXPECT_THAT(ErrorOf([&] { LiveIntegrator(flight, render, DetectOptions(), zero); }),
              HasSubstr("window_frames"));
}

}  // namespace
}  // namespace aos
