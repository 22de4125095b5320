#include <cmath>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "aos/geometry/pinhole.h"
#include "aos/geometry/rigid.h"

namespace aos {
namespace {

using ::testing::HasSubstr;

TEST(Rigid, LookAtBuildsOpenCvAxes) {
  // A camera 10 m above the origin looking down, image top towards +y (north).
  const Rigid3d cam_from_world = LookAt(Vec3d(0, 0, 10), Vec3d(0, 0, 0), Vec3d(0, 1, 0));
  const Vec3d x = Row(cam_from_world.rotation, 0), y = Row(cam_from_world.rotation, 1),
              z = Row(cam_from_world.rotation, 2);
  EXPECT_NEAR(glm::distance(z, Vec3d(0, 0, -1)), 0.0, 1e-15);  // forward = down
  EXPECT_NEAR(glm::distance(y, Vec3d(0, -1, 0)), 0.0, 1e-15);  // image down = south
  EXPECT_NEAR(glm::distance(x, Vec3d(1, 0, 0)), 0.0, 1e-15);   // image right = east
  EXPECT_NEAR(glm::distance(cam_from_world.Center(), Vec3d(0, 0, 10)), 0.0, 1e-12);
  EXPECT_FALSE(DescribeInvalidRigid(cam_from_world).has_value());
  // The target projects to the principal point.
  const Vec3d target_in_cam = cam_from_world * Vec3d(0, 0, 0);
  EXPECT_NEAR(target_in_cam.x, 0.0, 1e-12);
  EXPECT_NEAR(target_in_cam.y, 0.0, 1e-12);
  EXPECT_NEAR(target_in_cam.z, 10.0, 1e-12);
}

TEST(Rigid, LookAtRejectsDegenerateInput) {
  EXPECT_THROW(LookAt(Vec3d(1, 2, 3), Vec3d(1, 2, 3)), std::invalid_argument);
  EXPECT_THROW(LookAt(Vec3d(0, 0, 10), Vec3d(0, 0, 0), Vec3d(0, 0, 1)), std::invalid_argument);
}

TEST(Rigid, InverseAndMatrixRoundTrip) {
  const Rigid3d a = LookAt(Vec3d(3, -4, 12), Vec3d(1, 1, 0), Vec3d(0, 1, 0));
  const Rigid3d identity_check = a.Inverse();
  const Vec3d p(0.3, -7.0, 2.5);
  EXPECT_NEAR(glm::distance(identity_check * (a * p), p), 0.0, 1e-12);
  const Rigid3d b = Rigid3d::FromMatrix3x4(a.ToMatrix3x4());
  EXPECT_NEAR(glm::distance(b * p, a * p), 0.0, 0.0);
}

TEST(Rigid, DescribesInvalidTransforms) {
  Rigid3d bad;
  bad.translation.x = std::nan("");
  EXPECT_THAT(*DescribeInvalidRigid(bad), HasSubstr("non-finite"));
  bad = Rigid3d{};
  bad.rotation[0][1] = 0.3;
  EXPECT_THAT(*DescribeInvalidRigid(bad), HasSubstr("not orthonormal"));
  bad = Rigid3d{};
  bad.rotation[2][2] = -1.0;
  EXPECT_THAT(*DescribeInvalidRigid(bad), HasSubstr("reflection"));
  // Rounding as in files with 9 significant digits is accepted.
  Rigid3d rounded = LookAt(Vec3d(1, 2, 30), Vec3d(0, 0, 0), Vec3d(0, 1, 0));
  for (int c = 0; c < 3; ++c) {
    for (int r = 0; r < 3; ++r) rounded.rotation[c][r] = std::round(rounded.rotation[c][r] * 1e9) / 1e9;
  }
  EXPECT_FALSE(DescribeInvalidRigid(rounded).has_value());
}

TEST(Pinhole, FromFovAndPixelConvention) {
  const PinholeCamera camera = PinholeCamera::FromFov(512, 256, 90.0);
  EXPECT_DOUBLE_EQ(camera.fx, 256.0);  // (w/2) / tan(45 deg)
  EXPECT_DOUBLE_EQ(camera.cx, 256.0);
  EXPECT_DOUBLE_EQ(camera.cy, 128.0);
  EXPECT_NEAR(camera.FovXDeg(), 90.0, 1e-12);
  // The optical axis hits the image centre; the left image edge is at u = 0.
  const Vec2d centre = camera.Project(Vec3d(0, 0, 5));
  EXPECT_DOUBLE_EQ(centre.x, 256.0);
  EXPECT_DOUBLE_EQ(centre.y, 128.0);
  EXPECT_NEAR(camera.Project(Vec3d(-1, 0, 1)).x, 0.0, 1e-12);
  // Unproject inverts Project.
  const Vec2d pixel(17.5, 201.25);
  const Vec2d back = camera.Project(3.0 * camera.Unproject(pixel));
  EXPECT_NEAR(back.x, pixel.x, 1e-12);
  EXPECT_NEAR(back.y, pixel.y, 1e-12);
}

TEST(Pinhole, RejectsBadFieldOfView) {
  for (double fov : {0.0, -1.0, 180.0, 270.0, std::nan("")}) {
    try {
      PinholeCamera::FromFov(64, 64, fov);
      ADD_FAILURE() << fov;
    } catch (const std::invalid_argument& error) {
      EXPECT_THAT(error.what(), HasSubstr("fov_deg"));
    }
  }
  PinholeCamera camera = PinholeCamera::FromFov(64, 64, 50.0);
  camera.fx = -1.0;
  EXPECT_THROW(camera.Check("cam"), std::invalid_argument);
}

}  // namespace
}  // namespace aos
