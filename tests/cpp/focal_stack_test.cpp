// Tests of focal stacks (plane interpolation, plane depth, rendering, files) and of the integral
// renderer's per-pixel variance, against analytic truth.
#include "aos/render/focal_stack.h"

#include <sys/resource.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <sstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "aos/image/image_io.h"
#include "aos/lightfield/camera_file.h"
#include "aos/lightfield/formats.h"
#include "aos/render/merge.h"
#include "aos/util/error.h"
#include "error_of.h"
#include "render_test_util.h"
#include "temp_folder.h"

namespace aos {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using test_util::ConstantImage;
using test_util::GridCentres;
using test_util::NadirLightField;
using test_util::SameImage;

// Success when `actual` is the plane `expected` as a set of points: unit normals equal (same
// sign) within `tolerance`, and expected.point lies on `actual` within `tolerance` metres.
::testing::AssertionResult SamePlane(const Plane& actual, const Plane& expected, double tolerance) {
  const Vec3d na = glm::normalize(actual.normal), ne = glm::normalize(expected.normal);
  const double normal_error = glm::length(na - ne);
  const double offset = std::abs(glm::dot(na, expected.point - actual.point));
  if (normal_error > tolerance || offset > tolerance) {
    return ::testing::AssertionFailure()
           << "normal error " << normal_error << ", offset " << offset << " (actual normal "
           << na.x << " " << na.y << " " << na.z << ", expected " << ne.x << " " << ne.y << " "
           << ne.z << ")";
  }
  return ::testing::AssertionSuccess();
}

// ---------------------------------------------------------------------------------------------
// Plane interpolation

TEST(PlaneInterpolation, ParallelPlanesGiveEquallySpacedSlicesThroughTheCentreLine) {
  // z = 0 and z = 10, one normal not unit length and the points anywhere on the planes; centre
  // C = (1, 2, 35): h0 = -35, h1 = -25, slice i of 11 lies at z = i, stored through C + h n.
  const Plane first{Vec3d(-4, 7, 0), Vec3d(0, 0, 2)};
  const Plane last{Vec3d(3, -1, 10), Vec3d(0, 0, 1)};
  const Vec3d centre(1, 2, 35);
  const std::vector<Plane> planes = StackPlanes(first, last, 11, centre);
  ASSERT_EQ(planes.size(), 11u);
  for (int i = 0; i < 11; ++i) {
    const Plane& plane = planes[static_cast<size_t>(i)];
    // n = normalize((1 - s) z + s z) = z exactly; h = -35 + 10 s is off by a few ulp of 35.
    EXPECT_EQ(plane.normal, Vec3d(0, 0, 1)) << i;
    EXPECT_NEAR(plane.point.z, i, 1e-12) << i;
    EXPECT_DOUBLE_EQ(plane.point.x, centre.x) << i;
    EXPECT_DOUBLE_EQ(plane.point.y, centre.y) << i;
  }
}

TEST(PlaneInterpolation, AntiparallelLastNormalIsFlipped) {
  // The same planes as above, the last given with a downward normal: (n1, h1) is negated, so the
  // slices are those of the parallel case. Without the flip the blended normal vanishes at s=1/2.
  const Vec3d centre(1, 2, 35);
  const std::vector<Plane> up =
      StackPlanes(Plane::AtHeight(0.0), Plane{Vec3d(3, -1, 10), Vec3d(0, 0, 1)}, 5, centre);
  const std::vector<Plane> down =
      StackPlanes(Plane::AtHeight(0.0), Plane{Vec3d(3, -1, 10), Vec3d(0, 0, -3)}, 5, centre);
  ASSERT_EQ(down.size(), 5u);
  for (size_t i = 0; i < down.size(); ++i) {
    EXPECT_EQ(down[i].normal, Vec3d(0, 0, 1)) << i;
    EXPECT_NEAR(down[i].point.z, 2.5 * i, 1e-12) << i;
    EXPECT_NEAR(glm::length(down[i].point - up[i].point), 0.0, 1e-12) << i;
  }
  // Tilted: flipping a tilted last plane's normal changes nothing either.
  const Plane first{Vec3d(1, 0.5, -2), Vec3d(0.25, -0.2, 1)};
  const Plane last{Vec3d(0, 0, 12), Vec3d(-0.1, 0.3, 1)};
  const Plane flipped{last.point, -last.normal};
  const Vec3d tilted_centre(0.5, -1, 30);
  for (double s : {0.0, 0.3, 0.5, 1.0}) {
    EXPECT_TRUE(SamePlane(InterpolatePlane(first, flipped, s, tilted_centre),
                          InterpolatePlane(first, last, s, tilted_centre), 1e-12))
        << "s = " << s;
  }
}

TEST(PlaneInterpolation, IdenticalPlanesGiveIdenticalSlices) {
  const Plane plane{Vec3d(1, 0.5, -2), Vec3d(0.25, -0.2, 1)};
  const std::vector<Plane> planes = StackPlanes(plane, plane, 7, Vec3d(3, -2, 40));
  ASSERT_EQ(planes.size(), 7u);
  // (1 - s) n + s n and (1 - s) h + s h equal n and h up to a few ulp (h ~ 40 m: ~1e-14 m).
  for (size_t i = 0; i < planes.size(); ++i) {
    EXPECT_TRUE(SamePlane(planes[i], plane, 1e-12)) << i;
  }
}

TEST(PlaneInterpolation, OneSliceIsTheMidpoint) {
  const Vec3d centre(0, 0, 20);
  const std::vector<Plane> flat = StackPlanes(Plane::AtHeight(0.0), Plane::AtHeight(10.0), 1, centre);
  ASSERT_EQ(flat.size(), 1u);
  EXPECT_EQ(flat[0].normal, Vec3d(0, 0, 1));
  EXPECT_NEAR(flat[0].point.z, 5.0, 1e-12);
  const Plane first{Vec3d(1, 0.5, -2), Vec3d(0.25, -0.2, 1)};
  const Plane last{Vec3d(0, 0, 12), Vec3d(-0.1, 0.3, 1)};
  const std::vector<Plane> tilted = StackPlanes(first, last, 1, centre);
  ASSERT_EQ(tilted.size(), 1u);
  EXPECT_TRUE(SamePlane(tilted[0], InterpolatePlane(first, last, 0.5, centre), 1e-15));
}

TEST(PlaneInterpolation, TiltedPlanesEndOnTheBoundaryPlanesAndFollowTheFormulaBetween) {
  const Plane first{Vec3d(1, 0.5, -2), Vec3d(0.25, -0.2, 1)};
  const Plane last{Vec3d(0, 0, 12), Vec3d(-0.1, 0.3, 1)};
  const Vec3d centre(2, -3, 35);
  const std::vector<Plane> planes = StackPlanes(first, last, 9, centre);
  ASSERT_EQ(planes.size(), 9u);
  // Endpoints: s = 0 and 1 exactly, so only rounding of h (~40 m, 1e-14) and of n remains.
  EXPECT_TRUE(SamePlane(planes.front(), first, 1e-12));
  EXPECT_TRUE(SamePlane(planes.back(), last, 1e-12));
  // Every slice: unit normal n = normalize((1-s) n0 + s n1) and point C + h n with
  // h = (1-s) h0 + s h1, recomputed here from the definitions.
  const Vec3d n0 = glm::normalize(first.normal), n1 = glm::normalize(last.normal);
  const double h0 = glm::dot(n0, first.point - centre), h1 = glm::dot(n1, last.point - centre);
  for (int i = 0; i < 9; ++i) {
    const double s = i / 8.0;
    const Vec3d n = glm::normalize((1 - s) * n0 + s * n1);
    const double h = (1 - s) * h0 + s * h1;
    const Plane& plane = planes[static_cast<size_t>(i)];
    EXPECT_NEAR(glm::length(plane.normal - n), 0.0, 1e-15) << i;
    EXPECT_NEAR(glm::length(plane.point - (centre + h * n)), 0.0, 1e-12) << i;
  }
  // Slices of a tilted stack are not parallel: the middle normal lies strictly between.
  EXPECT_GT(glm::length(planes[4].normal - n0), 1e-3);
  EXPECT_GT(glm::length(planes[4].normal - n1), 1e-3);
}

TEST(PlaneInterpolation, BadPlanesAndSliceCountsAreNamed) {
  const Vec3d centre(0, 0, 20);
  auto error_of = [](auto&& call) -> std::string {
    try {
      call();
    } catch (const std::invalid_argument& error) {
      return error.what();
    }
    return "no error";
  };
  const Plane zero{Vec3d(0, 0, 0), Vec3d(0, 0, 0)};
  const Plane nan_normal{Vec3d(0, 0, 0), Vec3d(0, std::nan(""), 1)};
  EXPECT_THAT(error_of([&] { InterpolatePlane(zero, Plane::AtHeight(1), 0.5, centre); }),
              HasSubstr("first_plane"));
  EXPECT_THAT(error_of([&] { InterpolatePlane(Plane::AtHeight(1), nan_normal, 0.5, centre); }),
              HasSubstr("last_plane"));
  EXPECT_THAT(error_of([&] { StackPlanes(Plane::AtHeight(0), Plane::AtHeight(1), 0, centre); }),
              HasSubstr("slices"));
  FocalStackOptions options;
  options.render.cam_from_world = NadirCamFromWorld(centre);
  for (int slices : {0, -3, 100001}) {
    options.slices = slices;
    EXPECT_THAT(error_of([&] { options.Check(1); }), HasSubstr("slices")) << slices;
  }
  options.slices = 100000;
  EXPECT_EQ(error_of([&] { options.Check(1); }), "no error");
  options.first_plane = zero;
  EXPECT_THAT(error_of([&] { options.Check(1); }), HasSubstr("first_plane"));
}

// ---------------------------------------------------------------------------------------------
// Plane depth

TEST(PlaneDepth, HorizontalPlaneUnderANadirCameraIsAltitudeMinusHeightEverywhere) {
  const PinholeCamera camera = PinholeCamera::FromFov(40, 30, 60.0);
  const double altitude = 35.0;
  const Rigid3d pose = NadirCamFromWorld(Vec3d(1.5, -2.0, altitude));
  for (double height : {0.0, 3.0, -7.25}) {
    const Image depth = PlaneDepth(camera, pose, Plane{Vec3d(9, 4, height), Vec3d(0, 0, 1)});
    ASSERT_EQ(depth.width(), 40);
    ASSERT_EQ(depth.height(), 30);
    ASSERT_EQ(depth.type(), PixelType::kF32);
    ASSERT_EQ(depth.channels(), 1);
    // Camera z of every ray point is its distance below the camera; float32 keeps it to
    // 2^-24 relative, 1e-6 relative is a few ulp.
    for (int y = 0; y < 30; ++y) {
      for (int x = 0; x < 40; ++x) {
        ASSERT_NEAR(*depth.At<float>(x, y), altitude - height, 1e-6 * altitude) << x << "," << y;
      }
    }
  }
  // A plane above the camera is met behind it: depth 0 everywhere.
  const Image behind = PlaneDepth(camera, pose, Plane::AtHeight(altitude + 5.0));
  for (int y = 0; y < 30; ++y) {
    for (int x = 0; x < 40; ++x) ASSERT_EQ(*behind.At<float>(x, y), 0.0f) << x << "," << y;
  }
}

TEST(PlaneDepth, TiltedPlaneSeenToTheHorizonIsMetInFrontOrGivesZero) {
  // A camera looking at the horizon over a tilted ground: pixels below the horizon meet the
  // plane at a point on it at camera depth `depth`; pixels above it meet it behind (depth 0).
  const PinholeCamera camera = PinholeCamera::FromFov(32, 24, 90.0);
  const Rigid3d pose = LookAt(Vec3d(0, 0, 3), Vec3d(10, 1, 3), Vec3d(0, 0, 1));
  const Plane plane{Vec3d(0, 0, 0.5), Vec3d(0.05, -0.02, 1)};
  const Image depth = PlaneDepth(camera, pose, plane);
  const Vec3d n = glm::normalize(plane.normal);
  const Vec3d c = pose.Center();
  int in_front = 0, behind = 0;
  for (int y = 0; y < 24; ++y) {
    for (int x = 0; x < 32; ++x) {
      const double z = *depth.At<float>(x, y);
      const Vec3d direction = glm::transpose(pose.rotation) * camera.Unproject(Vec2d(x + 0.5, y + 0.5));
      // Independent check: the ray parameter of the crossing, sign decides front/behind.
      const double t = glm::dot(n, plane.point - c) / glm::dot(n, direction);
      if (t > 0.0) {
        ++in_front;
        // The point at camera depth z lies on the plane; float depth carries 2^-24 relative
        // error, so the offset is at most ~|direction| z 1e-7 (z < 1e3 here).
        const Vec3d point = c + z * direction;
        EXPECT_NEAR(glm::dot(n, point - plane.point), 0.0, 1e-6 * z * glm::length(direction))
            << x << "," << y;
        EXPECT_GT(z, 0.0);
      } else {
        ++behind;
        EXPECT_EQ(z, 0.0) << x << "," << y;
      }
    }
  }
  EXPECT_GT(in_front, 100);
  EXPECT_GT(behind, 100);
}

// ---------------------------------------------------------------------------------------------
// Rendering

// A 3x3 light field of 8-bit views of the textured ground at z = 0 from 20 m.
LightField GroundLightField() {
  return NadirLightField(test_util::TexturedGround(0.0), PinholeCamera::FromFov(32, 32, 60.0),
                         GridCentres(3, 2.0, 20.0), PixelType::kU8);
}

FocalStackOptions SmallStackOptions() {
  FocalStackOptions options;
  options.render.cam_from_world = LookAt(Vec3d(0.5, -0.3, 20), Vec3d(0, 0, 0), Vec3d(0, 1, 0));
  options.render.fov_deg = 40.0;
  options.render.width = 24;
  options.render.height = 20;
  options.render.aperture_radius = 5.0;
  options.render.variance = true;
  options.render.num_threads = 1;  // tiny renders: OpenMP barriers would dominate
  options.first_plane = Plane{Vec3d(0, 0, -1), Vec3d(0.1, 0, 1)};
  options.last_plane = Plane{Vec3d(0, 0, 3), Vec3d(0, -0.1, 1)};
  options.slices = 5;
  return options;
}

TEST(FocalStack, EverySliceIsRenderIntegralOnItsPlaneBitForBit) {
  const LightField light_field = GroundLightField();
  for (int pose_view : {-1, 4}) {
    FocalStackOptions options = SmallStackOptions();
    options.render.pose_view = pose_view;
    const FocalStack stack = RenderFocalStack(light_field, options);
    const Rigid3d pose = pose_view < 0 ? options.render.cam_from_world
                                       : light_field.views[static_cast<size_t>(pose_view)].cam_from_world;
    const std::vector<Plane> planes =
        StackPlanes(options.first_plane, options.last_plane, options.slices, pose.Center());
    ASSERT_EQ(stack.size(), 5);
    ASSERT_EQ(stack.images.size(), 5u);
    ASSERT_EQ(stack.counts.size(), 5u);
    ASSERT_EQ(stack.variances.size(), 5u);
    EXPECT_EQ(stack.cam_from_world.rotation, pose.rotation);
    EXPECT_EQ(stack.cam_from_world.translation, pose.translation);
    // The pose is resolved into the render options so a robust merge re-integrates from it.
    EXPECT_EQ(stack.render.pose_view, -1);
    EXPECT_EQ(stack.render.cam_from_world.rotation, pose.rotation);
    EXPECT_EQ(stack.render.cam_from_world.translation, pose.translation);
    const PinholeCamera camera = VirtualCamera(light_field, options.render);
    EXPECT_EQ(stack.camera.width, camera.width);
    EXPECT_EQ(stack.camera.height, camera.height);
    EXPECT_EQ(stack.camera.fx, camera.fx);
    EXPECT_EQ(stack.camera.cx, camera.cx);
    for (int i = 0; i < 5; ++i) {
      const size_t k = static_cast<size_t>(i);
      EXPECT_EQ(stack.focus.planes[k].point, planes[k].point) << i;
      EXPECT_EQ(stack.focus.planes[k].normal, planes[k].normal) << i;
      IntegralOptions single = options.render;
      single.focal_surface = FocalSurface::FromPlane(planes[k]);
      const IntegralResult reference = RenderIntegral(light_field, single);
      EXPECT_TRUE(SameImage(stack.images[k], reference.image)) << "slice " << i;
      EXPECT_TRUE(SameImage(stack.counts[k], reference.count)) << "slice " << i;
      EXPECT_TRUE(SameImage(stack.variances[k], reference.variance)) << "slice " << i;
      EXPECT_GT(reference.samples, 0);
    }
    // Different planes, different images: the comparison above is not vacuous.
    EXPECT_FALSE(SameImage(stack.images[0], stack.images[4]));
  }
}

TEST(FocalStack, WithoutVarianceTheStackHoldsNone) {
  FocalStackOptions options = SmallStackOptions();
  options.render.variance = false;
  const FocalStack stack = RenderFocalStack(GroundLightField(), options);
  EXPECT_EQ(stack.size(), 5);
  EXPECT_TRUE(stack.variances.empty());
  EXPECT_FALSE(stack.render.variance);
}

struct CountingSink : ProgressSink {
  void Start(const std::string& name, int64_t units) override {
    stage = name;
    total = units;
  }
  void Advance(int64_t units) override { done += units; }
  bool Cancelled() override { return cancel_after >= 0 && done.load() >= cancel_after; }
  std::string stage;
  int64_t total = 0;
  std::atomic<int64_t> done{0};
  int64_t cancel_after = -1;
};

TEST(FocalStack, SlicesAreHandedOverInOrderWithProgressPerSlice) {
  const LightField light_field = GroundLightField();
  FocalStackOptions options = SmallStackOptions();
  options.slices = 7;
  const std::vector<Plane> planes = StackPlanes(options.first_plane, options.last_plane, 7,
                                                options.render.cam_from_world.Center());
  std::vector<int> order;
  CountingSink sink;
  RenderFocalStackSlices(
      light_field, options,
      [&](int index, IntegralResult& slice) {
        order.push_back(index);
        EXPECT_EQ(slice.image.width(), 24);
        EXPECT_FALSE(slice.variance.empty());
        // The sink may take the slice's pixels.
        Image taken = std::move(slice.image);
        EXPECT_FALSE(taken.empty());
      },
      &sink);
  EXPECT_EQ(order, (std::vector<int>{0, 1, 2, 3, 4, 5, 6}));
  // Where the slices lie.
  const SliceFocus focus = ResolveSliceFocus(light_field, options);
  ASSERT_EQ(focus.size(), 7);
  for (size_t i = 0; i < planes.size(); ++i) {
    EXPECT_EQ(focus.planes[i].point, planes[i].point) << i;
    EXPECT_EQ(focus.planes[i].normal, planes[i].normal) << i;
  }
  EXPECT_EQ(sink.stage, "focal stack");
  EXPECT_EQ(sink.total, 7);
  EXPECT_EQ(sink.done.load(), 7);
  // Cancelling after three slices stops before the fourth is handed over.
  CountingSink cancelling;
  cancelling.cancel_after = 3;
  int handed = 0;
  EXPECT_THROW(RenderFocalStackSlices(
                   light_field, options, [&](int, IntegralResult&) { ++handed; },
                   &cancelling),
               Cancelled);
  EXPECT_EQ(handed, 3);
}

TEST(FocalStack, ASliceThatCannotBeRenderedIsNamed) {
  // The last plane lies above the camera (20 m), which looks down: slice 2 is behind it.
  FocalStackOptions options = SmallStackOptions();
  options.first_plane = Plane::AtHeight(0.0);
  options.last_plane = Plane::AtHeight(30.0);
  options.slices = 3;
  try {
    RenderFocalStack(GroundLightField(), options);
    ADD_FAILURE() << "a slice behind the camera must be refused";
  } catch (const std::invalid_argument& error) {
    EXPECT_THAT(error.what(), HasSubstr("slice 2"));
    EXPECT_THAT(error.what(), HasSubstr("behind"));
  }
}

// ---------------------------------------------------------------------------------------------
// Files

class FocalStackFiles : public testing_util::TempFolderTest {
 protected:
  static FocalStack Stack(bool variance, double aperture) {
    FocalStackOptions options = SmallStackOptions();
    options.render.variance = variance;
    options.render.aperture_radius = aperture;
    options.render.min_view_angle_deg = 2.5;
    options.render.view_indices = {0, 2, 4, 5, 8};
    options.render.lens_tolerance_px = 0.125;
    options.slices = 3;
    return RenderFocalStack(GroundLightField(), options);
  }
  std::string ErrorReading(const std::string& folder) {
    try {
      ReadFocalStack(folder);
    } catch (const std::invalid_argument& error) {
      return error.what();
    }
    return "no error";
  }
  // Rewrites stack.json of `folder` through `edit`.
  template <typename Edit>
  void EditJson(const std::string& folder, Edit edit) {
    const std::string file = folder + "/stack.json";
    std::ifstream in(file);
    nlohmann::json j = nlohmann::json::parse(in);
    in.close();
    edit(j);
    std::ofstream(file) << j.dump(2);
  }
  std::vector<std::string> Entries(const fs::path& folder) {
    std::vector<std::string> names;
    for (const auto& entry : fs::directory_iterator(folder)) {
      names.push_back(entry.path().filename().string());
    }
    std::sort(names.begin(), names.end());
    return names;
  }
};

TEST_F(FocalStackFiles, RoundTripKeepsEverything) {
  for (bool variance : {true, false}) {
    const double aperture = variance ? std::numeric_limits<double>::infinity() : 6.5;
    const FocalStack stack = Stack(variance, aperture);
    const std::string folder = Path(variance ? "with_variance" : "plain");
    WriteFocalStack(folder, stack);
    const FocalStack read = ReadFocalStack(folder);
    SCOPED_TRACE(variance ? "with variance, infinite aperture" : "no variance, aperture 6.5");
    ASSERT_EQ(read.size(), stack.size());
    ASSERT_EQ(read.variances.size(), stack.variances.size());
    for (size_t i = 0; i < stack.focus.planes.size(); ++i) {
      // Doubles go through JSON as shortest round-trip text: exact.
      EXPECT_EQ(read.focus.planes[i].point, stack.focus.planes[i].point) << i;
      EXPECT_EQ(read.focus.planes[i].normal, stack.focus.planes[i].normal) << i;
      // float32 TIFF and uint32 counts are lossless.
      EXPECT_TRUE(SameImage(read.images[i], stack.images[i])) << i;
      EXPECT_TRUE(SameImage(read.counts[i], stack.counts[i])) << i;
      if (variance) EXPECT_TRUE(SameImage(read.variances[i], stack.variances[i])) << i;
    }
    EXPECT_EQ(read.camera.width, stack.camera.width);
    EXPECT_EQ(read.camera.height, stack.camera.height);
    EXPECT_EQ(read.camera.fx, stack.camera.fx);
    EXPECT_EQ(read.camera.fy, stack.camera.fy);
    EXPECT_EQ(read.camera.cx, stack.camera.cx);
    EXPECT_EQ(read.camera.cy, stack.camera.cy);
    EXPECT_EQ(read.cam_from_world.rotation, stack.cam_from_world.rotation);
    EXPECT_EQ(read.cam_from_world.translation, stack.cam_from_world.translation);
    // The render options, all but num_threads (the slices replace the focus).
    EXPECT_EQ(read.render.cam_from_world.rotation, stack.render.cam_from_world.rotation);
    EXPECT_EQ(read.render.cam_from_world.translation, stack.render.cam_from_world.translation);
    EXPECT_EQ(read.render.pose_view, -1);
    EXPECT_EQ(read.render.fov_deg, stack.render.fov_deg);
    EXPECT_EQ(read.render.width, stack.render.width);
    EXPECT_EQ(read.render.height, stack.render.height);
    EXPECT_EQ(read.render.aperture_radius, aperture);
    EXPECT_EQ(read.render.min_view_angle_deg, 2.5);
    EXPECT_EQ(read.render.view_indices, (std::vector<int>{0, 2, 4, 5, 8}));
    EXPECT_EQ(read.render.lens_tolerance_px, 0.125);
    EXPECT_EQ(read.render.variance, variance);
  }
}

TEST_F(FocalStackFiles, AnExistingEmptyFolderIsFilledANonEmptyOneRefused) {
  const FocalStack stack = Stack(false, 5.0);
  fs::create_directory(Path("empty"));
  WriteFocalStack(Path("empty"), stack);
  EXPECT_EQ(ReadFocalStack(Path("empty")).size(), 3);

  fs::create_directory(Path("full"));
  std::ofstream(Path("full/keep.txt")) << "mine";
  try {
    WriteFocalStack(Path("full"), stack);
    ADD_FAILURE() << "a non-empty folder must be refused";
  } catch (const std::invalid_argument& error) {
    EXPECT_THAT(error.what(), HasSubstr(Path("full")));
    EXPECT_THAT(error.what(), HasSubstr("not empty"));
  }
  // Untouched, and no temporary folder left beside it.
  EXPECT_EQ(Entries(Path("full")), std::vector<std::string>{"keep.txt"});
  EXPECT_EQ(Entries(dir_), (std::vector<std::string>{"empty", "full"}));
}

TEST_F(FocalStackFiles, AFailedWriteLeavesNothingBehind) {
  const FocalStack stack = Stack(true, 5.0);
  // A missing parent folder: refused before anything is written.
  EXPECT_THROW(WriteFocalStack(Path("missing/stack"), stack), std::invalid_argument);
  // An inconsistent stack: refused by its check.
  FocalStack broken = stack;
  broken.counts.pop_back();
  EXPECT_THROW(WriteFocalStack(Path("broken"), broken), std::invalid_argument);
  // A write that fails part-way: a 200-byte file size limit lets the temporary folder be
  // created and then fails a file write (stack.json at the latest; SIGXFSZ is ignored so the
  // write fails with EFBIG instead of killing the process).
  rlimit old_limit{};
  ASSERT_EQ(getrlimit(RLIMIT_FSIZE, &old_limit), 0);
  rlimit small = old_limit;
  small.rlim_cur = 200;
  const auto old_handler = std::signal(SIGXFSZ, SIG_IGN);
  ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &small), 0);
  std::string message = "no error";
  try {
    WriteFocalStack(Path("stack"), stack);
  } catch (const std::invalid_argument& error) {
    message = error.what();
  }
  setrlimit(RLIMIT_FSIZE, &old_limit);
  std::signal(SIGXFSZ, old_handler);
  EXPECT_NE(message, "no error");
  EXPECT_TRUE(Entries(dir_).empty()) << "left behind: " << ::testing::PrintToString(Entries(dir_));
}

TEST_F(FocalStackFiles, ErrorsNameTheFileAndTheField) {
  WriteFocalStack(Path("good"), Stack(true, 5.0));
  struct Case {
    const char* name;
    std::function<void(nlohmann::json&)> edit;
    const char* field;
  };
  const std::vector<Case> cases = {
      {"missing key", [](nlohmann::json& j) { j["camera"].erase("fx"); }, "/camera/fx: missing"},
      {"missing slices", [](nlohmann::json& j) { j.erase("slices"); }, "/slices: missing"},
      {"wrong type", [](nlohmann::json& j) { j["version"] = "1"; }, "/version: expected a number"},
      {"wrong type in a slice", [](nlohmann::json& j) { j["slices"][1]["plane"]["normal"] = "up"; },
       "/slices/1/plane/normal"},
      {"short vector", [](nlohmann::json& j) { j["cam_from_world"]["translation"] = {1, 2}; },
       "/cam_from_world/translation"},
      {"aperture text", [](nlohmann::json& j) { j["render"]["aperture_radius"] = "wide"; },
       "/render/aperture_radius"},
      {"view index", [](nlohmann::json& j) { j["render"]["view_indices"] = {0.5}; },
       "/render/view_indices/0"},
      {"file name type", [](nlohmann::json& j) { j["slices"][2]["count"] = 7; },
       "/slices/2/count: must be a string"},
      {"bad format", [](nlohmann::json& j) { j["format"] = "other"; }, "format"},
      // Misspelled keys are refused with their key path at every level (they were ignored).
      {"unknown key", [](nlohmann::json& j) { j["slicess"] = 1; }, "stack.json: /slicess: unknown key"},
      {"unknown camera key", [](nlohmann::json& j) { j["camera"]["fxx"] = 1; },
       "stack.json: /camera/fxx: unknown key"},
      {"unknown pose key", [](nlohmann::json& j) { j["cam_from_world"]["scale"] = 1; },
       "stack.json: /cam_from_world/scale: unknown key"},
      {"unknown render key", [](nlohmann::json& j) { j["render"]["fov"] = 1; },
       "stack.json: /render/fov: unknown key"},
      {"unknown slice key", [](nlohmann::json& j) { j["slices"][1]["depth"] = 1; },
       "stack.json: /slices/1/depth: unknown key"},
      {"unknown plane key", [](nlohmann::json& j) { j["slices"][0]["plane"]["nromal"] = {0, 0, 1}; },
       "stack.json: /slices/0/plane/nromal: unknown key"},
      {"lens camera", [](nlohmann::json& j) { j["camera"]["model"] = "fisheye"; },
       "stack.json: /camera/model: a focal stack's camera is a pinhole"},
  };
  int index = 0;
  for (const Case& c : cases) {
    const std::string folder = Path("case" + std::to_string(index++));
    fs::copy(Path("good"), folder);
    EditJson(folder, c.edit);
    const std::string error = ErrorReading(folder);
    EXPECT_THAT(error, HasSubstr(folder + "/stack.json")) << c.name;
    EXPECT_THAT(error, HasSubstr(c.field)) << c.name;
  }
  // A missing slice file is named.
  const std::string missing = Path("missing_file");
  fs::copy(Path("good"), missing);
  fs::remove(missing + "/count_0001.tif");
  EXPECT_THAT(ErrorReading(missing), HasSubstr("count_0001.tif"));
  // A slice of the wrong size is named by its index and its file.
  const std::string resized = Path("resized");
  fs::copy(Path("good"), resized);
  fs::remove(resized + "/slice_0002.tif");
  WriteImage(resized + "/slice_0002.tif", ConstantImage(7, 5, {1.0f}));
  const std::string error = ErrorReading(resized);
  EXPECT_THAT(error, HasSubstr("stack.json"));
  EXPECT_THAT(error, HasSubstr("/slices/2/image"));
  EXPECT_THAT(error, HasSubstr("slice_0002.tif: is 7x5x1"));
  // And the untouched copy still reads.
  EXPECT_EQ(ErrorReading(Path("good")), "no error");
}

// The formats that take a camera (light field, camera file, stack.json) read and write it with
// one codec (lightfield/json_codec.h): the camera object one of them writes reads in the others,
// to the same camera. Camera files refused fov_deg and stack.json ignored misspelled keys before.
TEST_F(FocalStackFiles, ACameraWrittenByOneFormatReadsInEveryOther) {
  const auto read_json = [](const std::string& file) {
    std::ifstream in(file);
    return nlohmann::json::parse(in);
  };
  const auto write_json = [](const std::string& file, const nlohmann::json& j) {
    std::ofstream(file) << j.dump(2);
  };
  int files = 0;
  // The camera object read as a camera file's fields.
  const auto in_camera_file = [&](nlohmann::json camera) {
    camera["format"] = "aos-camera";
    camera["version"] = 1;
    const std::string file = Path("camera" + std::to_string(files++) + ".json");
    write_json(file, camera);
    return ReadCameraFile(file);
  };
  // ... as a light field's camera (one view of a frame of the camera's size).
  const auto in_light_field = [&](const nlohmann::json& camera) {
    const int width = camera["width"].get<int>(), height = camera["height"].get<int>();
    const std::string frame = "frame" + std::to_string(files) + ".tif";
    WriteImage(Path(frame), ConstantImage(width, height, {1.0f}));
    const nlohmann::json lf = {
        {"format", "aos-lightfield"}, {"version", 1}, {"cameras", {{"c", camera}}},
        {"views", {{{"image", frame}, {"camera", "c"},
                    {"cam_from_world", {{"rotation", {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}},
                                        {"translation", {0, 0, 5}}}}}}}};
    const std::string file = Path("lf" + std::to_string(files++) + ".json");
    write_json(file, lf);
    return LoadLightField(file).light_field.views[0].camera;
  };
  // ... as stack.json's camera (a copy of the stack written below).
  WriteFocalStack(Path("stack"), Stack(false, 5.0));
  const PinholeCamera stack_camera = ReadFocalStack(Path("stack")).camera;
  const auto in_stack = [&](const nlohmann::json& camera) {
    const std::string folder = Path("stack" + std::to_string(files++));
    fs::copy(Path("stack"), folder);
    EditJson(folder, [&](nlohmann::json& j) { j["camera"] = camera; });
    return LensCamera::FromPinhole(ReadFocalStack(folder).camera);
  };
  const auto expect_same = [](const LensCamera& a, const LensCamera& b, const char* what) {
    EXPECT_TRUE(a.SameParameters(b)) << what;
    EXPECT_EQ(a.theta_max, b.theta_max) << what;
    EXPECT_EQ(a.max_radius, b.max_radius) << what;
  };

  // A lens camera: camera file <-> light field.
  LensCamera fisheye;
  fisheye.model = LensModel::kFisheye;
  fisheye.width = 16;
  fisheye.height = 12;
  fisheye.fx = fisheye.fy = 8.0;
  fisheye.cx = 8.0;
  fisheye.cy = 6.0;
  fisheye.distortion = {0.01, -0.002, 0.0, 0.0, 0.0};
  fisheye.Finalize("fisheye");
  WriteCameraFile(Path("fisheye.json"), fisheye, "{\"rms_px\": 0.2}");
  nlohmann::json written = read_json(Path("fisheye.json"));
  for (const char* key : {"format", "version", "calibration"}) written.erase(key);
  expect_same(in_light_field(written), fisheye, "camera file -> light field");
  LightField light_field;
  light_field.views.push_back(MakeView("a", fisheye, NadirCamFromWorld(Vec3d(0, 0, 10)),
                                       ConstantImage(16, 12, {1.0f})));
  WriteLightField(Path("written_lf.json"), light_field);
  written = read_json(Path("written_lf.json"))["cameras"]["cam0"];
  expect_same(in_camera_file(written), fisheye, "light field -> camera file");

  // The stack's pinhole camera: stack.json -> camera file, light field, and back.
  const LensCamera pinhole = LensCamera::FromPinhole(stack_camera);
  written = read_json(Path("stack/stack.json"))["camera"];
  expect_same(in_camera_file(written), pinhole, "stack.json -> camera file");
  expect_same(in_light_field(written), pinhole, "stack.json -> light field");
  WriteCameraFile(Path("pinhole.json"), pinhole);
  written = read_json(Path("pinhole.json"));
  for (const char* key : {"format", "version"}) written.erase(key);
  expect_same(in_stack(written), pinhole, "camera file -> stack.json");
  light_field.views.assign(1, MakeView("b", pinhole, NadirCamFromWorld(Vec3d(0, 0, 10)),
                                       ConstantImage(pinhole.width, pinhole.height, {1.0f})));
  WriteLightField(Path("pinhole_lf.json"), light_field);
  written = read_json(Path("pinhole_lf.json"))["cameras"]["cam0"];
  expect_same(in_stack(written), pinhole, "light field -> stack.json");

  // fov_deg for a pinhole, in every format alike.
  const nlohmann::json by_fov = {{"model", "pinhole"},
                                 {"width", stack_camera.width},
                                 {"height", stack_camera.height},
                                 {"fov_deg", 40.0}};
  const LensCamera fov = LensCamera::FromPinhole(
      PinholeCamera::FromFov(stack_camera.width, stack_camera.height, 40.0));
  expect_same(in_camera_file(by_fov), fov, "fov_deg in a camera file");
  expect_same(in_light_field(by_fov), fov, "fov_deg in a light field");
  expect_same(in_stack(by_fov), fov, "fov_deg in stack.json");
  // And a lens model's fov_deg goes through its radial map in every format alike (as in a
  // scene): the same camera as LensFromFov.
  nlohmann::json fisheye_by_fov = by_fov;
  fisheye_by_fov["model"] = "fisheye";
  fisheye_by_fov["fov_deg"] = 150.0;
  fisheye_by_fov["distortion"] = {0.01, 0.0, 0.0, 0.0};
  const LensCamera wide =
      LensFromFov(LensModel::kFisheye, stack_camera.width, stack_camera.height, 150.0,
                  {0.01, 0.0, 0.0, 0.0, 0.0}, 0.0, "fisheye");
  for (const auto& read : {std::function<LensCamera(const nlohmann::json&)>(in_camera_file),
                           std::function<LensCamera(const nlohmann::json&)>(in_light_field)}) {
    EXPECT_TRUE(read(fisheye_by_fov).SameParameters(wide));
  }
}

// ---------------------------------------------------------------------------------------------
// Terrain-following stacks (render.focal_surface: one surface at N offsets along up)

// A flat square mesh (world coordinates) at z = height, 200 m wide.
Mesh FlatMesh(double height) {
  Mesh mesh;
  mesh.vertices = {{-100, -100, height}, {100, -100, height}, {100, 100, height}, {-100, 100, height}};
  mesh.triangles = {{0, 1, 2}, {0, 2, 3}};
  return mesh;
}

double MaxAbsDifference(const Image& a, const Image& b) {
  double worst = 0.0;
  for (int y = 0; y < a.height(); ++y) {
    for (int x = 0; x < a.width() * a.channels(); ++x) {
      worst = std::max(worst, std::abs(double(a.At<float>(0, y)[x]) - b.At<float>(0, y)[x]));
    }
  }
  return worst;
}

FocalStackOptions TerrainStackOptions(double mesh_height) {
  FocalStackOptions options = SmallStackOptions();
  options.render.focal_surface = FocalSurface::FromMesh(FlatMesh(mesh_height));
  options.first_offset = -0.3;
  options.last_offset = 1.2;
  options.slices = 4;
  return options;
}

TEST(TerrainFollowingStack, OffsetsAreEvenlySpacedRoundAndEndExactly) {
  EXPECT_EQ(StackOffsets(-1.0, 20.0, 8),
            (std::vector<double>{-1.0, 2.0, 5.0, 8.0, 11.0, 14.0, 17.0, 20.0}));
  EXPECT_EQ(StackOffsets(-0.3, 1.2, 4).back(), 1.2);
  EXPECT_EQ(StackOffsets(2.0, 4.0, 1), (std::vector<double>{3.0}));  // one slice: midway
  EXPECT_EQ(StackOffsets(5.0, 5.0, 3), (std::vector<double>{5.0, 5.0, 5.0}));
}

TEST(TerrainFollowingStack, AFlatMeshStackIsThePlaneStackAtTheMeshHeightPlusTheOffsets) {
  // Views at z = 20 look down on a mesh at z = 0.3, so up is +z: offsets -0.3, 0.2, 0.7, 1.2 put
  // the slices on z = 0, 0.5, 1, 1.5, the horizontal plane stack from 0 to 1.5. The mesh path
  // (Embree cast, per-sample kernel) and the plane path (homography kernel) agree to float
  // rounding of the sample positions: 1e-3 grey on 8-bit texture (as focal_surface_test).
  const LightField light_field = GroundLightField();
  FocalStackOptions terrain = TerrainStackOptions(0.3);
  terrain.render.variance = false;
  FocalStackOptions planes = SmallStackOptions();
  planes.render.variance = false;
  planes.first_plane = Plane::AtHeight(0.0);
  planes.last_plane = Plane::AtHeight(1.5);
  planes.slices = 4;
  const FocalStack on_mesh = RenderFocalStack(light_field, terrain);
  const FocalStack on_planes = RenderFocalStack(light_field, planes);
  ASSERT_EQ(on_mesh.size(), 4);
  EXPECT_TRUE(on_mesh.focus.planes.empty());
  ASSERT_TRUE(on_mesh.focus.surface);
  EXPECT_EQ(on_mesh.focus.placement.up, Vec3d(0, 0, 1));
  EXPECT_EQ(on_mesh.focus.offsets, StackOffsets(-0.3, 1.2, 4));
  for (size_t i = 0; i < 4; ++i) {
    EXPECT_TRUE(SameImage(on_mesh.counts[i], on_planes.counts[i])) << i;
    EXPECT_LT(MaxAbsDifference(on_mesh.images[i], on_planes.images[i]), 1e-3) << i;
  }
  // The slices differ (the comparison is not vacuous), and a wrong sign of up would pair slice
  // 0 with z = 0.6 instead of 0: it fails.
  EXPECT_GT(MaxAbsDifference(on_mesh.images[0], on_mesh.images[3]), 1.0);
  planes.first_plane = Plane::AtHeight(0.6);
  planes.last_plane = Plane::AtHeight(-0.9);
  EXPECT_GT(MaxAbsDifference(on_mesh.images[0], RenderFocalStack(light_field, planes).images[0]), 1.0);
}

TEST(TerrainFollowingStack, FractionalSlicesLieOnTheSurfaceAtTheInterpolatedOffset) {
  // DepthOfSlices of a flat mesh at z = 0.3 (offsets -0.3 .. 1.2, 4 slices, 0.5 m apart): a
  // pixel at fractional slice z lies on z_world = 0.3 - 0.3 + 0.5 z; its depth is PlaneDepth of
  // that plane, to one float32 rounding (relative 2^-23 of the depth, about 1.2e-7).
  const LightField light_field = GroundLightField();
  const FocalStackOptions options = TerrainStackOptions(0.3);
  const SliceFocus focus = ResolveSliceFocus(light_field, options);
  const PinholeCamera camera = VirtualCamera(light_field, options.render);
  const Rigid3d pose = options.render.cam_from_world;
  const std::vector<float> fractions = {0.0f, 0.25f, 1.0f, 1.5f, 2.75f, 3.0f, -1.0f};
  std::vector<float> slice(static_cast<size_t>(camera.width) * camera.height);
  for (size_t i = 0; i < slice.size(); ++i) slice[i] = fractions[i % fractions.size()];
  const Image depth = focus.DepthOfSlices(camera, pose, slice, 2);
  double worst = 0.0;
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const float z = slice[static_cast<size_t>(y) * camera.width + x];
      const float got = depth.At<float>(x, y)[0];
      if (z < 0.0f) {
        EXPECT_EQ(got, 0.0f);  // no slice: no depth
        continue;
      }
      const Image plane = PlaneDepth(camera, pose, Plane::AtHeight(0.5 * z));
      const double expected = plane.At<float>(x, y)[0];
      worst = std::max(worst, std::abs(got - expected) / expected);
    }
  }
  EXPECT_LE(worst, 2.5e-7);  // two float32 roundings: ours and PlaneDepth's
  // The grazing test of a re-integration measures against the horizontal (normal up).
  EXPECT_EQ(focus.GrazingPlane().normal, Vec3d(0, 0, 1));
  // A per-pixel offset map of the wrong size or with NaN is refused, naming it.
  EXPECT_THAT(test_util::ErrorOf([&] {
                focus.surface->DepthForOffsets(camera, pose, focus.placement, {0.0});
              }),
              HasSubstr("offsets: 1 entries for 24 x 20 pixels"));
  std::vector<double> bad(slice.size(), 0.0);
  bad[7] = std::nan("");
  EXPECT_THAT(test_util::ErrorOf([&] {
                focus.surface->DepthForOffsets(camera, pose, focus.placement, bad);
              }),
              HasSubstr("offsets: entry 7 is not finite"));
}

TEST(TerrainFollowingStack, OneAndTwoThreadsGiveTheSameDepths) {
  // The casts take the caller's thread count (merge/allinfocus num_threads); rows are
  // independent, so the depth maps are the same bytes for any count.
  const LightField light_field = GroundLightField();
  const FocalStackOptions options = TerrainStackOptions(0.3);
  const SliceFocus focus = ResolveSliceFocus(light_field, options);
  const PinholeCamera camera = VirtualCamera(light_field, options.render);
  std::vector<float> slice(static_cast<size_t>(camera.width) * camera.height);
  for (size_t i = 0; i < slice.size(); ++i) slice[i] = static_cast<float>(i % 7) * 0.5f - 0.5f;
  const Rigid3d pose = options.render.cam_from_world;
  EXPECT_TRUE(SameImage(focus.DepthOfSlices(camera, pose, slice, 1),
                        focus.DepthOfSlices(camera, pose, slice, 2)));
  EXPECT_TRUE(SameImage(focus.surface->DepthFor(camera, pose, focus.placement, 1),
                        focus.surface->DepthFor(camera, pose, focus.placement, 2)));
}

TEST(TerrainFollowingStack, BadOptionsAreNamed) {
  const LightField light_field = GroundLightField();
  FocalStackOptions options = TerrainStackOptions(0.3);
  options.render.surface_offset = 1.0;
  EXPECT_THAT(test_util::ErrorOf([&] { RenderFocalStack(light_field, options); }),
              HasSubstr("render.surface_offset: must be 0 in a stack"));
  options = TerrainStackOptions(0.3);
  options.last_offset = std::numeric_limits<double>::infinity();
  EXPECT_THAT(test_util::ErrorOf([&] { RenderFocalStack(light_field, options); }),
              HasSubstr("last_offset: must be finite"));
  options = TerrainStackOptions(0.3);
  options.first_offset = std::nan("");
  EXPECT_THAT(test_util::ErrorOf([&] { RenderFocalStack(light_field, options); }),
              HasSubstr("first_offset: must be finite"));
  // With a surface the planes are not used: a zero-normal plane is no error.
  options = TerrainStackOptions(0.3);
  options.first_plane = Plane{Vec3d(0.0), Vec3d(0.0)};
  EXPECT_EQ(test_util::ErrorOf([&] { options.Check(9); }), "no error");
}

TEST(StackAroundTheGround, PlanesParallelToTheGroundAtTheOffsetsTowardsTheViews) {
  // A ground plane z = 0.3 given with a DOWNWARD normal: turned towards the views (z = 20), the
  // offsets -0.3 .. 1.2 give the horizontal planes z = 0 .. 1.5: the plane stack between them.
  const LightField light_field = GroundLightField();
  FocalStackOptions around = SmallStackOptions();
  around.ground_plane = Plane{Vec3d(2.0, -1.0, 0.3), Vec3d(0, 0, -3)};
  around.first_offset = -0.3;
  around.last_offset = 1.2;
  around.slices = 4;
  around.first_plane = Plane{Vec3d(0.0), Vec3d(0.0)};  // ignored with a ground plane
  FocalStackOptions planes = SmallStackOptions();
  planes.first_plane = Plane::AtHeight(0.0);
  planes.last_plane = Plane::AtHeight(1.5);
  planes.slices = 4;
  const SliceFocus focus = ResolveSliceFocus(light_field, around);
  const SliceFocus expected = ResolveSliceFocus(light_field, planes);
  ASSERT_EQ(focus.size(), 4);
  for (size_t i = 0; i < 4; ++i) {
    EXPECT_TRUE(SamePlane(focus.planes[i], expected.planes[i], 1e-12)) << i;
  }
  const FocalStack stack = RenderFocalStack(light_field, around);
  const FocalStack reference = RenderFocalStack(light_field, planes);
  for (size_t i = 0; i < 4; ++i) {
    EXPECT_TRUE(SameImage(stack.counts[i], reference.counts[i])) << i;
    EXPECT_LT(MaxAbsDifference(stack.images[i], reference.images[i]), 1e-3) << i;
  }
  // A ground plane and a surface together, or a bad ground plane, are refused by name.
  around.render.focal_surface = FocalSurface::FromMesh(FlatMesh(0.3));
  EXPECT_THAT(test_util::ErrorOf([&] { around.Check(9); }), HasSubstr("ground_plane: give either"));
  around.render.focal_surface = FocalSurface::FromPlane(Plane::AtHeight(0.0));
  // Another plane as the stack's surface would be ignored (the slices replace it): refused.
  FocalStackOptions plane_surface = around;
  plane_surface.render.focal_surface = FocalSurface::FromPlane(Plane::AtHeight(100.0));
  EXPECT_THAT(test_util::ErrorOf([&] { plane_surface.Check(9); }),
              HasSubstr("render.focal_surface: a plane here would be ignored"));
  around.ground_plane = Plane{Vec3d(0.0), Vec3d(0.0)};
  EXPECT_THAT(test_util::ErrorOf([&] { around.Check(9); }), HasSubstr("ground_plane"));
}

TEST_F(FocalStackFiles, ATerrainFollowingStackRoundTripsWithItsSurface) {
  // A mesh stack (the surface stored as surface.ply) and a DEM stack (surface.tif, with its CRS):
  // offsets, placement and every slice come back; merging the read stack equals merging the
  // stack in memory (the depths come from the stored surface).
  Heightfield field;
  field.width = 40;
  field.height = 40;
  field.geotransform = {-20.0, 1.0, 0.0, 20.0, 0.0, -1.0};
  field.heights.assign(1600, 0.3f);
  field.crs_wkt = "EPSG:32633";
  const std::vector<std::pair<std::string, FocalSurface>> surfaces = {
      {"mesh", FocalSurface::FromMesh(FlatMesh(0.3))},
      {"dem", FocalSurface::FromHeightfield(field)}};
  for (const auto& [name, surface] : surfaces) {
    SCOPED_TRACE(name);
    FocalStackOptions options = TerrainStackOptions(0.3);
    options.render.focal_surface = surface;
    const FocalStack stack = RenderFocalStack(GroundLightField(), options);
    const std::string folder = Path("terrain_" + name);
    WriteFocalStack(folder, stack);
    EXPECT_TRUE(fs::exists(folder + (name == "dem" ? "/surface.tif" : "/surface.ply")));
    const FocalStack read = ReadFocalStack(folder);
    ASSERT_EQ(read.size(), 4);
    EXPECT_EQ(read.focus.offsets, stack.focus.offsets);
    EXPECT_EQ(read.focus.placement.up, stack.focus.placement.up);
    EXPECT_EQ(read.focus.placement.origin, stack.focus.placement.origin);
    ASSERT_TRUE(read.focus.surface);
    EXPECT_EQ(read.focus.surface->kind(),
              name == "dem" ? FocalSurfaceKind::kHeightfield : FocalSurfaceKind::kMesh);
    for (size_t i = 0; i < 4; ++i) EXPECT_TRUE(SameImage(read.images[i], stack.images[i])) << i;
    MergeOptions merge;
    merge.num_threads = 1;
    const MergeResult in_memory = MergeFocalStack(stack, merge);
    const MergeResult from_disk = MergeFocalStack(read, merge);
    EXPECT_TRUE(SameImage(in_memory.depth, from_disk.depth));
    EXPECT_TRUE(SameImage(in_memory.image, from_disk.image));
  }
  // Mixed-up files are refused, naming the field.
  const std::string folder = Path("terrain_mesh");
  EditJson(folder, [](nlohmann::json& j) { j["slices"][1]["plane"] = j["slices"][1]["offset"]; });
  EXPECT_THAT(ErrorReading(folder), HasSubstr("/slices/1/plane: a terrain-following stack's slice has an offset"));
  EditJson(folder, [](nlohmann::json& j) {
    j["slices"][1].erase("plane");
    j.erase("surface");
  });
  EXPECT_THAT(ErrorReading(folder), HasSubstr("/slices/0/offset: a slice with an offset needs"));
  fs::remove(folder + "/surface.ply");
  EditJson(folder, [](nlohmann::json& j) { j["surface"] = {{"file", "surface.ply"}, {"kind", "mesh"}, {"origin", {0, 0, 0}}, {"up", {0, 0, 1}}}; });
  EXPECT_THAT(ErrorReading(folder), HasSubstr("surface.ply"));
}

// ---------------------------------------------------------------------------------------------
// Per-pixel variance of the view samples (IntegralOptions::variance)

TEST(IntegralVariance, ViewsOfAConstantPlaneHaveVarianceZero) {
  // Every sample of a constant 77 is exactly 77 (bilinear weights of equal corners), so
  // sum x^2 / n - mean^2 is exactly 0; a formula without the mean term would give 5929.
  SyntheticScene scene;
  scene.layers.push_back(SceneLayer{Plane::AtHeight(0.0), [](const Vec3d&, float* value) {
    value[0] = 77.0f;
    return true;
  }});
  const LightField light_field = NadirLightField(scene, PinholeCamera::FromFov(24, 24, 60.0),
                                                 GridCentres(3, 2.0, 20.0), PixelType::kU8);
  IntegralOptions options;
  options.cam_from_world = NadirCamFromWorld(Vec3d(0, 0, 20));
  options.fov_deg = 70.0;
  options.width = options.height = 20;
  options.variance = true;
  options.num_threads = 1;
  const IntegralResult result = RenderIntegral(light_field, options);
  ASSERT_EQ(result.variance.width(), 20);
  ASSERT_EQ(result.variance.channels(), 1);
  ASSERT_EQ(result.variance.type(), PixelType::kF32);
  int shared = 0;
  for (int y = 0; y < 20; ++y) {
    for (int x = 0; x < 20; ++x) {
      EXPECT_EQ(*result.variance.At<float>(x, y), 0.0f) << x << "," << y;
      shared += *result.count.At<uint32_t>(x, y) >= 2;
    }
  }
  EXPECT_GT(shared, 100);
  // Without the flag there is no variance image.
  options.variance = false;
  EXPECT_TRUE(RenderIntegral(light_field, options).variance.empty());
}

TEST(IntegralVariance, TwoViewsGiveTheSquaredHalfDifference) {
  // Two float views of constant value a and b: where both see the point the population variance
  // is ((a - b) / 2)^2; where one sees it, 0. Values small integers: every step exact.
  const PinholeCamera camera = PinholeCamera::FromFov(32, 32, 50.0);
  for (int channels : {1, 3}) {
    const std::vector<float> a = channels == 1 ? std::vector<float>{100} : std::vector<float>{100, 0, 10};
    const std::vector<float> b = channels == 1 ? std::vector<float>{40} : std::vector<float>{40, 20, 10};
    LightField light_field;
    light_field.views.push_back(MakeView("a", camera, NadirCamFromWorld(Vec3d(-4, 0, 20)),
                                         ConstantImage(32, 32, a)));
    light_field.views.push_back(MakeView("b", camera, NadirCamFromWorld(Vec3d(4, 0, 20)),
                                         ConstantImage(32, 32, b)));
    IntegralOptions options;
    options.cam_from_world = NadirCamFromWorld(Vec3d(0, 0, 20));
    options.fov_deg = 80.0;
    options.width = options.height = 40;
    options.variance = true;
    options.num_threads = 1;
    const IntegralResult result = RenderIntegral(light_field, options);
    // Mean over channels of ((a_c - b_c) / 2)^2: 900 grey; (900 + 100 + 0) / 3 for RGB.
    double expected = 0.0;
    for (int c = 0; c < channels; ++c) expected += 0.25 * (a[c] - b[c]) * (a[c] - b[c]);
    expected /= channels;
    int both = 0, one = 0;
    for (int y = 0; y < 40; ++y) {
      for (int x = 0; x < 40; ++x) {
        const uint32_t count = *result.count.At<uint32_t>(x, y);
        const float variance = *result.variance.At<float>(x, y);
        if (count == 2) {
          ++both;
          ASSERT_EQ(variance, static_cast<float>(expected)) << x << "," << y;
          ASSERT_EQ(result.image.At<float>(x, y)[0], 0.5f * (a[0] + b[0]));
        } else {
          one += count == 1;
          ASSERT_EQ(variance, 0.0f) << "count " << count << " at " << x << "," << y;
        }
      }
    }
    EXPECT_GT(both, 100) << channels;
    EXPECT_GT(one, 100) << channels;
    // Nearest mode keeps one sample a pixel: variance 0 everywhere.
    options.aperture_radius = 0.0;
    const IntegralResult nearest = RenderIntegral(light_field, options);
    for (int y = 0; y < 40; ++y) {
      for (int x = 0; x < 40; ++x) ASSERT_EQ(*nearest.variance.At<float>(x, y), 0.0f);
    }
  }
}

TEST(IntegralVariance, ATexturedPlaneIsSharpOnlyInFocus) {
  // The variance is a focus cue: on the textured ground's own plane the views agree up to
  // bilinear interpolation error (float views, texture slopes of at most ~250 grey/m over 0.2 m
  // view pixels: a few grey levels, variance < 100), 3 m above it they see different texture
  // (hundreds of grey levels apart: variance > 1000 on average).
  const LightField light_field = NadirLightField(test_util::TexturedGround(0.0),
                                                 PinholeCamera::FromFov(96, 96, 50.0),
                                                 GridCentres(3, 3.0, 20.0), PixelType::kF32);
  IntegralOptions options;
  options.cam_from_world = NadirCamFromWorld(Vec3d(0, 0, 20));
  options.fov_deg = 20.0;
  options.width = options.height = 24;
  options.variance = true;
  options.num_threads = 1;
  auto mean_variance = [&](double height) {
    options.focal_surface = FocalSurface::FromPlane(Plane::AtHeight(height));
    const IntegralResult result = RenderIntegral(light_field, options);
    double sum = 0.0;
    for (int y = 0; y < 24; ++y) {
      for (int x = 0; x < 24; ++x) {
        EXPECT_EQ(*result.count.At<uint32_t>(x, y), 9u);
        sum += *result.variance.At<float>(x, y);
      }
    }
    return sum / (24 * 24);
  };
  EXPECT_LT(mean_variance(0.0), 100.0);
  EXPECT_GT(mean_variance(3.0), 1000.0);
}

}  // namespace
}  // namespace aos
