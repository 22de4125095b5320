#include <gtest/gtest.h>

#include "aos/sim/default_scene.h"

namespace aos {
namespace {

TEST(DefaultScene, IsDeterministicAndSeeded) {
  DefaultSceneOptions options;
  options.views_per_side = 2;
  options.width = options.height = 48;
  const LightField a = MakeDefaultLightField(options);
  const LightField b = MakeDefaultLightField(options);
  options.seed = 2;
  const LightField c = MakeDefaultLightField(options);
  ASSERT_EQ(a.views.size(), 4u);
  int differ_from_other_seed = 0;
  for (size_t i = 0; i < a.views.size(); ++i) {
    for (int y = 0; y < 48; ++y) {
      for (int x = 0; x < 48; ++x) {
        ASSERT_EQ(a.views[i].image.Value(x, y), b.views[i].image.Value(x, y));
        differ_from_other_seed += a.views[i].image.Value(x, y) != c.views[i].image.Value(x, y);
      }
    }
  }
  EXPECT_GT(differ_from_other_seed, 100);
}

TEST(DefaultScene, OccluderDensityIsTheBlockedFractionOfNadirRays) {
  // Straight down through the leaf layers: the fraction of leaf pixels in a nadir view with a
  // narrow field of view estimates the density (independent layers, 1 - (1 - p)^n).
  DefaultSceneOptions options;
  options.occluder_density = 0.5;
  options.leaf_size = 0.1;
  const SyntheticScene scene = MakeDefaultScene(options);
  const PinholeCamera camera = PinholeCamera::FromFov(200, 200, 20.0);
  const Image view = RenderSyntheticView(scene, camera, NadirCamFromWorld(Vec3d(0, 0, 35)),
                                         PixelType::kU8);
  int leaves = 0;
  for (int y = 0; y < 200; ++y) {
    for (int x = 0; x < 200; ++x) leaves += view.Value(x, y) <= 80.0;  // leaves are 40..80
  }
  // Ground values are >= 92 (checkerboard 100/130 with a +-8 ripple), so the split is clean.
  // Binomial over ~40,000 px of 10 cm cells seen at ~3-5 px each: a few per cent is plenty.
  EXPECT_NEAR(leaves / 40000.0, 0.5, 0.05);
}

TEST(DefaultScene, RejectsBadOptions) {
  DefaultSceneOptions options;
  options.occluder_density = 1.0;
  EXPECT_THROW(options.Check(), std::invalid_argument);
  options = DefaultSceneOptions{};
  options.occluder_heights = {40.0};  // above the cameras
  EXPECT_THROW(options.Check(), std::invalid_argument);
}

}  // namespace
}  // namespace aos
