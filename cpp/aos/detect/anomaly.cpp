#include "aos/detect/anomaly.h"

#include <algorithm>
#include <boost/math/distributions/chi_squared.hpp>
#include <cmath>
#include <numeric>
#include <type_traits>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "aos/util/error.h"
#include "aos/util/memory.h"
#include "aos/util/parallel.h"

namespace aos {
namespace {

// The most pixels the background statistics are estimated from (see ComputeAnomalyScores).
constexpr double kMaxBackgroundSamples = 65536.0;

// The background sample's grid step for an image of `pixels` pixels that take part: at most
// kMaxBackgroundSamples on the grid.
int SampleStep(int64_t pixels) {
  return std::max(1, static_cast<int>(std::ceil(std::sqrt(static_cast<double>(pixels) /
                                                          kMaxBackgroundSamples))));
}

// Per-pixel features, row-major, `d` floats each; valid[i] marks the pixels that take part.
struct Features {
  int width = 0, height = 0, d = 0;
  std::vector<float> values;
  std::vector<uint8_t> valid;
  int64_t count = 0;
  const float* At(size_t i) const { return values.data() + i * static_cast<size_t>(d); }
};

int FeatureCount(const std::string& channels, int image_channels, const std::string& detector) {
  if (detector == "temperature") return 1;
  if (channels == "auto") return image_channels;
  if (channels == "grey") return 1;
  if (channels == "rgb+thermal") return 4;
  return 3;  // rgb, hsv
}

Features MakeFeatures(const Image& image, const Image& count, const AnomalyOptions& options,
                      const std::optional<Radiometry>& radiometry) {
  const int c = image.channels();
  const std::string& choice = options.channels;
  if (options.detector == "temperature") {
    if (!radiometry) {
      ThrowInvalid("detector: 'temperature' needs a radiometric light field (its radiometry: "
                   "kelvin per unit of value)");
    }
    if (c != 1) {
      ThrowInvalid("detector: 'temperature' needs one channel of temperatures, the image has " +
                   std::to_string(c));
    }
  } else if ((choice == "grey" || choice == "rgb" || choice == "hsv") && c < 3) {
    ThrowInvalid("channels: '" + choice + "' needs 3 channels (RGB), the image has " +
                 std::to_string(c));
  } else if (choice == "rgb+thermal" && c < 4) {
    ThrowInvalid("channels: 'rgb+thermal' needs 4 channels (RGB and thermal), the image has " +
                 std::to_string(c));
  }
  if (c < 1 || c > 8) ThrowInvalid("channels: the image has " + std::to_string(c) + " channels");
  if (!count.empty() &&
      (count.width() != image.width() || count.height() != image.height() || count.channels() != 1 ||
       count.type() != PixelType::kU32)) {
    ThrowInvalid("count: must be uint32, one channel, the image's size");
  }
  Features f;
  f.width = image.width();
  f.height = image.height();
  f.d = FeatureCount(choice, c, options.detector);
  const size_t n = static_cast<size_t>(f.width) * static_cast<size_t>(f.height);
  f.values.assign(n * static_cast<size_t>(f.d), 0.0f);
  f.valid.assign(n, 0);
  // HSV needs values in [0, 1]: the image's largest finite value (uncovered pixels are 0 in a
  // render; the Mahalanobis distance does not change with V's scale, a linear map of the
  // features).
  double scale = 1.0;
  if (choice == "hsv") {
    double largest = 0.0;
    for (int y = 0; y < f.height; ++y) {
      for (int x = 0; x < f.width; ++x) {
        for (int k = 0; k < 3; ++k) {
          const double v = image.Value(x, y, k);
          if (std::isfinite(v)) largest = std::max(largest, v);
        }
      }
    }
    scale = largest > 0.0 ? 1.0 / largest : 1.0;
  }
  // One pixel's channels as doubles, by the image's type (no per-sample dispatch).
  const auto read_pixel = [&](int x, int y, double* v) {
    const auto copy = [&](const auto* p) {
      for (int k = 0; k < c; ++k) v[k] = p[k];
    };
    switch (image.type()) {
      case PixelType::kU8: copy(image.At<uint8_t>(x, y)); break;
      case PixelType::kU16: copy(image.At<uint16_t>(x, y)); break;
      case PixelType::kU32: copy(image.At<uint32_t>(x, y)); break;
      case PixelType::kF32: copy(image.At<float>(x, y)); break;
    }
  };
  // The choice, decided once (not per pixel).
  enum class Mode { kTemperature, kCopy, kGrey, kHsv };
  const Mode mode = options.detector == "temperature" ? Mode::kTemperature
                    : choice == "grey"                ? Mode::kGrey
                    : choice == "hsv"                 ? Mode::kHsv
                                                      : Mode::kCopy;  // auto, rgb, rgb+thermal
  // HSV of the whole image at once (OpenCV: H in degrees, S and V in [0, 1]).
  cv::Mat hsv;
  if (mode == Mode::kHsv) {
    cv::Mat rgb(f.height, f.width, CV_32FC3);
    for (int y = 0; y < f.height; ++y) {
      for (int x = 0; x < f.width; ++x) {
        double v[8];
        read_pixel(x, y, v);
        cv::Vec3f& out = rgb.at<cv::Vec3f>(y, x);
        for (int k = 0; k < 3; ++k) {
          out[k] = std::isfinite(v[k]) ? static_cast<float>(std::clamp(v[k] * scale, 0.0, 1.0))
                                       : 0.0f;
        }
      }
    }
    cv::cvtColor(rgb, hsv, cv::COLOR_RGB2HSV);
  }
  for (int y = 0; y < f.height; ++y) {
    const uint32_t* counts = count.empty() ? nullptr : count.At<uint32_t>(0, y);
    for (int x = 0; x < f.width; ++x) {
      const size_t i = static_cast<size_t>(y) * f.width + x;
      if (counts != nullptr && counts[x] == 0) continue;
      float* out = f.values.data() + i * static_cast<size_t>(f.d);
      double v[8];
      bool finite = true;
      read_pixel(x, y, v);
      for (int k = 0; k < c; ++k) finite = finite && std::isfinite(v[k]);
      if (!finite) continue;
      switch (mode) {
        case Mode::kTemperature:
          out[0] = static_cast<float>(radiometry->Celsius(v[0]));
          break;
        case Mode::kCopy:
          for (int k = 0; k < f.d; ++k) out[k] = static_cast<float>(v[k]);
          break;
        case Mode::kGrey:
          out[0] = static_cast<float>(0.299 * v[0] + 0.587 * v[1] + 0.114 * v[2]);
          break;
        case Mode::kHsv: {
          const cv::Vec3f h = hsv.at<cv::Vec3f>(y, x);
          const double hue = h[0] * M_PI / 180.0;
          out[0] = static_cast<float>(h[1] * std::cos(hue));
          out[1] = static_cast<float>(h[1] * std::sin(hue));
          out[2] = h[2];
          break;
        }
      }
      f.valid[i] = 1;
      ++f.count;
    }
  }
  if (f.count == 0) {
    ThrowInvalid("image: no pixel with a view and finite values: nothing to score");
  }
  return f;
}

// The points the background is estimated from: d floats each, with weights (empty = 1 each):
// sampled pixels' features, or a histogram's values and counts.
struct WeightedPoints {
  int d = 0;
  std::vector<float> values;    // n x d
  std::vector<double> weights;  // n, or empty
  size_t size() const { return values.size() / static_cast<size_t>(d); }
  double Weight(size_t i) const { return weights.empty() ? 1.0 : weights[i]; }
  const float* At(size_t i) const { return values.data() + i * static_cast<size_t>(d); }
};

// Weighted mean and covariance (population) of the points listed in `subset` with their weights
// scaled by `share` (1 where share is empty: the last kept point may count in part).
void MeanCovariance(const WeightedPoints& p, const std::vector<size_t>& subset,
                    const std::vector<double>& share, std::vector<double>* mean,
                    std::vector<double>* covariance) {
  const int d = p.d;
  mean->assign(d, 0.0);
  covariance->assign(static_cast<size_t>(d) * d, 0.0);
  double n = 0.0;
  const auto weight = [&](size_t k) {
    return p.Weight(subset[k]) * (share.empty() ? 1.0 : share[k]);
  };
  for (size_t k = 0; k < subset.size(); ++k) {
    const float* x = p.At(subset[k]);
    const double w = weight(k);
    for (int a = 0; a < d; ++a) (*mean)[a] += w * x[a];
    n += w;
  }
  for (double& m : *mean) m /= n;
  for (size_t k = 0; k < subset.size(); ++k) {
    const float* x = p.At(subset[k]);
    const double w = weight(k);
    double centred[8];
    for (int a = 0; a < d; ++a) centred[a] = x[a] - (*mean)[a];
    for (int a = 0; a < d; ++a) {
      for (int b = a; b < d; ++b) (*covariance)[a * d + b] += w * centred[a] * centred[b];
    }
  }
  for (int a = 0; a < d; ++a) {
    for (int b = a; b < d; ++b) {
      (*covariance)[a * d + b] /= n;
      (*covariance)[b * d + a] = (*covariance)[a * d + b];
    }
  }
}

double Trace(const std::vector<double>& covariance, int d) {
  double trace = 0.0;
  for (int k = 0; k < d; ++k) trace += covariance[k * d + k];
  return trace;
}

// The ridge of the contract: regularization * trace / d, plus a floor of 1e-12 of the features'
// squared scale.
double Ridge(double regularization, double trace, const std::vector<double>& mean, int d) {
  double scale = 0.0;
  for (double m : mean) scale += m * m;
  return regularization * trace / d + 1e-12 * (1.0 + scale / d + trace / d);
}

// (C + l I)^-1, d x d row-major, by OpenCV's SVD (well defined for any symmetric C, l > 0).
std::vector<double> RegularisedInverse(const std::vector<double>& covariance, int d, double ridge) {
  cv::Mat c(d, d, CV_64F);
  for (int a = 0; a < d; ++a) {
    for (int b = 0; b < d; ++b) c.at<double>(a, b) = covariance[a * d + b] + (a == b ? ridge : 0.0);
  }
  cv::Mat inverse;
  cv::invert(c, inverse, cv::DECOMP_SVD);
  std::vector<double> out(static_cast<size_t>(d) * d);
  for (int a = 0; a < d; ++a) {
    for (int b = 0; b < d; ++b) out[a * d + b] = inverse.at<double>(a, b);
  }
  return out;
}

double Mahalanobis2(const float* x, const double* mean, const double* inverse, int d) {
  double centred[8];
  for (int k = 0; k < d; ++k) centred[k] = x[k] - mean[k];
  double sum = 0.0;
  for (int a = 0; a < d; ++a) {
    double row = 0.0;
    for (int b = 0; b < d; ++b) row += inverse[a * d + b] * centred[b];
    sum += centred[a] * row;
  }
  return std::max(0.0, sum);
}

// (x - m)^T (C + l I)^-1 (x - m) by a Cholesky factorisation of C + l I (d <= 8); -1 when it
// is not positive definite (the caller falls back to the global estimate).
double CholeskyMahalanobis2(const float* x, const double* mean, const double* covariance,
                            double ridge, int d) {
  double a[8][8], y[8];
  for (int i = 0; i < d; ++i) {
    for (int j = 0; j <= i; ++j) {
      double sum = covariance[i * d + j] + (i == j ? ridge : 0.0);
      for (int k = 0; k < j; ++k) sum -= a[i][k] * a[j][k];
      if (i == j) {
        if (!(sum > 0.0)) return -1.0;
        a[i][i] = std::sqrt(sum);
      } else {
        a[i][j] = sum / a[j][j];
      }
    }
  }
  double total = 0.0;
  for (int i = 0; i < d; ++i) {
    double sum = x[i] - mean[i];
    for (int k = 0; k < i; ++k) sum -= a[i][k] * y[k];
    y[i] = sum / a[i][i];
    total += y[i] * y[i];
  }
  return total;
}

// The global background (mean, covariance, and the inverse scores use) of `points` by the
// contract's robust estimate: concentration steps keeping the (1 - t) share of the weight with the
// smallest scores (the last point kept in part), the consistency factor, and the reweighting.
struct Background {
  std::vector<double> mean, covariance, inverse;
};
Background EstimateBackground(const WeightedPoints& points, const AnomalyOptions& options) {
  const int d = points.d;
  Background bg;
  std::vector<size_t> all(points.size());
  std::iota(all.begin(), all.end(), size_t{0});
  double total = 0.0;
  for (size_t i : all) total += points.Weight(i);
  const auto refit = [&](const std::vector<size_t>& subset, const std::vector<double>& share,
                         double consistency) {
    MeanCovariance(points, subset, share, &bg.mean, &bg.covariance);
    for (double& c : bg.covariance) c *= consistency;
    bg.inverse = RegularisedInverse(
        bg.covariance, d, Ridge(options.regularization, Trace(bg.covariance, d), bg.mean, d));
  };
  refit(all, {}, 1.0);
  const double t = options.trim_fraction;
  const double keep = std::max(static_cast<double>(d) + 1.0, std::ceil((1.0 - t) * total));
  if (!(t > 0.0 && options.robust_iterations > 0 && keep < total)) return bg;
  const boost::math::chi_squared chi_d(d), chi_d2(d + 2);
  const double q = boost::math::quantile(chi_d, 1.0 - t);
  const double consistency = (1.0 - t) / boost::math::cdf(chi_d2, q);
  const bool unit = points.weights.empty();
  for (int iteration = 0; iteration < options.robust_iterations; ++iteration) {
    std::vector<std::pair<double, size_t>> ranked;
    ranked.reserve(all.size());
    for (size_t i : all) {
      ranked.emplace_back(Mahalanobis2(points.At(i), bg.mean.data(), bg.inverse.data(), d), i);
    }
    std::vector<size_t> kept;
    std::vector<double> share;
    if (unit) {  // every point weighs 1: the `keep` smallest, by selection
      const size_t k = static_cast<size_t>(keep);
      std::nth_element(ranked.begin(), ranked.begin() + static_cast<std::ptrdiff_t>(k - 1),
                       ranked.end());
      for (size_t j = 0; j < k; ++j) kept.push_back(ranked[j].second);
    } else {  // in score order until the weight `keep` is reached, the last point in part
      std::sort(ranked.begin(), ranked.end());
      double sum = 0.0;
      for (const auto& [score, i] : ranked) {
        const double w = points.Weight(i);
        if (w <= 0.0) continue;
        kept.push_back(i);
        share.push_back(std::min(1.0, (keep - sum) / w));
        sum += w;
        if (sum >= keep) break;
      }
    }
    refit(kept, share, consistency);
  }
  // Reweighting (as FastMCD ends): the points within the 97.5 % quantile of chi2_d under the raw
  // estimate, whatever the contamination was, give the final one.
  const double cut = boost::math::quantile(chi_d, 0.975);
  const double reweighted = 0.975 / boost::math::cdf(chi_d2, cut);
  std::vector<size_t> inliers;
  double inlier_weight = 0.0;
  for (size_t i : all) {
    if (Mahalanobis2(points.At(i), bg.mean.data(), bg.inverse.data(), d) <= cut) {
      inliers.push_back(i);
      inlier_weight += points.Weight(i);
    }
  }
  if (inlier_weight > static_cast<double>(d) + 1.0) refit(inliers, {}, reweighted);
  return bg;
}

void ScoreAll(const Features& f, const std::vector<double>& mean, const std::vector<double>& inverse,
              std::vector<double>* scores) {
  scores->assign(f.valid.size(), 0.0);
  for (size_t i = 0; i < f.valid.size(); ++i) {
    if (f.valid[i]) (*scores)[i] = Mahalanobis2(f.At(i), mean.data(), inverse.data(), f.d);
  }
}

// Local RX: box sums of x and x x^T over the outer window minus the inner one.
void LocalScores(const Features& f, const AnomalyOptions& options, double global_trace,
                 const std::vector<double>& global_mean, const std::vector<double>& global_inverse,
                 int num_threads, std::vector<double>* scores) {
  const int d = f.d, w = f.width, h = f.height;
  const int pairs = d * (d + 1) / 2;
  // Integral images (double) of 1 (valid), y_k and y_a y_b with y = x - the global mean: centred,
  // the sums of large uncentred values (centikelvin, big maps) keep the local variance's digits.
  const std::vector<double>& g = global_mean;
  std::vector<cv::Mat> sums;
  const auto integral_of = [&](auto&& value) {
    cv::Mat plane(h, w, CV_64F);
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        const size_t i = static_cast<size_t>(y) * w + x;
        plane.at<double>(y, x) = f.valid[i] ? value(f.At(i)) : 0.0;
      }
    }
    cv::Mat integral;
    cv::integral(plane, integral, CV_64F);
    sums.push_back(integral);
  };
  integral_of([](const float*) { return 1.0; });
  for (int k = 0; k < d; ++k) {
    integral_of([k, &g](const float* x) { return static_cast<double>(x[k]) - g[k]; });
  }
  for (int a = 0; a < d; ++a) {
    for (int b = a; b < d; ++b) {
      integral_of([a, b, &g](const float* x) {
        return (static_cast<double>(x[a]) - g[a]) * (static_cast<double>(x[b]) - g[b]);
      });
    }
  }
  // Local statistics need a quarter of the nominal background ring (a window clipped by the
  // image or by uncovered pixels beyond that holds too few pixels for a covariance whose scores
  // follow chi-square); below it the global estimate stands in.
  const double nominal = static_cast<double>(options.outer_window_px) * options.outer_window_px -
                         static_cast<double>(options.inner_window_px) * options.inner_window_px;
  const double least = std::max(2.0 * d + 1.0, 0.25 * nominal);
  const int outer = options.outer_window_px / 2, inner = options.inner_window_px / 2;
  const auto box = [&](const cv::Mat& s, int x, int y, int r) {
    const int x0 = std::max(0, x - r), y0 = std::max(0, y - r);
    const int x1 = std::min(w, x + r + 1), y1 = std::min(h, y + r + 1);
    return s.at<double>(y1, x1) - s.at<double>(y0, x1) - s.at<double>(y1, x0) + s.at<double>(y0, x0);
  };
  scores->assign(f.valid.size(), 0.0);
  // Rows in parallel (each pixel's score depends on the integral images only).
  ParallelFor(h, num_threads, nullptr, [&](int64_t row) {
    const int y = static_cast<int>(row);
    std::vector<double> mean(d), covariance(static_cast<size_t>(d) * d);
    std::vector<double> values(1 + d + pairs);
    for (int x = 0; x < w; ++x) {
      const size_t i = static_cast<size_t>(y) * w + x;
      if (!f.valid[i]) continue;
      for (size_t k = 0; k < values.size(); ++k) {
        values[k] = box(sums[k], x, y, outer) - box(sums[k], x, y, inner);
      }
      const double n = values[0];
      if (n < least) {
        (*scores)[i] = Mahalanobis2(f.At(i), global_mean.data(), global_inverse.data(), d);
        continue;
      }
      double centred_mean[8];
      for (int k = 0; k < d; ++k) centred_mean[k] = values[1 + k] / n;
      int p = 0;
      for (int a = 0; a < d; ++a) {
        for (int b = a; b < d; ++b, ++p) {
          const double c = values[1 + d + p] / n - centred_mean[a] * centred_mean[b];
          covariance[a * d + b] = c;
          covariance[b * d + a] = c;
        }
      }
      for (int k = 0; k < d; ++k) mean[k] = centred_mean[k] + g[k];
      // The local ridge, plus a millionth of the global scale: a flat window stays invertible.
      const double ridge = Ridge(options.regularization, Trace(covariance, d), mean, d) +
                           1e-6 * global_trace / d;
      const double score = CholeskyMahalanobis2(f.At(i), mean.data(), covariance.data(), ridge, d);
      (*scores)[i] = score >= 0.0
                         ? score
                         : Mahalanobis2(f.At(i), global_mean.data(), global_inverse.data(), d);
    }
  });
}

}  // namespace

void AnomalyOptions::Check() const {
  CheckFieldRanges(*this);
  if (inner_window_px % 2 == 0 || outer_window_px % 2 == 0) {
    ThrowInvalid("inner_window_px, outer_window_px: must be odd (a window centred on its pixel), "
                 "got " + std::to_string(inner_window_px) + " and " +
                 std::to_string(outer_window_px));
  }
  if (outer_window_px <= inner_window_px) {
    ThrowInvalid("outer_window_px: must be larger than inner_window_px (" +
                 std::to_string(inner_window_px) + "), got " + std::to_string(outer_window_px));
  }
  if (one_sided && detector != "rx" && detector != "anomaly-imaging") {
    ThrowInvalid("one_sided: detectors rx and anomaly-imaging only, got '" + detector + "'");
  }
}

double ChiSquareQuantile(int dof, double p_exceed) {
  if (dof < 1) ThrowInvalid("ChiSquareQuantile: dof must be >= 1");
  if (!(p_exceed > 0.0 && p_exceed < 1.0)) {
    ThrowInvalid("false_alarm_rate: must be in (0, 1), got " + FormatNumber(p_exceed));
  }
  const boost::math::chi_squared distribution(dof);
  return boost::math::quantile(boost::math::complement(distribution, p_exceed));
}

AnomalyScores ComputeAnomalyScores(const Image& image, const Image& count,
                                   const AnomalyOptions& options,
                                   const std::optional<Radiometry>& radiometry, int num_threads) {
  options.Check();
  if (image.empty()) ThrowInvalid("image: empty");
  {
    // The working memory, refused up front: features (float) and flags, scores (double), and
    // for rx-local its integral images (double) of 1, the d features and their d (d + 1) / 2
    // products.
    const uint64_t pixels = static_cast<uint64_t>(image.width()) * image.height();
    const uint64_t d = static_cast<uint64_t>(FeatureCount(options.channels, image.channels(),
                                                           options.detector));
    const uint64_t planes = options.detector == "rx-local" ? 1 + d + d * (d + 1) / 2 : 0;
    CheckMemoryBudget(SaturatingProduct({pixels, 4 * d + 1 + 8 + 8 * planes}),
                      "image: " + std::to_string(image.width()) + " x " +
                          std::to_string(image.height()) + " pixels",
                      "the anomaly scores' working memory");
  }
  const Features f = MakeFeatures(image, count, options, radiometry);
  const int d = f.d;
  AnomalyScores result;
  result.dimensions = d;
  result.pixels = f.count;
  result.scores = Image(f.width, f.height, 1, PixelType::kF32);
  std::vector<double> scores;
  if (options.detector == "temperature") {
    scores.assign(f.valid.size(), 0.0);
    for (size_t i = 0; i < f.valid.size(); ++i) {
      if (f.valid[i]) scores[i] = f.At(i)[0];
    }
  } else {
    // The background statistics from at most kMaxBackgroundSamples pixels on a regular grid
    // (all pixels of smaller images): the estimate's relative error, about sqrt(2 / n) per
    // element, stays below 0.6 %, and large images and every frame of anomaly imaging score fast.
    std::vector<size_t> sample;
    {
      const int step = SampleStep(f.count);
      for (int y = 0; y < f.height; y += step) {
        for (int x = 0; x < f.width; x += step) {
          const size_t i = static_cast<size_t>(y) * f.width + x;
          if (f.valid[i]) sample.push_back(i);
        }
      }
      if (sample.size() < static_cast<size_t>(d) + 1) {  // a sparse mask: every valid pixel
        sample.clear();
        for (size_t i = 0; i < f.valid.size(); ++i) {
          if (f.valid[i]) sample.push_back(i);
        }
      }
    }
    WeightedPoints points;
    points.d = d;
    points.values.reserve(sample.size() * static_cast<size_t>(d));
    for (size_t i : sample) points.values.insert(points.values.end(), f.At(i), f.At(i) + d);
    Background bg = EstimateBackground(points, options);
    std::vector<double>& mean = bg.mean;
    std::vector<double>& covariance = bg.covariance;
    std::vector<double>& inverse = bg.inverse;
    result.mean = mean;
    result.covariance = covariance;
    const double ridge = Ridge(options.regularization, Trace(covariance, d), mean, d);
    for (int k = 0; k < d; ++k) result.covariance[k * d + k] += ridge;
    if (options.detector == "rx-local") {
      LocalScores(f, options, Trace(covariance, d), mean, inverse, num_threads, &scores);
    } else {
      ScoreAll(f, mean, inverse, &scores);
      if (options.one_sided) {
        if (d != 1) {
          ThrowInvalid("one_sided: needs one feature (grey or thermal), got " +
                       std::to_string(d) + " (channels '" + options.channels + "')");
        }
        for (size_t i = 0; i < scores.size(); ++i) {
          if (f.valid[i] && f.At(i)[0] < mean[0]) scores[i] = 0.0;
        }
      }
    }
  }
  for (int y = 0; y < f.height; ++y) {
    float* row = result.scores.At<float>(0, y);
    for (int x = 0; x < f.width; ++x) {
      row[x] = static_cast<float>(scores[static_cast<size_t>(y) * f.width + x]);
    }
  }
  return result;
}

int AnomalyFeatureCount(const AnomalyOptions& options, int image_channels) {
  return FeatureCount(options.channels, image_channels, options.detector);
}

namespace {

// Global RX's background of a frame of one channel, one feature and 8 or 16 bits, from the
// histogram of its sample grid: one weighted point per value that occurs (nullopt for other
// frames).
std::optional<Background> HistogramBackground(const Image& frame, const AnomalyOptions& options) {
  const bool integer = frame.type() == PixelType::kU8 || frame.type() == PixelType::kU16;
  if (!integer || frame.channels() != 1 || options.channels != "auto") return std::nullopt;
  AnomalyOptions rx = options;
  rx.detector = "rx";
  const int w = frame.width(), h = frame.height();
  const int levels = frame.type() == PixelType::kU8 ? 256 : 65536;
  std::vector<uint32_t> histogram(static_cast<size_t>(levels), 0);
  const int step = SampleStep(static_cast<int64_t>(w) * h);
  const auto count_values = [&](const auto* type_tag) {
    using T = std::remove_const_t<std::remove_pointer_t<decltype(type_tag)>>;
    for (int y = 0; y < h; y += step) {
      const T* row = frame.At<T>(0, y);
      for (int x = 0; x < w; x += step) ++histogram[row[x]];
    }
  };
  if (frame.type() == PixelType::kU8) {
    count_values(static_cast<const uint8_t*>(nullptr));
  } else {
    count_values(static_cast<const uint16_t*>(nullptr));
  }
  WeightedPoints points;
  points.d = 1;
  for (int v = 0; v < levels; ++v) {
    if (histogram[static_cast<size_t>(v)] == 0) continue;
    points.values.push_back(static_cast<float>(v));
    points.weights.push_back(histogram[static_cast<size_t>(v)]);
  }
  return EstimateBackground(points, rx);
}

}  // namespace

std::optional<ViewQuadratic> FrameQuadratic(const Image& frame, const AnomalyOptions& options) {
  AnomalyOptions rx = options;
  rx.detector = "rx";
  rx.Check();
  if (frame.empty()) ThrowInvalid("image: empty");
  const std::optional<Background> bg = HistogramBackground(frame, options);
  if (!bg) return std::nullopt;
  ViewQuadratic quadratic;
  quadratic.centre = static_cast<float>(bg->mean[0]);
  quadratic.scale = static_cast<float>(bg->inverse[0]);
  quadratic.one_sided = options.one_sided;
  return quadratic;
}

Image QuantisedFrameScores(const Image& frame, const AnomalyOptions& options) {
  AnomalyOptions rx = options;
  rx.detector = "rx";
  rx.Check();
  if (frame.empty()) ThrowInvalid("image: empty");
  const int w = frame.width(), h = frame.height();
  Image out(w, h, 1, PixelType::kU16, 1);
  constexpr double kSteps = 1.0 / kFrameScoreStep;
  const auto quantise = [](double score) {
    return static_cast<uint16_t>(std::min(65535.0, std::floor(score * kSteps + 0.5)));
  };
  if (const std::optional<Background> histogram_bg = HistogramBackground(frame, options)) {
    const double m = histogram_bg->mean[0], inverse = histogram_bg->inverse[0];
    if (frame.type() == PixelType::kU8) {
      uint16_t table[256];
      for (int v = 0; v < 256; ++v) {
        table[v] = options.one_sided && v < m ? 0 : quantise(std::max(0.0, (v - m) * (v - m) * inverse));
      }
      for (int y = 0; y < h; ++y) {
        const uint8_t* in = frame.At<uint8_t>(0, y);
        uint16_t* row = out.At<uint16_t>(0, y);
        for (int x = 0; x < w; ++x) row[x] = table[in[x]];
      }
    } else {
      // (v - m)^2 * inverse * kSteps in float: within a float's rounding of the double score,
      // far below the quantisation step.
      const float mf = static_cast<float>(m), scale = static_cast<float>(inverse * kSteps);
      // one_sided: values below the mean score 0.
      const float lowest = options.one_sided ? 0.0f : -std::numeric_limits<float>::infinity();
      for (int y = 0; y < h; ++y) {
        const uint16_t* in = frame.At<uint16_t>(0, y);
        uint16_t* row = out.At<uint16_t>(0, y);
        for (int x = 0; x < w; ++x) {
          const float c = std::max(static_cast<float>(in[x]) - mf, lowest);
          row[x] = static_cast<uint16_t>(std::min(65535.0f, c * c * scale + 0.5f));
        }
      }
    }
  } else {
    const AnomalyScores scores = ComputeAnomalyScores(frame, Image(), rx, std::nullopt);
    for (int y = 0; y < h; ++y) {
      const float* in = scores.scores.At<float>(0, y);
      uint16_t* row = out.At<uint16_t>(0, y);
      for (int x = 0; x < w; ++x) row[x] = quantise(in[x]);
    }
  }
  out.FillBorder();
  return out;
}

}  // namespace aos
