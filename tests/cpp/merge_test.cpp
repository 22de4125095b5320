// Tests of all-in-focus merging (merge.h) and of integral rendering on a depth map
// (surface_integral.h): analytic focus curves on hand-made stacks, depth recovery on simulated
// ground, the hard cases (one slice, identical planes, constant images, uncovered pixels), and
// agreement between the streaming pipeline and the merge of a stored stack.
#include "aos/render/merge.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "aos/render/surface_integral.h"
#include "aos/sim/simulator.h"
#include "aos/util/error.h"
#include "render_test_util.h"

#include "error_of.h"

namespace aos {
namespace {

using ::testing::AllOf;
using ::testing::HasSubstr;
using test_util::AllFinite;
using test_util::ConstantImage;
using test_util::GridCentres;
using test_util::NadirLightField;
using test_util::SameImage;

constexpr MergeMethod kAllMethods[] = {MergeMethod::kSobel, MergeMethod::kImproved,
                                       MergeMethod::kRobust};

using test_util::ErrorOf;

// Every output of a merge is finite and the shapes are the camera's.
::testing::AssertionResult WellFormed(const MergeResult& result, int width, int height) {
  for (const Image* image : {&result.image, &result.depth, &result.confidence, &result.slice}) {
    if (image->width() != width || image->height() != height || image->type() != PixelType::kF32) {
      return ::testing::AssertionFailure() << "an output is not float32 " << width << "x" << height;
    }
  }
  const std::vector<std::pair<const Image*, const char*>> outputs = {
      {&result.image, "image"}, {&result.depth, "depth"}, {&result.confidence, "confidence"},
      {&result.slice, "slice"}};
  for (const auto& [image, name] : outputs) {
    if (auto failure = AllFinite(*image, name); !failure) return failure;
  }
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const float c = *result.confidence.At<float>(x, y);
      if (!(c >= 0.0f && c <= 1.0f)) {
        return ::testing::AssertionFailure() << "confidence " << c << " at " << x << "," << y;
      }
    }
  }
  return ::testing::AssertionSuccess();
}

::testing::AssertionResult SameMerge(const MergeResult& a, const MergeResult& b) {
  const std::vector<std::tuple<const Image*, const Image*, const char*>> outputs = {
      {&a.image, &b.image, "image"}, {&a.depth, &b.depth, "depth"},
      {&a.confidence, &b.confidence, "confidence"}, {&a.slice, &b.slice, "slice"}};
  for (const auto& [x, y, name] : outputs) {
    if (auto same = SameImage(*x, *y); !same) return same << " (" << name << ")";
  }
  if (a.uncovered_pixels != b.uncovered_pixels || a.fallback_pixels != b.fallback_pixels) {
    return ::testing::AssertionFailure() << "pixel counts differ";
  }
  return ::testing::AssertionSuccess();
}

// ---------------------------------------------------------------------------------------------
// Hand-made stacks: parallel horizontal slices at z = 0, 1, ..., N-1 under a nadir camera at
// kAltitude, so slice k lies at depth kAltitude - k everywhere and fractional slice f at
// kAltitude - f.

constexpr double kAltitude = 10.0;

// images[k] and counts[k] as given; every pixel covered (count 1) when `counts` is empty.
FocalStack HandStack(const std::vector<Image>& images, std::vector<Image> counts = {}) {
  FocalStack stack;
  const int n = static_cast<int>(images.size());
  stack.camera = PinholeCamera::FromFov(images[0].width(), images[0].height(), 40.0);
  stack.cam_from_world = NadirCamFromWorld(Vec3d(0, 0, kAltitude));
  stack.render.cam_from_world = stack.cam_from_world;
  stack.render.width = stack.camera.width;
  stack.render.height = stack.camera.height;
  stack.render.fov_deg = 40.0;
  stack.focus.planes = StackPlanes(Plane::AtHeight(0.0), Plane::AtHeight(std::max(n - 1, 1)), n,
                             stack.cam_from_world.Center());
  if (n == 1) stack.focus.planes = {Plane::AtHeight(0.0)};
  stack.images = images;
  if (counts.empty()) {
    for (int k = 0; k < n; ++k) counts.push_back(ConstantImage(images[0].width(), images[0].height(), {1}, PixelType::kU32));
  }
  stack.counts = counts;
  return stack;
}

// value = offset + slope * x where column x is covered (x >= first_column), 0 elsewhere (as
// RenderIntegral leaves uncovered pixels); the matching count image.
Image Ramp(int w, int h, double slope, double offset = 100.0, int first_column = 0) {
  Image image(w, h, 1, PixelType::kF32);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      *image.At<float>(x, y) = x >= first_column ? static_cast<float>(offset + slope * x) : 0.0f;
    }
  }
  return image;
}

Image Coverage(int w, int h, int first_column) {
  Image count(w, h, 1, PixelType::kU32);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) *count.At<uint32_t>(x, y) = x >= first_column ? 1u : 0u;
  }
  return count;
}

// One thread unless a test compares thread counts: on a loaded 2-core machine OpenMP barriers
// of tiny renders cost milliseconds each.
MergeOptions Options(MergeMethod method) {
  MergeOptions options;
  options.method = method;
  options.num_threads = 1;
  return options;
}

TEST(MergeFocalStack, SobelPicksTheSteepestRampAndItsPlane) {
  // Ramps of slope 1, 3, 2 along x: the 3x3 Sobel gives |g| = 8 s inside (4 s on the clamped
  // left/right columns), so slice 1 wins everywhere; confidence (24 - 16) / 24 = 1/3 (and
  // (12 - 8) / 12 on the edge columns).
  const int w = 16, h = 12;
  const FocalStack stack = HandStack({Ramp(w, h, 1), Ramp(w, h, 3), Ramp(w, h, 2)});
  const MergeResult result = MergeFocalStack(stack, Options(MergeMethod::kSobel));
  ASSERT_TRUE(WellFormed(result, w, h));
  EXPECT_EQ(result.uncovered_pixels, 0);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      ASSERT_EQ(*result.slice.At<float>(x, y), 1.0f) << x << "," << y;
      // Depth of plane z = 1: float rounding of 9 m only.
      ASSERT_NEAR(*result.depth.At<float>(x, y), kAltitude - 1.0, 1e-5) << x << "," << y;
      ASSERT_FLOAT_EQ(*result.confidence.At<float>(x, y), 1.0f / 3.0f) << x << "," << y;
      // sobel's image is the winning slice's pixel, unchanged.
      ASSERT_EQ(*result.image.At<float>(x, y), *stack.images[1].At<float>(x, y));
    }
  }
}

TEST(MergeFocalStack, ImprovedRefinesThePeakWithAParabola) {
  // Energies (8 s)^2 = 64, 576, 256 inside: the parabola through (-1, 64), (0, 576), (1, 256)
  // peaks at 0.5 (64 - 256) / (64 - 2 576 + 256) = 0.1153846 slices after slice 1. Window radius
  // 1 and columns 2..13 keep the clamped edge columns out of the window; smoothing off.
  // Confidence: (576 - 896/3) / 576.
  const int w = 16, h = 12;
  const FocalStack stack = HandStack({Ramp(w, h, 1), Ramp(w, h, 3), Ramp(w, h, 2)});
  MergeOptions options = Options(MergeMethod::kImproved);
  options.window_radius = 1;
  options.smoothing_sigma = 0.0;
  const MergeResult result = MergeFocalStack(stack, options);
  ASSERT_TRUE(WellFormed(result, w, h));
  const double offset = 0.5 * (64.0 - 256.0) / (64.0 - 2.0 * 576.0 + 256.0);
  const double confidence = (576.0 - (64.0 + 576.0 + 256.0) / 3.0) / 576.0;
  for (int y = 0; y < h; ++y) {
    for (int x = 2; x < w - 2; ++x) {
      const float slice = *result.slice.At<float>(x, y);
      // The slice is float32: 1e-6 covers its rounding; depth likewise (float of ~9 m).
      ASSERT_NEAR(slice, 1.0 + offset, 1e-6) << x << "," << y;
      ASSERT_NEAR(*result.depth.At<float>(x, y), kAltitude - (1.0 + offset), 1e-5) << x << "," << y;
      ASSERT_NEAR(*result.confidence.At<float>(x, y), confidence, 1e-6) << x << "," << y;
      // The image blends slices 1 and 2 linearly: 100 + (3 (1 - f) + 2 f) x, f the stored
      // fraction (float rounding of ~150 grey: 1e-4).
      const double f = slice - 1.0;
      ASSERT_NEAR(*result.image.At<float>(x, y), 100.0 + (3.0 * (1.0 - f) + 2.0 * f) * x, 1e-4);
    }
  }
  // A symmetric curve (slopes 1, 3, 1) peaks exactly on the slice.
  const MergeResult symmetric =
      MergeFocalStack(HandStack({Ramp(w, h, 1), Ramp(w, h, 3), Ramp(w, h, 1)}), options);
  EXPECT_EQ(*symmetric.slice.At<float>(8, 6), 1.0f);
  // A peak on the first or the last slice has one neighbour: no refinement, no extrapolation.
  const MergeResult first =
      MergeFocalStack(HandStack({Ramp(w, h, 3), Ramp(w, h, 2), Ramp(w, h, 1)}), options);
  EXPECT_EQ(*first.slice.At<float>(8, 6), 0.0f);
  const MergeResult last =
      MergeFocalStack(HandStack({Ramp(w, h, 1), Ramp(w, h, 2), Ramp(w, h, 3)}), options);
  EXPECT_EQ(*last.slice.At<float>(8, 6), 2.0f);
  EXPECT_NEAR(*last.depth.At<float>(8, 6), kAltitude - 2.0, 1e-5);
}

TEST(MergeFocalStack, UncoveredPixelsHaveNoFocusValue) {
  // Slice 0: a slope-1 ramp covering x >= 4; slice 1: constant 50 covering x >= 8; slice 2:
  // constant 70 covering x >= 2. Uncovered pixels hold 0, as RenderIntegral leaves them.
  // - x < 2: no slice covers: image 0, depth 0, confidence 0, slice -1.
  // - x in [2, 4): only slice 2 (focus 0): slice 2, confidence 0 (one slice), image 70. Taking
  //   an uncovered slice's pixel as focus 0 would tie and pick slice 0.
  // - x >= 4: slice 0's ramp is the only edge. A Sobel tap on an uncovered pixel takes the
  //   centre's value, so slices 1 and 2 stay flat at their coverage borders (x = 8, x = 2);
  //   taps of value 0 there would give them |g| >= 200 and let them win. Confidence counts only
  //   the covering slices: (F - F/2) / F = 1/2 for x < 8, (F - F/3) / F = 2/3 beyond.
  const int w = 16, h = 8;
  Image flat1 = Ramp(w, h, 0.0, 50.0, 8), flat2 = Ramp(w, h, 0.0, 70.0, 2);
  const FocalStack stack = HandStack({Ramp(w, h, 1.0, 100.0, 4), flat1, flat2},
                                     {Coverage(w, h, 4), Coverage(w, h, 8), Coverage(w, h, 2)});
  for (MergeMethod method : {MergeMethod::kSobel, MergeMethod::kImproved}) {
    SCOPED_TRACE(MergeMethodName(method));
    MergeOptions options = Options(method);
    options.window_radius = 1;
    options.smoothing_sigma = 0.0;
    const MergeResult result = MergeFocalStack(stack, options);
    ASSERT_TRUE(WellFormed(result, w, h));
    EXPECT_EQ(result.uncovered_pixels, 2 * h);
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        const float slice = *result.slice.At<float>(x, y);
        const float depth = *result.depth.At<float>(x, y);
        const float confidence = *result.confidence.At<float>(x, y);
        const float value = *result.image.At<float>(x, y);
        if (x < 2) {
          EXPECT_EQ(slice, -1.0f) << x << "," << y;
          EXPECT_EQ(depth, 0.0f) << x << "," << y;
          EXPECT_EQ(confidence, 0.0f) << x << "," << y;
          EXPECT_EQ(value, 0.0f) << x << "," << y;
        } else if (x < 4) {
          EXPECT_EQ(slice, 2.0f) << x << "," << y;
          EXPECT_NEAR(depth, kAltitude - 2.0, 1e-5) << x << "," << y;
          EXPECT_EQ(confidence, 0.0f) << x << "," << y;
          EXPECT_EQ(value, 70.0f) << x << "," << y;
        } else {
          EXPECT_EQ(slice, 0.0f) << x << "," << y;
          EXPECT_NEAR(depth, kAltitude, 1e-5) << x << "," << y;
          EXPECT_FLOAT_EQ(confidence, x < 8 ? 0.5f : 2.0f / 3.0f) << x << "," << y;
          EXPECT_EQ(value, static_cast<float>(100 + x)) << x << "," << y;
        }
      }
    }
  }
}

TEST(MergeFocalStack, TheFocusWindowAveragesOnlyCoveredPixels) {
  // Slice 0: a slope-1 ramp covering x >= 4 (energy 64 inside, 16 at x = 4 where the left tap
  // takes the centre's value); slice 1: a slope-0.75 ramp everywhere (energy 36). With window
  // radius 1, x = 4 averages slice 0 over its covered columns 4 and 5: (16 + 64) / 2 = 40 > 36,
  // so slice 0 wins; counting the uncovered column 3 as 0 would give 80 / 3 < 36 and slice 1.
  const int w = 12, h = 6;
  const FocalStack stack = HandStack({Ramp(w, h, 1.0, 100.0, 4), Ramp(w, h, 0.75)},
                                     {Coverage(w, h, 4), Coverage(w, h, 0)});
  MergeOptions options = Options(MergeMethod::kImproved);
  options.window_radius = 1;
  options.smoothing_sigma = 0.0;
  const MergeResult result = MergeFocalStack(stack, options);
  ASSERT_TRUE(WellFormed(result, w, h));
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      // A peak on slice 0, or on slice 1 with slice 0 uncovered, has no two neighbours: the
      // index stays whole.
      EXPECT_EQ(*result.slice.At<float>(x, y), x < 4 ? 1.0f : 0.0f) << x << "," << y;
    }
  }
}

TEST(MergeFocalStack, SmoothingTakesOnlyConfidentNeighbours) {
  // Left half (x < 8) flat in every slice: no focus, slice 0, confidence 0. Right half ramps of
  // slope 1, 2, 3 from x = 8: a clear peak on the last slice (no refinement), confidence > 0.
  // One smoothing pass (sigma 2: radius 4): right pixels average only confident (right)
  // neighbours, all on slice 2, and stay there; left pixels within reach of the right half
  // take the right half's slice 2; pixels farther left have no confident neighbour and keep 0.
  const int w = 16, h = 8;
  std::vector<Image> images;
  for (double slope : {1.0, 2.0, 3.0}) {
    Image image(w, h, 1, PixelType::kF32);
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) *image.At<float>(x, y) = static_cast<float>(100.0 + slope * std::max(0, x - 8));
    }
    images.push_back(image);
  }
  MergeOptions options = Options(MergeMethod::kImproved);
  options.window_radius = 0;
  options.smoothing_sigma = 2.0;
  options.smoothing_iterations = 1;
  options.edge_sigma = 1.0;
  const MergeResult result = MergeFocalStack(HandStack(images), options);
  ASSERT_TRUE(WellFormed(result, w, h));
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const float slice = *result.slice.At<float>(x, y);
      if (x >= 8) {
        ASSERT_GT(*result.confidence.At<float>(x, y), 0.0f) << x;
        // A weighted mean of equal values: 2 up to float rounding.
        EXPECT_NEAR(slice, 2.0f, 1e-6) << x << "," << y;
      } else if (x >= 8 - 4) {
        EXPECT_EQ(*result.confidence.At<float>(x, y), 0.0f) << x;
        EXPECT_NEAR(slice, 2.0f, 1e-6) << x << "," << y;
      } else {
        EXPECT_EQ(slice, 0.0f) << x << "," << y;
      }
    }
  }
}

TEST(MergeFocalStack, SmoothingStopsAtEdgesOfTheGuide) {
  // Two regions separated by two uncovered columns (x = 7, 8: no false Sobel edges, no slice):
  // left (x <= 6) dark, ramps of slope 3, 2, 1 (peak on slice 0); right (x >= 9) bright, slopes
  // 1, 2, 3 (peak on slice 2). The guide (sharpest slice) differs by > 170 grey across the gap,
  // more than 4 range sigmas (edge_sigma 0.1 x a contrast of ~210): the smoothing, though its
  // radius (4) reaches across, mixes nothing and each side keeps its slice.
  const int w = 16, h = 8;
  std::vector<Image> images;
  for (int k = 0; k < 3; ++k) {
    Image image(w, h, 1, PixelType::kF32);
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        float value = 0.0f;
        if (x <= 6) value = static_cast<float>(10 + (3 - k) * x);
        if (x >= 9) value = static_cast<float>(200 + (1 + k) * (x - 9));
        *image.At<float>(x, y) = value;
      }
    }
    images.push_back(image);
  }
  Image count(w, h, 1, PixelType::kU32);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) *count.At<uint32_t>(x, y) = x == 7 || x == 8 ? 0u : 1u;
  }
  MergeOptions options = Options(MergeMethod::kImproved);
  options.window_radius = 0;
  options.smoothing_sigma = 2.0;
  options.smoothing_iterations = 2;
  options.edge_sigma = 0.1;
  const MergeResult result = MergeFocalStack(HandStack(images, {count, count, count}), options);
  ASSERT_TRUE(WellFormed(result, w, h));
  EXPECT_EQ(result.uncovered_pixels, 2 * h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const float expected = x <= 6 ? 0.0f : x >= 9 ? 2.0f : -1.0f;
      // Weighted means of equal values: exact up to float rounding.
      EXPECT_NEAR(*result.slice.At<float>(x, y), expected, 1e-6) << x << "," << y;
    }
  }
}

TEST(MergeFocalStack, ASingleSliceIsItsOwnAllInFocusImage) {
  const int w = 12, h = 10;
  const FocalStack stack = HandStack({Ramp(w, h, 2.5)});
  for (MergeMethod method : {MergeMethod::kSobel, MergeMethod::kImproved}) {
    SCOPED_TRACE(MergeMethodName(method));
    const MergeResult result = MergeFocalStack(stack, Options(method));
    ASSERT_TRUE(WellFormed(result, w, h));
    EXPECT_TRUE(SameImage(result.image, stack.images[0]));
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        // One slice: best = mean, confidence 0; the only plane's depth.
        ASSERT_EQ(*result.slice.At<float>(x, y), 0.0f);
        ASSERT_EQ(*result.confidence.At<float>(x, y), 0.0f);
        ASSERT_NEAR(*result.depth.At<float>(x, y), kAltitude, 1e-5);
      }
    }
  }
}

TEST(MergeFocalStack, ConstantSlicesGiveTheFirstSliceAndNoConfidence) {
  // Every focus value is 0: ties go to slice 0, confidence is 0/0 -> 0, nothing is NaN, and the
  // result does not depend on the thread count.
  const int w = 14, h = 9;
  const Image flat = ConstantImage(w, h, {50.0f});
  const FocalStack stack = HandStack({flat, flat.Clone(), flat.Clone(), flat.Clone()});
  for (MergeMethod method : {MergeMethod::kSobel, MergeMethod::kImproved}) {
    SCOPED_TRACE(MergeMethodName(method));
    MergeOptions options = Options(method);
    const MergeResult result = MergeFocalStack(stack, options);
    ASSERT_TRUE(WellFormed(result, w, h));
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        ASSERT_EQ(*result.slice.At<float>(x, y), 0.0f);
        ASSERT_EQ(*result.confidence.At<float>(x, y), 0.0f);
        ASSERT_EQ(*result.image.At<float>(x, y), 50.0f);
        ASSERT_NEAR(*result.depth.At<float>(x, y), kAltitude, 1e-5);
      }
    }
    options.num_threads = 2;
    EXPECT_TRUE(SameMerge(MergeFocalStack(stack, options), result));
  }
}

TEST(MergeFocalStack, RobustNeedsVariancesAndTheLightField) {
  const FocalStack stack = HandStack({Ramp(8, 8, 1), Ramp(8, 8, 2)});
  const MergeOptions robust = Options(MergeMethod::kRobust);
  LightField light_field;
  EXPECT_THAT(ErrorOf([&] { MergeFocalStack(stack, robust, &light_field); }),
              HasSubstr("no variance images"));
  FocalStack with_variance = stack;
  with_variance.variances = {ConstantImage(8, 8, {0.0f}), ConstantImage(8, 8, {0.0f})};
  EXPECT_THAT(ErrorOf([&] { MergeFocalStack(with_variance, robust); }),
              HasSubstr("needs the light field"));
  // sobel and improved need neither.
  EXPECT_EQ(ErrorOf([&] { MergeFocalStack(stack, Options(MergeMethod::kImproved)); }), "no error");
}

TEST(MergeFocalStack, AFlatPatchInsideTextureHasExactlyZeroFocusAndNoConfidence) {
  // Slices with large-valued texture on the left half and a flat patch (value 0) on the right:
  // any window lying wholly in the patch has Sobel energy exactly 0 in every slice, so its
  // focus curve is flat: slice 0 (ties to the lower slice) and confidence exactly 0, and no
  // rounding residue from the textured part may make one slice win there.
  const int w = 48, h = 16;
  std::vector<Image> images;
  for (int k = 0; k < 4; ++k) {
    Image image(w, h, 1, PixelType::kF32);
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        *image.At<float>(x, y) =
            x < w / 2 ? static_cast<float>(1000.0 * ((x * 7 + y * 13 + k * 5) % 11)) : 0.0f;
      }
    }
    images.push_back(image);
  }
  const FocalStack stack = HandStack(images);
  MergeOptions options = Options(MergeMethod::kImproved);
  options.smoothing_sigma = 0.0;  // the raw focus state
  const MergeResult result = MergeFocalStack(stack, options);
  ASSERT_TRUE(WellFormed(result, w, h));
  // Window radius 3 plus the Sobel's 1: columns from w/2 + 4 on see only the patch.
  for (int y = 0; y < h; ++y) {
    for (int x = w / 2 + options.window_radius + 1; x < w; ++x) {
      ASSERT_EQ(*result.confidence.At<float>(x, y), 0.0f) << x << "," << y;
      ASSERT_EQ(*result.slice.At<float>(x, y), 0.0f) << x << "," << y;
    }
  }
}

TEST(MergeFocalStack, NonFiniteSlicesAndNegativeVariancesAreRefused) {
  FocalStack stack = HandStack({Ramp(8, 8, 1), Ramp(8, 8, 2)});
  stack.images[1].At<float>(3, 4)[0] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THAT(ErrorOf([&] { MergeFocalStack(stack, Options(MergeMethod::kSobel)); }),
              AllOf(HasSubstr("slice 1"), HasSubstr("image")));
  FocalStack negative = HandStack({Ramp(8, 8, 1), Ramp(8, 8, 2)});
  negative.variances = {ConstantImage(8, 8, {0.0f}), ConstantImage(8, 8, {-1.0f})};
  EXPECT_THAT(ErrorOf([&] { MergeFocalStack(negative, Options(MergeMethod::kImproved)); }),
              AllOf(HasSubstr("slice 1"), HasSubstr("variance: negative")));
}

TEST(MergeFocalStack, RobustRefusesAPinholeStack) {
  FocalStack stack = HandStack({Ramp(8, 8, 1), Ramp(8, 8, 2)});
  stack.variances = {ConstantImage(8, 8, {0.0f}), ConstantImage(8, 8, {0.0f})};
  stack.render.aperture_radius = 0.0;
  LightField light_field;
  EXPECT_THAT(ErrorOf([&] { MergeFocalStack(stack, Options(MergeMethod::kRobust), &light_field); }),
              HasSubstr("aperture_radius 0"));
  AllInFocusOptions options;
  options.merge.method = MergeMethod::kRobust;
  options.stack.render.aperture_radius = 0.0;
  EXPECT_THAT(ErrorOf([&] { options.Check(3); }), HasSubstr("aperture_radius"));
}

// Three constant views at 20 m (for checks that need a light field, not its content).
LightField ConstantViewsForChecks() {
  const PinholeCamera camera = PinholeCamera::FromFov(16, 16, 60.0);
  LightField light_field;
  for (int i = 0; i < 3; ++i) {
    light_field.views.push_back(MakeView("v" + std::to_string(i), camera,
                                         NadirCamFromWorld(Vec3d(i - 1.0, 0, 20)),
                                         ConstantImage(16, 16, {50.0f}, PixelType::kU8)));
  }
  return light_field;
}

TEST(MergeOptions, CheckNamesTheField) {
  struct Case {
    const char* field;
    std::function<void(MergeOptions&)> set;
  };
  const double nan = std::nan(""), inf = std::numeric_limits<double>::infinity();
  const std::vector<Case> cases = {
      {"window_radius", [](MergeOptions& o) { o.window_radius = -1; }},
      {"window_radius", [](MergeOptions& o) { o.window_radius = 33; }},
      {"smoothing_sigma", [](MergeOptions& o) { o.smoothing_sigma = -0.5; }},
      {"smoothing_sigma", [](MergeOptions& o) { o.smoothing_sigma = 16.5; }},
      {"smoothing_sigma", [=](MergeOptions& o) { o.smoothing_sigma = nan; }},
      {"edge_sigma", [](MergeOptions& o) { o.edge_sigma = 0.0; }},
      {"edge_sigma", [=](MergeOptions& o) { o.edge_sigma = inf; }},
      {"edge_sigma", [=](MergeOptions& o) { o.edge_sigma = nan; }},
      {"smoothing_iterations", [](MergeOptions& o) { o.smoothing_iterations = -1; }},
      {"smoothing_iterations", [](MergeOptions& o) { o.smoothing_iterations = 21; }},
      {"num_threads", [](MergeOptions& o) { o.num_threads = 0; }},
      {"num_threads", [](MergeOptions& o) { o.num_threads = -2; }},
      {"agreement", [](MergeOptions& o) { o.robust.agreement = 0.0; }},
      {"min_inlier_fraction", [](MergeOptions& o) { o.robust.min_inlier_fraction = 1.5; }},
  };
  for (const Case& c : cases) {
    MergeOptions options;
    c.set(options);
    EXPECT_THAT(ErrorOf([&] { options.Check(); }), HasSubstr(c.field)) << c.field;
  }
  // The limits themselves are valid.
  MergeOptions edge;
  edge.window_radius = 32;
  edge.smoothing_sigma = 16.0;
  edge.smoothing_iterations = 20;
  edge.num_threads = -1;
  EXPECT_EQ(ErrorOf([&] { edge.Check(); }), "no error");
  edge.window_radius = 0;
  edge.smoothing_sigma = 0.0;
  edge.smoothing_iterations = 0;
  EXPECT_EQ(ErrorOf([&] { edge.Check(); }), "no error");
  // A merge checks its options first.
  MergeOptions bad;
  bad.window_radius = 40;
  EXPECT_THAT(ErrorOf([&] { MergeFocalStack(HandStack({Ramp(4, 4, 1)}), bad); }),
              HasSubstr("window_radius"));
  // Method names.
  for (const char* name : {"sobel", "improved", "robust"}) {
    EXPECT_STREQ(MergeMethodName(ParseMergeMethod(name)), name);
  }
  const std::string error = ErrorOf([] { ParseMergeMethod("sharpest", "--merge"); });
  EXPECT_THAT(error, HasSubstr("--merge"));
  EXPECT_THAT(error, HasSubstr("sharpest"));
}

TEST(AllInFocusOptions, CheckNamesTheField) {
  const LightField light_field = ConstantViewsForChecks();
  AllInFocusOptions options;
  options.stack.render.cam_from_world = NadirCamFromWorld(Vec3d(0, 0, 20));
  options.stack.render.width = options.stack.render.height = 8;
  options.stack.slices = 0;
  EXPECT_THAT(ErrorOf([&] { RenderAllInFocus(light_field, options); }), HasSubstr("slices"));
  options.stack.slices = 3;
  options.stack.render.fov_deg = 190.0;
  EXPECT_THAT(ErrorOf([&] { RenderAllInFocus(light_field, options); }), HasSubstr("fov_deg"));
  options.stack.render.fov_deg = 30.0;
  options.merge.edge_sigma = -1.0;
  EXPECT_THAT(ErrorOf([&] { RenderAllInFocus(light_field, options); }), HasSubstr("edge_sigma"));
  options.merge.edge_sigma = 0.1;
  for (const int factor : {1, -1, 17}) {
    options.coarse_to_fine = factor;
    EXPECT_THAT(ErrorOf([&] { RenderAllInFocus(light_field, options); }),
                HasSubstr("coarse_to_fine"));
  }
  options.coarse_to_fine = 0;
  EXPECT_EQ(ErrorOf([&] { RenderAllInFocus(light_field, options); }), "no error");
}

struct StopSink : ProgressSink {
  void Start(const std::string& name, int64_t) override { stages.push_back(name); }
  void Advance(int64_t units) override { done += units; }
  bool Cancelled() override { return done.load() >= stop_after; }
  std::vector<std::string> stages;
  std::atomic<int64_t> done{0};
  int64_t stop_after = 1;
};

TEST(Merge, CancellationStops) {
  const LightField light_field = ConstantViewsForChecks();
  AllInFocusOptions options;
  options.stack.render.cam_from_world = NadirCamFromWorld(Vec3d(0, 0, 20));
  options.stack.render.width = options.stack.render.height = 8;
  options.stack.render.num_threads = 1;
  options.stack.slices = 5;
  options.merge.num_threads = 1;
  StopSink pipeline;
  EXPECT_THROW(RenderAllInFocus(light_field, options, &pipeline), Cancelled);
  const FocalStack stack = RenderFocalStack(light_field, options.stack);
  StopSink merge;
  EXPECT_THROW(MergeFocalStack(stack, options.merge, nullptr, &merge), Cancelled);
  EXPECT_EQ(merge.stages, std::vector<std::string>{"merge"});
  StopSink surface;
  surface.stop_after = 0;
  EXPECT_THROW(RenderIntegralOnDepth(light_field, options.stack.render, ConstantImage(8, 8, {20.0f}),
                                     {}, &surface),
               Cancelled);
}

TEST(SurfaceIntegralOptions, CheckNamesTheField) {
  const double nan = std::nan(""), inf = std::numeric_limits<double>::infinity();
  struct Case {
    const char* field;
    std::function<void(SurfaceIntegralOptions&)> set;
  };
  const std::vector<Case> cases = {
      {"agreement", [](SurfaceIntegralOptions& o) { o.agreement = 0.0; }},
      {"agreement", [](SurfaceIntegralOptions& o) { o.agreement = -0.1; }},
      {"agreement", [](SurfaceIntegralOptions& o) { o.agreement = 1.01; }},
      {"agreement", [=](SurfaceIntegralOptions& o) { o.agreement = inf; }},
      {"agreement", [=](SurfaceIntegralOptions& o) { o.agreement = nan; }},
      {"min_inlier_fraction", [](SurfaceIntegralOptions& o) { o.min_inlier_fraction = -0.1; }},
      {"min_inlier_fraction", [](SurfaceIntegralOptions& o) { o.min_inlier_fraction = 1.01; }},
      {"min_inlier_fraction", [=](SurfaceIntegralOptions& o) { o.min_inlier_fraction = nan; }},
  };
  for (const Case& c : cases) {
    SurfaceIntegralOptions options;
    c.set(options);
    EXPECT_THAT(ErrorOf([&] { options.Check(); }), HasSubstr(c.field)) << c.field;
  }
  SurfaceIntegralOptions edge;
  edge.agreement = 1.0;
  edge.min_inlier_fraction = 1.0;
  EXPECT_EQ(ErrorOf([&] { edge.Check(); }), "no error");
  edge.min_inlier_fraction = 0.0;
  EXPECT_EQ(ErrorOf([&] { edge.Check(); }), "no error");
}

// ---------------------------------------------------------------------------------------------
// Light fields

// 5 x 5 8-bit nadir views, 3 m apart at 20 m, of a checker ground (0.6 m squares) at z = 0, no
// occluders. View pixels cover ~0.19 m on the ground.
const LightField& SimulatedGround() {
  static const LightField light_field = [] {
    Scene scene;
    scene.ground.texture.kind = TextureSpec::Kind::kChecker;
    scene.ground.texture.square = 0.6;
    scene.camera.width = scene.camera.height = 96;
    scene.camera.fov_deg = 50.0;
    scene.sampling.altitude = 20.0;
    scene.sampling.grid = 5;
    scene.sampling.aperture_diameter = 12.0;
    scene.truth.blocked_fraction = false;
    scene.truth.width = scene.truth.height = 8;
    return Simulate(scene).light_field;
  }();
  return light_field;
}

AllInFocusOptions GroundStackOptions(MergeMethod method, int size, int slices) {
  AllInFocusOptions options;
  options.stack.render.cam_from_world = NadirCamFromWorld(Vec3d(0, 0, 20));
  options.stack.render.fov_deg = 20.0;
  options.stack.render.width = options.stack.render.height = size;
  options.stack.first_plane = Plane::AtHeight(-2.0);
  options.stack.last_plane = Plane::AtHeight(2.0);
  options.stack.slices = slices;
  options.merge.method = method;
  options.merge.num_threads = 1;
  return options;
}

TEST(RenderAllInFocus, RecoversTheDepthOfTexturedGround) {
  // 21 slices 0.2 m apart from z = -2 to 2; the ground at z = 0 lies at depth 20 m (slice 10).
  // A slice step moves the extreme views' images apart by 12 m x 0.2 m / 20 m = 0.12 m, about
  // 0.6 view pixel, so the focus curve is a few slices wide: sobel must land within one slice
  // (0.2 m), the parabola-refined, smoothed methods within half a slice (0.1 m).
  const int size = 24;
  for (MergeMethod method : kAllMethods) {
    SCOPED_TRACE(MergeMethodName(method));
    const MergeResult result = RenderAllInFocus(SimulatedGround(), GroundStackOptions(method, size, 21));
    ASSERT_TRUE(WellFormed(result, size, size));
    EXPECT_EQ(result.uncovered_pixels, 0);
    // (+ 1e-5: float rounding of a 20 m depth.)
    const double tolerance = (method == MergeMethod::kSobel ? 0.2 : 0.1) + 1e-5;
    for (int y = 8; y < 16; ++y) {
      for (int x = 8; x < 16; ++x) {
        EXPECT_NEAR(*result.depth.At<float>(x, y), 20.0, tolerance) << x << "," << y;
      }
    }
  }
}

TEST(RenderAllInFocus, CoarseToFineEqualsTheFullStackWhereTheFocusIsInRange) {
  // Flat ground at slice 20 of 41 (0.1 m apart): a block whose coarse maximum is coarse slice 5
  // (full slice 20) takes the full slices 16..24, narrowed to those within 1.5 slices of the
  // coarse peak's vertex (merge.cpp kFineMargin) where it is concave: 4 or 5 slices. With the
  // vertex within half a slice of 20 (the ground), every block takes 19..21 at least, so on the
  // pixels whose full-stack peak lies within half a slice of 20 (peak and both parabola
  // neighbours taken) the fold without smoothing must give the full stack's slice: equal up to
  // the float rounding between the plane render and the point render (a relative 1e-6 on the focus values moves a parabola vertex by far less than 1e-3
  // slice). Those are most pixels for improved and robust (their focus window sees texture);
  // sobel's 3 x 3 gradient is 0 inside the checker squares (near-ties decide its peaks), so it
  // is only run. With smoothing the confidence is the coarse stack's, so the depth
  // may move a little: within 0.05 slice (5 mm), and the image within 1 grey level on average.
  const int size = 32;
  for (MergeMethod method : kAllMethods) {
    SCOPED_TRACE(MergeMethodName(method));
    for (const double sigma : {0.0, 3.0}) {
      SCOPED_TRACE(sigma);
      AllInFocusOptions options = GroundStackOptions(method, size, 41);
      options.merge.smoothing_sigma = sigma;
      const MergeResult full = RenderAllInFocus(SimulatedGround(), options);
      options.coarse_to_fine = 4;
      const MergeResult fine = RenderAllInFocus(SimulatedGround(), options);
      ASSERT_TRUE(WellFormed(fine, size, size));
      EXPECT_EQ(full.rendered_fraction, 1.0);
      // 4 or 5 of 41 slices a pixel (9 without the narrowing).
      EXPECT_LE(fine.rendered_fraction, 5.0 / 41.0 + 1e-9);
      EXPECT_GE(fine.rendered_fraction, 4.0 / 41.0 - 1e-9);
      EXPECT_EQ(fine.uncovered_pixels, full.uncovered_pixels);
      const double slice_tolerance = sigma == 0.0 ? 1e-3 : 0.05;
      double image_difference = 0.0;
      int in_range = 0;
      for (int y = 0; y < size; ++y) {
        for (int x = 0; x < size; ++x) {
          image_difference += std::abs(*fine.image.At<float>(x, y) - *full.image.At<float>(x, y));
          const float peak = *full.slice.At<float>(x, y);
          if (method == MergeMethod::kSobel || !(peak >= 19.5f && peak <= 20.5f)) continue;
          ++in_range;
          ASSERT_NEAR(*fine.slice.At<float>(x, y), *full.slice.At<float>(x, y), slice_tolerance)
              << x << "," << y;
          ASSERT_NEAR(*fine.depth.At<float>(x, y), *full.depth.At<float>(x, y),
                      0.1 * slice_tolerance + 1e-5)
              << x << "," << y;
        }
      }
      if (method != MergeMethod::kSobel) {
        // The pixels' full-stack peaks spread over a few slices around 20 (texture); about half
        // lie within half a slice of it here (improved, robust).
        EXPECT_GT(in_range, size * size * 3 / 10);
        EXPECT_LT(image_difference / (size * size), sigma == 0.0 ? 0.05 : 1.0);
      }
      // Thread-count independence.
      options.merge.num_threads = options.stack.render.num_threads = 2;
      const MergeResult two = RenderAllInFocus(SimulatedGround(), options);
      for (int y = 0; y < size; ++y) {
        for (int x = 0; x < size; ++x) {
          ASSERT_EQ(*two.slice.At<float>(x, y), *fine.slice.At<float>(x, y)) << x << "," << y;
          ASSERT_EQ(*two.image.At<float>(x, y), *fine.image.At<float>(x, y)) << x << "," << y;
        }
      }
    }
  }
}

// Coarse-to-fine (factor 4) over 41 slices of the simulated ground: planes, or with `surface`
// a terrain-following stack on a tilted mesh (the slices' depths vary over the image).
AllInFocusOptions CoarseToFineOptions(MergeMethod method, int size, bool surface) {
  AllInFocusOptions options = GroundStackOptions(method, size, 41);
  options.coarse_to_fine = 4;
  if (surface) {
    Mesh tilted;
    tilted.vertices = {{-100, -100, -4.0}, {100, -100, 4.0}, {100, 100, 4.0}, {-100, 100, -4.0}};
    tilted.triangles = {{0, 1, 2}, {0, 2, 3}};
    options.stack.render.focal_surface =
        (FocalSurface::FromMesh(tilted));
    options.stack.first_offset = -2.0;
    options.stack.last_offset = 2.0;
  }
  return options;
}

TEST(RenderAllInFocus, CoarseToFineBlockPackingEqualsSlicePacking) {
  // The fine pass packs its (slice, pixel) points block by block in one render call (the
  // default) or slice by slice (the reference): the same points, each with its samples in view
  // order, so every output must be equal bit for bit; for planes and for a terrain-following
  // stack (a tilted mesh: the slices' depths vary over the image), with 1 and 2 threads; 30
  // pixels wide too, so that the last blocks are partial (factor 4).
  for (const int size : {32, 30}) {
    SCOPED_TRACE(size);
    for (MergeMethod method : kAllMethods) {
      SCOPED_TRACE(MergeMethodName(method));
      for (const bool surface : {false, true}) {
        SCOPED_TRACE(surface);
        AllInFocusOptions options = CoarseToFineOptions(method, size, surface);
        for (const int threads : {1, 2}) {
          options.merge.num_threads = options.stack.render.num_threads = threads;
          internal::SetCoarseToFineBlockPacking(false);
          const MergeResult slice_packed = RenderAllInFocus(SimulatedGround(), options);
          internal::SetCoarseToFineBlockPacking(true);
          const MergeResult block_packed = RenderAllInFocus(SimulatedGround(), options);
          ASSERT_TRUE(WellFormed(block_packed, size, size));
          EXPECT_EQ(block_packed.rendered_fraction, slice_packed.rendered_fraction);
          EXPECT_LT(block_packed.rendered_fraction, 0.2);
          EXPECT_EQ(block_packed.uncovered_pixels, slice_packed.uncovered_pixels);
          EXPECT_EQ(block_packed.fallback_pixels, slice_packed.fallback_pixels);
          EXPECT_TRUE(SameImage(block_packed.image, slice_packed.image));
          EXPECT_TRUE(SameImage(block_packed.depth, slice_packed.depth));
          EXPECT_TRUE(SameImage(block_packed.slice, slice_packed.slice));
          EXPECT_TRUE(SameImage(block_packed.confidence, slice_packed.confidence));
        }
      }
    }
  }
}

TEST(RenderAllInFocus, CoarseToFineCoarseStackThroughPointsAgreesWithTheSliceRender) {
  // The coarse stack through packed points (the default) or slice by slice through the plane
  // render (the reference): the same samples up to float rounding, so on this ground the blocks
  // choose the same slices (the same rendered fraction), and the merged slice and image agree
  // to far below a slice and a grey level; planes and a tilted surface, 1 and 2 threads (the
  // outputs independent of the thread count).
  const int size = 32;
  for (MergeMethod method : kAllMethods) {
    SCOPED_TRACE(MergeMethodName(method));
    for (const bool surface : {false, true}) {
      SCOPED_TRACE(surface);
      AllInFocusOptions options = CoarseToFineOptions(method, size, surface);
      MergeResult first;
      for (const int threads : {1, 2}) {
        options.merge.num_threads = options.stack.render.num_threads = threads;
        internal::SetCoarseToFineCoarsePoints(false);
        const MergeResult spans = RenderAllInFocus(SimulatedGround(), options);
        internal::SetCoarseToFineCoarsePoints(true);
        const MergeResult points = RenderAllInFocus(SimulatedGround(), options);
        ASSERT_TRUE(WellFormed(points, size, size));
        EXPECT_EQ(points.rendered_fraction, spans.rendered_fraction);
        EXPECT_EQ(points.uncovered_pixels, spans.uncovered_pixels);
        double image_difference = 0.0;
        for (int y = 0; y < size; ++y) {
          for (int x = 0; x < size; ++x) {
            ASSERT_NEAR(*points.slice.At<float>(x, y), *spans.slice.At<float>(x, y), 1e-2)
                << x << "," << y;
            image_difference += std::abs(*points.image.At<float>(x, y) - *spans.image.At<float>(x, y));
          }
        }
        EXPECT_LT(image_difference / (size * size), 0.05);
        if (threads == 1) {
          first = points;
        } else {
          EXPECT_TRUE(SameImage(points.image, first.image));
          EXPECT_TRUE(SameImage(points.slice, first.slice));
          EXPECT_TRUE(SameImage(points.confidence, first.confidence));
        }
      }
    }
  }
}

TEST(RenderAllInFocus, CoarseToFineSkipsSlicesFarFromTheFocus) {
  // 101 slices from z = -2 to 2 m (0.04 m apart) over flat ground at z = 0 (slice 50): with
  // factor 4 the coarse maximum is at full slice 48 or 52 (coarse slice 12 or 13) or between, so
  // a block renders at most the 9 full slices around it and never the slices 0..40 or 60..100;
  // the merged depth lies near the ground (20 m) as the full stack's does.
  const int size = 32;
  AllInFocusOptions options = GroundStackOptions(MergeMethod::kImproved, size, 101);
  options.coarse_to_fine = 4;
  const MergeResult fine = RenderAllInFocus(SimulatedGround(), options);
  EXPECT_LE(fine.rendered_fraction, 9.0 / 101.0 + 1e-9);
  for (int y = 8; y < 24; ++y) {
    for (int x = 8; x < 24; ++x) {
      EXPECT_GT(*fine.slice.At<float>(x, y), 40.0f) << x << "," << y;
      EXPECT_LT(*fine.slice.At<float>(x, y), 60.0f) << x << "," << y;
      EXPECT_NEAR(*fine.depth.At<float>(x, y), 20.0, 0.1) << x << "," << y;
    }
  }
}

TEST(RenderAllInFocus, ATerrainFollowingStackFindsTheGroundOffTheGivenSurface) {
  // The ground lies at z = 0 but the "DEM" given is a flat mesh 0.6 m too low (z = -0.6): the
  // terrain-following stack from 2 m below to 2 m above it (21 slices, 0.2 m apart) must find
  // the ground at offset +0.6 (slice 13) and depth 20 m, within the tolerances of the plane case
  // above (sobel one slice, the others half a slice). A wrong up sign would put it at z = -1.2.
  const int size = 24;
  Mesh low;
  low.vertices = {{-100, -100, -0.6}, {100, -100, -0.6}, {100, 100, -0.6}, {-100, 100, -0.6}};
  low.triangles = {{0, 1, 2}, {0, 2, 3}};
  for (MergeMethod method : kAllMethods) {
    SCOPED_TRACE(MergeMethodName(method));
    AllInFocusOptions options = GroundStackOptions(method, size, 21);
    options.stack.render.focal_surface = FocalSurface::FromMesh(low);
    options.stack.first_offset = -2.0;
    options.stack.last_offset = 2.0;
    const MergeResult result = RenderAllInFocus(SimulatedGround(), options);
    ASSERT_TRUE(WellFormed(result, size, size));
    EXPECT_EQ(result.uncovered_pixels, 0);
    const double tolerance = (method == MergeMethod::kSobel ? 0.2 : 0.1) + 1e-5;
    for (int y = 8; y < 16; ++y) {
      for (int x = 8; x < 16; ++x) {
        EXPECT_NEAR(*result.depth.At<float>(x, y), 20.0, tolerance) << x << "," << y;
        EXPECT_NEAR(*result.slice.At<float>(x, y), 13.0, tolerance / 0.2) << x << "," << y;
      }
    }
    // Merging the stored stack gives the pipeline's depth (the same focus values and surface).
    if (method != MergeMethod::kRobust) {
      const FocalStack stack = RenderFocalStack(SimulatedGround(), options.stack);
      const MergeResult merged = MergeFocalStack(stack, options.merge);
      EXPECT_TRUE(SameImage(merged.depth, result.depth));
    }
  }
}

TEST(RenderAllInFocus, OneSliceAndIdenticalBoundaryPlanes) {
  // One slice lies midway (z = 0 between -2 and 2); four slices on one plane are identical, so
  // every focus curve is flat: slice 0 (ties to the lower), confidence 0, that plane's depth.
  const PinholeCamera camera = PinholeCamera::FromFov(16, 16, 20.0);
  for (MergeMethod method : kAllMethods) {
    SCOPED_TRACE(MergeMethodName(method));
    AllInFocusOptions one = GroundStackOptions(method, 16, 1);
    AllInFocusOptions same = GroundStackOptions(method, 16, 4);
    same.stack.first_plane = same.stack.last_plane = Plane{Vec3d(0, 0, 0.5), Vec3d(0.1, 0, 1)};
    for (const AllInFocusOptions& options : {one, same}) {
      const Plane plane = options.stack.slices == 1 ? Plane::AtHeight(0.0) : options.stack.first_plane;
      const Image truth = PlaneDepth(camera, options.stack.render.cam_from_world, plane);
      const MergeResult result = RenderAllInFocus(SimulatedGround(), options);
      ASSERT_TRUE(WellFormed(result, 16, 16));
      for (int y = 0; y < 16; ++y) {
        for (int x = 0; x < 16; ++x) {
          ASSERT_EQ(*result.slice.At<float>(x, y), 0.0f) << x << "," << y;
          ASSERT_EQ(*result.confidence.At<float>(x, y), 0.0f) << x << "," << y;
          // Interpolated planes equal the plane to ~1e-14 m; depth is float (~2e-6 at 20 m).
          ASSERT_NEAR(*result.depth.At<float>(x, y), *truth.At<float>(x, y), 1e-5) << x << "," << y;
        }
      }
    }
  }
}

TEST(RenderAllInFocus, ConstantViewsGiveADeterministicFlatResult) {
  // Views of one grey value: no focus anywhere. Every method must give slice 0, confidence 0,
  // the grey value, no NaN, and the same bytes for 1 and 2 threads.
  SyntheticScene scene;
  scene.layers.push_back(SceneLayer{Plane::AtHeight(0.0), [](const Vec3d&, float* value) {
    value[0] = 90.0f;
    return true;
  }});
  const LightField light_field = NadirLightField(scene, PinholeCamera::FromFov(32, 32, 50.0),
                                                 GridCentres(3, 2.0, 20.0), PixelType::kU8);
  for (MergeMethod method : kAllMethods) {
    SCOPED_TRACE(MergeMethodName(method));
    AllInFocusOptions options = GroundStackOptions(method, 16, 6);
    const MergeResult result = RenderAllInFocus(light_field, options);
    ASSERT_TRUE(WellFormed(result, 16, 16));
    EXPECT_EQ(result.fallback_pixels, 0);
    for (int y = 0; y < 16; ++y) {
      for (int x = 0; x < 16; ++x) {
        ASSERT_EQ(*result.slice.At<float>(x, y), 0.0f) << x << "," << y;
        ASSERT_EQ(*result.confidence.At<float>(x, y), 0.0f) << x << "," << y;
        ASSERT_EQ(*result.image.At<float>(x, y), 90.0f) << x << "," << y;
        ASSERT_NEAR(*result.depth.At<float>(x, y), 22.0, 1e-5) << x << "," << y;  // z = -2
      }
    }
    options.merge.num_threads = 2;
    EXPECT_TRUE(SameMerge(RenderAllInFocus(light_field, options), result));
  }
}

TEST(RenderAllInFocus, PixelsNoSliceCoversAreZeroWithSliceMinusOne) {
  // A virtual camera far wider than the views: its corners see no view on any slice.
  const int size = 24;
  for (MergeMethod method : kAllMethods) {
    SCOPED_TRACE(MergeMethodName(method));
    AllInFocusOptions options = GroundStackOptions(method, size, 5);
    options.stack.render.fov_deg = 120.0;
    const MergeResult result = RenderAllInFocus(SimulatedGround(), options);
    ASSERT_TRUE(WellFormed(result, size, size));
    // Coverage per pixel from the slices themselves: the most views any slice saw it with.
    FocalStackOptions stack_options = options.stack;
    stack_options.render.variance = false;
    const FocalStack stack = RenderFocalStack(SimulatedGround(), stack_options);
    int64_t uncovered = 0;
    for (int y = 0; y < size; ++y) {
      for (int x = 0; x < size; ++x) {
        uint32_t views = 0;
        for (const Image& count : stack.counts) views = std::max(views, *count.At<uint32_t>(x, y));
        const float slice = *result.slice.At<float>(x, y);
        if (views == 0) {
          ++uncovered;
          ASSERT_EQ(slice, -1.0f) << x << "," << y;
          ASSERT_EQ(*result.depth.At<float>(x, y), 0.0f) << x << "," << y;
          ASSERT_EQ(*result.confidence.At<float>(x, y), 0.0f) << x << "," << y;
          ASSERT_EQ(*result.image.At<float>(x, y), 0.0f) << x << "," << y;
        } else if (views >= 2 || method != MergeMethod::kRobust) {
          // Covered: a slice in [0, N-1] and a depth in front of the camera. (robust's cue, the
          // variance, needs two samples; pixels only ever seen by one view are not asserted
          // for it here.)
          ASSERT_GE(slice, 0.0f) << x << "," << y;
          ASSERT_LE(slice, 4.0f) << x << "," << y;
          ASSERT_GT(*result.depth.At<float>(x, y), 0.0f) << x << "," << y;
        }
      }
    }
    EXPECT_GT(uncovered, 20);
    if (method != MergeMethod::kRobust) EXPECT_EQ(result.uncovered_pixels, uncovered);
  }
}

TEST(RenderAllInFocus, StreamingAThousandSlicesMatchesMergingTheStack) {
  // The pipeline folds the slices one at a time; merging the stored stack folds the same focus
  // values in the same order, so depth, slice and confidence are the same bytes (and sobel's
  // image: the winning slice's pixels).
  const int size = 16;
  for (MergeMethod method : {MergeMethod::kSobel, MergeMethod::kImproved}) {
    SCOPED_TRACE(MergeMethodName(method));
    const AllInFocusOptions options = GroundStackOptions(method, size, 1000);
    const MergeResult streamed = RenderAllInFocus(SimulatedGround(), options);
    const FocalStack stack = RenderFocalStack(SimulatedGround(), options.stack);
    ASSERT_EQ(stack.size(), 1000);
    const MergeResult merged = MergeFocalStack(stack, options.merge);
    ASSERT_TRUE(WellFormed(streamed, size, size));
    EXPECT_TRUE(SameImage(streamed.depth, merged.depth));
    EXPECT_TRUE(SameImage(streamed.slice, merged.slice));
    EXPECT_TRUE(SameImage(streamed.confidence, merged.confidence));
    if (method == MergeMethod::kSobel) EXPECT_TRUE(SameImage(streamed.image, merged.image));
    // Not a comparison of empty maps: every pixel lies on a slice (depth 18..22 m). On slices
    // 4 mm apart the focus curve is flat over ~1 m, so only improved's smoothed, refined peak is
    // held to the ground's depth (20 m, within 0.2 m).
    EXPECT_EQ(streamed.uncovered_pixels, 0);
    for (int y = 0; y < size; ++y) {
      for (int x = 0; x < size; ++x) {
        ASSERT_GE(*streamed.depth.At<float>(x, y), 18.0f - 1e-5f);
        ASSERT_LE(*streamed.depth.At<float>(x, y), 22.0f + 1e-5f);
      }
    }
    if (method == MergeMethod::kImproved) EXPECT_NEAR(*streamed.depth.At<float>(8, 8), 20.0, 0.2);
  }
}

// Forward declaration: six constant views, one an outlier (defined with the robust mean tests).
LightField ConstantViews(const std::vector<float>& values, PixelType type);

TEST(RenderAllInFocus, RobustReintegratesWithTheOutlierRejectingMean) {
  // Six constant views, one of them 250 among 100s: every slice is flat, so the depth is slice
  // 0's; robust re-integrates there with the robust mean (100: the 250 is rejected), improved
  // with the plain mean ((5 x 100 + 250) / 6 = 125). With min_inlier_fraction = 1 too few
  // agree: the plain mean is kept and every pixel counts as a fallback.
  const LightField light_field = ConstantViews({100, 100, 100, 250, 100, 100}, PixelType::kU8);
  AllInFocusOptions options = GroundStackOptions(MergeMethod::kRobust, 12, 3);
  options.stack.render.fov_deg = 30.0;
  FocalStackOptions stack_options = options.stack;
  stack_options.render.variance = true;
  const FocalStack stack = RenderFocalStack(light_field, stack_options);
  for (int strict = 0; strict < 2; ++strict) {
    options.merge.robust.min_inlier_fraction = strict ? 1.0 : 0.5;
    const MergeResult streamed = RenderAllInFocus(light_field, options);
    const MergeResult merged = MergeFocalStack(stack, options.merge, &light_field);
    for (const MergeResult* result : {&streamed, &merged}) {
      ASSERT_TRUE(WellFormed(*result, 12, 12));
      EXPECT_EQ(result->fallback_pixels, strict ? 144 : 0);
      for (int y = 0; y < 12; ++y) {
        for (int x = 0; x < 12; ++x) {
          ASSERT_EQ(*result->image.At<float>(x, y), strict ? 125.0f : 100.0f) << x << "," << y;
        }
      }
    }
  }
  options.merge.method = MergeMethod::kImproved;
  const MergeResult plain = RenderAllInFocus(light_field, options);
  EXPECT_EQ(*plain.image.At<float>(6, 6), 125.0f);
  EXPECT_EQ(plain.fallback_pixels, 0);
}

// A 3 x 3 light field of 8-bit views of ground under a few random boxes at 6 m: robust's
// re-integration has outliers to reject.
const LightField& SimulatedOccludedGround() {
  static const LightField light_field = [] {
    Scene scene;
    scene.ground.texture.kind = TextureSpec::Kind::kChecker;
    scene.ground.texture.square = 0.6;
    scene.has_voxels = true;
    scene.voxels.center = {0.0, 0.0, 6.0};
    scene.voxels.size = {20.0, 20.0, 2.0};
    scene.voxels.grid = {40, 40, 4};
    scene.voxels.density = 0.3;
    scene.camera.width = scene.camera.height = 48;
    scene.camera.fov_deg = 50.0;
    scene.sampling.altitude = 20.0;
    scene.sampling.grid = 3;
    scene.sampling.aperture_diameter = 6.0;
    scene.truth.blocked_fraction = false;
    scene.truth.width = scene.truth.height = 8;
    return Simulate(scene).light_field;
  }();
  return light_field;
}

TEST(MergeThreads, OneAndTwoThreadsGiveTheSameBytes) {
  const LightField& light_field = SimulatedOccludedGround();
  for (MergeMethod method : kAllMethods) {
    SCOPED_TRACE(MergeMethodName(method));
    AllInFocusOptions options = GroundStackOptions(method, 20, 8);
    options.stack.last_plane = Plane::AtHeight(7.0);
    options.merge.num_threads = 1;
    const MergeResult one = RenderAllInFocus(light_field, options);
    options.merge.num_threads = 2;
    const MergeResult two = RenderAllInFocus(light_field, options);
    ASSERT_TRUE(WellFormed(one, 20, 20));
    EXPECT_TRUE(SameMerge(one, two));
    // The stored-stack merge too, of a stack rendered as the pipeline renders its slices
    // (variance only for robust: the variance pass may round the sums differently).
    FocalStackOptions stack_options = options.stack;
    stack_options.render.variance = method == MergeMethod::kRobust;
    const FocalStack stack = RenderFocalStack(light_field, stack_options);
    options.merge.num_threads = 1;
    const MergeResult merged_one = MergeFocalStack(stack, options.merge, &light_field);
    options.merge.num_threads = 2;
    const MergeResult merged_two = MergeFocalStack(stack, options.merge, &light_field);
    EXPECT_TRUE(SameMerge(merged_one, merged_two));
    // The stored-stack merge finds the same depth as the pipeline.
    EXPECT_TRUE(SameImage(merged_two.depth, two.depth));
  }
}

// ---------------------------------------------------------------------------------------------
// Integral rendering on a depth map

TEST(RenderIntegralOnDepth, PlainMeanOnAPlanesDepthIsRenderIntegralOnThatPlane) {
  // The same focal points, projected per pixel in double here and through a homography with
  // float sample positions in RenderIntegral's kernels (~1e-5 px at ~100 px coordinates). The
  // smooth texture's slope is at most ~290 grey/m, ~60 grey per 0.19 m view pixel, so values
  // agree within ~6e-4 grey (< 1e-3) and the admission tests give the same counts.
  static const LightField light_field =
      NadirLightField(test_util::TexturedGround(0.0), PinholeCamera::FromFov(96, 96, 50.0),
                      GridCentres(5, 3.0, 20.0), PixelType::kU8);
  for (double aperture : {std::numeric_limits<double>::infinity(), 3.0, 0.0}) {
    SCOPED_TRACE(aperture);
    IntegralOptions options;
    options.cam_from_world = LookAt(Vec3d(0.7, -0.4, 20), Vec3d(0, 1, 0), Vec3d(0, 1, 0));
    options.fov_deg = 60.0;
    options.width = 40;
    options.height = 30;
    options.aperture_radius = aperture;
    options.focal_surface = FocalSurface::FromPlane(Plane{Vec3d(0, 0, 0.3), Vec3d(0.1, -0.05, 1)});
    options.num_threads = 1;
    const IntegralResult reference = RenderIntegral(light_field, options);
    const Image depth = PlaneDepth(VirtualCamera(light_field, options), options.cam_from_world, options.focal_surface.plane());
    const SurfaceIntegralResult result = RenderIntegralOnDepth(light_field, options, depth);
    EXPECT_TRUE(result.inliers.empty());
    EXPECT_EQ(result.fallback_pixels, 0);
    EXPECT_TRUE(SameImage(result.integral.count, reference.count));
    double max_difference = 0.0;
    for (int y = 0; y < 30; ++y) {
      for (int x = 0; x < 40; ++x) {
        max_difference = std::max(max_difference, std::abs(double(*result.integral.image.At<float>(x, y)) -
                                                           *reference.image.At<float>(x, y)));
      }
    }
    EXPECT_LT(max_difference, 1e-3);
    EXPECT_EQ(result.integral.samples, reference.samples);
    EXPECT_EQ(result.integral.uncovered_pixels, reference.uncovered_pixels);
    EXPECT_EQ(result.integral.views_used, reference.views_used);
    EXPECT_EQ(result.integral.views_selected, reference.views_selected);
    EXPECT_GT(reference.samples, 0);
  }
}

// Six views of constant values that all see the whole 12 x 12 virtual image of the ground
// (z = 0, depth 20) at 20 m: each pixel's samples are exactly `values`.
LightField ConstantViews(const std::vector<float>& values, PixelType type) {
  const PinholeCamera camera = PinholeCamera::FromFov(32, 32, 60.0);
  LightField light_field;
  const std::vector<Vec3d> centres = {{-1, -1, 20}, {1, -1, 20}, {-1, 1, 20},
                                      {1, 1, 20},   {0, 0, 20},  {0, 1.5, 20}};
  for (size_t i = 0; i < values.size(); ++i) {
    light_field.views.push_back(MakeView("v" + std::to_string(i), camera,
                                         NadirCamFromWorld(centres[i]),
                                         ConstantImage(32, 32, {values[i]}, type)));
  }
  return light_field;
}

class RobustMean : public ::testing::Test {
 protected:
  RobustMean() {
    options.cam_from_world = NadirCamFromWorld(Vec3d(0, 0, 20));
    options.fov_deg = 30.0;
    options.width = options.height = 12;
    options.num_threads = 1;
  }
  // Renders ConstantViews(values) on the ground's depth; every pixel must have one sample per
  // view and the same value and inlier count, which are returned with the fallback count.
  struct Uniform {
    float value;
    uint32_t inliers;
    int64_t fallback_pixels;
  };
  Uniform Render(const std::vector<float>& values, PixelType type,
                 const SurfaceIntegralOptions& surface) {
    const SurfaceIntegralResult result =
        RenderIntegralOnDepth(ConstantViews(values, type), options, depth, surface);
    const float value = *result.integral.image.At<float>(0, 0);
    const uint32_t inliers = result.inliers.empty() ? 0u : *result.inliers.At<uint32_t>(0, 0);
    for (int y = 0; y < 12; ++y) {
      for (int x = 0; x < 12; ++x) {
        EXPECT_EQ(*result.integral.count.At<uint32_t>(x, y), values.size()) << x << "," << y;
        EXPECT_EQ(*result.integral.image.At<float>(x, y), value) << x << "," << y;
        if (!result.inliers.empty()) EXPECT_EQ(*result.inliers.At<uint32_t>(x, y), inliers);
      }
    }
    return {value, inliers, result.fallback_pixels};
  }
  IntegralOptions options;
  const Image depth = ConstantImage(12, 12, {20.0f});
  static constexpr int64_t kPixels = 12 * 12;
};

TEST_F(RobustMean, RejectsASingleOutlierView) {
  // Five samples of 100 and one of 250: the densest band (2 x 2 % of 255 = 10.2 grey wide)
  // holds the five; their mean is 100 exactly, the plain mean (5 x 100 + 250) / 6 = 125.
  const std::vector<float> values = {100, 100, 100, 250, 100, 100};
  SurfaceIntegralOptions surface;
  const Uniform plain = Render(values, PixelType::kU8, surface);
  EXPECT_EQ(plain.value, 125.0f);
  EXPECT_EQ(plain.fallback_pixels, 0);
  surface.robust = true;
  const Uniform robust = Render(values, PixelType::kU8, surface);
  EXPECT_EQ(robust.value, 100.0f);
  EXPECT_EQ(robust.inliers, 5u);
  EXPECT_EQ(robust.fallback_pixels, 0);
  // The band is a fraction of the views' full range, 1 for float views: 0.04 wide, it holds
  // 0.5, 0.5, 0.5, 0.52 (mean 0.505) and not 0.7 or 0.9 (a 255-based band would hold all six).
  const Uniform float_robust = Render({0.5f, 0.7f, 0.5f, 0.52f, 0.9f, 0.5f}, PixelType::kF32, surface);
  EXPECT_FLOAT_EQ(float_robust.value, static_cast<float>((1.5 + double(0.52f)) / 4.0));
  EXPECT_EQ(float_robust.inliers, 4u);
}

TEST_F(RobustMean, TooFewAgreeingSamplesKeepThePlainMeanAndAreCounted) {
  // 5 of 6 agree: with min_inlier_fraction = 1 that is too few, every pixel keeps the plain mean
  // 125, its inlier count is the sample count, and every pixel is a fallback.
  SurfaceIntegralOptions surface;
  surface.robust = true;
  surface.min_inlier_fraction = 1.0;
  const Uniform strict = Render({100, 100, 100, 250, 100, 100}, PixelType::kU8, surface);
  EXPECT_EQ(strict.value, 125.0f);
  EXPECT_EQ(strict.inliers, 6u);
  EXPECT_EQ(strict.fallback_pixels, kPixels);
}

TEST_F(RobustMean, TheBandIsTwiceTheAgreementWideAndTiesGoToTheLowest) {
  SurfaceIntegralOptions surface;
  surface.robust = true;
  // 100, 104, 108, 109 fit a 10.2-grey band (a band of half that width would hold at most 3,
  // 104..109, and give 107); mean (100 + 104 + 108 + 109) / 4 = 105.25.
  const Uniform spread = Render({100, 200, 104, 250, 108, 109}, PixelType::kU8, surface);
  EXPECT_EQ(spread.value, 105.25f);
  EXPECT_EQ(spread.inliers, 4u);
  // Two groups of three (3 >= 0.5 x 6): the lower band wins the tie.
  const Uniform tie = Render({200, 100, 200, 100, 200, 100}, PixelType::kU8, surface);
  EXPECT_EQ(tie.value, 100.0f);
  EXPECT_EQ(tie.inliers, 3u);
  EXPECT_EQ(tie.fallback_pixels, 0);
  // Six values all more than a band apart: one sample per band, 1 < 0.5 x 6: plain mean.
  const Uniform scattered = Render({10, 40, 70, 100, 130, 160}, PixelType::kU8, surface);
  EXPECT_EQ(scattered.value, 85.0f);
  EXPECT_EQ(scattered.inliers, 6u);
  EXPECT_EQ(scattered.fallback_pixels, kPixels);
}

TEST(RenderIntegralOnDepth, PixelsWithoutAPositiveFiniteDepthAreUncovered) {
  // Views at 40 m look down past the virtual camera at 20 m: they also see the points a depth
  // <= 0 would name (the camera centre, points behind it), so only the depth rule keeps those
  // pixels at count 0.
  static const LightField light_field =
      NadirLightField(test_util::TexturedGround(0.0), PinholeCamera::FromFov(48, 48, 50.0),
                      GridCentres(3, 2.0, 40.0), PixelType::kU8);
  IntegralOptions options;
  options.cam_from_world = NadirCamFromWorld(Vec3d(0, 0, 20));
  options.fov_deg = 30.0;
  options.width = options.height = 16;
  options.num_threads = 1;
  const Image good = ConstantImage(16, 16, {20.0f});
  Image bad = good.Clone();
  const float nan = std::nanf(""), inf = std::numeric_limits<float>::infinity();
  const std::vector<std::pair<int, float>> holes = {{0, 0.0f}, {1, -3.0f}, {2, nan}, {3, inf},
                                                    {4, -inf}, {5, -0.0f}};
  for (const auto& [x, value] : holes) *bad.At<float>(x, 7) = value;
  for (bool robust : {false, true}) {
    SCOPED_TRACE(robust ? "robust" : "plain");
    SurfaceIntegralOptions surface;
    surface.robust = robust;
    const SurfaceIntegralResult reference = RenderIntegralOnDepth(light_field, options, good, surface);
    const SurfaceIntegralResult result = RenderIntegralOnDepth(light_field, options, bad, surface);
    EXPECT_TRUE(AllFinite(result.integral.image, "image"));
    EXPECT_EQ(result.integral.uncovered_pixels, static_cast<int64_t>(holes.size()));
    EXPECT_EQ(reference.integral.uncovered_pixels, 0);
    for (int y = 0; y < 16; ++y) {
      for (int x = 0; x < 16; ++x) {
        const bool hole = y == 7 && x < static_cast<int>(holes.size());
        if (hole) {
          EXPECT_EQ(*result.integral.count.At<uint32_t>(x, y), 0u) << x;
          EXPECT_EQ(*result.integral.image.At<float>(x, y), 0.0f) << x;
          if (robust) EXPECT_EQ(*result.inliers.At<uint32_t>(x, y), 0u) << x;
        } else {
          // Every other pixel is untouched by its neighbours' holes.
          ASSERT_EQ(*result.integral.count.At<uint32_t>(x, y), *reference.integral.count.At<uint32_t>(x, y));
          ASSERT_EQ(*result.integral.image.At<float>(x, y), *reference.integral.image.At<float>(x, y));
        }
      }
    }
  }
  // A depth map of the wrong shape is refused, naming it.
  EXPECT_THAT(ErrorOf([&] { RenderIntegralOnDepth(light_field, options, ConstantImage(15, 16, {20.0f})); }),
              HasSubstr("depth"));
  EXPECT_THAT(ErrorOf([&] { RenderIntegralOnDepth(light_field, options, Image()); }),
              HasSubstr("depth"));
  EXPECT_THAT(ErrorOf([&] {
                RenderIntegralOnDepth(light_field, options, ConstantImage(16, 16, {20.0f, 20.0f}));
              }),
              HasSubstr("depth"));
  SurfaceIntegralOptions bad_surface;
  bad_surface.agreement = -1.0;
  EXPECT_THAT(ErrorOf([&] { RenderIntegralOnDepth(light_field, options, good, bad_surface); }),
              HasSubstr("agreement"));
}

TEST(RenderIntegralOnDepth, NearestModeTiesGoToTheLowerViewIndex) {
  // Two views 1 m either side of the virtual camera at its height: their lines cross the lens
  // plane exactly 1 m from its centre for every focal point, a tie; the lower index (value 10)
  // wins, as in RenderIntegral.
  const PinholeCamera camera = PinholeCamera::FromFov(32, 32, 60.0);
  LightField light_field;
  light_field.views.push_back(MakeView("right", camera, NadirCamFromWorld(Vec3d(1, 0, 20)),
                                       ConstantImage(32, 32, {10.0f})));
  light_field.views.push_back(MakeView("left", camera, NadirCamFromWorld(Vec3d(-1, 0, 20)),
                                       ConstantImage(32, 32, {20.0f})));
  IntegralOptions options;
  options.cam_from_world = NadirCamFromWorld(Vec3d(0, 0, 20));
  options.fov_deg = 30.0;
  options.width = options.height = 8;
  options.aperture_radius = 0.0;
  options.num_threads = 1;
  const SurfaceIntegralResult result =
      RenderIntegralOnDepth(light_field, options, ConstantImage(8, 8, {20.0f}));
  const IntegralResult reference = RenderIntegral(light_field, options);
  for (int y = 0; y < 8; ++y) {
    for (int x = 0; x < 8; ++x) {
      EXPECT_EQ(*result.integral.count.At<uint32_t>(x, y), 1u);
      EXPECT_EQ(*result.integral.image.At<float>(x, y), 10.0f) << x << "," << y;
      EXPECT_EQ(*reference.image.At<float>(x, y), 10.0f) << x << "," << y;
    }
  }
  EXPECT_EQ(result.integral.views_used, 1);
}

TEST(RenderIntegralOnDepth, GrazingIsMeasuredAgainstTheFocalPlaneNormal) {
  // 3 x 3 views 4 m apart at 20 m; focal points on the ground within 0.6 m of the axis. With a
  // vertical focal plane, normal (1, 0, 0), a view's ray makes an angle asin(|dx| / |d|) with
  // that plane: the outer columns (|dx| >= 3.4 m, >= 9.6 deg) pass a 5 deg limit, the middle
  // column (|dx| <= 0.6 m, <= 1.7 deg) does not: 6 of 9 views. The horizontal normal admits all
  // 9, and so does any surface that is not a plane, however steep: its grazing test measures
  // against the horizontal (GrazingNormal: the up axis).
  const LightField light_field =
      NadirLightField(test_util::TexturedGround(0.0), PinholeCamera::FromFov(48, 48, 60.0),
                      GridCentres(3, 4.0, 20.0), PixelType::kU8);
  IntegralOptions options;
  options.cam_from_world = NadirCamFromWorld(Vec3d(0, 0, 20));
  options.fov_deg = 3.0;  // 0.52 m across on the ground
  options.width = options.height = 8;
  options.min_view_angle_deg = 5.0;
  options.num_threads = 1;
  const Image depth = ConstantImage(8, 8, {20.0f});
  const SurfaceIntegralResult level = RenderIntegralOnDepth(light_field, options, depth);
  options.focal_surface = FocalSurface::FromPlane(Plane{Vec3d(0, 0, 0), Vec3d(1, 0, 0)});
  const SurfaceIntegralResult vertical = RenderIntegralOnDepth(light_field, options, depth);
  for (int y = 0; y < 8; ++y) {
    for (int x = 0; x < 8; ++x) {
      EXPECT_EQ(*level.integral.count.At<uint32_t>(x, y), 9u) << x << "," << y;
      EXPECT_EQ(*vertical.integral.count.At<uint32_t>(x, y), 6u) << x << "," << y;
    }
  }
  Mesh steep;  // a wall-like triangle: its own normal is nearly (1, 0, 0)
  steep.vertices = {Vec3d(0, -50, -50), Vec3d(0.1, 50, -50), Vec3d(0, 0, 50)};
  steep.triangles = {{0, 1, 2}};
  options.focal_surface = FocalSurface::FromMesh(steep);
  const SurfaceIntegralResult on_mesh = RenderIntegralOnDepth(light_field, options, depth);
  EXPECT_TRUE(SameImage(on_mesh.integral.count, level.integral.count));
}

TEST(RenderIntegralOnDepth, RobustResultDoesNotDependOnTheThreadCount) {
  const LightField& light_field = SimulatedOccludedGround();
  IntegralOptions options;
  options.cam_from_world = NadirCamFromWorld(Vec3d(0, 0, 20));
  options.fov_deg = 40.0;
  options.width = options.height = 24;
  Image depth = PlaneDepth(VirtualCamera(light_field, options), options.cam_from_world, Plane::AtHeight(0.0));
  SurfaceIntegralOptions surface;
  surface.robust = true;
  options.num_threads = 1;
  const SurfaceIntegralResult one = RenderIntegralOnDepth(light_field, options, depth, surface);
  options.num_threads = 2;
  const SurfaceIntegralResult two = RenderIntegralOnDepth(light_field, options, depth, surface);
  EXPECT_TRUE(SameImage(one.integral.image, two.integral.image));
  EXPECT_TRUE(SameImage(one.integral.count, two.integral.count));
  EXPECT_TRUE(SameImage(one.inliers, two.inliers));
  EXPECT_EQ(one.fallback_pixels, two.fallback_pixels);
}

}  // namespace
}  // namespace aos
