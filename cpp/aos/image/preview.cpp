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

PreviewRange PercentileRange(const std::vector<const Image*>& images,
                             const std::vector<const Image*>& valid, double low_percentile,
                             double high_percentile) {
  if (images.empty() || valid.size() != images.size()) {
    ThrowInvalid("preview: give one mask (or null) per image, and at least one image");
  }
  // At most about 4 M samples in all (channels counted): every k-th pixel of each image.
  size_t samples_total = 0;
  for (size_t i = 0; i < images.size(); ++i) {
    CheckInputs(*images[i], valid[i], low_percentile, high_percentile);
    samples_total += static_cast<size_t>(images[i]->width()) * images[i]->height() *
                     images[i]->channels();
  }
  const size_t step = std::max<size_t>(1, samples_total / (size_t{4} << 20));
  std::vector<double> samples;
  for (size_t i = 0; i < images.size(); ++i) {
    const Image& image = *images[i];
    size_t k = 0;
    for (int y = 0; y < image.height(); ++y) {
      for (int x = 0; x < image.width(); ++x, ++k) {
        if (k % step != 0 || !IsValid(valid[i], x, y)) continue;
        for (int c = 0; c < image.channels(); ++c) {
          const double value = image.Value(x, y, c);
          if (std::isfinite(value)) samples.push_back(value);
        }
      }
    }
  }
  return RangeOf(std::move(samples), low_percentile, high_percentile);
}

Image StretchedPreview(const Image& image, const Image* valid, double low_percentile,
                       double high_percentile, PreviewRange* range) {
  const PreviewRange r = PercentileRange(image, valid, low_percentile, high_percentile);
  if (range != nullptr) *range = r;
  return MappedPreview(image, valid, r);
}

Image MappedPreview(const Image& image, const Image* valid, const PreviewRange& r) {
  CheckInputs(image, valid, 0.0, 100.0);
  if (!(r.hi > r.lo)) ThrowInvalid("preview: the range must have hi > lo");
  // Grey or RGB: a fourth channel is dropped, and a second one too (a grey+alpha PNG would show
  // the stretched second band as transparency).
  const int channels = image.channels() == 2 ? 1 : std::min(image.channels(), 3);
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

Image ContactSheet(const std::vector<Image>& previews, int columns, int max_tile_width) {
  if (previews.empty() || columns < 1 || max_tile_width < 1) {
    ThrowInvalid("preview: a contact sheet needs images, columns >= 1 and a tile width >= 1");
  }
  const Image& first = previews.front();
  for (const Image& preview : previews) {
    if (preview.type() != PixelType::kU8 || preview.width() != first.width() ||
        preview.height() != first.height() || preview.channels() != first.channels()) {
      ThrowInvalid("preview: contact-sheet tiles must be 8-bit images of one size and layout");
    }
  }
  const double scale = std::min(1.0, static_cast<double>(max_tile_width) / first.width());
  const int tile_w = std::max(1, static_cast<int>(std::lround(first.width() * scale)));
  const int tile_h = std::max(1, static_cast<int>(std::lround(first.height() * scale)));
  constexpr int kGap = 2;
  const int n = static_cast<int>(previews.size());
  const int cols = std::min(columns, n);
  const int rows = (n + cols - 1) / cols;
  const int channels = first.channels();
  const int cv_type = CV_8UC(channels);
  cv::Mat sheet(rows * tile_h + (rows - 1) * kGap, cols * tile_w + (cols - 1) * kGap, cv_type,
                cv::Scalar::all(0));
  for (int i = 0; i < n; ++i) {
    const Image& preview = previews[static_cast<size_t>(i)];
    cv::Mat full(preview.height(), preview.width(), cv_type);
    for (int y = 0; y < preview.height(); ++y) {
      std::copy_n(preview.At<uint8_t>(0, y), static_cast<size_t>(preview.width()) * channels,
                  full.ptr<uint8_t>(y));
    }
    cv::Mat tile;
    cv::resize(full, tile, cv::Size(tile_w, tile_h), 0, 0, cv::INTER_AREA);
    tile.copyTo(sheet(cv::Rect((i % cols) * (tile_w + kGap), (i / cols) * (tile_h + kGap),
                               tile_w, tile_h)));
  }
  Image result(sheet.cols, sheet.rows, channels, PixelType::kU8);
  for (int y = 0; y < sheet.rows; ++y) {
    std::copy_n(sheet.ptr<uint8_t>(y), static_cast<size_t>(sheet.cols) * channels,
                result.At<uint8_t>(0, y));
  }
  return result;
}

}  // namespace aos
