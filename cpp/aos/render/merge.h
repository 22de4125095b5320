#pragma once
// All-in-focus merging of a focal stack into one image, a depth map and a confidence map.
//
// Methods
// - sobel (the paper's baseline): per slice the Sobel gradient magnitude of the luminance, the
//   3 x 3 Sobel operator being the paper's "3x3 neighbourhood" (no further window); per pixel the
//   slice where it is largest wins (ties to the lower slice); the image is that slice's pixel and
//   the depth that slice's plane.
// - improved (default), context-aware: the focus measure is the Sobel energy gx^2 + gy^2 averaged
//   over a (2 window_radius + 1)^2 window; the peak of each pixel's focus curve is refined to a
//   fraction of a slice by a parabola through the best slice and its two neighbours (|offset|
//   <= 1/2); the fractional slice map is smoothed edge-aware (a joint bilateral filter guided by
//   the sharpest slice's image, each neighbour weighted by its confidence, applied separably:
//   along rows, then columns; smoothing_iterations passes); the image blends the two slices around the smoothed depth linearly (from a stored
//   stack), or is re-integrated from the views on the smoothed depth surface (the one-call
//   pipeline, RenderAllInFocus, which never holds the slices).
// - robust: the focus cue adds what only the rays show, the per-pixel variance of the view
//   samples (IntegralOptions::variance; in-focus ground looks the same from every view,
//   occluders and defocused points do not): the window's Sobel energy divided by its mean
//   variance (both scale with the square of the values, so the ratio has no units); refinement and smoothing as improved; then the image is
//   re-integrated on the depth surface with the outlier-rejecting mean of surface_integral.h,
//   which falls back to the plain mean where too few rays agree. Needs the light field.
//
// Contract (all methods)
// - A slice's pixel with count 0 has no focus value; a Sobel tap on such a pixel takes the centre
//   pixel's value (no false edge along coverage borders). A pixel no slice covers gets image 0,
//   depth 0, confidence 0 and slice -1. robust needs a variance, so two views: a pixel that no
//   slice covers with at least two views is treated the same way (and counted as uncovered).
// - depth is z in the virtual camera frame, metres, on the (interpolated) plane of the pixel's
//   fractional slice (0 where that plane is met behind the camera or not at all); slice is that
//   fractional index in [0, N-1]. For a terrain-following stack (focal_stack.h) the slice's
//   focus is the surface at the interpolated offset (SliceFocus::DepthOfSlices), and the
//   re-integration measures grazing angles against the horizontal.
// - The streaming pipeline and the merge of a stored stack fold the same focus values, so their
//   depth, slice and confidence maps are identical when the stack was rendered as the pipeline
//   renders it (variance on for robust, off otherwise: the variance pass uses the scalar
//   kernel, whose samples differ from the AVX2 kernel's in the last float bit).
// - confidence = (F_best - mean F) / max(|F_best|, |mean F|) over the slices covering the pixel
//   (0 when that is 0/0: a constant image or one slice), in [0, 1].
// - Deterministic: the result depends neither on the thread count nor on the order of
//   floating-point work across threads; no NaN or infinity reaches an output.
//
// Coarse-to-fine (RenderAllInFocus with AllInFocusOptions::coarse_to_fine = factor f >= 2)
// - A coarse stack: the virtual camera at 1/f the width and height (rounded up; the field of
//   view widened to match, so a coarse pixel is an f x f block of output pixels), on every f-th
//   slice and the last, all rendered in one call of the depth path (RenderIntegralAtPoints on
//   the slices' points, packed 16 coarse pixels at a time with their slices together, so each
//   view's pixels under a patch stay in cache across the slices; the plane render's rules,
//   equal up to float rounding), merged with the same focus cue (window radius ceil(r / f), at
//   least 1).
// - Each block takes the full slices from the coarse slice before its coarse focus maximum to
//   the one after it (at most 2f + 1 slices; every slice where no coarse slice covers it);
//   where the coarse peak is concave (both neighbours, negative curvature) only those within
//   1.5 full slices of the parabola's vertex (its coarse position mapped linearly onto the full
//   slices): 4 or 5 slices, which hold the full-stack peak and both its parabola neighbours
//   wherever that peak lies within half a slice of the vertex. Full slice i is rendered at full
//   resolution only on the blocks that take it, through the depth path
//   (RenderIntegralAtPoints on the plane's or surface's points: the plane render's rules,
//   results equal up to float rounding; every (slice, pixel) pair in one call, packed block by
//   block so that each tile of points covers a compact patch of the image, or slice by slice
//   in calls of at most 2^21 points where there are more or the planes' normals differ: the
//   same outputs either way), and its focus values, computed
//   as for a full slice with the pixels not rendered counting as uncovered, enter the fold only
//   there; elsewhere the slice has no focus value.
// - So where a pixel's full-stack peak and its two neighbours lie in its block's slices, and the
//   blocks within window_radius + 1 pixels take them too, the fold (best slice, parabola) equals
//   the full stack's up to that rounding; elsewhere it is the best slice within the band (a
//   focus curve with several peaks, as on real low-texture data, may then end elsewhere than
//   the full stack's: docs/benchmarks.md, F0). The confidence is the coarse stack's (over every
//   slice; the fine fold sees only the slices near the peak), so the smoothed depth and the
//   image differ slightly from the full stack's everywhere (tests: merge_test
//   CoarseToFine*; figures: docs/accuracy-vs-time.md, tools/bench_coarse_to_fine.py).
// - MergeResult::rendered_fraction says which fraction of the full stack's pixels was
//   rendered; seconds_render counts the coarse stack, the fine slices and the re-integration.
//
// Throws std::invalid_argument naming the option or the missing input; aos::Cancelled.
#include <string>

#include "aos/render/focal_stack.h"
#include "aos/render/surface_integral.h"
#include "aos/util/option_fields.h"
#include "aos/util/parallel.h"

namespace aos {

enum class MergeMethod { kSobel, kImproved, kRobust };

// "sobel", "improved", "robust"; throws std::invalid_argument naming `option` otherwise.
MergeMethod ParseMergeMethod(const std::string& name, const std::string& option = "method");
const char* MergeMethodName(MergeMethod method);
template <>
struct EnumNames<MergeMethod> {
  static constexpr std::pair<MergeMethod, const char*> kValues[] = {
      {MergeMethod::kSobel, "sobel"}, {MergeMethod::kImproved, "improved"},
      {MergeMethod::kRobust, "robust"}};
};

struct MergeOptions {
  MergeMethod method = MergeMethod::kImproved;
  // improved/robust: focus measure window radius, pixels (window 2r+1 on a side), 0..32.
  int window_radius = 3;
  // improved/robust: spatial sigma of the edge-aware depth smoothing, pixels, [0, 16]; 0 = off.
  double smoothing_sigma = 3.0;
  // improved/robust: range sigma of the smoothing, as a fraction of the guide image's contrast
  // (its 1st to 99th percentile), > 0.
  double edge_sigma = 0.2;
  // improved/robust: smoothing passes, 0..20.
  int smoothing_iterations = 3;
  // robust: the outlier-rejecting mean (surface_integral.h); `robust.robust` is forced on.
  SurfaceIntegralOptions robust;
  // Worker threads of the merge (the slices render with their own render.num_threads); -1 = all
  // cores.
  int num_threads = -1;

  void Check() const;
  // The field table (util/option_fields.h): every field once, in declaration order.
  template <class Visit>
  static void Fields(Visit&& field) {
    using O = MergeOptions;
    field(OptionField("method", &O::method, "", Range::Any(),
                      "sobel, improved (default) or robust."));
    field(OptionField("window_radius", &O::window_radius, "px", Range::Closed(0, 32),
                      "improved/robust: focus measure window radius, pixels (window 2r+1 on a "
                      "side), 0..32."));
    field(OptionField("smoothing_sigma", &O::smoothing_sigma, "px", Range::Closed(0.0, 16.0),
                      "improved/robust: spatial sigma of the edge-aware depth smoothing, "
                      "pixels, [0, 16]; 0 = off."));
    field(OptionField("edge_sigma", &O::edge_sigma, "", Range::FiniteAtLeast(0.0, /*open=*/true),
                      "improved/robust: range sigma of the smoothing, as a fraction of the "
                      "guide image's contrast (1st to 99th percentile), > 0."));
    field(OptionField("smoothing_iterations", &O::smoothing_iterations, "", Range::Closed(0, 20),
                      "improved/robust: smoothing passes, 0..20."));
    field(OptionField("robust", &O::robust, "", Range::Any(),
                      "robust: the outlier-rejecting mean (SurfaceIntegralOptions; its robust "
                      "flag is forced on)."));
    field(OptionField("num_threads", &O::num_threads, "", kThreadCountRange,
                      "Worker threads of the merge (slices render with render.num_threads); "
                      "-1 = all cores."));
  }
};

struct MergeResult {
  Image image;       // float32, the views' channels: the all-in-focus image
  Image depth;       // float32, metres (camera z); 0 where no slice covers the pixel
  Image confidence;  // float32, [0, 1]
  Image slice;       // float32, fractional slice index; -1 where no slice covers the pixel
  int64_t uncovered_pixels = 0;  // pixels no slice covers
  int64_t fallback_pixels = 0;   // robust: pixels that kept the plain mean
  double seconds_merge = 0.0;    // focus measures, refinement, smoothing, image
  double seconds_render = 0.0;   // rendering (slices and re-integration)
  // RenderAllInFocus: the full-resolution slice pixels rendered, as a fraction of the full
  // stack's (1 without coarse_to_fine; the coarse stack not counted).
  double rendered_fraction = 1.0;
};

// Merges a stack held in memory. The robust method needs the stack's variances and the light
// field it was rendered from (the stack's `render` options are reused).
MergeResult MergeFocalStack(const FocalStack& stack, const MergeOptions& options,
                            const LightField* light_field = nullptr,
                            ProgressSink* progress = nullptr);

struct AllInFocusOptions {
  FocalStackOptions stack;  // stack.render.variance is set by the method (robust needs it)
  MergeOptions merge;
  // Coarse-to-fine (see the contract above): 0 = off, every slice rendered at full resolution;
  // a factor 2..16 = a coarse stack of 1/factor the width and height on every factor-th slice
  // chooses each factor x factor block's slices, and only those are rendered at full
  // resolution (4: docs/accuracy-vs-time.md).
  int coarse_to_fine = 0;
  // Also refuses robust with aperture_radius 0 (one view a pixel has no variance), and a
  // coarse_to_fine outside 0 and 2..16.
  void Check(int view_count) const;
  // The field table (util/option_fields.h): every field once, in declaration order.
  template <class Visit>
  static void Fields(Visit&& field) {
    using O = AllInFocusOptions;
    field(OptionField("stack", &O::stack, "", Range::Any(),
                      "The slices (FocalStackOptions)."));
    field(OptionField("merge", &O::merge, "", Range::Any(),
                      "The merge (MergeOptions)."));
    field(OptionField("coarse_to_fine", &O::coarse_to_fine, "", Range::Closed(2, 16).Or(0),
                      "0 = off; a factor 2..16: a coarse stack (1/factor the size, every "
                      "factor-th slice) chooses each factor x factor block's slices, only "
                      "those render at full resolution."));
  }
};

// The one-call pipeline: renders the slices one at a time and folds each into per-pixel focus
// state, so memory does not grow with the number of slices; then refines, smooths and
// re-integrates (improved: plain mean, robust: robust mean) on the depth surface; sobel keeps the
// winning slice's pixels.
MergeResult RenderAllInFocus(const LightField& light_field, const AllInFocusOptions& options,
                             ProgressSink* progress = nullptr);

namespace internal {
// Coarse-to-fine's fine pass packs its (slice, pixel) points block by block, one render call
// (on by default; where they exceed one call's bound, or the planes' normals differ, it packs
// them slice by slice); off: always slice by slice, as before. The outputs are the same either
// way (tests compare them); only the time differs. Not thread-safe: set it before rendering.
void SetCoarseToFineBlockPacking(bool enabled);
// Coarse-to-fine's coarse stack renders every coarse slice in one call of packed points (on by
// default, under the same conditions as above); off: slice by slice through RenderIntegral
// (the plane's span kernels), as before. The focus values then differ by float rounding
// (the depth path's samples against the span kernels'), so the outputs agree up to that
// (tests compare them). Not thread-safe: set it before rendering.
void SetCoarseToFineCoarsePoints(bool enabled);
}  // namespace internal

}  // namespace aos
