#pragma once
// Integral rendering onto a per-pixel focal surface: the virtual camera's depth map says where
// each pixel's ray meets the surface, and the views are averaged there, plainly or robustly.
// This is how an all-in-focus image is re-integrated on an estimated depth map (merge.h) and how
// the "oracle" image on the true depth is rendered.
//
// Contract
// - The virtual camera, aperture, view selection, grazing angle and threads come from
//   IntegralOptions exactly as in integral.h; GrazingNormal(light_field, options) (integral.h: a
//   plane's normal, else the up axis) is the normal against which the grazing test measures each
//   view's ray (the surface is taken as locally parallel to it). The renderer's admission rules are integral.h's: in front of the view, inside its image,
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
// - Masked light fields (lightfield.h, LoadOptions::mask): the plain mean divides by the mask
//   weight once at the end (masked_mean.h). The robust mean divides per sample instead: a sample
//   whose bilinear mask weight is 0 is left out, the others become (v m) / m, the weighted mean
//   of their valid taps; count is then the number of samples kept (views with weight > 0 at
//   the point), and the band, inliers and variance are over those samples.
//
// - Lens views (View::camera with a lens model) are sampled through the lens: exactly (each
//   focal point through LensCamera::Project) where lens_tolerance_px is 0, else quad by quad of
//   the output (64 x 64 pixels, split down to 8 x 8): the quad's nodes (corners, edge midpoints,
//   centre) are projected exactly, a homography is fitted to the corners (affine in the tangent
//   plane of the centre ray; for radtan lenses in the view's own pinhole coordinates; where that
//   misses the tolerance by less than 4x, a full homography by least squares over the nine
//   nodes; for fisheye and omnidirectional lenses on 64- and 32-pixel quads a cubic polynomial
//   in the tangent-plane coordinates instead, by least squares over a 5 x 5 grid of nodes, its
//   error bounded between them from its second differences), and the quad is sampled through
//   it (the point kernel) when
//   its error at the nodes, plus a first-order bound for the focal points' departure from the
//   bilinear sheet through the corner points (steps and relief of the surface), is within
//   lens_tolerance_px and every ray of the quad keeps inside the lens's valid field (with a
//   margin of the quad's angular spread); quads that fail are split, and 8 x 8 quads that fail
//   are projected exactly. The sample positions then differ from the exact ones by at most about
//   lens_tolerance_px (a bound checked at the nodes, not everywhere: a smooth map's error between
//   them is assumed to be of their order), so a sample differs by at most about
//   lens_tolerance_px times the view's largest intensity step between neighbouring pixels;
//   admission near the image edge is decided on the fitted position (the exact one within a
//   float rounding margin). Not in nearest mode (aperture 0) or for views without an AVX2 kernel
//   (several channels, masks): those project every sample exactly.
//
// - Everything above is RenderIntegralAtPoints on the focal points C + depth * ray (the one
//   per-sample route; maps give it orthographic points).
//
// Throws std::invalid_argument naming the option or "depth" for bad input, aos::Cancelled if the
// progress sink asks to stop.
#include <cstdint>
#include <limits>
#include <vector>

#include "aos/render/integral.h"
#include "aos/util/option_fields.h"

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
  // The field table (util/option_fields.h): every field once, in declaration order.
  template <class Visit>
  static void Fields(Visit&& field) {
    using O = SurfaceIntegralOptions;
    field(OptionField("robust", &O::robust, "", Range::Any(),
                      "Outlier-rejecting mean instead of the plain mean."));
    field(OptionField("agreement", &O::agreement, "", Range::OpenClosed(0.0, 1.0),
                      "Half-width of the band within which samples agree, as a fraction of "
                      "the views' full range (255 for 8-bit, 65535 for 16-bit, 1 for float), "
                      "(0, 1]."));
    field(OptionField("min_inlier_fraction", &O::min_inlier_fraction, "", Range::Closed(0.0, 1.0),
                      "Fewest inliers, as a fraction of the pixel's samples, for the robust "
                      "mean to be used, [0, 1]; fewer keep the plain mean."));
  }
};

// The focal points of an output image, for renders whose pixels do not come from a plane: the
// perspective depth path below, and orthographic maps. points[y * width + x] is where pixel
// (x, y) focuses, in the light field's local frame relative to `reference` (both double, so
// UTM-sized frames lose nothing); a non-finite point means the pixel meets no surface (count 0).
struct FocalPoints {
  int width = 0;
  int height = 0;
  Vec3d reference{0.0};
  std::vector<Vec3d> points;
};

// How RenderIntegralAtPoints chooses the views at a focal point X: the rules of integral.h
// (in front of the view, inside its image, not grazing against surface_normal), and an aperture.
// The aperture (aperture.h; aperture_radius is measured as `aperture` says) and the geometry
// of the points' cameras below.
struct PointIntegralOptions : ApertureOptions {
  enum class Aperture {
    // A perspective virtual camera: the line from X through the view centre C_i must cross the
    // lens plane (through lens_center, perpendicular to lens_axis) within aperture_radius of
    // lens_center; aperture_radius 0 takes the single view crossing nearest to it (integral.h).
    kLensPlane,
    // An orthographic (map) camera: C_i must lie within aperture_radius of the line through X
    // along lens_axis (a vertical cylinder around the point for a map looking straight down);
    // aperture_radius 0 takes the single view nearest to that line.
    kCylinder,
  };
  Aperture aperture = Aperture::kLensPlane;
  Vec3d lens_center{0.0};            // local frame (kLensPlane)
  Vec3d lens_axis{0.0, 0.0, 1.0};    // unit: the virtual camera's optical axis, or the map's up
  Vec3d surface_normal{0.0, 0.0, 1.0};  // what the grazing test measures against
  bool variance = false;             // as IntegralOptions

  // Throws std::invalid_argument naming the field.
  void Check(int view_count) const;
};

struct SurfaceIntegralResult {
  IntegralResult integral;     // image, count (samples), statistics as RenderIntegral's
  Image inliers;               // uint32: samples averaged per pixel (robust), else empty
  int64_t fallback_pixels = 0; // robust: pixels that kept the plain mean
  // Light-field indices of the views that contributed to at least one pixel, ascending
  // (integral.views_used of them); what a tiled render (map.h) unites over its tiles.
  std::vector<int> used_view_indices;
};

// Averages the views at every focal point (plain or robust mean as above). The result's
// cam_from_world is left as the identity; renders of a virtual camera set it.
SurfaceIntegralResult RenderIntegralAtPoints(const LightField& light_field,
                                             const FocalPoints& points,
                                             const PointIntegralOptions& options,
                                             const SurfaceIntegralOptions& surface = {},
                                             ProgressSink* progress = nullptr);

// The depth path: the virtual camera of `options` (integral.h) and its depth map give the focal
// points (relative to the camera centre), the lens plane is the camera's, and
// GrazingNormal(light_field, options) is the grazing test's (the depth map, not
// options.focal_surface, gives the focal points).
SurfaceIntegralResult RenderIntegralOnDepth(const LightField& light_field,
                                            const IntegralOptions& options, const Image& depth,
                                            const SurfaceIntegralOptions& surface = {},
                                            ProgressSink* progress = nullptr);

}  // namespace aos
