#pragma once
// Previews: 8-bit images that open correctly in ordinary viewers, made from float results (an
// all-in-focus image in the views' units, a depth map in metres, a count map) that open all
// white or all black there.
//
// Contract
// - StretchedPreview: 8-bit, grey or RGB (of 2 channels the first, of 4 the first three); the
//   valid samples' low_percentile..high_percentile (over all channels) map linearly onto 0..255,
//   clamped;
//   invalid pixels are 0. `range` receives the values mapped to 0 and 255.
// - MappedPreview: as StretchedPreview with a given range (lo -> 0, hi -> 255).
// - PercentileRange over several images: one range for a set (a focal stack's slices), from
//   every k-th valid sample so that at most about 4 M samples are sorted.
// - ContactSheet: 8-bit images of one size and layout as tiles at most max_tile_width pixels
//   wide (INTER_AREA), `columns` per row, 2-pixel black gaps.
// - ColourMappedPreview: 8-bit RGB of a one-channel image through the turbo colour map (blue =
//   range.lo, red = range.hi); invalid pixels black.
// - `valid` (optional, any type, the image's size): non-zero = valid.
// Throws std::invalid_argument for an empty image, percentiles outside 0 <= low < high <= 100, a
// mask of another size, or (colour map) an image of more than one channel.
#include <vector>

#include "aos/image/image.h"

namespace aos {

struct PreviewRange {
  double lo = 0.0;
  double hi = 1.0;
};

Image StretchedPreview(const Image& image, const Image* valid, double low_percentile,
                       double high_percentile, PreviewRange* range);

// The low..high percentile range of the valid samples of a one-channel image (lo < hi).
PreviewRange PercentileRange(const Image& image, const Image* valid, double low_percentile,
                             double high_percentile);

Image ColourMappedPreview(const Image& image, const Image* valid, const PreviewRange& range);

Image MappedPreview(const Image& image, const Image* valid, const PreviewRange& range);

// `valid` has one entry (or nullptr) per image.
PreviewRange PercentileRange(const std::vector<const Image*>& images,
                             const std::vector<const Image*>& valid, double low_percentile,
                             double high_percentile);

Image ContactSheet(const std::vector<Image>& previews, int columns, int max_tile_width);

}  // namespace aos
