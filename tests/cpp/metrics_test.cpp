// Quality metrics against closed-form values.
#include "aos/metrics/quality.h"

#include <cmath>
#include <cstdlib>
#include <functional>
#include <random>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "aos/util/error.h"
#include "aos/util/progress.h"

namespace aos {
namespace {

using ::testing::HasSubstr;

Image Filled(int width, int height, int channels, PixelType type,
             const std::function<double(int, int, int)>& value) {
  Image image(width, height, channels, type);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      for (int c = 0; c < channels; ++c) {
        const double v = value(x, y, c);
        if (type == PixelType::kU8) image.At<uint8_t>(x, y)[c] = static_cast<uint8_t>(v);
        if (type == PixelType::kU16) image.At<uint16_t>(x, y)[c] = static_cast<uint16_t>(v);
        if (type == PixelType::kF32) image.At<float>(x, y)[c] = static_cast<float>(v);
        if (type == PixelType::kU32) image.At<uint32_t>(x, y)[c] = static_cast<uint32_t>(v);
      }
    }
  }
  return image;
}

Image Textured(int channels, uint32_t seed) {
  std::mt19937 random(seed);
  return Filled(40, 30, channels, PixelType::kU8, [&](int x, int y, int c) {
    return std::fmod(100 + 60 * std::sin(0.3 * x + c) * std::cos(0.2 * y) + random() % 20, 256.0);
  });
}

TEST(Metrics, IdenticalImagesArePerfect) {
  const Image image = Textured(3, 1);
  const QualityResult result = CompareImages(image, image);
  EXPECT_EQ(result.mse, 0.0);
  EXPECT_TRUE(std::isinf(result.psnr_db));
  EXPECT_NEAR(result.ssim, 1.0, 1e-12);
  EXPECT_NEAR(result.color_ssim, 1.0, 1e-12);
  EXPECT_EQ(result.data_range, 255.0);  // from the 8-bit reference
  EXPECT_EQ(result.mse_pixels, 40 * 30);
  EXPECT_EQ(result.ssim_pixels, (40 - 10) * (30 - 10));  // windows of 11 x 11 inside
}

TEST(Metrics, ConstantOffsetGivesClosedFormPsnrAndSsim) {
  // b = a + d with a constant: MSE = d^2, PSNR = 20 log10(255 / d); both images are flat, so
  // variances vanish and SSIM = (2 a b + C1) / (a^2 + b^2 + C1) exactly.
  const double a = 100.0, d = 5.0;
  const Image test = Filled(20, 20, 1, PixelType::kU8, [&](int, int, int) { return a + d; });
  const Image reference = Filled(20, 20, 1, PixelType::kU8, [&](int, int, int) { return a; });
  const QualityResult result = CompareImages(test, reference);
  EXPECT_DOUBLE_EQ(result.mse, d * d);
  EXPECT_NEAR(result.psnr_db, 20.0 * std::log10(255.0 / d), 1e-12);
  const double C1 = std::pow(0.01 * 255.0, 2);
  EXPECT_NEAR(result.ssim, (2 * a * (a + d) + C1) / (a * a + (a + d) * (a + d) + C1), 1e-12);
}

TEST(Metrics, NoiseOfKnownVarianceGivesItsPsnr) {
  // Additive noise uniform in {-s..s}: MSE = s (s + 1) / 3 in expectation.
  std::mt19937 random(5);
  const int s = 6;
  const Image reference = Filled(200, 200, 1, PixelType::kF32, [](int x, int y, int) { return 100.0 + (x + y) % 7; });
  const Image test = Filled(200, 200, 1, PixelType::kF32, [&](int x, int y, int) {
    return 100.0 + (x + y) % 7 + static_cast<int>(random() % (2 * s + 1)) - s;
  });
  QualityOptions options;
  options.data_range = 255.0;
  const QualityResult result = CompareImages(test, reference, nullptr, options);
  const double expected = s * (s + 1) / 3.0;  // 14
  // 40,000 samples of a variance-~190 square error: standard error ~0.07.
  EXPECT_NEAR(result.mse, expected, 0.35);
  EXPECT_LT(result.ssim, 0.9);
}

TEST(Metrics, ColourSsimReducesToSsimForGreyAndSeesColourChanges) {
  const Image grey_a = Textured(1, 2), grey_b = Textured(1, 3);
  const QualityResult grey = CompareImages(grey_a, grey_b);
  EXPECT_EQ(grey.color_ssim, grey.ssim);
  // Three identical channels: the quaternion cross terms vanish and every statistic triples,
  // so the colour SSIM is the grey SSIM with the constants divided by 3 (k / sqrt(3)).
  auto as_rgb = [](const Image& g) {
    return Filled(g.width(), g.height(), 3, PixelType::kU8, [&](int x, int y, int) { return g.Value(x, y); });
  };
  const QualityResult rgb = CompareImages(as_rgb(grey_a), as_rgb(grey_b));
  QualityOptions scaled;
  scaled.k1 = 0.01 / std::sqrt(3.0);
  scaled.k2 = 0.03 / std::sqrt(3.0);
  EXPECT_NEAR(rgb.color_ssim, CompareImages(grey_a, grey_b, nullptr, scaled).ssim, 1e-9);
  EXPECT_NEAR(rgb.ssim, grey.ssim, 1e-12);
  // Swapping two channels keeps every per-channel statistic's distribution but changes colours:
  // the colour SSIM must notice.
  const Image colour = Textured(3, 4);
  const Image swapped = Filled(40, 30, 3, PixelType::kU8, [&](int x, int y, int c) {
    return colour.Value(x, y, c == 0 ? 1 : (c == 1 ? 0 : 2));
  });
  const QualityResult result = CompareImages(swapped, colour);
  EXPECT_LT(result.color_ssim, 0.999);
  EXPECT_GT(result.color_ssim, 0.0);
}

TEST(Metrics, MaskRestrictsTheComparison) {
  // Differences only where the mask is 0 do not count.
  const Image reference = Textured(1, 7);
  Image test = reference.Clone();
  for (int y = 0; y < 30; ++y) *test.At<uint8_t>(0, y) = 0;  // column 0 wrong
  const Image mask = Filled(40, 30, 1, PixelType::kU32, [](int x, int, int) { return x == 0 ? 0 : 3; });
  const QualityResult masked = CompareImages(test, reference, &mask);
  EXPECT_EQ(masked.mse, 0.0);
  EXPECT_EQ(masked.mse_pixels, 39 * 30);
  EXPECT_NEAR(masked.ssim, 1.0, 1e-12);
  EXPECT_GT(CompareImages(test, reference).mse, 0.0);
}

TEST(Metrics, BadInputIsRefused) {
  const Image a = Textured(1, 1), rgb = Textured(3, 1);
  auto error = [](auto&& call) {
    try {
      call();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_THAT(error([&] { CompareImages(a, rgb); }), HasSubstr("40x30x1 but the reference is 40x30x3"));
  const Image empty_mask = Filled(40, 30, 1, PixelType::kU8, [](int, int, int) { return 0; });
  EXPECT_THAT(error([&] { CompareImages(a, a, &empty_mask); }), HasSubstr("mask is empty"));
  QualityOptions options;
  options.gaussian_sigma = 0.0;
  EXPECT_THAT(error([&] { CompareImages(a, a, nullptr, options); }), HasSubstr("gaussian_sigma"));
  Image nan = Filled(40, 30, 1, PixelType::kF32, [](int, int, int) { return 1.0; });
  *nan.At<float>(3, 3) = std::nanf("");
  EXPECT_THAT(error([&] { CompareImages(nan, nan); }), HasSubstr("NaN"));
}

TEST(Metrics, GreyComparesLuminancesAndTheErrorOffersIt) {
  const Image rgb = Textured(3, 11);
  Image grey(rgb.width(), rgb.height(), 1, rgb.type());
  for (int y = 0; y < rgb.height(); ++y) {
    for (int x = 0; x < rgb.width(); ++x) {
      // Rec. 601 luma, computed here independently of LuminanceImage().
      const double luma = 0.299 * rgb.Value(x, y, 0) + 0.587 * rgb.Value(x, y, 1) +
                          0.114 * rgb.Value(x, y, 2);
      if (rgb.type() == PixelType::kF32) {
        *grey.At<float>(x, y) = static_cast<float>(luma);
      } else {
        *grey.At<uint8_t>(x, y) = static_cast<uint8_t>(std::lround(luma));
      }
    }
  }
  QualityOptions options;
  std::string error;
  try {
    CompareImages(grey, rgb, nullptr, options);
  } catch (const std::invalid_argument& e) {
    error = e.what();
  }
  EXPECT_THAT(error, testing::HasSubstr("x1 but the reference is"));
  EXPECT_THAT(error, testing::HasSubstr("set grey (QualityOptions::grey"));
  options.grey = true;
  const QualityResult r = CompareImages(grey, rgb, nullptr, options);
  EXPECT_TRUE(std::isinf(r.psnr_db)) << r.mse;  // the luminance of the reference is the test
  EXPECT_DOUBLE_EQ(r.ssim, 1.0);
  EXPECT_THAT(r.note, testing::HasSubstr("Rec. 601"));
}

// SSIM by its definition, window by window (no OpenCV): the Gaussian weights of an 11 x 11
// window with sigma 1.5, normalised per axis as OpenCV's separable kernel is.
double DirectSsim(const Image& a, const Image& b) {
  const int r = 5;
  std::vector<double> w(2 * r + 1);
  double total = 0.0;
  for (int i = -r; i <= r; ++i) total += w[i + r] = std::exp(-i * i / (2 * 1.5 * 1.5));
  for (double& v : w) v /= total;
  const double C1 = std::pow(0.01 * 255, 2), C2 = std::pow(0.03 * 255, 2);
  double sum = 0.0;
  int64_t n = 0;
  for (int y = r; y < a.height() - r; ++y) {
    for (int x = r; x < a.width() - r; ++x) {
      double ma = 0, mb = 0, aa = 0, bb = 0, ab = 0;
      for (int dy = -r; dy <= r; ++dy) {
        for (int dx = -r; dx <= r; ++dx) {
          const double k = w[dy + r] * w[dx + r];
          const double va = a.Value(x + dx, y + dy), vb = b.Value(x + dx, y + dy);
          ma += k * va;
          mb += k * vb;
          aa += k * va * va;
          bb += k * vb * vb;
          ab += k * va * vb;
        }
      }
      sum += ((2 * ma * mb + C1) * (2 * (ab - ma * mb) + C2)) /
             ((ma * ma + mb * mb + C1) * (aa - ma * ma + bb - mb * mb + C2));
      ++n;
    }
  }
  return sum / static_cast<double>(n);
}

TEST(Metrics, SsimOfATallImageMatchesItsDefinition) {
  // Tall enough that the SSIM is computed in several bands of rows: the bands' seams must not
  // show. The direct sums and OpenCV's separable blur differ by rounding only (~1e-15 each).
  std::mt19937 random(21);
  const Image a = Filled(48, 2600, 1, PixelType::kU8, [&](int, int, int) { return random() % 256; });
  const Image b = Filled(48, 2600, 1, PixelType::kU8, [&](int x, int y, int) {
    return std::min(255.0, a.Value(x, y) * 0.8 + (random() % 40));
  });
  const QualityResult result = CompareImages(b, a);
  EXPECT_EQ(result.ssim_pixels, (48 - 10) * (2600 - 10));
  EXPECT_NEAR(result.ssim, DirectSsim(b, a), 1e-9);
}

// Cancels at the `after`-th poll.
class CancelAfter : public ProgressSink {
 public:
  explicit CancelAfter(int after) : after_(after) {}
  void Start(const std::string&, int64_t total) override { total_ += total; }
  void Advance(int64_t units) override { done_ += units; }
  bool Cancelled() override { return ++polls_ > after_; }
  int polls_ = 0;
  int64_t total_ = 0, done_ = 0;

 private:
  int after_;
};

TEST(Metrics, ComparisonPollsCancellation) {
  const Image a = Filled(300, 3000, 3, PixelType::kU8, [](int x, int y, int c) { return (x * y + c) % 251; });
  CancelAfter never(1 << 30);
  const QualityResult result = CompareImages(a, a, nullptr, {}, &never);
  EXPECT_DOUBLE_EQ(result.ssim, 1.0);
  EXPECT_GE(never.polls_, 6);  // the MSE rows and the SSIM bands are polled
  EXPECT_EQ(never.done_, never.total_);
  for (const int after : {0, 1, 3}) {
    CancelAfter cancel(after);
    EXPECT_THROW(CompareImages(a, a, nullptr, {}, &cancel), Cancelled) << after;
  }
}

TEST(Metrics, WorkingMemoryIsCheckedAgainstTheBudget) {
  const Image a = Filled(2000, 300, 1, PixelType::kU8, [](int x, int y, int) { return (x + y) % 256; });
  EXPECT_GT(CompareImagesWorkingBytes(2000, 300, 1, PixelType::kU8, 1, PixelType::kU8, {}),
            uint64_t{1} << 20);
  ::setenv("AOS_MEMORY_LIMIT_MB", "1", 1);
  std::string error;
  try {
    CompareImages(a, a);
  } catch (const std::invalid_argument& e) {
    error = e.what();
  }
  ::unsetenv("AOS_MEMORY_LIMIT_MB");
  EXPECT_THAT(error, HasSubstr("compare: images of 2000x300x1"));
  EXPECT_THAT(error, HasSubstr("AOS_MEMORY_LIMIT_MB"));
  EXPECT_DOUBLE_EQ(CompareImages(a, a).ssim, 1.0);
}

}  // namespace
}  // namespace aos
