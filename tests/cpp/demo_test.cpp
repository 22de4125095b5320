// The demo (demo/demo.h): the default scene hides its target in one view and shows it in the
// integral; the folder written holds an index.html whose links all resolve; nothing is
// overwritten; the default scene is scenes/forest_person.json.
#include "aos/demo/demo.h"

#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "aos/util/file_util.h"
#include "temp_folder.h"

namespace aos {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

// The default scene with fewer, smaller views and a smaller truth image, so one run takes a few
// seconds; the trees, the target and the aperture stay as they are, so the occlusion the views
// see is the default scene's.
Scene SmallDefaultScene() {
  Scene scene = DefaultScene();
  scene.sampling.grid = 7;
  scene.camera.width = 192;
  scene.camera.height = 192;
  scene.truth.width = 160;
  scene.truth.height = 160;
  scene.Check();
  return scene;
}

DemoOptions SmallOptions() {
  DemoOptions options;
  options.all_in_focus_slices = 6;
  return options;
}

const DemoResult& SmallDemo() {
  static const DemoResult result = RunDemo(SmallDefaultScene(), SmallOptions());
  return result;
}

TEST(Demo, TheTargetIsHiddenInOneViewAndVisibleInTheIntegral) {
  const DemoResult& result = SmallDemo();
  // The target is 0.6 x 1.8 m; the 160-pixel truth camera covers 2 x 30 m x tan(10 deg) = 10.6 m,
  // 6.6 cm a pixel, so the target covers about 0.6 x 1.8 / 0.066^2 = 250 pixels.
  ASSERT_TRUE(result.truth_visibility.has_target);
  EXPECT_NEAR(result.truth_visibility.target_pixels, 250, 40);
  // In the truth the flat red target stands out entirely.
  EXPECT_GT(result.truth_visibility.standout_fraction, 0.95);
  // The trees block about two thirds of the rays to the target (the scene is made so: 50-70 %).
  EXPECT_GT(result.target_blocked_fraction, 0.5);
  EXPECT_LT(result.target_blocked_fraction, 0.8);
  const TargetVisibility& single = result.Render("single_view").visibility;
  const TargetVisibility& integral = result.Render("integral_ground").visibility;
  ASSERT_TRUE(single.has_target && integral.has_target);
  // One view sees the target only through the gaps of the crown above it: at most what is
  // unblocked from straight above, which is less than the mean over the views' rays (oblique
  // rays through a crown's edge pass more often); a third is a loose bound on the 1 - 0.66
  // average, and the sharp leaves keep the contrast-to-noise ratio below 1.
  EXPECT_LT(single.standout_fraction, 0.33);
  EXPECT_LT(single.contrast_to_noise, 1.0);
  // The integral mixes each target pixel with the same veil of blurred leaves as its
  // surroundings: the target keeps a third of its contrast but loses the leaves' noise, so
  // nearly every pixel stands out, and the contrast-to-noise ratio is several times the view's.
  EXPECT_GT(integral.standout_fraction, 0.8);
  EXPECT_GT(integral.contrast_to_noise, 3.0);
  EXPECT_GT(integral.contrast_to_noise, 4 * single.contrast_to_noise);
  // Focused inside the canopy the ground blurs and the target disappears again.
  EXPECT_LT(result.Render("integral_occluders").visibility.standout_fraction, 0.33);
  // The integral is closer to the truth than the single view.
  EXPECT_GT(result.Render("integral_ground").quality.ssim, result.Render("single_view").quality.ssim);
  EXPECT_GT(result.Render("integral_ground").quality.psnr_db,
            result.Render("single_view").quality.psnr_db);
  EXPECT_EQ(result.renders.size(), 4u);
  EXPECT_EQ(result.Render("all_in_focus").image.width(), 160);
  EXPECT_THROW(result.Render("nothing"), std::invalid_argument);
}

std::string ReadAll(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

class DemoFolder : public testing_util::TempFolderTest {};

TEST_F(DemoFolder, IndexLinksOnlyToFilesInTheFolderAndShowsTheFigures) {
  const DemoResult& result = SmallDemo();
  const std::string folder = Path("demo");
  const std::vector<std::string> files = WriteDemo(result, folder);
  const std::set<std::string> written(files.begin(), files.end());
  for (const char* name : {"index.html", "demo.json", "single_view.png", "integral_ground.png",
                           "integral_occluders.png", "all_in_focus.png", "lightfield.json",
                           "scene.json", "truth/ground.png", "truth/truth.json"}) {
    EXPECT_EQ(written.count(name), 1u) << name;
    EXPECT_TRUE(fs::is_regular_file(fs::path(folder) / name)) << name;
  }
  const std::string html = ReadAll(fs::path(folder) / "index.html");
  // Every href and src is a relative path to a file that exists in the folder (no external
  // assets, nothing outside).
  const std::regex link("(href|src)=\"([^\"]*)\"");
  int links = 0;
  std::set<std::string> images;
  for (auto it = std::sregex_iterator(html.begin(), html.end(), link); it != std::sregex_iterator();
       ++it) {
    const std::string target = (*it)[2];
    EXPECT_EQ(target.find(':'), std::string::npos) << target;  // no scheme (http:, file:, data:)
    EXPECT_NE(target.rfind("..", 0), 0u) << target;
    EXPECT_NE(target.rfind("/", 0), 0u) << target;
    EXPECT_EQ(written.count(target), 1u) << target;
    if ((*it)[1] == "src") images.insert(target);
    ++links;
  }
  EXPECT_GT(links, 10);
  EXPECT_EQ(images, (std::set<std::string>{"single_view.png", "integral_ground.png",
                                           "integral_occluders.png", "all_in_focus.png",
                                           "truth/ground.png"}));
  EXPECT_EQ(html.find("<script"), std::string::npos);
  // The figures: each render's PSNR and its standout share as printed in the table.
  char psnr[32];
  std::snprintf(psnr, sizeof(psnr), "%.2f", result.Render("integral_ground").quality.psnr_db);
  EXPECT_THAT(html, HasSubstr(psnr));
  char standout[32];
  std::snprintf(standout, sizeof(standout), "%.0f %%",
                100 * result.Render("integral_ground").visibility.standout_fraction);
  EXPECT_THAT(html, HasSubstr(standout));
  EXPECT_THAT(html, HasSubstr("aos-render demo"));
  EXPECT_THAT(ReadAll(fs::path(folder) / "demo.json"), HasSubstr("\"standout_fraction\""));

  // Nothing is overwritten: a second write into the same folder is refused, and so is the
  // check before the work.
  try {
    WriteDemo(result, folder);
    FAIL() << "a second WriteDemo into a non-empty folder was accepted";
  } catch (const std::invalid_argument& error) {
    EXPECT_THAT(error.what(), HasSubstr("not an empty folder"));
  }
  EXPECT_THROW(CheckDemoFolder(folder), std::invalid_argument);
  // No temporary folder is left beside it.
  int entries = 0;
  for (const auto& entry : fs::directory_iterator(dir_)) entries += entry.exists() ? 1 : 0;
  EXPECT_EQ(entries, 1);
}

TEST(Demo, OptionsAreChecked) {
  DemoOptions options;
  options.all_in_focus_slices = -1;
  try {
    options.Check();
    FAIL();
  } catch (const std::invalid_argument& error) {
    EXPECT_THAT(error.what(), HasSubstr("all_in_focus_slices"));
  }
  options = {};
  options.target_margin_m = 0.0;
  EXPECT_THROW(options.Check(), std::invalid_argument);
  options = {};
  options.num_threads = 0;
  EXPECT_THROW(options.Check(), std::invalid_argument);
}

TEST(Demo, DefaultSceneIsTheForestPersonFile) {
  const Scene file = LoadScene(std::string(AOS_SOURCE_DIR) + "/scenes/forest_person.json");
  EXPECT_EQ(SceneToJson(file), SceneToJson(DefaultScene()));
  EXPECT_TRUE(DefaultScene().has_trees);
  EXPECT_EQ(DefaultScene().camera.channels, 3);
}

}  // namespace
}  // namespace aos
