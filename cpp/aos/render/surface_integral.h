#pragma once
// Integral rendering onto a per-pixel focal surface: the virtual camera's depth map says where
// each pixel's ray meets the surface, and the views are averaged there, plainly or robustly.
// This is how an all-in-focus image is re-integrated on an estimated depth map (merge.h) and how
// the "oracle" image on the true depth is rendered.
//
// Contract
// - The virtual camera, aperture, view selection, grazing angle and threads come from
//   IntegralOptions exactly as in integral.h; focal_plane is used only for its normal, against
//   which the grazing test measures each view's ray (the surface is taken as locally parallel to
//   it). The renderer's admission rules are integral.h's: in front of the view, inside its image,
//   not grazing, through the aperture (0 = the single nearest view, ties to the lower index).
// - depth(x, y) is the z of the surface point in the virtual camera frame, metres (the focal
//   point is C + depth * R^T K^-1 (x + 0.5, y + 0.5, 1)); pixels whose depth is not finite or
//   not > 0 get count 0 and value 0.
// - Plain mean: image = mean of the bilinear samples, like RenderIntegral on a plane (the two
//   agree to float rounding when the depth map is that plane's).
// - Robust mean (robust = true), per pixel: the samples agree when their luminances (mean over
//   channels) lie within a band of width 2 * agreement * full range of the views' type (255 for
//   8-bit, 65535 for 16-bit, 4294967295 for 32-bit integer, 1 for float). The band placed where it holds the most samples (the
//   lowest such band on ties) gives the inliers: points on the focal surface look alike from
//   every view, while occluders seen from different views are different points. If the inliers
//   are at least min_inlier_fraction of the samples, the pixel is their mean, else the plain mean
//   (too few rays agree; counted in `fallback_pixels`). inliers(x, y) holds the number of
//   samples averaged.
//
// Throws std::invalid_argument naming the option or "depth" for bad input, aos::Cancelled if the
// progress sink asks to stop.
#include <cstdint>

#include "aos/render/integral.h"

namespace aos {

struct SurfaceIntegralOptions {
  // Outlier-rejecting mean instead of the plain mean.
  bool robust = false;
  // Half-width of the agreement band, as a fraction of the views' full range, (0, 1]: about
  // 2-3 times the noise of in-focus samples (sensor noise, resampling).
  double agreement = 0.02;
  // Fewest inliers, as a fraction of the pixel's samples, for the robust mean to be used, [0, 1].
  double min_inlier_fraction = 0.5;

  void Check() const;
};

struct SurfaceIntegralResult {
  IntegralResult integral;     // image, count (samples), statistics as RenderIntegral's
  Image inliers;               // uint32: samples averaged per pixel (robust), else empty
  int64_t fallback_pixels = 0; // robust: pixels that kept the plain mean
};

SurfaceIntegralResult RenderIntegralOnDepth(const LightField& light_field,
                                            const IntegralOptions& options, const Image& depth,
                                            const SurfaceIntegralOptions& surface = {},
                                            ProgressSink* progress = nullptr);

}  // namespace aos
