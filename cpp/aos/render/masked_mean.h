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
//   count < 2. It is recovered from V: the sum over channels of mean(s^2) is C'V + sum a^2, and
//   for binary weights the weight channel's mean(w^2) is full range * a_C and
//   mean((v m)^2) = mean(v^2 m). Exact away from mask edges up to the float32 rounding of V and
//   the means (about 1e-7 of full range^2 / mbar^2).
// - samples and uncovered_pixels are recounted from the new counts; views_used stays the views
//   geometrically admitted somewhere.
#include "aos/render/integral.h"

namespace aos::internal {

// Applies the above to `result` in place; `full_range` is the views' pixel type's full range
// (PixelTypeFullRange). Throws std::invalid_argument for an image of fewer than 2 channels.
void DivideByMaskWeight(IntegralResult& result, double full_range);

}  // namespace aos::internal
