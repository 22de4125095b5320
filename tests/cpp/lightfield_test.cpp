#include "aos/lightfield/lightfield.h"

#include <cmath>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace aos {
namespace {

using ::testing::HasSubstr;

std::string MakeViewError(const Image& image, const PinholeCamera& camera, const Rigid3d& pose) {
  try {
    MakeView("frame7.exr", camera, pose, image);
  } catch (const std::invalid_argument& error) {
    return error.what();
  }
  return "no error";
}

TEST(LightField, MakeViewAddsABorderAndChecksEverything) {
  const PinholeCamera camera = PinholeCamera::FromFov(8, 6, 50.0);
  Image image(8, 6, 1, PixelType::kF32);
  for (int y = 0; y < 6; ++y) {
    for (int x = 0; x < 8; ++x) *image.At<float>(x, y) = static_cast<float>(x + 10 * y + 1);
  }
  const View view = MakeView("ok", camera, Rigid3d{}, image);
  EXPECT_EQ(view.image.border(), 1);
  EXPECT_EQ(view.image.Value(-1, -1), 1.0);   // corner replicated from (0, 0)
  EXPECT_EQ(view.image.Value(8, 6), 58.0);    // from (7, 5)
  EXPECT_EQ(view.image.Value(3, -1), 4.0);    // top edge from (3, 0)

  Image nan_image = image.Clone();
  *nan_image.At<float>(3, 2) = std::nanf("");
  EXPECT_THAT(MakeViewError(nan_image, camera, Rigid3d{}),
              HasSubstr("frame7.exr: image: pixel (3, 2) channel 0 is NaN"));
  EXPECT_EQ(image.Value(3, 2), 24.0) << "Clone() must not share pixels";

  Rigid3d bad_pose;
  bad_pose.rotation[0][1] = 0.5;
  EXPECT_THAT(MakeViewError(image, camera, bad_pose), HasSubstr("cam_from_world"));
  EXPECT_THAT(MakeViewError(image, PinholeCamera::FromFov(9, 6, 50.0), Rigid3d{}),
              HasSubstr("8x6 but the camera says 9x6"));
}

TEST(LightField, ChannelCountsMustAgree) {
  const PinholeCamera camera = PinholeCamera::FromFov(4, 4, 50.0);
  LightField light_field;
  light_field.views.push_back(MakeView("grey", camera, Rigid3d{}, Image(4, 4, 1, PixelType::kU8)));
  light_field.views.push_back(MakeView("rgb", camera, Rigid3d{}, Image(4, 4, 3, PixelType::kU8)));
  try {
    CheckLightField(light_field, "lf.json");
    ADD_FAILURE();
  } catch (const std::invalid_argument& error) {
    EXPECT_THAT(error.what(), HasSubstr("lf.json: view 1 (rgb): image has 3 channels"));
  }
  EXPECT_EQ(light_field.ImageBytes(), 4u * 4u * 4u);
}

}  // namespace
}  // namespace aos
