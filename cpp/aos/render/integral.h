#pragma once
// Integral rendering (Eq. 1 of the AOS paper): for every pixel of a virtual camera, intersect its
// ray with the focal plane, project that focal point into every selected view, sample the view
// bilinearly and average over the views that actually see the point.
//
// Contract
// - Inputs are in the light field's local frame (see lightfield.h), metres; the pixel convention
//   is pinhole.h's (pixel centres at +0.5). The virtual camera is a pinhole with square pixels and
//   principal point at the image centre; fov_deg is its horizontal field of view.
// - A view contributes to a pixel when the focal point X (a) lies in front of the view (depth > 0)
//   and projects inside its image area [0, width] x [0, height] (edges replicated for the
//   bilinear taps), (b) is not seen at a grazing angle: the ray from X to the view centre makes
//   an angle of at least min_view_angle_deg with the focal plane, and (c) passes the aperture:
//   the line from X through the view centre crosses the virtual camera's lens plane (through its
//   centre, perpendicular to its optical axis) inside the disk of radius aperture_radius around
//   the virtual camera centre. aperture_radius = infinity admits every view; 0 is a pinhole: each
//   pixel takes the single view whose line crosses the lens plane nearest to the centre (ties go
//   to the lower view index).
// - image(x, y) = sum of samples / count(x, y), accumulated in double precision; pixels no view
//   sees get count 0 and the value 0.
// - Pixels whose ray misses the focal plane, or hits it behind the virtual camera, get count 0
//   (a plane of any orientation may be seen by only part of the image). A plane that no pixel's
//   ray meets in front of the camera (it lies behind), or that contains the camera centre (its
//   rays run along it), is an error.
// - In nearest mode (aperture_radius 0), ties go to the lower view index; views_used counts the
//   views chosen for at least one pixel.
// - With `variance`, variance(x, y) = mean over channels of (sum of samples^2 / count - mean^2),
//   the population variance of the view samples (0 where count < 2, never negative). Points on
//   the focal surface look alike from every view, occluders and defocused points do not: it is
//   a focus cue (merge.h). The image then comes from the scalar kernel (equal to the default
//   render up to float rounding).
//
// - Views with a lens model (View::lens, lens.h) are sampled through it directly: each pixel's
//   focal point is projected through the lens model into the raw frame (one resampling; no
//   rectified copy). Such renders take surface_integral.h's per-sample path on the plane's depth
//   map, with the same admission rules; the lens projection is replaced by local maps
//   (homographies; cubic polynomials for fisheye and omnidirectional lenses) within
//   lens_tolerance_px view pixels (0: every sample projected exactly, results then equal up to
//   float rounding), at about 1.2x (radial-tangential) to 1.4x (fisheye, omnidirectional) the
//   time of the homography path pinhole views take on rectified frames (docs/lens-models.md).
//
// - With a focal_surface (focal_surface.h) that is not a plane, or with views that have a lens
//   model, the render takes surface_integral.h's path on the surface's depth map
//   (FocalSurface::DepthFor): pixels whose rays miss the surface get count 0 and count in
//   uncovered_pixels. A plane surface over pinhole views takes the homography path. The
//   grazing test (b) measures against the plane, or for other surfaces against the horizontal
//   (GrazingNormal). surface_offset moves any surface, a plane too, along up.
//
// Throws std::invalid_argument (naming the option) for bad options, aos::Cancelled if the
// progress sink asks to stop.
#include <cstdint>
#include <limits>
#include <memory>
#include <vector>

#include "aos/geometry/rigid.h"
#include "aos/image/image.h"
#include "aos/lightfield/lightfield.h"
#include "aos/render/aperture.h"
#include "aos/render/focal_surface.h"
#include "aos/util/progress.h"
#include "aos/util/option_fields.h"
#include "aos/util/parallel.h"

namespace aos {

// The virtual camera when neither it nor a pose view gives one.
constexpr double kDefaultFovDeg = 50.0;
constexpr int kDefaultSize = 512;

// The aperture (aperture.h: aperture_radius, view_indices, min_view_angle_deg,
// lens_tolerance_px, num_threads) and the virtual camera, focus and outputs below.
struct IntegralOptions : ApertureOptions {
  // Virtual camera pose, local frame -> camera (OpenCV axes). Ignored when pose_view >= 0.
  Rigid3d cam_from_world;
  // If >= 0, the virtual camera takes the pose of this view (index into the light field).
  int pose_view = -1;
  // Horizontal field of view of the virtual camera, degrees, (0, 180); 0 = view pose_view's
  // (its pinhole part), or kDefaultFovDeg without pose_view.
  double fov_deg = 0.0;
  // Output size, pixels (1 .. 65536 each); 0 = view pose_view's size, or kDefaultSize without
  // pose_view.
  int width = 0;
  int height = 0;
  // Where the rays are focused (focal_surface.h): a plane (local frame; the exact homography
  // kernel), a mesh, a DEM height field or a depth map. The default is the horizontal plane z = 0.
  // One value for every render (stack, merge, map, viewer); `--focal-height H` is the CLI
  // spelling of FocalSurface::FromPlane(Plane::AtHeight(H)). Shares its data, never modified.
  FocalSurface focal_surface = FocalSurface::FromPlane(Plane::AtHeight(0.0));
  // Offset of focal_surface along the up axis (focal_surface.h: +-z, towards the views), metres:
  // 1.0 focuses one metre above the terrain (or above the plane).
  double surface_offset = 0.0;
  // Also return the per-pixel variance of the view samples (the kernels then also sum their
  // squares: AVX2 for 1-channel views, else scalar).
  bool variance = false;
  // Pixels averaged over fewer views than this are left uncovered (image and variance 0, count
  // 0): at the rim of the synthetic aperture few views see a point and its occluders do not
  // blur away. 0 or 1 keeps every pixel a view sees. IntegralResult::views_used still counts
  // the views that reached any pixel before this threshold.
  int min_view_count = 0;

  // Throws std::invalid_argument naming the offending field. `view_count` is the number of views
  // in the light field (for pose_view and view_indices).
  void Check(int view_count) const;
  // The field table (util/option_fields.h): every field once, in declaration order.
  template <class Visit>
  static void Fields(Visit&& field) {
    using O = IntegralOptions;
    field(OptionField("cam_from_world", &O::cam_from_world, "", Range::Any(),
                      "Virtual camera pose, local frame -> camera (OpenCV axes). Ignored when "
                      "pose_view >= 0."));
    field(OptionField("pose_view", &O::pose_view, "", Range::AtLeast(-1),
                      "If >= 0, the virtual camera takes the pose of this view (index into "
                      "the light field)."));
    field(OptionField("fov_deg", &O::fov_deg, "deg", Range::Open(0.0, 180.0).Or(0.0),
                      "Horizontal field of view of the virtual camera, degrees, (0, 180); 0 = "
                      "the pose view's, else 50."));
    field(OptionField("width", &O::width, "px", Range::Closed(1, 65536).Or(0),
                      "Output width, pixels (1 .. 65536); 0 = the pose view's, else 512."));
    field(OptionField("height", &O::height, "px", Range::Closed(1, 65536).Or(0),
                      "Output height, pixels (1 .. 65536); 0 = the pose view's, else 512."));
    field(OptionField("focal_surface", &O::focal_surface, "", Range::Any(),
                      "Where the rays are focused: a plane (a number is the horizontal plane "
                      "z = that height, local frame), a Mesh, a Heightfield (DEM) or a "
                      "FocalSurface; default the plane z = 0."));
    field(OptionField("surface_offset", &O::surface_offset, "m", Range::Finite(),
                      "Offset of focal_surface along up (towards the views), metres."));
    field(OptionField("variance", &O::variance, "", Range::Any(),
                      "Also return the per-pixel variance of the view samples (the samples "
                      "then go through the scalar kernel, which also sums their squares: a "
                      "few times slower)."));
    field(OptionField("min_view_count", &O::min_view_count, "", Range::AtLeast(0),
                      "Pixels averaged over fewer views than this are left uncovered (image "
                      "and count 0): the rim of the aperture, where few views see a point and "
                      "its occluders stay; 0 = keep every pixel a view sees."));
    ApertureOptions::Fields(field);  // aperture.h
  }
};

// The normal the grazing-angle test measures against: a plane surface's unit normal, else the
// up axis of the surface's placement for these views (ResolveSurfacePlacement: +-z).
Vec3d GrazingNormal(const LightField& light_field, const IntegralOptions& options);

struct IntegralResult {
  Image image;          // float32, width x height x channels of the views
  Image count;          // uint32, width x height: views that contributed to each pixel
  Image variance;       // float32, width x height, when IntegralOptions::variance (else empty)
  int64_t samples = 0;  // sum of count (view samples taken)
  int views_used = 0;   // selected views that contributed to at least one pixel
  int views_selected = 0;
  int64_t uncovered_pixels = 0;  // pixels with count 0
  Rigid3d cam_from_world;        // the virtual camera pose that was used
};

IntegralResult RenderIntegral(const LightField& light_field, const IntegralOptions& options,
                              ProgressSink* progress = nullptr);

// Scores of one view's frame as a quadratic of its value: scale * (value - centre)^2, with
// one_sided 0 below centre (global RX of a 1-channel frame is one: detect/anomaly.h
// FrameQuadratic).
struct ViewQuadratic {
  float centre = 0.0f;
  float scale = 0.0f;
  bool one_sided = false;
};

struct QuadraticIntegralResult {
  // RenderIntegral's result for the same options: bit for bit where both take the same kernel
  // (1-channel 8-bit frames with SIMD row loads, 16-bit frames, or no SIMD); float frames, and
  // 8-bit frames with row loads off, sum through the scalar quadratic kernel, within float
  // rounding of RenderIntegral's SIMD sums.
  IntegralResult integral;
  Image scores;             // float32, width x height x 1: the integrated scores (0: uncovered)
};

// RenderIntegral, and from the same samples the integral of every view's quadratic scores: at a
// pixel, the mean over the views averaged there of the bilinear interpolation of their four taps'
// scores scale_v * (tap - centre_v)^2 (float; 0 for a tap below centre_v where one_sided) — the integral of the frames' score images, without
// making them (synthetic aperture anomaly imaging, detect.h). `per_view` holds one entry per view
// of the light field (only the selected ones are read). Needs what QuadraticIntegralSupported
// checks; otherwise throws std::invalid_argument naming the field.
QuadraticIntegralResult RenderIntegralWithQuadratic(const LightField& light_field,
                                                    const IntegralOptions& options,
                                                    const std::vector<ViewQuadratic>& per_view,
                                                    ProgressSink* progress = nullptr);
// Whether RenderIntegralWithQuadratic takes `options` on `light_field`: an unmasked light field
// of 1-channel frames, pinhole views, a focal plane (the homography route), aperture_radius > 0
// (the mean, not the nearest view) and no variance.
bool QuadraticIntegralSupported(const LightField& light_field, const IntegralOptions& options);

// IntegralOptions::min_view_count on a rendered `result`: pixels averaged over fewer views become
// uncovered (image, count and variance 0; samples and uncovered_pixels follow). Every render of
// IntegralOptions applies it (RenderIntegral, RenderIntegralOnDepth).
void DropThinPixels(int min_view_count, IntegralResult* result);

// The virtual camera's intrinsics for `options`: square pixels, centred principal point, and
// fov_deg, width and height where given; what is not given (0) comes from view pose_view's
// camera (its horizontal field of view and size), else from kDefaultFovDeg and kDefaultSize.
PinholeCamera VirtualCamera(const LightField& light_field, const IntegralOptions& options);

// `options` with the virtual camera made explicit: cam_from_world, fov_deg, width and height as
// VirtualCamFromWorld and VirtualCamera resolve them, pose_view -1. Renders with it equal renders
// with `options` (what stacks and merges pass on).
IntegralOptions WithResolvedCamera(const LightField& light_field, const IntegralOptions& options);

// The virtual camera's pose: view pose_view's, or options.cam_from_world. Throws
// std::invalid_argument if that pose is not a rigid transform.
Rigid3d VirtualCamFromWorld(const LightField& light_field, const IntegralOptions& options);

}  // namespace aos
