#include "aos/metrics/quality.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <new>
#include <limits>
#include <string>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "aos/util/error.h"
#include "aos/util/memory.h"

namespace aos {
namespace {

// Output rows of one SSIM band: about kBandPixels pixels (a few MiB of double planes), at least
// four window radii (the band reads a halo of one radius above and below), at most
// kMaxBandRows. The MSE pass polls cancellation as often.
constexpr int64_t kBandPixels = int64_t{1} << 18;
constexpr int kMaxBandRows = 1024;
int BandRows(int width, int radius) {
  return static_cast<int>(
      std::clamp<int64_t>(kBandPixels / std::max(width, 1), 4 * int64_t{radius}, kMaxBandRows));
}

// Double planes a band holds at once for `channels` channels: per channel the two images, the
// five Gaussian statistics and one product being blurred; the validity and window-validity
// planes; for three channels the three quaternion cross terms and their three temporaries.
int WorkingPlanes(int channels) { return 8 * channels + 2 + (channels == 3 ? 6 : 0); }

// Rows [y0, y1) of channel c of `image`, times `scale`, as a double matrix.
cv::Mat ChannelRows(const Image& image, int c, int y0, int y1, double scale) {
  cv::Mat plane(y1 - y0, image.width(), CV_64F);
  for (int y = y0; y < y1; ++y) {
    double* row = plane.ptr<double>(y - y0);
    for (int x = 0; x < image.width(); ++x) row[x] = image.Value(x, y, c) * scale;
  }
  return plane;
}

void ThrowIfCancelled(ProgressSink* progress) {
  if (ProgressCancelled(progress)) throw Cancelled();
}

QualityResult Compare(const Image& test, const Image& reference, const Image* mask,
                      const QualityOptions& options, ProgressSink* progress);

}  // namespace

uint64_t CompareImagesWorkingBytes(int width, int height, int test_channels, PixelType test_type,
                                   int reference_channels, PixelType reference_type,
                                   const QualityOptions& options) {
  const uint64_t pixels = SaturatingProduct({static_cast<uint64_t>(std::max(width, 0)),
                                             static_cast<uint64_t>(std::max(height, 0))});
  uint64_t bytes = 0;
  int channels = std::max(test_channels, reference_channels);
  if (options.grey) {
    if (test_channels >= 3) bytes += SaturatingProduct({pixels, PixelTypeSize(test_type)});
    if (reference_channels >= 3) {
      bytes += SaturatingProduct({pixels, PixelTypeSize(reference_type)});
    }
    channels = std::max(test_channels >= 3 ? 1 : test_channels,
                        reference_channels >= 3 ? 1 : reference_channels);
  }
  const int r = options.window_radius;
  const int rows = std::min(std::max(height, 0), BandRows(width, r) + 2 * r);
  const uint64_t planes = SaturatingProduct(
      {static_cast<uint64_t>(WorkingPlanes(channels)), static_cast<uint64_t>(rows),
       static_cast<uint64_t>(std::max(width, 0)), sizeof(double)});
  return bytes + planes < bytes ? std::numeric_limits<uint64_t>::max() : bytes + planes;
}

void QualityOptions::Check() const {
  if (!(data_range >= 0.0) || !std::isfinite(data_range)) {
    ThrowInvalid("data_range: must be > 0, or 0 for the reference's type (got " +
                 FormatNumber(data_range) + ")");
  }
  if (!(gaussian_sigma > 0.0) || !std::isfinite(gaussian_sigma)) {
    ThrowInvalid("gaussian_sigma: must be > 0 pixels (got " + FormatNumber(gaussian_sigma) + ")");
  }
  if (window_radius < 1 || window_radius > 100) {
    ThrowInvalid("window_radius: must be 1..100 pixels (got " + std::to_string(window_radius) + ")");
  }
  if (!(k1 > 0.0 && k1 < 1.0) || !(k2 > 0.0 && k2 < 1.0)) {
    ThrowInvalid("k1/k2: must be in (0, 1) (got " + FormatNumber(k1) + ", " + FormatNumber(k2) + ")");
  }
}

QualityResult CompareImages(const Image& test, const Image& reference, const Image* mask,
                            const QualityOptions& options, ProgressSink* progress) {
  options.Check();
  if (test.empty() || reference.empty()) ThrowInvalid("compare: an image is empty");
  const std::string size = std::to_string(test.width()) + "x" + std::to_string(test.height()) +
                           "x" + std::to_string(test.channels());
  CheckMemoryBudget(CompareImagesWorkingBytes(test.width(), test.height(), test.channels(),
                                              test.type(), reference.channels(), reference.type(),
                                              options),
                    "compare: images of " + size + " pixels",
                    "working planes of the SSIM" +
                        std::string(options.grey ? " and the luminance images" : ""));
  try {
    return Compare(test, reference, mask, options, progress);
  } catch (const cv::Exception& error) {
    if (error.code == cv::Error::StsNoMem) {
      ThrowInvalid("compare: not enough memory to compare images of " + size + " pixels (" +
                   OneLine(error.err) + ")");
    }
    ThrowInvalid("compare: OpenCV failed on images of " + size + " pixels (" + OneLine(error.err) +
                 ")");
  } catch (const std::bad_alloc&) {
    ThrowInvalid("compare: not enough memory to compare images of " + size + " pixels");
  }
}

namespace {

QualityResult Compare(const Image& test, const Image& reference, const Image* mask,
                      const QualityOptions& options, ProgressSink* progress) {
  if (options.grey) {
    QualityOptions plain = options;
    plain.grey = false;
    const auto grey = [](const Image& image) {
      return image.channels() >= 3 ? LuminanceImage(image) : image;
    };
    QualityResult result = Compare(grey(test), grey(reference), mask, plain, progress);
    if (test.channels() >= 3 || reference.channels() >= 3) {
      const std::string converted = "compared as luminance (Rec. 601: 0.299 R + 0.587 G + 0.114 B)";
      result.note = result.note.empty() ? converted : converted + "; " + result.note;
    }
    return result;
  }
  if (test.width() != reference.width() || test.height() != reference.height() ||
      test.channels() != reference.channels()) {
    const bool grey_against_colour = test.width() == reference.width() &&
                                     test.height() == reference.height() &&
                                     std::min(test.channels(), reference.channels()) <= 2 &&
                                     std::max(test.channels(), reference.channels()) >= 3;
    ThrowInvalid("compare: the test image is " + std::to_string(test.width()) + "x" +
                 std::to_string(test.height()) + "x" + std::to_string(test.channels()) +
                 " but the reference is " + std::to_string(reference.width()) + "x" +
                 std::to_string(reference.height()) + "x" + std::to_string(reference.channels()) +
                 (grey_against_colour
                      ? "; to compare luminances (Rec. 601) set grey (QualityOptions::grey: "
                        "aos-render metrics --grey, compare_images(grey=True))"
                      : ""));
  }
  if (mask != nullptr && (mask->width() != test.width() || mask->height() != test.height())) {
    ThrowInvalid("compare: the mask is " + std::to_string(mask->width()) + "x" +
                 std::to_string(mask->height()) + ", not the images' size");
  }
  const int width = test.width(), height = test.height(), channels = test.channels();
  QualityResult result;
  // Images of different sample types are brought to one scale before anything is compared
  // (comparing raw codes of an 8-bit and a 16-bit image is meaningless); see the header.
  const bool test_float = test.type() == PixelType::kF32;
  const bool reference_float = reference.type() == PixelType::kF32;
  PixelType units = reference.type();
  if (test.type() != reference.type()) {
    if (!test_float && !reference_float) {
      result.test_scale = PixelTypeFullRange(reference.type()) / PixelTypeFullRange(test.type());
      result.note = std::string("the ") + PixelTypeName(test.type()) +
                    " test image was scaled by " + FormatNumber(result.test_scale) +
                    " to the " + PixelTypeName(reference.type()) +
                    " reference's range (each normalised by its type's full range)";
    } else {
      const Image& floating = test_float ? test : reference;
      const Image& integer = test_float ? reference : test;
      units = integer.type();
      double float_max = 0.0, integer_max = 0.0;
      const int poll_rows = BandRows(width, options.window_radius);
      for (int y = 0; y < height; ++y) {
        if (y % poll_rows == 0) ThrowIfCancelled(progress);
        for (int x = 0; x < width; ++x) {
          for (int c = 0; c < channels; ++c) {
            float_max = std::max(float_max, std::abs(floating.Value(x, y, c)));
            integer_max = std::max(integer_max, integer.Value(x, y, c));
          }
        }
      }
      if (float_max > 0.0 && float_max <= 1.0 && integer_max > 1.0) {
        ThrowInvalid(std::string("compare: the ") + (test_float ? "test" : "reference") +
                     " image is float32 with values in [-1, 1] but the " +
                     (test_float ? "reference" : "test") + " image is " +
                     PixelTypeName(integer.type()) + " with values up to " +
                     FormatNumber(integer_max) +
                     ": the float image looks normalised to [0, 1] while aos compares a float "
                     "image in the units of the integer one (as aos writes float renders); "
                     "convert one of them so both are in the same units");
      }
      result.note = std::string("the float32 ") + (test_float ? "test" : "reference") +
                    " image was compared in the units of the " + PixelTypeName(integer.type()) +
                    " " + (test_float ? "reference" : "test") + " image";
    }
  }
  result.data_range = options.data_range > 0.0 ? options.data_range : PixelTypeFullRange(units);
  const double L = result.data_range;
  const double C1 = (options.k1 * L) * (options.k1 * L), C2 = (options.k2 * L) * (options.k2 * L);

  // The MSE over valid pixels, and every value checked finite, a band of rows at a time.
  const int r = options.window_radius, side = 2 * r + 1;
  const int band_rows = BandRows(width, r);
  const int64_t mse_bands = (height + band_rows - 1) / band_rows;
  const int64_t ssim_bands = (std::max(height - 2 * r, 0) + band_rows - 1) / band_rows;
  ProgressStart(progress, "metrics", mse_bands + ssim_bands);
  const double scale = result.test_scale;
  double squared_error = 0.0;
  for (int y0 = 0; y0 < height; y0 += band_rows) {
    ThrowIfCancelled(progress);
    for (int y = y0; y < std::min(height, y0 + band_rows); ++y) {
      for (int x = 0; x < width; ++x) {
        const bool valid = mask == nullptr || mask->Value(x, y) != 0.0;
        if (valid) ++result.mse_pixels;
        for (int c = 0; c < channels; ++c) {
          const double a = test.Value(x, y, c) * scale, b = reference.Value(x, y, c);
          if (!std::isfinite(a) || !std::isfinite(b)) {
            ThrowInvalid("compare: the images contain NaN or infinite values");
          }
          if (valid) squared_error += (a - b) * (a - b);
        }
      }
    }
    ProgressAdvance(progress, 1);
  }
  if (result.mse_pixels == 0) ThrowInvalid("compare: no valid pixel to compare (the mask is empty)");
  result.mse = squared_error / (static_cast<double>(result.mse_pixels) * channels);
  result.psnr_db = result.mse > 0.0 ? 10.0 * std::log10(L * L / result.mse)
                                    : std::numeric_limits<double>::infinity();

  // Gaussian-weighted local statistics over bands of output rows [y0, y1), each read with a halo
  // of r rows [y0 - r, y1 + r): the pixels scored (whole window inside the image) see exactly the
  // rows of the whole image, so the border rule of the blur never enters a score.
  const cv::Size window(side, side);
  auto blur = [&](const cv::Mat& in) {
    cv::Mat out;
    cv::GaussianBlur(in, out, window, options.gaussian_sigma, options.gaussian_sigma,
                     cv::BORDER_REFLECT);
    return out;
  };
  std::vector<double> ssim_sum(channels, 0.0);
  double color_sum = 0.0;
  const double full = static_cast<double>(side) * side;
  std::vector<cv::Mat> a(channels), b(channels), mu_a(channels), mu_b(channels), aa(channels),
      bb(channels), ab(channels), cross(3);
  for (int y0 = r; y0 < height - r; y0 += band_rows) {
    ThrowIfCancelled(progress);
    const int y1 = std::min(height - r, y0 + band_rows);
    const int top = y0 - r, bottom = y1 + r;
    // Pixels whose whole window is valid (mask): the count of valid pixels in the window.
    cv::Mat window_valid;
    if (mask != nullptr) {
      cv::Mat valid(bottom - top, width, CV_64F);
      for (int y = top; y < bottom; ++y) {
        double* row = valid.ptr<double>(y - top);
        for (int x = 0; x < width; ++x) row[x] = mask->Value(x, y) != 0.0 ? 1.0 : 0.0;
      }
      cv::boxFilter(valid, window_valid, CV_64F, window, cv::Point(-1, -1), false,
                    cv::BORDER_CONSTANT);
    }
    for (int c = 0; c < channels; ++c) {
      a[c] = ChannelRows(test, c, top, bottom, scale);
      b[c] = ChannelRows(reference, c, top, bottom, 1.0);
      mu_a[c] = blur(a[c]);
      mu_b[c] = blur(b[c]);
      aa[c] = blur(a[c].mul(a[c]));
      bb[c] = blur(b[c].mul(b[c]));
      ab[c] = blur(a[c].mul(b[c]));
    }
    // Quaternion cross terms E[a x b] for three channels.
    if (channels == 3) {
      for (int k = 0; k < 3; ++k) {
        const int i = (k + 1) % 3, j = (k + 2) % 3;
        cross[k] = blur(a[i].mul(b[j]) - a[j].mul(b[i]));
      }
    }
    for (int y = y0 - top; y < y1 - top; ++y) {
      for (int x = r; x < width - r; ++x) {
        if (mask != nullptr && window_valid.at<double>(y, x) < full - 0.5) continue;
        ++result.ssim_pixels;
        double mean_dot = 0.0, norm_a = 0.0, norm_b = 0.0, var_a = 0.0, var_b = 0.0, cov = 0.0;
        for (int c = 0; c < channels; ++c) {
          const double ma = mu_a[c].at<double>(y, x), mb = mu_b[c].at<double>(y, x);
          const double sa = aa[c].at<double>(y, x) - ma * ma;
          const double sb = bb[c].at<double>(y, x) - mb * mb;
          const double sab = ab[c].at<double>(y, x) - ma * mb;
          ssim_sum[c] += ((2 * ma * mb + C1) * (2 * sab + C2)) / ((ma * ma + mb * mb + C1) * (sa + sb + C2));
          mean_dot += ma * mb;
          norm_a += ma * ma;
          norm_b += mb * mb;
          var_a += sa;
          var_b += sb;
          cov += sab;
        }
        // Quaternion form: 2 mu_a mu_b* = 2 (mu_a . mu_b, -mu_a x mu_b); sigma_ab likewise.
        double mean_cross2 = 0.0, cov_cross2 = 0.0;
        if (channels == 3) {
          for (int k = 0; k < 3; ++k) {
            const int i = (k + 1) % 3, j = (k + 2) % 3;
            const double m = mu_a[i].at<double>(y, x) * mu_b[j].at<double>(y, x) -
                             mu_a[j].at<double>(y, x) * mu_b[i].at<double>(y, x);
            const double v = cross[k].at<double>(y, x) - m;
            mean_cross2 += m * m;
            cov_cross2 += v * v;
          }
        }
        const double luminance = std::hypot(2 * mean_dot + C1, 2 * std::sqrt(mean_cross2));
        const double structure = std::hypot(2 * cov + C2, 2 * std::sqrt(cov_cross2));
        color_sum += luminance * structure / ((norm_a + norm_b + C1) * (var_a + var_b + C2));
      }
    }
    ProgressAdvance(progress, 1);
  }
  if (result.ssim_pixels == 0) {
    ThrowInvalid("compare: no pixel has a whole " + std::to_string(side) + "x" +
                 std::to_string(side) + " SSIM window inside the image and the mask");
  }
  const double n = static_cast<double>(result.ssim_pixels);
  result.ssim = 0.0;
  for (int c = 0; c < channels; ++c) {
    result.ssim_channels.push_back(ssim_sum[c] / n);
    result.ssim += ssim_sum[c] / n / channels;
  }
  result.color_ssim = channels == 1 ? result.ssim : color_sum / n;
  return result;
}

}  // namespace
}  // namespace aos
