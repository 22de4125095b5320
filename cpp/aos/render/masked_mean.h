#pragma once
// Internal to the renderer: the one place where a render of a masked light field (lightfield.h:
// each view's last channel is a mask weight w = m * full range, the others premultiplied by m,
// m in {0, 1}) becomes the mean over valid samples. Every render route ends here
// (RenderIntegral's homography path in integral.cpp, RenderIntegralAtPoints' plain mean in
// surface_integral.cpp, which the depth, mesh, DEM and map paths take), so stacks, merges, maps
// and Python see the masked mean and never the weight channel. The robust mean alone divides
// per sample (it keeps each sample apart: surface_integral.h). Not part of the public API.
//
// Per pixel, from the renderer's plain means over the n admitted samples (a_c = mean of v_c m,
// c < C, and a_C = mean of w) and its variance V over all C + 1 channels:
// - mbar = a_C / full range, the mean mask weight. mbar = 0 (every sample masked, or n = 0):
//   count 0, value 0, variance 0, as a pixel no view sees.
// - value_c = a_c / mbar = sum(v_c m) / sum(m): bilinear samples of premultiplied values divided
//   by the bilinear samples of the weight, exactly the weighted mean (normalised convolution);
//   away from mask edges each view's sample is either v or left out.
// - count = max(1, round(n mbar)): the summed mask weight of the admitted samples, i.e. the
//   number of views whose valid pixels contributed wherever no sample straddles a mask edge (a
//   sample on an edge counts by its weight).
// - variance (when the render has one) = mean over the C value channels of
//   sum(v_c^2 m) / sum(m) - value_c^2, the population variance of the valid samples; 0 where
//   count < 2. The renderer computes it per pixel from its double sums with MaskedVariance below
//   (for binary weights (v m)^2 = v^2 m and w^2 = full range * w), and DivideByMaskWeight keeps
//   it. Exact away from mask edges up to double rounding (about 1e-16 of the squared values:
//   integer samples of a 16-bit view near 65535 give 0 for equal samples). It used to be
//   recovered here from the float32 variance over all C + 1 channels and the float32 means,
//   which for 16-bit values cost tens of units^2 wherever a view was masked out.
// - samples and uncovered_pixels are recounted from the new counts; views_used stays the views
//   geometrically admitted somewhere.
#include "aos/render/integral.h"

namespace aos::internal {

// Applies the above to `result` in place; `full_range` is the views' pixel type's full range
// (PixelTypeFullRange). result.variance, if any, must already be MaskedVariance's. Throws
// std::invalid_argument for an image of fewer than 2 channels.
void DivideByMaskWeight(IntegralResult& result, double full_range);

// The masked variance of one pixel (above) from a render's double sums over its admitted
// samples: sum[c] for the channels_in = C + 1 channels (the last is the weight w) and
// value_squares, the sum over the C value channels of the squared premultiplied samples.
// 0 where no valid sample contributed.
inline double MaskedVariance(const double* sum, double value_squares, int channels_in,
                             double full_range) {
  const int channels = channels_in - 1;
  const double weight = sum[channels] / full_range;  // sum(m): the valid samples
  if (!(weight > 0.0) || channels < 1) return 0.0;
  double squared_sums = 0.0;  // sum over c of sum(v_c m)^2
  for (int c = 0; c < channels; ++c) squared_sums += sum[c] * sum[c];
  const double variance = (value_squares - squared_sums / weight) / weight / channels;
  return variance > 0.0 ? variance : 0.0;
}

}  // namespace aos::internal
