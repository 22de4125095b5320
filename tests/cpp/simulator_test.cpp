// The occlusion simulator: analytic truth, the voxel density definition, only-requested effects
// (stage counters), determinism, blocked fractions, hard cases, and memory bounds.
#include "aos/sim/simulator.h"

#include <cmath>
#include <filesystem>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "aos/sim/occluders.h"
#include "aos/util/error.h"
#include "temp_folder.h"

namespace aos {
namespace {

using ::testing::HasSubstr;

// A small, fast scene: 24 x 20 grey 8-bit views, 3 x 3 grid, no occluders, no effects.
Scene SmallScene() {
  Scene scene;
  scene.camera.width = 24;
  scene.camera.height = 20;
  scene.camera.fov_deg = 60.0;
  scene.sampling.grid = 3;
  scene.sampling.aperture_diameter = 10.0;
  scene.truth.width = 16;
  scene.truth.height = 16;
  return scene;
}

Scene WithVoxels(Scene scene, double density = 0.5) {
  scene.has_voxels = true;
  scene.voxels.center = {0.0, 0.0, 8.0};
  scene.voxels.size = {20.0, 20.0, 8.0};
  scene.voxels.grid = {40, 40, 16};
  scene.voxels.density = density;
  return scene;
}

bool SameBytes(const Image& a, const Image& b) {
  if (a.width() != b.width() || a.height() != b.height() || a.channels() != b.channels() ||
      a.type() != b.type()) {
    return false;
  }
  for (int y = 0; y < a.height(); ++y) {
    for (int x = 0; x < a.width(); ++x) {
      for (int c = 0; c < a.channels(); ++c) {
        if (a.Value(x, y, c) != b.Value(x, y, c)) return false;
      }
    }
  }
  return true;
}

TEST(Simulator, NadirViewOfACheckerGroundMatchesTheAnalyticPattern) {
  // One view at 20 m, no occluders: pixel (x, y) sees the ground point of its centre ray, so
  // its value is the checker colour there, 0.9 or 0.1, stored as round(255 v): within half a
  // code (229.5 sits on a rounding boundary, so which way it goes is not asserted).
  Scene scene = SmallScene();
  scene.sampling.grid = 1;
  scene.ground.texture.kind = TextureSpec::Kind::kChecker;
  scene.ground.texture.square = 0.7;
  scene.truth.width = 24;  // the view's own camera, so the view sees every truth pixel
  scene.truth.height = 20;
  const SimulationResult result = Simulate(scene);
  ASSERT_EQ(result.light_field.views.size(), 1u);
  const View& view = result.light_field.views[0];
  const PinholeCamera camera = view.camera.Pinhole();
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      // Nadir camera at (0, 0, 20), image top towards +y: x_world = 20 (u - cx) / fx,
      // y_world = -20 (v - cy) / fy.
      const double gx = 20.0 * (x + 0.5 - camera.cx) / camera.fx;
      const double gy = -20.0 * (y + 0.5 - camera.cy) / camera.fy;
      const int64_t parity = static_cast<int64_t>(std::floor(gx / 0.7)) +
                             static_cast<int64_t>(std::floor(gy / 0.7));
      const double expected = (parity & 1) == 0 ? 0.9 : 0.1;
      ASSERT_NEAR(view.image.Value(x, y), expected * 255.0, 0.5 + 1e-9) << x << "," << y;
    }
  }
  // Truth of a horizontal ground: depth = altitude everywhere, height 0, every pixel seen.
  const GroundTruth& truth = result.truth;
  for (int y = 0; y < truth.depth.height(); ++y) {
    for (int x = 0; x < truth.depth.width(); ++x) {
      EXPECT_NEAR(truth.depth.Value(x, y), 20.0, 2e-5);  // float32 at 20 m: 2e-6 relative
      EXPECT_EQ(truth.height.Value(x, y), 0.0);
      EXPECT_EQ(truth.views_seeing.Value(x, y), 1.0);
      EXPECT_EQ(truth.blocked_fraction.Value(x, y), 0.0);
    }
  }
  EXPECT_EQ(result.stats.blocked_fraction_rays, 0);  // nothing can block: no rays traced
}

// Pixels of lens views see, through the lens model, the checker colour where their centre ray
// meets the ground (within half a code), 0 where the ray points above the horizon or where the
// lens has no ray (outside a fisheye's image circle). Pixels whose ground point lies within
// 1e-6 of the distance of a checker edge are skipped (float32 ray directions).
void ExpectLensViewOfACheckerGround(const SimulationResult& result, int* ground, int* sky,
                                    int* masked) {
  const View& view = result.light_field.views[0];
  const LensCamera& lens = view.camera;
  for (int y = 0; y < lens.height; ++y) {
    for (int x = 0; x < lens.width; ++x) {
      Vec3d ray;
      const double value = view.image.Value(x, y);
      if (!lens.Unproject(Vec2d(x + 0.5, y + 0.5), &ray)) {
        ++*masked;
        ASSERT_EQ(value, 0.0) << x << "," << y;
        continue;
      }
      if (ray.z < 1e-3) {
        if (ray.z < -1e-3) {
          ++*sky;
          ASSERT_EQ(value, 0.0) << x << "," << y;
        }
        continue;
      }
      const double t = 20.0 / ray.z;
      const double gx = t * ray.x, gy = -t * ray.y;
      const double fx = gx / 0.7 - std::floor(gx / 0.7), fy = gy / 0.7 - std::floor(gy / 0.7);
      const double margin = 1e-6 * t / 0.7;
      if (std::min({fx, 1.0 - fx, fy, 1.0 - fy}) < margin) continue;
      const int64_t parity = static_cast<int64_t>(std::floor(gx / 0.7)) +
                             static_cast<int64_t>(std::floor(gy / 0.7));
      ++*ground;
      ASSERT_NEAR(value, ((parity & 1) == 0 ? 0.9 : 0.1) * 255.0, 0.5 + 1e-9) << x << "," << y;
    }
  }
}

TEST(Simulator, LensViewsTraceEachPixelThroughTheLensModel) {
  for (const char* model : {"fisheye", "omnidir", "radtan"}) {
    SCOPED_TRACE(model);
    Scene scene = SmallScene();
    scene.camera.width = 64;
    scene.camera.height = 48;
    scene.camera.lens = model;
    if (scene.camera.lens == "fisheye") {
      // 200 degrees; the distortion stops increasing at 148 degrees, inside the corners.
      scene.camera.fov_deg = 200.0;
      scene.camera.distortion = {-0.05, 0, 0, 0, 0};
    } else if (scene.camera.lens == "omnidir") {
      scene.camera.fov_deg = 200.0;
      scene.camera.xi = 1.2;
      scene.camera.distortion = {-0.02, 0.001, 0.001, -0.001, 0};
    } else {
      scene.camera.fov_deg = 90.0;
      scene.camera.distortion = {-0.1, 0.01, 0.001, 0.002, 0};
    }
    scene.sampling.grid = 1;
    scene.truth.fov_deg = 60.0;
    scene.ground.texture.kind = TextureSpec::Kind::kChecker;
    scene.ground.texture.square = 0.7;
    const SimulationResult result = Simulate(scene);
    const View& view = result.light_field.views[0];
    EXPECT_EQ(LensModelName(view.camera.model), scene.camera.lens);
    int ground = 0, sky = 0, masked = 0;
    ExpectLensViewOfACheckerGround(result, &ground, &sky, &masked);
    EXPECT_GT(ground, 64 * 48 / 3);
    if (scene.camera.lens == "fisheye") {
      EXPECT_GT(sky, 0);
      EXPECT_GT(masked, 0);
    }
    if (scene.camera.lens == "omnidir") EXPECT_GT(sky, 0);
    // The lens stage ran: every traced ray came through the lens; masked pixels traced none.
    EXPECT_EQ(result.stats.lens_rays, result.stats.primary_rays);
    EXPECT_EQ(result.stats.primary_rays, 64 * 48 - masked);
    // The truth camera (60 degrees) sees ground that the lens view sees.
    for (int y = 0; y < result.truth.views_seeing.height(); ++y) {
      for (int x = 0; x < result.truth.views_seeing.width(); ++x) {
        ASSERT_EQ(result.truth.views_seeing.Value(x, y), 1.0) << x << "," << y;
      }
    }
  }
}

TEST(Simulator, ViewsSeeingCountsTheLensFieldNotItsPinholeApproximation) {
  // A barrel-distorted radtan view covers more ground than a pinhole with its focal length; a
  // truth camera wider than the view sees its frame edge. Each truth pixel's count must follow
  // the lens (lens.Project inside the frame), which differs from the pinhole along that edge.
  Scene scene = SmallScene();
  scene.camera.width = 64;
  scene.camera.height = 48;
  scene.camera.lens = "radtan";
  scene.camera.fov_deg = 70.0;
  scene.camera.distortion = {-0.25, 0.05, 0, 0, 0};
  scene.sampling.grid = 1;
  scene.truth.fov_deg = 110.0;
  scene.truth.width = 64;
  scene.truth.height = 64;
  const SimulationResult result = Simulate(scene);
  const View& view = result.light_field.views[0];
  const GroundTruth& truth = result.truth;
  int differ = 0, seen = 0;
  for (int y = 0; y < 64; ++y) {
    for (int x = 0; x < 64; ++x) {
      // The truth pixel's ground point (flat ground at z = 0, truth at the view's centre).
      const Vec3d d = glm::transpose(truth.cam_from_world.rotation) *
                      Vec3d((x + 0.5 - truth.camera.cx) / truth.camera.fx,
                            (y + 0.5 - truth.camera.cy) / truth.camera.fy, 1.0);
      const Vec3d centre = truth.cam_from_world.Center();
      const Vec3d ground = centre + (-centre.z / d.z) * d;
      const Vec3d in_cam = view.cam_from_world * ground;
      Vec2d lens_pixel;
      const bool in_lens = view.camera.Project(in_cam, &lens_pixel) && lens_pixel.x >= 0 &&
                           lens_pixel.x <= 64 && lens_pixel.y >= 0 && lens_pixel.y <= 48;
      const Vec2d pinhole_pixel = view.camera.Pinhole().Project(in_cam);
      const bool in_pinhole = pinhole_pixel.x >= 0 && pinhole_pixel.x <= 64 &&
                              pinhole_pixel.y >= 0 && pinhole_pixel.y <= 48;
      differ += in_lens != in_pinhole;
      seen += in_lens;
      ASSERT_EQ(truth.views_seeing.Value(x, y), in_lens ? 1.0 : 0.0) << x << "," << y;
    }
  }
  EXPECT_GT(differ, 20);  // the test tells the two apart
  EXPECT_GT(seen, 64 * 64 / 8);
}

TEST(Simulator, VoxelDensityIsTheFractionOfNadirColumnsBlocked) {
  for (double density : {0.1, 0.5, 0.9}) {
    VoxelSpec spec;
    spec.grid = {200, 200, 50};
    spec.density = density;
    const VoxelGrid grid = MakeVoxelGrid(spec, 11);
    // 40,000 independent columns: the binomial standard deviation is at most 0.0025; 5 sigma.
    EXPECT_NEAR(grid.NadirBlockedFraction(), density, 0.0125) << density;
    // Occupied cells per column ~ -ln(1 - d) (Poisson limit of the per-cell probability).
    const double per_column = static_cast<double>(grid.cells.size()) / (200.0 * 200.0);
    EXPECT_NEAR(per_column, -std::log1p(-density), 0.05 * -std::log1p(-density) + 0.01);
  }
  VoxelSpec empty;
  empty.density = 0.0;
  EXPECT_TRUE(MakeVoxelGrid(empty, 1).cells.empty());
}

TEST(Simulator, NadirRaysThroughTheVolumeAreBlockedAtTheStatedDensity) {
  // A narrow view from 1 km straight down through the volume (rays within 0.6 degrees of
  // vertical, so each stays in its column): the fraction of pixels that see a voxel instead of
  // the (white) ground is the density, within binomial noise.
  Scene scene;
  scene.ground.texture.kind = TextureSpec::Kind::kConstant;
  scene.ground.texture.color_a = {1.0, 1.0, 1.0};
  scene = WithVoxels(scene, 0.5);
  scene.voxels.albedo = {0.2, 0.2, 0.2};
  scene.voxels.albedo_variation = 0.0;
  scene.sampling.grid = 1;
  scene.sampling.altitude = 1000.0;
  scene.camera.width = scene.camera.height = 101;
  scene.camera.fov_deg = 2.0 * std::atan(10.0 / 1000.0) * 180.0 / 3.14159265358979;  // 20 m
  scene.truth.blocked_fraction = false;
  const SimulationResult result = Simulate(scene);
  const Image& image = result.light_field.views[0].image;
  int blocked = 0;
  for (int y = 0; y < 101; ++y) {
    for (int x = 0; x < 101; ++x) blocked += image.Value(x, y) < 200 ? 1 : 0;
  }
  // 10,201 rays over the 40 x 40 columns of 0.5 m: ~6 rays per column, so the 1,600 columns
  // (sigma 0.0125) set the noise; 4 sigma.
  EXPECT_NEAR(blocked / 10201.0, 0.5, 0.05);
}

TEST(Simulator, OnlyRequestedStagesRun) {
  const Scene base = SmallScene();
  const SimulationResult plain = Simulate(base);
  const int64_t pixels = 9 * 24 * 20;
  const SimulationStats& s = plain.stats;
  EXPECT_EQ(s.primary_rays, pixels);
  EXPECT_EQ(s.truth_rays, 2 * 16 * 16);  // ground image + centre sample for depth/seeing
  EXPECT_FALSE(s.occluder_bvh);
  EXPECT_FALSE(s.ground_bvh);
  EXPECT_EQ(s.voxels + s.leaf_quads + s.trunk_quads + s.ground_cells, 0);
  EXPECT_EQ(s.shadow_rays, 0);
  EXPECT_EQ(s.sensor_noise_draws, 0);
  EXPECT_EQ(s.pose_noise_draws, 0);
  EXPECT_EQ(s.blocked_fraction_rays, 0);
  EXPECT_EQ(s.lens_rays, 0);
  EXPECT_EQ(s.seconds_geometry, 0.0);
  EXPECT_EQ(s.seconds_blocked_fraction, 0.0);

  // Sun: shadow rays (only for surfaces facing it), nothing else changes in the counters.
  Scene sun = base;
  sun.effects.sun = true;
  const SimulationStats sun_stats = Simulate(sun).stats;
  EXPECT_EQ(sun_stats.shadow_rays, pixels + 16 * 16);
  EXPECT_EQ(sun_stats.primary_rays, s.primary_rays);
  EXPECT_FALSE(sun_stats.occluder_bvh);

  // Sensor noise: one draw per stored value, nothing else.
  Scene noise = base;
  noise.effects.sensor_noise = true;
  noise.effects.sensor_noise_spec.sigma = 0.02;
  const SimulationResult noisy = Simulate(noise);
  EXPECT_EQ(noisy.stats.sensor_noise_draws, pixels);
  EXPECT_EQ(noisy.stats.shadow_rays, 0);
  EXPECT_TRUE(SameBytes(noisy.truth.ground, plain.truth.ground));  // truth untouched

  // Pose noise: six draws per view; images identical, recorded poses moved, true poses kept.
  Scene pose = base;
  pose.effects.pose_noise = true;
  pose.effects.pose_noise_spec.position_sigma_cm = 5.0;
  pose.effects.pose_noise_spec.rotation_sigma_deg = 0.2;
  const SimulationResult posed = Simulate(pose);
  EXPECT_EQ(posed.stats.pose_noise_draws, 6 * 9);
  for (size_t v = 0; v < 9; ++v) {
    EXPECT_TRUE(SameBytes(posed.light_field.views[v].image, plain.light_field.views[v].image));
    EXPECT_EQ(posed.true_cam_from_world[v].translation, plain.true_cam_from_world[v].translation);
    const double moved = glm::length(posed.light_field.views[v].cam_from_world.Center() -
                                     plain.light_field.views[v].cam_from_world.Center());
    EXPECT_GT(moved, 0.0);
    EXPECT_LT(moved, 0.05 * 6);  // 6 sigma of a 3-D Gaussian with 5 cm per axis
  }

  // Occluders: geometry and a BVH, blocked-fraction rays; primary rays unchanged.
  const SimulationResult occluded = Simulate(WithVoxels(base));
  EXPECT_TRUE(occluded.stats.occluder_bvh);
  EXPECT_GT(occluded.stats.voxels, 0);
  EXPECT_FALSE(occluded.stats.ground_bvh);
  EXPECT_EQ(occluded.stats.primary_rays, s.primary_rays);
  EXPECT_GT(occluded.stats.blocked_fraction_rays, 0);
  EXPECT_TRUE(SameBytes(occluded.truth.ground, plain.truth.ground));  // truth has no occluders

  // Steps make the ground a height field (an Embree grid); a tilted plane does not.
  Scene tilted = base;
  tilted.ground.slope = {0.1, 0.0};
  EXPECT_FALSE(Simulate(tilted).stats.ground_bvh);
  Scene stepped = base;
  stepped.ground.steps.push_back(StepSpec{});
  const SimulationStats stepped_stats = Simulate(stepped).stats;
  EXPECT_TRUE(stepped_stats.ground_bvh);
  EXPECT_GT(stepped_stats.ground_cells, 0);
  EXPECT_FALSE(stepped_stats.occluder_bvh);
}

TEST(Simulator, AddingAnEffectChangesOnlyWhatItTouches) {
  const Scene base = WithVoxels(SmallScene());
  const SimulationResult plain = Simulate(base);
  Scene noise = base;
  noise.effects.sensor_noise = true;
  noise.effects.sensor_noise_spec.sigma = 0.02;
  const SimulationResult noisy = Simulate(noise);
  // Same occluders (their random stream is separate), same truth and poses.
  EXPECT_EQ(noisy.stats.voxels, plain.stats.voxels);
  EXPECT_TRUE(SameBytes(noisy.truth.blocked_fraction, plain.truth.blocked_fraction));
  EXPECT_TRUE(SameBytes(noisy.truth.ground, plain.truth.ground));
  // Views differ by the noise only: mean difference ~0, spread ~sigma (5.1 grey levels).
  double sum = 0.0, sum2 = 0.0;
  int64_t n = 0;
  for (size_t v = 0; v < plain.light_field.views.size(); ++v) {
    const Image& a = plain.light_field.views[v].image;
    const Image& b = noisy.light_field.views[v].image;
    for (int y = 0; y < a.height(); ++y) {
      for (int x = 0; x < a.width(); ++x) {
        const double d = b.Value(x, y) - a.Value(x, y);
        if (a.Value(x, y) < 20 || a.Value(x, y) > 235) continue;  // away from clamping
        sum += d;
        sum2 += d * d;
        ++n;
      }
    }
  }
  ASSERT_GT(n, 1000);
  const double mean = sum / n, spread = std::sqrt(sum2 / n - mean * mean);
  EXPECT_NEAR(mean, 0.0, 4.0 * 5.1 / std::sqrt(static_cast<double>(n)) + 0.05);
  EXPECT_NEAR(spread, 0.02 * 255.0, 0.1 * 0.02 * 255.0);  // rounding adds 1/12 in quadrature
}

TEST(Simulator, DeterministicForAnyThreadCountAndSeeded) {
  Scene scene = WithVoxels(SmallScene());
  scene.has_trees = true;
  scene.trees.per_hectare = 2000;
  scene.trees.height = {5.0, 7.0};
  scene.trees.leaves_per_tree = 50;
  scene.effects.sun = true;
  scene.effects.sensor_noise = true;
  scene.effects.sensor_noise_spec.sigma = 0.01;
  SimulateOptions one, two;
  one.num_threads = 1;
  two.num_threads = 2;
  const SimulationResult a = Simulate(scene, one);
  const SimulationResult b = Simulate(scene, two);
  for (size_t v = 0; v < a.light_field.views.size(); ++v) {
    EXPECT_TRUE(SameBytes(a.light_field.views[v].image, b.light_field.views[v].image)) << v;
  }
  EXPECT_TRUE(SameBytes(a.truth.blocked_fraction, b.truth.blocked_fraction));
  EXPECT_EQ(a.stats.shadow_rays, b.stats.shadow_rays);
  scene.seed = 2;
  const SimulationResult c = Simulate(scene, two);
  EXPECT_NE(c.stats.voxels, a.stats.voxels);
}

TEST(Simulator, BlockedFractionMatchesSegmentsThroughAnOpaqueBox) {
  // One voxel cell filling a 4 x 4 x 1 m box at z 9.5..10.5 over the origin (density close to 1
  // and a single cell, so it is occupied for this seed). A view blocks the centre ground point
  // exactly when the segment from the point to the view centre crosses the box.
  Scene scene = SmallScene();
  scene.has_voxels = true;
  scene.voxels.center = {0.0, 0.0, 10.0};
  scene.voxels.size = {4.0, 4.0, 1.0};
  scene.voxels.grid = {1, 1, 1};
  scene.voxels.density = 0.999;
  scene.sampling.grid = 5;
  scene.sampling.aperture_diameter = 20.0;
  scene.camera.fov_deg = 100.0;
  scene.truth.width = scene.truth.height = 15;  // odd: the centre pixel looks straight down
  const SimulationResult result = Simulate(scene);
  ASSERT_EQ(result.stats.voxels, 1);
  const std::vector<Vec3d> views = ViewPositions(scene);
  int seeing = 0, blocked = 0;
  for (const Vec3d& c : views) {
    const Vec3d in_cam = NadirCamFromWorld(c) * Vec3d(0, 0, 0);
    const Vec2d uv = result.light_field.views[0].camera.Pinhole().Project(in_cam);
    if (uv.x < 0 || uv.x > 24 || uv.y < 0 || uv.y > 20) continue;
    ++seeing;
    // The segment crosses z = 9.5..10.5 at x, y = c.xy * z / c.z; it is inside the box (|x|,
    // |y| <= 2) at the bottom face or the top face.
    const auto inside = [&](double z) {
      return std::abs(c.x * z / c.z) <= 2.0 && std::abs(c.y * z / c.z) <= 2.0;
    };
    blocked += inside(9.5) || inside(10.5) ? 1 : 0;
  }
  ASSERT_GT(seeing, 1);
  EXPECT_EQ(result.truth.views_seeing.Value(7, 7), seeing);
  EXPECT_FLOAT_EQ(result.truth.blocked_fraction.Value(7, 7), static_cast<float>(blocked) / seeing);
  EXPECT_GT(blocked, 0);
  EXPECT_LT(blocked, seeing);
}

TEST(Simulator, GrazingRaysAndExactVoxelEdgesGiveFiniteValues) {
  // Float views, a 170-degree camera 1 m above a tilted ground: rays near the horizon graze the
  // ground or miss it (value 0). A 5-pixel-wide view whose centre ray runs exactly along a
  // voxel face (camera x on a cell boundary).
  Scene scene = SmallScene();
  scene.camera.bit_depth = 32;
  scene.camera.fov_deg = 170.0;
  scene.sampling.positions = {{0.0, 0.0, 1.0}};
  scene.ground.slope = {0.02, 0.0};
  scene.truth.blocked_fraction = true;
  SimulationResult result = Simulate(scene);
  const Image& grazing = result.light_field.views[0].image;
  for (int y = 0; y < grazing.height(); ++y) {
    for (int x = 0; x < grazing.width(); ++x) {
      ASSERT_TRUE(std::isfinite(grazing.Value(x, y)));
      ASSERT_GE(grazing.Value(x, y), 0.0);
    }
  }
  Scene edge = WithVoxels(SmallScene(), 0.9);
  edge.camera.bit_depth = 32;
  edge.camera.width = edge.camera.height = 5;
  edge.voxels.grid = {20, 20, 8};  // 1 m cells from -10 m: x = 3 is a boundary
  edge.sampling.positions = {{3.0, 2.0, 20.0}, {3.0, 2.0, 25.0}};
  edge.truth.width = edge.truth.height = 5;
  result = Simulate(edge);
  for (const View& view : result.light_field.views) {
    for (int y = 0; y < 5; ++y) {
      for (int x = 0; x < 5; ++x) ASSERT_TRUE(std::isfinite(view.image.Value(x, y)));
    }
  }
  for (int y = 0; y < 5; ++y) {
    for (int x = 0; x < 5; ++x) {
      ASSERT_TRUE(std::isfinite(result.truth.blocked_fraction.Value(x, y)));
      ASSERT_TRUE(std::isfinite(result.truth.depth.Value(x, y)));
    }
  }
}

TEST(Simulator, ZeroAndMaximalVoxelDensitiesAreExact) {
  // The ends of density's range [0, 1). Density 0: a voxel volume with no voxel, so the views
  // are the occluder-free scene's to the byte and no ground point is blocked (exactly 0).
  // The largest double below 1: each of the 16 layers' cells is occupied with probability
  // q = 1 - (1 - density)^(1/16) = 0.9, so a column (or any segment crossing all 16 layers) is
  // clear with probability 1 - density = 1.1e-16. Every column blocks, and so does every segment
  // from the ground under the volume's middle to a view (views at 20 m within 5 m of the axis,
  // the volume from 4 to 12 m and 20 x 20 m wide): blocked fraction exactly 1 there.
  Scene clear = SmallScene();
  clear.truth.blocked_fraction = true;
  const SimulationResult reference = Simulate(clear);
  const SimulationResult empty = Simulate(WithVoxels(clear, 0.0));
  EXPECT_EQ(empty.stats.voxels, 0);
  EXPECT_EQ(empty.stats.nadir_blocked_fraction, 0.0);
  ASSERT_EQ(empty.light_field.views.size(), reference.light_field.views.size());
  for (size_t i = 0; i < reference.light_field.views.size(); ++i) {
    EXPECT_TRUE(SameBytes(empty.light_field.views[i].image, reference.light_field.views[i].image))
        << i;
  }
  const Image& none_blocked = empty.truth.blocked_fraction;
  for (int y = 0; y < none_blocked.height(); ++y) {
    for (int x = 0; x < none_blocked.width(); ++x) {
      ASSERT_EQ(none_blocked.Value(x, y), 0.0) << x << "," << y;
    }
  }

  const SimulationResult full = Simulate(WithVoxels(clear, std::nextafter(1.0, 0.0)));
  EXPECT_EQ(full.stats.nadir_blocked_fraction, 1.0);
  EXPECT_GT(full.stats.voxels, 40 * 40);  // at least one cell per column
  const Image& blocked = full.truth.blocked_fraction;
  const Image& seeing = full.truth.views_seeing;
  int asserted = 0;
  for (int y = 0; y < blocked.height(); ++y) {
    for (int x = 0; x < blocked.width(); ++x) {
      ASSERT_TRUE(std::isfinite(blocked.Value(x, y)));
      ASSERT_GE(blocked.Value(x, y), 0.0);
      ASSERT_LE(blocked.Value(x, y), 1.0);
      // The truth camera's middle 4 x 4 pixels (1.44 m each at 20 m) see the ground within
      // 2.9 m of the axis; their segments to the views stay inside the volume's sides.
      const bool middle = std::abs(x + 0.5 - blocked.width() / 2) < 2 &&
                          std::abs(y + 0.5 - blocked.height() / 2) < 2;
      if (middle && seeing.Value(x, y) > 0) {
        EXPECT_EQ(blocked.Value(x, y), 1.0) << x << "," << y;
        ++asserted;
      }
    }
  }
  EXPECT_EQ(asserted, 16);
  for (const View& view : full.light_field.views) {
    for (int y = 0; y < view.image.height(); ++y) {
      for (int x = 0; x < view.image.width(); ++x) {
        ASSERT_TRUE(std::isfinite(view.image.Value(x, y)));
      }
    }
  }
}

TEST(Simulator, A512CubedGridAt90PercentStaysSmall) {
  // 512^3 cells at 90 %: about -ln(0.1) * 512^2 = 604,000 occupied cells at 4 bytes each
  // (2.4 MB), instead of 134 million cells; generation is O(occupied cells).
  VoxelSpec spec;
  spec.grid = {512, 512, 512};
  spec.density = 0.9;
  const VoxelGrid grid = MakeVoxelGrid(spec, 5);
  EXPECT_NEAR(static_cast<double>(grid.cells.size()), 2.302585 * 512 * 512, 0.01 * 2.3 * 512 * 512);
  EXPECT_LT(grid.cells.capacity() * sizeof(uint32_t), 4u << 20);
  EXPECT_NEAR(grid.NadirBlockedFraction(), 0.9, 0.003);  // 262,144 columns, 5 sigma
}

TEST(Simulator, TreesFollowTheSpec) {
  TreeSpec spec;
  spec.per_hectare = 400;
  spec.leaves_per_tree = 30;
  GroundSpec ground;
  ground.height = 2.0;
  const TreeMesh mesh = MakeTrees(spec, ground, {0, 0, 50, 50}, 3);
  EXPECT_EQ(mesh.trees, 100);  // 400 per hectare on 0.25 ha
  EXPECT_EQ(mesh.leaf_quads, 100 * 30);
  EXPECT_EQ(mesh.trunk_quads, 100 * 6);
  for (const auto& v : mesh.vertices) {
    EXPECT_GE(v[2], 2.0 - 0.5 - 1e-4);  // trunks start 0.5 m below the ground
    EXPECT_LE(v[2], 2.0 + spec.height[1] + spec.leaf_size);
  }
}

TEST(Simulator, CancelsAndChecksOptions) {
  struct Cancel : ProgressSink {
    void Start(const std::string&, int64_t) override {}
    void Advance(int64_t) override {}
    bool Cancelled() override { return true; }
  } cancel;
  EXPECT_THROW(Simulate(SmallScene(), {}, &cancel), Cancelled);
  SimulateOptions bad;
  bad.num_threads = 0;
  EXPECT_THROW(Simulate(SmallScene(), bad), std::invalid_argument);
  Scene scene = SmallScene();
  scene.ground.steps.push_back(StepSpec{});
  scene.ground.cell_size = 0.001;
  try {
    Simulate(scene);
    FAIL() << "no error";
  } catch (const std::invalid_argument& error) {
    EXPECT_THAT(error.what(), HasSubstr("/ground/cell_size"));
  }
}

class SimulatorFiles : public testing_util::TempFolderTest {};

TEST_F(SimulatorFiles, WritesEverythingOrNothingAndNeverOverwrites) {
  const Scene scene = WithVoxels(SmallScene());
  const SimulationResult result = Simulate(scene);
  const std::string out = Path("out");
  WriteSimulation(result, scene, out);
  namespace fs = std::filesystem;
  for (const char* name : {"lightfield.json", "lightfield_true.json", "scene.json", "views/0000.png",
                           "views/0008.png", "truth/ground.png", "truth/depth.tif",
                           "truth/height.tif", "truth/views_seeing.tif",
                           "truth/blocked_fraction.tif", "truth/truth.json"}) {
    EXPECT_TRUE(fs::is_regular_file(fs::path(out) / name)) << name;
  }
  // A non-empty folder is refused and left as it was.
  try {
    WriteSimulation(result, scene, out);
    FAIL() << "no error";
  } catch (const std::invalid_argument& error) {
    EXPECT_THAT(error.what(), HasSubstr("exists and is not empty"));
  }
  // Nothing but the finished folder is left beside it (no temporary folders).
  int entries = 0;
  for (const auto& entry : fs::directory_iterator(dir_)) entries += entry.path() == fs::path(out) ? 0 : 1;
  EXPECT_EQ(entries, 0);
  // A missing parent folder is an error naming the output.
  EXPECT_THROW(WriteSimulation(result, scene, Path("no/such/folder")), std::invalid_argument);
}

}  // namespace
}  // namespace aos
