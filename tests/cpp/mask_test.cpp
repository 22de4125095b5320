// Masks (lightfield/mask.h) and the renderer's division by the mask weight
// (render/masked_mean.h), against hand-computed values. The end-to-end tests (a letterbox
// painted into frames, against a numpy per-pixel reference) are tests/python/test_masks.py.
#include "aos/lightfield/mask.h"

#include <string>
#include <utility>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "error_of.h"
#include "temp_folder.h"

#include "aos/image/image_io.h"
#include "aos/render/integral_kernels.h"
#include "aos/render/masked_mean.h"

namespace aos {
namespace {

using ::testing::HasSubstr;
using test_util::ErrorOf;

class MaskTest : public testing_util::TempFolderTest {};

Image Filled(int width, int height, int channels, PixelType type,
             std::initializer_list<double> values) {
  Image image(width, height, channels, type);
  auto it = values.begin();
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      for (int c = 0; c < channels; ++c, ++it) {
        if (type == PixelType::kU8) image.At<uint8_t>(x, y)[c] = static_cast<uint8_t>(*it);
        if (type == PixelType::kU16) image.At<uint16_t>(x, y)[c] = static_cast<uint16_t>(*it);
        if (type == PixelType::kF32) image.At<float>(x, y)[c] = static_cast<float>(*it);
      }
    }
  }
  return image;
}

TEST_F(MaskTest, NonZeroColourIsValidAlphaIgnored) {
  // RGBA: pixel 0 black with alpha 255 (masked), pixel 1 blue only (valid), pixel 2 grey.
  WriteImage(Path("mask.png"),
             Filled(3, 1, 4, PixelType::kU8, {0, 0, 0, 255, 0, 0, 1, 0, 9, 9, 9, 255}));
  const Image valid = ReadMask(Path("mask.png"));
  ASSERT_EQ(valid.channels(), 1);
  EXPECT_EQ(valid.Value(0, 0), 0);
  EXPECT_EQ(valid.Value(1, 0), 1);
  EXPECT_EQ(valid.Value(2, 0), 1);
  EXPECT_EQ(CountValid(valid), 2);
  EXPECT_THAT(ErrorOf([&] { ReadMask(Path("missing.png")); }), HasSubstr("missing.png"));
}

TEST_F(MaskTest, PremultipliesAndAppendsTheWeight) {
  const Image valid = Filled(2, 1, 1, PixelType::kU8, {1, 0});
  const Image rgb16 = Filled(2, 1, 3, PixelType::kU16, {100, 200, 300, 400, 500, 600});
  const Image masked = ApplyMask(rgb16, valid, "m.png", "view 0");
  ASSERT_EQ(masked.channels(), 4);
  EXPECT_EQ(masked.type(), PixelType::kU16);
  EXPECT_GE(masked.border(), 1);
  const double expected[2][4] = {{100, 200, 300, 65535}, {0, 0, 0, 0}};
  for (int x = 0; x < 2; ++x) {
    for (int c = 0; c < 4; ++c) EXPECT_EQ(masked.Value(x, 0, c), expected[x][c]) << x << c;
  }
  // The border replicates the edge (bilinear taps at the image edge).
  EXPECT_EQ(masked.Value(-1, 0, 3), 65535);
  EXPECT_EQ(masked.Value(2, 0, 3), 0);
  const Image grey_float = Filled(2, 1, 1, PixelType::kF32, {0.25, 0.5});
  const Image masked_float = ApplyMask(grey_float, valid, "m.png", "view 0");
  EXPECT_EQ(masked_float.Value(0, 0, 1), 1.0);  // float frames: weight 1
  EXPECT_EQ(masked_float.Value(1, 0, 0), 0.0);
}

TEST_F(MaskTest, RefusesRgbaFramesAndOtherSizes) {
  const Image valid = Filled(2, 1, 1, PixelType::kU8, {1, 1});
  EXPECT_THAT(ErrorOf([&] { ApplyMask(Image(2, 1, 4, PixelType::kU8), valid, "m.png", "view 3"); }),
              HasSubstr("view 3: mask: the frame has 4 channels"));
  EXPECT_THAT(ErrorOf([&] { ApplyMask(Image(3, 2, 1, PixelType::kU8), valid, "m.png", "view 3"); }),
              HasSubstr("view 3: mask m.png is 2x1 but the frame is 3x2"));
}

TEST(MaskedMean, DividesCountsAndKeepsTheRenderersMaskedVariance) {
  // Pixel 0: four 8-bit samples of one channel, premultiplied: (10, 255), (20, 255),
  // (30, 255), (0, 0) (masked). The renderer's sums: 60 and 765, the value channel's squares
  // 100 + 400 + 900; its means 60/4 = 15 and 765/4 = 191.25. Pixel 1: two samples, both masked.
  // Pixel 2: no sample.
  const double sums[2] = {60.0, 765.0};
  const double variance = internal::MaskedVariance(sums, 1400.0, 2, 255.0);
  EXPECT_DOUBLE_EQ(variance, 200.0 / 3.0);  // the population variance of 10, 20, 30
  const double nothing[2] = {0.0, 0.0};
  EXPECT_EQ(internal::MaskedVariance(nothing, 0.0, 2, 255.0), 0.0);
  // 16-bit samples near the top of the range: equal ones give exactly 0, 60000 +- 1 exactly 1.
  const double equal[2] = {3 * 60000.0, 3 * 65535.0};
  EXPECT_EQ(internal::MaskedVariance(equal, 3 * 60000.0 * 60000.0, 2, 65535.0), 0.0);
  const double spread[2] = {4 * 60000.0, 4 * 65535.0};
  EXPECT_EQ(internal::MaskedVariance(spread, 2 * 59999.0 * 59999.0 + 2 * 60001.0 * 60001.0, 2,
                                     65535.0),
            1.0);
  IntegralResult result;
  result.image = Filled(3, 1, 2, PixelType::kF32, {15, 191.25, 0, 0, 0, 0});
  result.count = Image(3, 1, 1, PixelType::kU32);
  result.count.At<uint32_t>(0, 0)[0] = 4;
  result.count.At<uint32_t>(1, 0)[0] = 2;
  result.variance = Filled(3, 1, 1, PixelType::kF32, {variance, 0, 0});
  internal::DivideByMaskWeight(result, 255.0);
  ASSERT_EQ(result.image.channels(), 1);
  // The mean, count and population variance of the valid samples 10, 20, 30.
  EXPECT_NEAR(result.image.Value(0, 0), 20.0, 1e-5);
  EXPECT_EQ(result.count.Value(0, 0), 3);
  EXPECT_FLOAT_EQ(result.variance.Value(0, 0), 200.0 / 3.0);
  for (int x = 1; x < 3; ++x) {
    EXPECT_EQ(result.image.Value(x, 0), 0.0);
    EXPECT_EQ(result.count.Value(x, 0), 0);
    EXPECT_EQ(result.variance.Value(x, 0), 0.0);
  }
  EXPECT_EQ(result.samples, 3);
  EXPECT_EQ(result.uncovered_pixels, 2);
}

TEST(MaskedMean, RefusesAnImageWithoutAWeightChannel) {
  IntegralResult result;
  result.image = Image(1, 1, 1, PixelType::kF32);
  result.count = Image(1, 1, 1, PixelType::kU32);
  EXPECT_THAT(ErrorOf([&] { internal::DivideByMaskWeight(result, 255.0); }),
              HasSubstr("weight channel"));
}

TEST(MaskedMean, TwoChannel8BitSpanKernelMatchesTheScalarOne) {
  // Masked grey frames (2 channels, 8-bit) have their own AVX2 kernel; it samples as the scalar
  // reference, up to float rounding (values <= 255: 1e-3).
  Image image(37, 23, 2, PixelType::kU8, 1);
  for (int y = 0; y < 23; ++y) {
    for (int x = 0; x < 37; ++x) {
      image.At<uint8_t>(x, y)[0] = static_cast<uint8_t>((x * 37 + y * 91) % 251);
      image.At<uint8_t>(x, y)[1] = static_cast<uint8_t>(((x + y) % 3) ? 255 : 0);
    }
  }
  image.FillBorder();
  const internal::SpanKernel simd = internal::Avx2SpanKernel(image);
  if (simd == nullptr) GTEST_SKIP() << "no AVX2 on this CPU";
  const internal::RowLine line{0.7, 0.83, 3.2, 0.31, 1.0, 0.001};
  for (const auto& [xa, xb] : {std::pair{3, 29}, std::pair{0, 8}, std::pair{5, 6}}) {
    std::vector<double> fast(2 * 40 + internal::kSpanPadding, 0.0), slow = fast;
    simd(image, line, xa, xb, 0, fast.data());
    internal::ScalarSpanKernel(image)(image, line, xa, xb, 0, slow.data());
    for (size_t i = 0; i < fast.size(); ++i) EXPECT_NEAR(fast[i], slow[i], 1e-3) << i;
  }
}

}  // namespace
}  // namespace aos
