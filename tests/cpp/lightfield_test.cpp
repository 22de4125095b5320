#include "aos/lightfield/lightfield.h"

#include <cmath>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace aos {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

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

std::string FindViewError(const LightField& light_field, const std::string& name) {
  try {
    return "found view " + std::to_string(FindViewByName(light_field, name, "--pose-view"));
  } catch (const std::invalid_argument& error) {
    return error.what();
  }
}

TEST(LightField, FindViewByNameTakesNamesStemsAndCase) {
  LightField light_field;
  for (const char* name : {"images/DJI_0041.JPG", "images/DJI_0042.JPG", "images/DJI_0042.png",
                           "images/other.tif", "IMG_7.png"}) {
    View view;
    view.name = name;
    light_field.views.push_back(view);
  }
  EXPECT_EQ(FindViewByName(light_field, "images/DJI_0041.JPG"), 0);  // the name
  EXPECT_EQ(FindViewByName(light_field, "DJI_0041.JPG"), 0);         // the file name
  EXPECT_EQ(FindViewByName(light_field, "DJI_0041"), 0);             // the stem
  EXPECT_EQ(FindViewByName(light_field, "dji_0041.jpg"), 0);         // ignoring case
  EXPECT_EQ(FindViewByName(light_field, "DJI_0042.png"), 2);         // exact file name
  EXPECT_EQ(FindViewByName(light_field, "other"), 3);
  EXPECT_EQ(FindViewByName(light_field, "img_7"), 4);
  // Two views share the stem DJI_0042: ambiguous, both named with their indices.
  const std::string ambiguous = FindViewError(light_field, "DJI_0042");
  EXPECT_THAT(ambiguous, HasSubstr("--pose-view: \"DJI_0042\" is ambiguous: 2 views match"));
  EXPECT_THAT(ambiguous, HasSubstr("images/DJI_0042.JPG (view 1)"));
  EXPECT_THAT(ambiguous, HasSubstr("images/DJI_0042.png (view 2)"));
  // Unknown: close names suggested.
  const std::string unknown = FindViewError(light_field, "DJI_0043");
  EXPECT_THAT(unknown, HasSubstr("--pose-view: no view named \"DJI_0043\" among the 5 views"));
  EXPECT_THAT(unknown, HasSubstr("close: \"images/DJI_0041.JPG (view 0)\""));
  EXPECT_THAT(unknown, Not(HasSubstr("other.tif")));
  EXPECT_THAT(FindViewError(light_field, "zzzzzzzzzzzz"), HasSubstr("names run from"));
  EXPECT_THAT(FindViewError(light_field, ""), HasSubstr("empty view name"));
  // A view named otherwise than its frame file answers to the file too (a simulated view
  // "view_0004" written as views/0004.png), and is listed with it.
  LightField named;
  named.views.resize(2);
  named.views[0].name = "view_0000";
  named.views[0].image_path = "/data/scene/views/0000.png";
  named.views[1].name = "view_0001";
  named.views[1].image_path = "/data/scene/views/0001.png";
  EXPECT_EQ(FindViewByName(named, "0001.png"), 1);
  EXPECT_EQ(FindViewByName(named, "0001"), 1);
  EXPECT_EQ(FindViewByName(named, "views/0001.png"), 1);
  EXPECT_EQ(FindViewByName(named, "view_0000"), 0);
  EXPECT_THAT(FindViewError(named, "cenes/0001.png"), HasSubstr("no view named"));
  EXPECT_EQ(ViewNameAndFile(named.views[1], 1), "view_0001 (view 1, file views/0001.png)");
}

}  // namespace
}  // namespace aos
