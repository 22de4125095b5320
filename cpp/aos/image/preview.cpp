#include "aos/image/preview.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "aos/util/error.h"

namespace aos {
namespace {

void CheckInputs(const Image& image, const Image* valid, double low, double high) {
  if (image.empty()) ThrowInvalid("preview: the image is empty");
  if (!(low >= 0.0 && low < high && high <= 100.0)) {
    ThrowInvalid("preview: percentiles must satisfy 0 <= low < high <= 100");
  }
  if (valid != nullptr && (valid->width() != image.width() || valid->height() != image.height())) {
    ThrowInvalid("preview: the mask is not the image's size");
  }
}

bool IsValid(const Image* valid, int x, int y) { return valid == nullptr || valid->Value(x, y) != 0.0; }

PreviewRange RangeOf(std::vector<double> samples, double low, double high) {
  PreviewRange range;
  if (samples.empty()) return range;
  const auto at = [&](double percentile) {
    const size_t k = static_cast<size_t>(
        std::clamp(percentile / 100.0 * (samples.size() - 1) + 0.5, 0.0, samples.size() - 1.0));
    std::nth_element(samples.begin(), samples.begin() + static_cast<std::ptrdiff_t>(k),
                     samples.end());
    return samples[k];
  };
  range.lo = at(low);
  range.hi = at(high);
  if (!(range.hi > range.lo)) range.hi = range.lo + 1.0;  // flat: everything maps to 0
  return range;
}

}  // namespace

PreviewRange PercentileRange(const Image& image, const Image* valid, double low_percentile,
                             double high_percentile) {
  CheckInputs(image, valid, low_percentile, high_percentile);
  std::vector<double> samples;
  for (int y = 0; y < image.height(); ++y) {
    for (int x = 0; x < image.width(); ++x) {
      if (!IsValid(valid, x, y)) continue;
      for (int c = 0; c < image.channels(); ++c) {
        const double value = image.Value(x, y, c);
        if (std::isfinite(value)) samples.push_back(value);
      }
    }
  }
  return RangeOf(std::move(samples), low_percentile, high_percentile);
}

Image StretchedPreview(const Image& image, const Image* valid, double low_percentile,
                       double high_percentile, PreviewRange* range) {
  const PreviewRange r = PercentileRange(image, valid, low_percentile, high_percentile);
  if (range != nullptr) *range = r;
  const int channels = std::min(image.channels(), 3);
  Image preview(image.width(), image.height(), channels, PixelType::kU8);
  const double scale = 255.0 / (r.hi - r.lo);
  for (int y = 0; y < image.height(); ++y) {
    for (int x = 0; x < image.width(); ++x) {
      uint8_t* out = preview.At<uint8_t>(x, y);
      const bool ok = IsValid(valid, x, y);
      for (int c = 0; c < channels; ++c) {
        const double value = image.Value(x, y, c);
        out[c] = ok && std::isfinite(value)
                     ? static_cast<uint8_t>(std::clamp(std::round((value - r.lo) * scale), 0.0, 255.0))
                     : 0;
      }
    }
  }
  return preview;
}

Image ColourMappedPreview(const Image& image, const Image* valid, const PreviewRange& range) {
  CheckInputs(image, valid, 0.0, 100.0);
  if (image.channels() != 1) ThrowInvalid("preview: a colour map takes a one-channel image");
  if (!(range.hi > range.lo)) ThrowInvalid("preview: the range must have hi > lo");
  cv::Mat grey(image.height(), image.width(), CV_8UC1);
  const double scale = 255.0 / (range.hi - range.lo);
  for (int y = 0; y < image.height(); ++y) {
    for (int x = 0; x < image.width(); ++x) {
      const double value = image.Value(x, y);
      grey.at<uint8_t>(y, x) = static_cast<uint8_t>(
          std::isfinite(value) ? std::clamp(std::round((value - range.lo) * scale), 0.0, 255.0)
                               : 0.0);
    }
  }
  cv::Mat bgr;
  cv::applyColorMap(grey, bgr, cv::COLORMAP_TURBO);
  Image preview(image.width(), image.height(), 3, PixelType::kU8);
  for (int y = 0; y < image.height(); ++y) {
    for (int x = 0; x < image.width(); ++x) {
      uint8_t* out = preview.At<uint8_t>(x, y);
      const cv::Vec3b& colour = bgr.at<cv::Vec3b>(y, x);
      const bool ok = IsValid(valid, x, y);
      out[0] = ok ? colour[2] : 0;
      out[1] = ok ? colour[1] : 0;
      out[2] = ok ? colour[0] : 0;
    }
  }
  return preview;
}

}  // namespace aos
