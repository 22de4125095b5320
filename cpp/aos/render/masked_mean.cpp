#include "aos/render/masked_mean.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "aos/util/error.h"

namespace aos::internal {

void DivideByMaskWeight(IntegralResult& result, double full_range) {
  const Image& weighted = result.image;
  const int channels_in = weighted.channels();
  if (channels_in < 2) {
    ThrowInvalid("masked light field: the views have " + std::to_string(channels_in) +
                 " channel(s); a masked view has its values and a weight channel");
  }
  const int channels = channels_in - 1;
  const int width = weighted.width(), height = weighted.height();
  const bool has_variance = !result.variance.empty();
  Image image(width, height, channels, PixelType::kF32);
  result.samples = 0;
  result.uncovered_pixels = 0;
  for (int y = 0; y < height; ++y) {
    const float* in = weighted.At<float>(0, y);
    float* out = image.At<float>(0, y);
    uint32_t* count = result.count.At<uint32_t>(0, y);
    float* variance = has_variance ? result.variance.At<float>(0, y) : nullptr;
    for (int x = 0; x < width; ++x, in += channels_in, out += channels) {
      const double n = count[x];
      const double mbar = in[channels] / full_range;
      if (!(n > 0.0 && mbar > 0.0)) {
        count[x] = 0;
        if (variance != nullptr) variance[x] = 0.0f;
        ++result.uncovered_pixels;
        continue;  // the value stays 0
      }
      for (int c = 0; c < channels; ++c) out[c] = static_cast<float>(in[c] / mbar);
      const uint32_t masked_count =
          static_cast<uint32_t>(std::max(1.0, std::round(n * mbar)));
      count[x] = masked_count;
      result.samples += masked_count;
      // The renderer's MaskedVariance stays, but for fewer than two valid samples.
      if (variance != nullptr && masked_count < 2) variance[x] = 0.0f;
    }
  }
  result.image = std::move(image);
}

}  // namespace aos::internal
