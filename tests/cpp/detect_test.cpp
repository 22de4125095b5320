// Anomaly scores and detections (detect/anomaly.h, detect/detect.h) against analytic truth.
#include <algorithm>
#include <cmath>
#include <array>
#include <random>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "aos/detect/anomaly.h"
#include "aos/detect/detect.h"
#include "error_of.h"
#include "render_test_util.h"

namespace aos {
namespace {

using testing::HasSubstr;
using test_util::ErrorOf;

// A W x H float image of C channels, pixel (x, y) = f(x, y, c).
template <class F>
Image MakeImage(int w, int h, int c, F&& f) {
  Image image(w, h, c, PixelType::kF32);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      for (int k = 0; k < c; ++k) image.At<float>(x, y)[k] = static_cast<float>(f(x, y, k));
    }
  }
  return image;
}

// x = m + L z, z standard normal: a Gaussian background of covariance L L^T; pixel (7, 11) is
// planted at m + L u with |u|^2 = 100, a squared Mahalanobis distance of 100 from the truth.
struct Gaussian {
  static constexpr int kW = 200, kH = 200;
  double m[3] = {100.0, 60.0, 30.0};
  double L[3][3] = {{10.0, 0.0, 0.0}, {4.0, 6.0, 0.0}, {-2.0, 1.0, 3.0}};
  Image image;
  Gaussian() {
    std::mt19937 rng(12345);
    std::normal_distribution<double> normal;
    std::vector<double> z(static_cast<size_t>(kW) * kH * 3);
    for (double& v : z) v = normal(rng);
    const double u[3] = {6.0, 8.0, 0.0};  // |u|^2 = 100
    image = MakeImage(kW, kH, 3, [&](int x, int y, int k) {
      const double* zz = (x == 7 && y == 11) ? u : &z[(static_cast<size_t>(y) * kW + x) * 3];
      double v = m[k];
      for (int j = 0; j < 3; ++j) v += L[k][j] * zz[j];
      return v;
    });
  }
};

// The sample mean and covariance (population) of every pixel, in double, and the squared
// Mahalanobis distance of pixel (7, 11) under them: what classical RX must give.
double ClassicalDistance(const Image& image) {
  const int n = image.width() * image.height();
  double mean[3] = {0, 0, 0}, c[3][3] = {};
  for (int y = 0; y < image.height(); ++y)
    for (int x = 0; x < image.width(); ++x)
      for (int k = 0; k < 3; ++k) mean[k] += image.At<float>(x, y)[k];
  for (double& v : mean) v /= n;
  for (int y = 0; y < image.height(); ++y)
    for (int x = 0; x < image.width(); ++x)
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b)
          c[a][b] += (image.At<float>(x, y)[a] - mean[a]) * (image.At<float>(x, y)[b] - mean[b]) / n;
  // Solve C v = (x - m) by Cramer's rule.
  const double r[3] = {image.At<float>(7, 11)[0] - mean[0], image.At<float>(7, 11)[1] - mean[1],
                       image.At<float>(7, 11)[2] - mean[2]};
  const auto det = [](const double a[3][3]) {
    return a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) -
           a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) +
           a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
  };
  const double d = det(c);
  double v[3];
  for (int k = 0; k < 3; ++k) {
    double ck[3][3];
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) ck[a][b] = b == k ? r[a] : c[a][b];
    v[k] = det(ck) / d;
  }
  return r[0] * v[0] + r[1] * v[1] + r[2] * v[2];
}

// Global RX (the default detector is the local one).
AnomalyOptions Global() {
  AnomalyOptions options;
  options.detector = "rx";
  return options;
}

TEST(Anomaly, ClassicalRxGivesTheSampleMahalanobisDistance) {
  const Gaussian g;
  AnomalyOptions options = Global();
  options.trim_fraction = 0.0;
  options.regularization = 0.0;
  const AnomalyScores scores = ComputeAnomalyScores(g.image, Image(), options);
  ASSERT_EQ(scores.dimensions, 3);
  const double expected = ClassicalDistance(g.image);
  // Float features (7 significant digits) in double sums: 1e-5 relative.
  EXPECT_NEAR(*scores.scores.At<float>(7, 11), expected, 1e-5 * expected);
  // The sample estimate is close to the truth (100) at N = 40000: the planted pixel itself
  // shifts the mean by 1/N of its offset; a few per cent is the sampling spread.
  EXPECT_NEAR(expected, 100.0, 5.0);
}

TEST(Anomaly, RobustRxRecoversTheTrueDistanceAndTheOutlierScoresHighest) {
  Gaussian g;
  // 3 % of the pixels replaced by a cluster three times as far out in the planted pixel's
  // direction (whitened distance 30): classical RX's covariance grows along it (by about
  // 0.03 * 30^2 = 27 in whitened units, so the planted pixel drops to about 100 / 28), the robust
  // estimate's does not.
  const double u3[3] = {18.0, 24.0, 0.0};
  for (int y = 100; y < 200; ++y)
    for (int x = 0; x < 12; ++x)
      for (int k = 0; k < 3; ++k) {
        double v = g.m[k];
        for (int j = 0; j < 3; ++j) v += g.L[k][j] * u3[j];
        g.image.At<float>(x, y)[k] = static_cast<float>(v);
      }
  AnomalyOptions robust = Global();
  const AnomalyScores scores = ComputeAnomalyScores(g.image, Image(), robust);
  // The consistency-corrected, reweighted covariance estimates the truth to about
  // sqrt(2 / N) ~ 0.7 % per element, the mean to 1 / sqrt(N) of a sigma; the planted pixel's
  // distance (100) then to about 2 %: 100 +- 4. Without the consistency factor it would be
  // some 30 % higher, without trimming far lower (below).
  EXPECT_NEAR(*scores.scores.At<float>(7, 11), 100.0, 4.0);
  AnomalyOptions classical = Global();
  classical.trim_fraction = 0.0;
  const AnomalyScores inflated = ComputeAnomalyScores(g.image, Image(), classical);
  EXPECT_LT(*inflated.scores.At<float>(7, 11), 10.0);  // masked by the inflated covariance
}

TEST(Anomaly, ConstantAndRankDeficientImagesScoreFinitely) {
  const Image constant = MakeImage(32, 24, 3, [](int, int, int) { return 42.0; });
  for (const char* detector : {"rx", "rx-local"}) {
    AnomalyOptions options;
    options.detector = detector;
    const AnomalyScores scores = ComputeAnomalyScores(constant, Image(), options);
    for (int y = 0; y < 24; ++y)
      for (int x = 0; x < 32; ++x) EXPECT_EQ(*scores.scores.At<float>(x, y), 0.0f);
    DetectOptions detect;
    std::string rule;
    const double threshold = ResolveThreshold(scores, Image(), detect, &rule);
    EXPECT_TRUE(FindBlobs(scores.scores, Image(), threshold, 1).empty());
  }
  // R = G = B (rank 1) with one bright pixel: finite, the bright one highest.
  const Image grey = MakeImage(32, 24, 3, [](int x, int y, int) {
    return (x == 5 && y == 6) ? 250.0 : 100.0 + ((x * 7 + y * 13) % 11);
  });
  const AnomalyScores scores = ComputeAnomalyScores(grey, Image(), Global());
  float best = -1.0f;
  int best_x = -1, best_y = -1;
  for (int y = 0; y < 24; ++y)
    for (int x = 0; x < 32; ++x) {
      ASSERT_TRUE(std::isfinite(*scores.scores.At<float>(x, y)));
      if (*scores.scores.At<float>(x, y) > best) {
        best = *scores.scores.At<float>(x, y);
        best_x = x;
        best_y = y;
      }
    }
  EXPECT_EQ(best_x, 5);
  EXPECT_EQ(best_y, 6);
}

TEST(Anomaly, LocalRxFindsASmallBumpThatGlobalRxMisses) {
  // Two fields of unit noise, around 0 (left half) and 500 (right half), and a 3 x 3 bump of +8
  // at (50, 40). Globally the two halves dominate the variance (250^2): the bump is an ordinary
  // left-half pixel. Locally (a window inside the left half) it is 8 sigma out: about 64.
  std::mt19937 rng(7);
  std::normal_distribution<double> normal;
  const Image halves = MakeImage(200, 80, 1, [&](int x, int y, int) {
    const double bump = (std::abs(x - 50) <= 1 && std::abs(y - 40) <= 1) ? 8.0 : 0.0;
    return (x < 100 ? 0.0 : 500.0) + normal(rng) + bump;
  });
  AnomalyOptions local;
  local.detector = "rx-local";
  local.inner_window_px = 5;
  local.outer_window_px = 15;
  const AnomalyScores scores = ComputeAnomalyScores(halves, Image(), local);
  EXPECT_GT(*scores.scores.At<float>(50, 40), 30.0f);
  // A threshold of 30 (P(chi2_1 > 30) = 4e-8 per pixel) flags the bump, and the seam between
  // the halves, where a window straddles both.
  std::vector<Detection> blobs = FindBlobs(scores.scores, Image(), 30.0, 4);
  int bumps = 0;
  for (const Detection& d : blobs) {
    const bool bump = std::abs(d.pixel.x - 50.5) < 1.0 && std::abs(d.pixel.y - 40.5) < 1.0;
    bumps += bump ? 1 : 0;
    EXPECT_TRUE(bump || (d.pixel.x > 90.0 && d.pixel.x < 110.0)) << d.pixel.x << ", " << d.pixel.y;
  }
  EXPECT_EQ(bumps, 1);
  const AnomalyScores global = ComputeAnomalyScores(halves, Image(), Global());
  EXPECT_LT(*global.scores.At<float>(50, 40), 2.0f);
}

TEST(Anomaly, LocalRxEqualsABruteForceDualWindowWithClipping) {
  // Two channels of pseudo-noise with a large offset (centring keeps the digits); every pixel's
  // background is the 7 x 7 window minus the 3 x 3 one, clipped by the image: computed here
  // directly, in double, and compared.
  std::mt19937 rng(11);
  std::normal_distribution<double> normal;
  const int w = 20, h = 15;
  const Image image = MakeImage(w, h, 2, [&](int, int, int k) { return 30000.0 + 5.0 * k + normal(rng); });
  AnomalyOptions options;
  options.detector = "rx-local";
  options.inner_window_px = 3;
  options.outer_window_px = 7;
  options.regularization = 0.0;
  const AnomalyScores scores = ComputeAnomalyScores(image, Image(), options);
  int compared = 0;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      double n = 0, m[2] = {0, 0}, c[2][2] = {{0, 0}, {0, 0}};
      std::vector<std::array<double, 2>> ring;
      for (int v = std::max(0, y - 3); v <= std::min(h - 1, y + 3); ++v)
        for (int u = std::max(0, x - 3); u <= std::min(w - 1, x + 3); ++u) {
          if (std::abs(u - x) <= 1 && std::abs(v - y) <= 1) continue;
          ring.push_back({image.At<float>(u, v)[0], image.At<float>(u, v)[1]});
        }
      n = static_cast<double>(ring.size());
      if (n < 0.25 * (49 - 9)) continue;  // the global estimate stands in there
      for (const auto& p : ring) { m[0] += p[0] / n; m[1] += p[1] / n; }
      for (const auto& p : ring)
        for (int a = 0; a < 2; ++a)
          for (int b = 0; b < 2; ++b) c[a][b] += (p[a] - m[a]) * (p[b] - m[b]) / n;
      // anomaly.h's ridge with regularization 0: 1e-12 of the squared scale (here 9e-4: the
      // values are 30000) plus 1e-6 of the global trace / d (about 1e-6, left out: below the
      // tolerance).
      const double trace = c[0][0] + c[1][1];
      const double ridge = 1e-12 * (1.0 + (m[0] * m[0] + m[1] * m[1]) / 2.0 + trace / 2.0);
      c[0][0] += ridge;
      c[1][1] += ridge;
      const double r[2] = {image.At<float>(x, y)[0] - m[0], image.At<float>(x, y)[1] - m[1]};
      const double det = c[0][0] * c[1][1] - c[0][1] * c[1][0];
      const double expected = (c[1][1] * r[0] * r[0] - 2 * c[0][1] * r[0] * r[1] + c[0][0] * r[1] * r[1]) / det;
      // The left-out 1e-6 ridge (1e-6 relative per unit variance) and the float score: 1e-4.
      EXPECT_NEAR(*scores.scores.At<float>(x, y), expected, 1e-4 * expected + 1e-5) << x << ", " << y;
      ++compared;
    }
  }
  EXPECT_GT(compared, w * h / 2);
}

// Anomaly imaging's per-frame scores: the histogram path (8- and 16-bit one-channel frames)
// estimates the same background as ComputeAnomalyScores and quantises its scores to
// kFrameScoreStep. A frame of 400 x 300 pixels (over 65,536: the sample grid is used) with a
// planted warm patch; the expected value is ComputeAnomalyScores' score rounded to the step,
// and the two may differ by one step where a float rounding of the score straddles a rounding
// boundary (ties between values of equal score aside, which these smooth values do not have).
TEST(Anomaly, QuantisedFrameScoresMatchTheGeneralScorerWithinAStep) {
  for (PixelType type : {PixelType::kU8, PixelType::kU16}) {
    const double scale = type == PixelType::kU8 ? 1.0 : 97.0;  // 16 bit: centikelvin-like values
    Image frame(400, 300, 1, type, 1);
    std::mt19937 rng(7);
    std::normal_distribution<double> normal(0.0, 1.0);
    for (int y = 0; y < 300; ++y) {
      for (int x = 0; x < 400; ++x) {
        double v = 120.0 + 9.0 * normal(rng) + (x >= 200 && x < 210 && y >= 100 && y < 112 ? 60.0 : 0.0);
        v = std::clamp(std::round(v * scale), 0.0, type == PixelType::kU8 ? 255.0 : 65535.0);
        if (type == PixelType::kU8) {
          *frame.At<uint8_t>(x, y) = static_cast<uint8_t>(v);
        } else {
          *frame.At<uint16_t>(x, y) = static_cast<uint16_t>(v);
        }
      }
    }
    frame.FillBorder();
    AnomalyOptions options;
    options.detector = "rx";
    const AnomalyScores reference = ComputeAnomalyScores(frame, Image(), options);
    const Image quantised = QuantisedFrameScores(frame, options);
    ASSERT_EQ(quantised.type(), PixelType::kU16);
    ASSERT_EQ(quantised.border(), 1);
    int mismatches = 0;
    double largest = 0.0;
    for (int y = 0; y < 300; ++y) {
      for (int x = 0; x < 400; ++x) {
        const double expected = std::min(
            65535.0, std::floor(*reference.scores.At<float>(x, y) / kFrameScoreStep + 0.5));
        const double got = *quantised.At<uint16_t>(x, y);
        EXPECT_LE(std::abs(got - expected), 1.0) << "pixel " << x << ", " << y;
        mismatches += got != expected;
        largest = std::max(largest, got * kFrameScoreStep);
      }
    }
    EXPECT_LT(mismatches, 400 * 300 / 100);  // rounding-boundary cases only
    EXPECT_GT(largest, 40.0);  // the patch, 60 / 9 sigma: a score near 44
    // The border replicates the edge (the renderer samples it).
    EXPECT_EQ(*quantised.At<uint16_t>(-1, 0), *quantised.At<uint16_t>(0, 0));
  }
  // Other frames (float, RGB) take ComputeAnomalyScores itself: exactly its rounded scores.
  const Gaussian g;
  AnomalyOptions options;
  options.detector = "rx";
  const AnomalyScores reference = ComputeAnomalyScores(g.image, Image(), options);
  const Image quantised = QuantisedFrameScores(g.image, options);
  for (int y = 0; y < Gaussian::kH; y += 7) {
    for (int x = 0; x < Gaussian::kW; x += 7) {
      EXPECT_EQ(*quantised.At<uint16_t>(x, y),
                std::min(65535.0, std::floor(*reference.scores.At<float>(x, y) / kFrameScoreStep + 0.5)));
    }
  }
}

// Anomaly imaging of 8- and 16-bit grey frames integrates every frame's scores in the render's
// own pass (RenderIntegralWithQuadratic, FrameQuadratic); it must agree with the route other
// frames take, each frame's quantised score image (QuantisedFrameScores, tested against
// ComputeAnomalyScores above) rendered apart, within that route's half a quantisation step (the
// mean of values each within half a step) and float rounding. Its integral image must be the
// plain render's. Gently textured ground with a warm square under 3 x 3 nadir views.
TEST(Detect, AnomalyImagingOfGreyFramesIsTheIntegralOfTheFramesScores) {
  SyntheticScene scene;
  scene.layers.push_back(SceneLayer{Plane::AtHeight(0.0), [](const Vec3d& p, float* value) {
    value[0] = static_cast<float>(100.0 + 8.0 * std::sin(2.1 * p.x + 0.4) * std::cos(1.7 * p.y));
    return true;
  }});
  scene.layers.insert(scene.layers.begin(),
                      SceneLayer{Plane::AtHeight(0.01), [](const Vec3d& p, float* value) {
                                   if (std::abs(p.x - 0.7) > 0.6 || std::abs(p.y + 0.4) > 0.6) {
                                     return false;
                                   }
                                   value[0] = 200.0f;
                                   return true;
                                 }});
  for (const auto& [type, one_sided] :
       std::vector<std::pair<PixelType, bool>>{{PixelType::kU8, false}, {PixelType::kU16, false},
                                               {PixelType::kU8, true}, {PixelType::kU16, true}}) {
    const LightField light_field = test_util::NadirLightField(
        scene, PinholeCamera::FromFov(80, 60, 60.0), test_util::GridCentres(3, 1.5, 12.0), type);
    IntegralOptions options;
    options.pose_view = 4;
    options.focal_surface = FocalSurface::FromPlane(Plane::AtHeight(0.0));
    DetectOptions detect;
    detect.detector = "anomaly-imaging";
    detect.min_score = 8.0;
    detect.one_sided = one_sided;
    const DetectResult result = Detect(light_field, options, detect);
    // Every frame's quadratic is its quantised score table's, before rounding.
    for (const View& view : light_field.views) {
      const std::optional<ViewQuadratic> quadratic = FrameQuadratic(view.image, detect);
      ASSERT_TRUE(quadratic.has_value()) << PixelTypeName(type);
      const Image table = QuantisedFrameScores(view.image, detect);
      for (int y = 0; y < table.height(); y += 3) {
        for (int x = 0; x < table.width(); x += 3) {
          double d = view.image.Value(x, y) - quadratic->centre;
          if (quadratic->one_sided) d = std::max(d, 0.0);
          ASSERT_NEAR(quadratic->scale * d * d, *table.At<uint16_t>(x, y) * kFrameScoreStep,
                      0.5 * kFrameScoreStep + 1e-4);
        }
      }
    }
    // The route of other frames.
    LightField quantised = light_field;
    for (View& view : quantised.views) view.image = QuantisedFrameScores(view.image, detect);
    const IntegralResult apart = RenderIntegral(quantised, WithResolvedCamera(light_field, options));
    const IntegralResult plain = RenderIntegral(light_field, options);
    EXPECT_TRUE(test_util::SameImage(result.render.image, plain.image)) << PixelTypeName(type);
    double largest = 0.0, worst = 0.0;
    for (int y = 0; y < apart.image.height(); ++y) {
      for (int x = 0; x < apart.image.width(); ++x) {
        const double want = *apart.image.At<float>(x, y) * kFrameScoreStep;
        const double got = *result.scores.scores.At<float>(x, y);
        largest = std::max(largest, want);
        worst = std::max(worst, std::abs(got - want));
      }
    }
    EXPECT_GT(largest, 20.0) << PixelTypeName(type);  // the warm square
    EXPECT_LE(worst, 0.5 * kFrameScoreStep + 1e-5 * largest) << PixelTypeName(type);
    // The one-pass route ran: the score-image route's means are multiples of step / count
    // where these, exact, mostly are not.
    int off_grid = 0, covered = 0;
    for (int y = 0; y < apart.image.height(); ++y) {
      for (int x = 0; x < apart.image.width(); ++x) {
        const uint32_t n = *result.render.count.At<uint32_t>(x, y);
        const double steps = *result.scores.scores.At<float>(x, y) * n / kFrameScoreStep;
        covered += n > 0;
        off_grid += n > 0 && std::abs(steps - std::round(steps)) > 0.01;
      }
    }
    EXPECT_GT(off_grid, covered / 2) << PixelTypeName(type);
    ASSERT_EQ(result.detections.size(), 1u) << PixelTypeName(type);
    EXPECT_NEAR(result.detections[0].local.x, 0.7, 0.1);
    EXPECT_NEAR(result.detections[0].local.y, -0.4, 0.1);
    // Views out of range or given twice are refused before any frame is scored.
    IntegralOptions bad = options;
    bad.view_indices = {0, 100000000};
    EXPECT_THAT(ErrorOf([&] { Detect(light_field, bad, detect); }), HasSubstr("view_indices"));
    bad.view_indices = {1, 1};
    EXPECT_THAT(ErrorOf([&] { Detect(light_field, bad, detect); }), HasSubstr("view_indices"));
  }
}

TEST(Anomaly, BlobCentroidsWeighTheScoresAboveTheThreshold) {
  Image scores(10, 10, 1, PixelType::kF32);
  for (int y = 0; y < 10; ++y)
    for (int x = 0; x < 10; ++x) *scores.At<float>(x, y) = 0.0f;
  *scores.At<float>(2, 3) = 2.0f;  // weight 2 - 1 = 1
  *scores.At<float>(3, 3) = 4.0f;  // weight 3
  const std::vector<Detection> blobs = FindBlobs(scores, Image(), 1.0, 1);
  ASSERT_EQ(blobs.size(), 1u);
  EXPECT_DOUBLE_EQ(blobs[0].pixel.x, (1.0 * 2.5 + 3.0 * 3.5) / 4.0);
  EXPECT_DOUBLE_EQ(blobs[0].pixel.y, 3.5);
  EXPECT_DOUBLE_EQ(blobs[0].mean_score, 3.0);
}

TEST(Anomaly, BlobsHaveTheirAreaCentroidAndOrder) {
  Image scores(40, 30, 1, PixelType::kF32);
  for (int y = 0; y < 30; ++y)
    for (int x = 0; x < 40; ++x) *scores.At<float>(x, y) = 0.0f;
  for (int y = 5; y < 8; ++y)
    for (int x = 10; x < 14; ++x) *scores.At<float>(x, y) = 5.0f;  // 12 px, peak 5
  for (int y = 20; y < 22; ++y)
    for (int x = 30; x < 32; ++x) *scores.At<float>(x, y) = 9.0f;  // 4 px, peak 9
  *scores.At<float>(0, 0) = 9.0f;                                  // 1 px: below min area
  const std::vector<Detection> blobs = FindBlobs(scores, Image(), 1.0, 2);
  ASSERT_EQ(blobs.size(), 2u);
  EXPECT_EQ(blobs[0].area_px, 4);  // highest peak first
  EXPECT_DOUBLE_EQ(blobs[0].pixel.x, 31.0);
  EXPECT_DOUBLE_EQ(blobs[0].pixel.y, 21.0);
  EXPECT_EQ(blobs[1].area_px, 12);
  EXPECT_DOUBLE_EQ(blobs[1].pixel.x, 12.0);
  EXPECT_DOUBLE_EQ(blobs[1].pixel.y, 6.5);
  EXPECT_EQ(blobs[1].box, (std::array<int, 4>{10, 5, 14, 8}));
}

TEST(Anomaly, ChiSquareQuantileAndOptionErrors) {
  // Two degrees of freedom: P(X > x) = exp(-x / 2).
  EXPECT_NEAR(ChiSquareQuantile(2, std::exp(-5.0)), 10.0, 1e-9);
  DetectOptions options;
  options.false_alarm_rate = 1.5;
  EXPECT_THAT(ErrorOf([&] { options.Check(); }), HasSubstr("false_alarm_rate: must be in (0, 1)"));
  options.false_alarm_rate = 1e-4;
  options.min_score = 10.0;
  EXPECT_THAT(ErrorOf([&] { options.Check(); }),
              HasSubstr("give one threshold rule, not min_score and false_alarm_rate"));
  DetectOptions temperature;
  temperature.detector = "temperature";
  EXPECT_THAT(ErrorOf([&] { temperature.Check(); }), HasSubstr("min_temperature_c: detector"));
  AnomalyOptions windows;
  windows.detector = "rx-local";
  windows.inner_window_px = 9;
  windows.outer_window_px = 9;
  EXPECT_THAT(ErrorOf([&] { windows.Check(); }), HasSubstr("outer_window_px: must be larger"));
  const Image two = MakeImage(8, 8, 2, [](int, int, int) { return 1.0; });
  AnomalyOptions rgb;
  rgb.channels = "rgb";
  EXPECT_THAT(ErrorOf([&] { ComputeAnomalyScores(two, Image(), rgb); }),
              HasSubstr("channels: 'rgb' needs 3 channels"));
  Image nothing(8, 8, 1, PixelType::kF32);
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 8; ++x) *nothing.At<float>(x, y) = std::nanf("");
  EXPECT_THAT(ErrorOf([&] { ComputeAnomalyScores(nothing, Image(), AnomalyOptions()); }),
              HasSubstr("no pixel with a view and finite values"));
}

// robust_sigmas: the covered scores' median plus k x 1.4826 x their median absolute deviation.
// Scores 1..101 (median 51; absolute deviations 0, 1, 1, ..., 50, 50: median 25); the uncovered
// pixel (count 0, score 1000) takes no part. One rule at a time; one-sided anomaly imaging's
// default.
TEST(Detect, RobustSigmasThresholdIsMedianPlusScaledMad) {
  AnomalyScores scores;
  scores.dimensions = 1;
  scores.scores = MakeImage(102, 1, 1, [](int x, int, int) { return x < 101 ? x + 1.0 : 1000.0; });
  Image count(102, 1, 1, PixelType::kU32);
  for (int x = 0; x < 102; ++x) *count.At<uint32_t>(x, 0) = x < 101 ? 1 : 0;
  DetectOptions options;
  options.robust_sigmas = 2.0;
  std::string rule;
  EXPECT_NEAR(ResolveThreshold(scores, count, options, &rule), 51.0 + 2.0 * 1.4826 * 25.0, 1e-9);
  EXPECT_THAT(rule, HasSubstr("robust_sigmas 2 (median 51, MAD 25)"));
  DetectOptions imaging;
  imaging.detector = "anomaly-imaging";
  imaging.one_sided = true;  // its default; two-sided, quantile 0.998
  EXPECT_NEAR(ResolveThreshold(scores, count, imaging, &rule),
              51.0 + kDefaultRobustSigmas * 1.4826 * 25.0, 1e-9);
  imaging.one_sided = false;
  ResolveThreshold(scores, count, imaging, &rule);
  EXPECT_EQ(rule, "quantile 0.998");
  // An even count: the median is the mean of the middle two. Scores 1..100: median 50.5,
  // deviations 0.5, 0.5, 1.5, 1.5, ..., 49.5, 49.5: median 25.
  *count.At<uint32_t>(100, 0) = 0;
  EXPECT_NEAR(ResolveThreshold(scores, count, options, &rule), 50.5 + 2.0 * 1.4826 * 25.0, 1e-9);
  EXPECT_THAT(rule, HasSubstr("(median 50.5, MAD 25)"));
  // No spread (more than half the scores 0, as one-sided scores of a cold scene): the quantile
  // rule stands in, and says so, rather than flagging every score above the median.
  AnomalyScores quiet;
  quiet.dimensions = 1;
  quiet.scores = MakeImage(100, 1, 1, [](int x, int, int) { return x < 60 ? 0.0 : x - 59.0; });
  // Scores 0 (60 times) and 1..40: the 0.998 quantile is the 99th of 100 sorted, 39.
  EXPECT_EQ(ResolveThreshold(quiet, Image(), options, &rule), 39.0);
  EXPECT_THAT(rule, HasSubstr("no spread, so quantile 0.998 instead"));
  options.quantile = 0.99;
  EXPECT_THAT(ErrorOf([&] { options.Check(); }),
              HasSubstr("give one threshold rule, not quantile and robust_sigmas"));
  options.quantile.reset();
  options.robust_sigmas = 0.0;
  EXPECT_THAT(ErrorOf([&] { options.Check(); }), HasSubstr("robust_sigmas: must be a finite"));
}

// one_sided: of one feature, a pixel below the background mean scores 0 and one above it as RX
// scores it. A Gaussian background (mean 100, sigma 10) with a warm (+60) and a cold (-60)
// outlier: two-sided both score about 36; one-sided the warm one only. The quantised frame
// scores follow, and only rx and anomaly imaging take it; RGB is refused.
TEST(Anomaly, OneSidedScoresOnlyValuesAboveTheBackground) {
  std::mt19937 rng(3);
  std::normal_distribution<double> normal(100.0, 10.0);
  const Image grey = MakeImage(120, 100, 1, [&](int x, int y, int) {
    if (x == 10 && y == 20) return 160.0;
    if (x == 90 && y == 70) return 40.0;
    return normal(rng);
  });
  AnomalyOptions both;
  both.detector = "rx";
  AnomalyOptions warm = both;
  warm.one_sided = true;
  const AnomalyScores two = ComputeAnomalyScores(grey, Image(), both);
  const AnomalyScores one = ComputeAnomalyScores(grey, Image(), warm);
  EXPECT_NEAR(*two.scores.At<float>(10, 20), 36.0, 4.0);
  EXPECT_NEAR(*two.scores.At<float>(90, 70), 36.0, 4.0);
  EXPECT_EQ(*one.scores.At<float>(10, 20), *two.scores.At<float>(10, 20));
  EXPECT_EQ(*one.scores.At<float>(90, 70), 0.0f);
  int zeros = 0;
  for (int y = 0; y < 100; ++y) {
    for (int x = 0; x < 120; ++x) {
      const float value = *grey.At<float>(x, y);
      const float expected = value < one.mean[0] ? 0.0f : *two.scores.At<float>(x, y);
      ASSERT_EQ(*one.scores.At<float>(x, y), expected);
      zeros += expected == 0.0f;
    }
  }
  EXPECT_NEAR(zeros, 6000, 400);  // about half the pixels lie below the mean
  // 8-bit frames: the quantised table scores 0 below the mean, as the scorer.
  Image frame(120, 100, 1, PixelType::kU8, 1);
  for (int y = 0; y < 100; ++y) {
    for (int x = 0; x < 120; ++x) {
      *frame.At<uint8_t>(x, y) =
          static_cast<uint8_t>(std::clamp(std::round(*grey.At<float>(x, y)), 0.0f, 255.0f));
    }
  }
  frame.FillBorder();
  const AnomalyScores reference = ComputeAnomalyScores(frame, Image(), warm);
  const Image quantised = QuantisedFrameScores(frame, warm);
  for (int y = 0; y < 100; ++y) {
    for (int x = 0; x < 120; ++x) {
      ASSERT_NEAR(*quantised.At<uint16_t>(x, y) * kFrameScoreStep,
                  *reference.scores.At<float>(x, y), kFrameScoreStep);
    }
  }
  AnomalyOptions local = warm;
  local.detector = "rx-local";
  EXPECT_THAT(ErrorOf([&] { local.Check(); }), HasSubstr("one_sided: detectors rx and"));
  const Gaussian rgb;
  EXPECT_THAT(ErrorOf([&] { ComputeAnomalyScores(rgb.image, Image(), warm); }),
              HasSubstr("one_sided: needs one feature"));
  // Detect refuses it before any render where the frames are RGB.
  LightField colour;
  colour.views.push_back(MakeView("v", PinholeCamera::FromFov(200, 200, 60.0),
                                  NadirCamFromWorld(Vec3d(0, 0, 10)), rgb.image));
  DetectOptions detect;
  detect.detector = "anomaly-imaging";
  detect.one_sided = true;
  IntegralOptions render;
  render.pose_view = 0;
  EXPECT_THAT(ErrorOf([&] { Detect(colour, render, detect); }),
              HasSubstr("one_sided: needs one feature (grey or thermal), got 3"));
}

TEST(Anomaly, TemperatureDetectorScoresDegreesCelsius) {
  const Image kelvin = MakeImage(16, 16, 1, [](int x, int y, int) {
    return (x == 3 && y == 4) ? 30950.0 : 29315.0;  // centikelvin: 36.35 C and 20 C
  });
  DetectOptions options;
  options.detector = "temperature";
  options.min_temperature_c = 30.0;
  const AnomalyScores scores =
      ComputeAnomalyScores(kelvin, Image(), options, Radiometry{0.01, 0.0});
  EXPECT_NEAR(*scores.scores.At<float>(3, 4), 36.35, 1e-4);
  EXPECT_NEAR(*scores.scores.At<float>(0, 0), 20.0, 1e-4);
  std::string rule;
  const double threshold = ResolveThreshold(scores, Image(), options, &rule);
  EXPECT_EQ(threshold, 30.0);
  EXPECT_EQ(FindBlobs(scores.scores, Image(), threshold, 1).size(), 1u);
  EXPECT_THAT(ErrorOf([&] { ComputeAnomalyScores(kelvin, Image(), options); }),
              HasSubstr("needs a radiometric light field"));
}

}  // namespace
}  // namespace aos
