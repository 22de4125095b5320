// Scene files: strict parsing (unknown keys, wrong types and bad values name the key path),
// defaults, the JSON round trip, and the view layout.
#include "aos/sim/scene.h"

#include <fstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "aos/image/image_io.h"
#include "temp_folder.h"

namespace aos {
namespace {

using ::testing::HasSubstr;

std::string ErrorOf(const std::string& json) {
  try {
    ParseScene(json, "scene.json");
  } catch (const std::invalid_argument& error) {
    return error.what();
  }
  return "(no error)";
}

TEST(Scene, EmptyObjectGivesTheDocumentedDefaults) {
  const Scene scene = ParseScene("{}", "scene.json");
  EXPECT_EQ(scene.seed, 1u);
  EXPECT_FALSE(scene.HasOccluders());
  EXPECT_TRUE(scene.targets.empty());
  EXPECT_EQ(scene.camera.width, 512);
  EXPECT_EQ(scene.camera.fov_deg, 80.0);
  EXPECT_EQ(scene.sampling.altitude, 20.0);
  EXPECT_EQ(scene.sampling.grid, 9);
  EXPECT_EQ(scene.sampling.aperture_diameter, 30.0);
  EXPECT_FALSE(scene.effects.sun || scene.effects.sensor_noise || scene.effects.pose_noise ||
               scene.effects.thermal);
  EXPECT_EQ(ViewPositions(scene).size(), 81u);
}

TEST(Scene, UnknownKeysAreErrorsWithTheirPath) {
  EXPECT_THAT(ErrorOf(R"({"occluders": {"voxels": {"densty": 0.5}}})"),
              HasSubstr("scene.json: /occluders/voxels/densty: unknown key"));
  EXPECT_THAT(ErrorOf(R"({"camera": {"fov": 60}})"), HasSubstr("/camera/fov: unknown key"));
  EXPECT_THAT(ErrorOf(R"({"colour": 1})"), HasSubstr("/colour: unknown key"));
  EXPECT_THAT(ErrorOf(R"({"targets": [{"centre": [0, 0]}]})"),
              HasSubstr("/targets/0/centre: unknown key"));
  EXPECT_THAT(ErrorOf(R"({"ground": {"texture": {"type": "checker", "patch": 2}}})"),
              HasSubstr("/ground/texture/patch: unknown key"));
}

TEST(Scene, WrongTypesAreErrorsWithTheirPath) {
  EXPECT_THAT(ErrorOf(R"({"camera": {"width": "512"}})"),
              HasSubstr("/camera/width: expected a whole number, got \"512\""));
  EXPECT_THAT(ErrorOf(R"({"camera": {"width": 512.5}})"), HasSubstr("/camera/width: expected a whole number"));
  EXPECT_THAT(ErrorOf(R"({"sampling": {"altitude": [20]}})"),
              HasSubstr("/sampling/altitude: expected a number, got ["));
  EXPECT_THAT(ErrorOf(R"({"occluders": {"voxels": {"center": [0, 0]}}})"),
              HasSubstr("/occluders/voxels/center: expected a list of 3 numbers"));
  EXPECT_THAT(ErrorOf(R"({"truth": {"blocked_fraction": 1}})"),
              HasSubstr("/truth/blocked_fraction: expected true or false"));
  EXPECT_THAT(ErrorOf(R"({"occluders": []})"), HasSubstr("/occluders: expected an object, got []"));
  EXPECT_THAT(ErrorOf("[1, 2]"), HasSubstr("scene.json: expected an object, got [1,2]"));
  // Syntax errors name the file and the key path where the parser stopped.
  EXPECT_THAT(ErrorOf("{\"seed\": 1,"), HasSubstr("scene.json: /seed: not valid JSON"));
  EXPECT_THAT(ErrorOf(R"({"sampling": {"grid": 1e999}})"),
              HasSubstr("scene.json: /sampling/grid: not valid JSON (number overflow"));
}

TEST(Scene, OutOfRangeValuesAreErrors) {
  EXPECT_THAT(ErrorOf(R"({"occluders": {"voxels": {"density": 1.0}}})"),
              HasSubstr("/occluders/voxels/density: 1 is outside [0, 1)"));
  EXPECT_THAT(ErrorOf(R"({"occluders": {"voxels": {"density": -0.1}}})"),
              HasSubstr("/occluders/voxels/density: -0.1 is outside [0, 1)"));
  EXPECT_THAT(ErrorOf(R"({"occluders": {"voxels": {"size": [10, -1, 10]}}})"),
              HasSubstr("/occluders/voxels/size/1: -1 must be > 0"));
  EXPECT_THAT(ErrorOf(R"({"occluders": {"voxels": {"grid": 513}}})"),
              HasSubstr("/occluders/voxels/grid/0: 513 is outside 1..512"));
  EXPECT_THAT(ErrorOf(R"({"targets": [{"size": [0, 1]}]})"), HasSubstr("/targets/0/size/0"));
  EXPECT_THAT(ErrorOf(R"({"occluders": {"trees": {"leaf_size": -0.3}}})"),
              HasSubstr("/occluders/trees/leaf_size"));
  EXPECT_THAT(ErrorOf(R"({"occluders": {"trees": {"height": [9, 5]}}})"),
              HasSubstr("/occluders/trees/height: the upper end is below the lower end"));
  EXPECT_THAT(ErrorOf(R"({"camera": {"fov_deg": 180}})"), HasSubstr("/camera/fov_deg"));
  EXPECT_THAT(ErrorOf(R"({"camera": {"channels": 2}})"), HasSubstr("/camera/channels: must be 1 or 3"));
  EXPECT_THAT(ErrorOf(R"({"sampling": {"aperture": {"shape": "hexagon"}}})"),
              HasSubstr("/sampling/aperture/shape"));
  EXPECT_THAT(ErrorOf(R"({"ground": {"texture": {"type": "marble"}}})"),
              HasSubstr("/ground/texture/type: \"marble\" is not one of"));
  EXPECT_THAT(ErrorOf(R"({"ground": {"texture": {"colors": [0.5, 1.5]}}})"),
              HasSubstr("/ground/texture/colors/1: 1.5 is outside [0, 1]"));
  EXPECT_THAT(ErrorOf(R"({"ground": {"texture": {"type": "constant", "color": 1.5}}})"),
              HasSubstr("/ground/texture/color: 1.5 is outside [0, 1]"));
  EXPECT_THAT(ErrorOf(R"({"ground": {"texture": {"type": "noise", "seed": -1}}})"),
              HasSubstr("/ground/texture/seed: must be >= 0"));
  EXPECT_THAT(ErrorOf(R"({"effects": {"sun": {"elevation_deg": 0}}})"),
              HasSubstr("/effects/sun/elevation_deg"));
  EXPECT_THAT(ErrorOf(R"({"effects": {"thermal": {}}, "camera": {"channels": 3}})"),
              HasSubstr("/camera/channels: must be 1 in thermal mode"));
}

TEST(Scene, CamerasBelowTheGroundOrInsideOccludersAreErrors) {
  EXPECT_THAT(ErrorOf(R"({"ground": {"height": 25}})"),
              HasSubstr("is not above the ground (z = 25 m there)"));
  EXPECT_THAT(ErrorOf(R"({"sampling": {"positions": [[0, 0, 30], [0, 0, -1]]}})"),
              HasSubstr("/sampling/positions/1: camera at z = -1 m is not above the ground"));
  // A slope lifts the ground under the outer views.
  EXPECT_THAT(ErrorOf(R"({"ground": {"slope": [1.5, 0]}})"), HasSubstr("not above the ground"));
  EXPECT_THAT(ErrorOf(R"({"occluders": {"voxels": {"center": [0, 0, 18], "size": [40, 40, 10]}}})"),
              HasSubstr("camera is inside the voxel occluder volume"));
  EXPECT_THAT(ErrorOf(R"({"occluders": {"trees": {"height": [15, 25]}}})"),
              HasSubstr("camera is not above the trees"));
  EXPECT_THAT(ErrorOf(R"({"truth": {"position": [0, 0, -2]}})"),
              HasSubstr("/truth/position: camera at z = -2 m is not above the ground"));
}

TEST(Scene, LensCamerasParseCheckAndRoundTrip) {
  const Scene scene = ParseScene(
      R"({"camera": {"lens": "omnidir", "fov_deg": 200, "xi": 1.2, "distortion": [-0.05, 0.01]}})",
      "scene.json");
  EXPECT_EQ(scene.camera.lens, "omnidir");
  EXPECT_EQ(scene.camera.distortion, (std::array<double, 5>{-0.05, 0.01, 0, 0, 0}));
  const Scene again = ParseScene(SceneToJson(scene), "again.json");
  EXPECT_EQ(again.camera.lens, "omnidir");
  EXPECT_EQ(again.camera.distortion, scene.camera.distortion);
  EXPECT_EQ(again.camera.xi, 1.2);
  EXPECT_EQ(again.camera.fov_deg, 200.0);
  // The focal length puts the ray at half the field of view on the image's side edges.
  const LensCamera lens = ViewLens(scene);
  const double half = 100.0 * M_PI / 180.0;
  Vec2d pixel;
  ASSERT_TRUE(lens.Project(Vec3d(std::sin(half), 0.0, std::cos(half)), &pixel));
  EXPECT_NEAR(pixel.x, scene.camera.width, 1e-9);
  EXPECT_NEAR(pixel.y, 0.5 * scene.camera.height, 1e-9);
  // The same for the other models (radial part: tangential terms are not in the definition).
  for (const char* json : {R"({"camera": {"lens": "fisheye", "fov_deg": 190, "distortion": [0.02, -0.003]}})",
                           R"({"camera": {"lens": "radtan", "fov_deg": 100, "distortion": [-0.1, 0.01, 0, 0, 0.001]}})",
                           R"({"camera": {"fov_deg": 70}})"}) {
    const LensCamera other = ViewLens(ParseScene(json, "scene.json"));
    const double h = 0.5 * ParseScene(json, "scene.json").camera.fov_deg * M_PI / 180.0;
    ASSERT_TRUE(other.Project(Vec3d(std::sin(h), 0.0, std::cos(h)), &pixel)) << json;
    EXPECT_NEAR(pixel.x, other.width, 1e-9) << json;
  }
  // A pinhole scene writes no lens fields and still round-trips.
  const Scene plain = ParseScene("{}", "plain.json");
  EXPECT_EQ(SceneToJson(plain).find("distortion"), std::string::npos);
}

TEST(Scene, LensCamerasThatCannotBeInvertedOverTheFieldAreErrors) {
  EXPECT_THAT(ErrorOf(R"({"camera": {"lens": "fisheye2"}})"),
              HasSubstr("/camera/lens: \"fisheye2\" is not a lens model"));
  EXPECT_THAT(ErrorOf(R"({"camera": {"distortion": [0.1]}})"),
              HasSubstr("/camera/distortion/0: a pinhole lens has no distortion"));
  EXPECT_THAT(ErrorOf(R"({"camera": {"lens": "fisheye", "xi": 2}})"),
              HasSubstr("/camera/xi: only the omnidir lens has xi"));
  EXPECT_THAT(ErrorOf(R"({"camera": {"lens": "fisheye", "distortion": [0, 0, 0, 0, 0.1]}})"),
              HasSubstr("/camera/distortion/4: the fisheye model has k1..k4 only"));
  EXPECT_THAT(ErrorOf(R"({"camera": {"lens": "radtan", "fov_deg": 190}})"),
              HasSubstr("/camera/fov_deg: 190 is outside [0, 180)"));
  EXPECT_THAT(ErrorOf(R"({"camera": {"distortion": []}})"),
              HasSubstr("/camera/distortion: must be an array of 1 to 5 numbers"));
  // A radtan lens whose distortion folds inside the frame is not invertible.
  EXPECT_THAT(ErrorOf(R"({"camera": {"lens": "radtan", "fov_deg": 120, "distortion": [-0.2]}})"),
              HasSubstr("/camera: distortion: folds the image"));
  // A fisheye whose distortion stops increasing before half the field of view.
  EXPECT_THAT(ErrorOf(R"({"camera": {"lens": "fisheye", "fov_deg": 300, "distortion": [-0.05]}})"),
              HasSubstr("camera.fov_deg: half the field of view (150 degrees) is beyond the "
                        "lens's valid field"));
  // Mei's model images rays up to cos(theta) + xi > 0 only.
  EXPECT_THAT(ErrorOf(R"({"camera": {"lens": "omnidir", "fov_deg": 200, "xi": 0.1}})"),
              HasSubstr("camera.fov_deg: 200 degrees is beyond what an omnidir lens with xi = 0.1 "
                        "images"));
  EXPECT_THAT(ErrorOf(R"({"camera": {"lens": "omnidir", "xi": -1}})"),
              HasSubstr("/camera/xi: -1 is outside [0, 1000]"));
  // The lens is set on the camera, not as an effect.
  EXPECT_THAT(ErrorOf(R"({"effects": {"lens_distortion": {"k1": 0.1}}})"),
              HasSubstr("/effects/lens_distortion: is not an effect"));
}

class SceneFiles : public testing_util::TempFolderTest {};

TEST_F(SceneFiles, ImageTexturesAreLoadedAndMissingFilesNamed) {
  Image image(4, 2, 3, PixelType::kU8);
  WriteImage(Path("tex.png"), image);
  const Scene scene = ParseScene(
      R"({"ground": {"texture": {"type": "image", "path": "tex.png", "size": [4, 2]}}})",
      "scene.json", dir_.string());
  ASSERT_TRUE(scene.ground.texture.image);
  EXPECT_EQ(scene.ground.texture.image->width(), 4);
  const std::string error = [&] {
    try {
      ParseScene(R"({"ground": {"texture": {"type": "image", "path": "missing.png"}}})",
                 "scene.json", dir_.string());
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string();
  }();
  EXPECT_THAT(error, HasSubstr("scene.json: /ground/texture/path:"));
  EXPECT_THAT(error, HasSubstr("missing.png"));
}

TEST(Scene, JsonRoundTripIsExact) {
  const std::string json = R"({
    "seed": 7,
    "ground": {"height": 1.5, "slope": [0.05, -0.02],
               "steps": [{"point": [2, 0], "direction": [1, 0.5], "height": 0.4}],
               "texture": {"type": "noise", "square": 0.3, "colors": [0.2, [0.9, 0.8, 0.7]], "seed": 3}},
    "targets": [{"center": [1, 2], "size": [2.4, 0.8], "rotation_deg": 30}],
    "occluders": {"voxels": {"grid": [64, 32, 16], "density": 0.3},
                  "trees": {"per_hectare": 150, "leaves_per_tree": 20}},
    "camera": {"width": 64, "height": 48, "fov_deg": 70, "channels": 3, "bit_depth": 16},
    "sampling": {"altitude": 35, "aperture": {"shape": "disk", "diameter": 20}, "grid": 5},
    "effects": {"pose_noise": {"position_sigma_cm": 5, "rotation_sigma_deg": 0.2},
                "sensor_noise": {"sigma": 0.01}, "sun": {"azimuth_deg": 10}},
    "truth": {"position": [1, 1, 30], "fov_deg": 40, "width": 32, "height": 32,
              "blocked_fraction": false}
  })";
  const Scene scene = ParseScene(json, "a.json");
  const std::string once = SceneToJson(scene);
  const Scene again = ParseScene(once, "b.json");
  EXPECT_EQ(SceneToJson(again), once);
  EXPECT_EQ(again.ground.steps.size(), 1u);
  EXPECT_TRUE(again.has_voxels && again.has_trees);
  EXPECT_EQ(again.voxels.grid[1], 32);
  EXPECT_TRUE(again.effects.pose_noise && again.effects.sensor_noise && again.effects.sun);
  EXPECT_FALSE(again.effects.thermal);
  EXPECT_EQ(SceneToJson(ParseScene(SceneToJson(DefaultScene()), "d.json")), SceneToJson(DefaultScene()));
}

TEST(Scene, ViewGridCoversTheApertureRowsFromNorthToSouth) {
  Scene scene;
  scene.sampling.grid = 3;
  scene.sampling.aperture_diameter = 30.0;
  scene.sampling.center = {100.0, -50.0};
  const std::vector<Vec3d> square = ViewPositions(scene);
  ASSERT_EQ(square.size(), 9u);
  EXPECT_EQ(square[0], Vec3d(85.0, -35.0, 20.0));  // first row is the +y row
  EXPECT_EQ(square[4], Vec3d(100.0, -50.0, 20.0));
  EXPECT_EQ(square[8], Vec3d(115.0, -65.0, 20.0));
  scene.sampling.aperture_shape = "disk";
  EXPECT_EQ(ViewPositions(scene).size(), 5u);  // the corners lie 21.2 m out, beyond the 15 m disk
  scene.sampling.grid = 1;
  EXPECT_EQ(ViewPositions(scene), std::vector<Vec3d>{Vec3d(100.0, -50.0, 20.0)});
}

TEST_F(SceneFiles, LoadSceneNamesTheFile) {
  const std::string path = Path("bad.json");
  std::ofstream(path) << R"({"camera": {"widht": 10}})";
  try {
    LoadScene(path);
    FAIL() << "no error";
  } catch (const std::invalid_argument& error) {
    EXPECT_THAT(error.what(), HasSubstr(path + ": /camera/widht: unknown key"));
  }
  EXPECT_THROW(LoadScene(Path("missing.json")), std::invalid_argument);
}

}  // namespace
}  // namespace aos
