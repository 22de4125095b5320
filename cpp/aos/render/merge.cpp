#include "aos/render/merge.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <utility>
#include <vector>

#include <omp.h>

#include "aos/util/error.h"
#include "aos/util/memory.h"
#include "aos/util/parallel.h"
#include "aos/util/timer.h"

// How it works
// Every method reduces a slice to one focus value per pixel (higher = sharper) and folds the
// slices, in order, into per-pixel state: the best value and its slice, the values of the slices
// just before and after it, and the sum of values (for the confidence). That state is all the
// refinement needs, so the streaming pipeline and the merge of a stored stack share it and give
// the same depth maps; only the final image differs (see merge.h).

namespace aos {
namespace {

constexpr float kNone = -std::numeric_limits<float>::infinity();

// Luminance (mean over channels) of a float32 image.
std::vector<float> Luminance(const Image& image) {
  const int w = image.width(), h = image.height(), channels = image.channels();
  std::vector<float> out(static_cast<size_t>(w) * h);
  for (int y = 0; y < h; ++y) {
    const float* row = image.At<float>(0, y);
    for (int x = 0; x < w; ++x) {
      float sum = 0.0f;
      for (int c = 0; c < channels; ++c) sum += row[x * channels + c];
      out[static_cast<size_t>(y) * w + x] = sum / static_cast<float>(channels);
    }
  }
  return out;
}

// Box mean of `value` over the (2r+1)^2 window, over the pixels where `valid` is set; centres
// that are not valid get kNone. Each window is summed directly (a row pass, then a column pass
// of 2r+1 terms each), not from a summed-area table: a table's four-corner differences leave
// rounding residue where the values are all 0 (flat ground), which a focus measure must see as
// exactly 0. Fixed order: deterministic.
std::vector<float> WindowMean(const std::vector<double>& value, const std::vector<uint8_t>& valid,
                              int w, int h, int r, int threads) {
  const size_t n = static_cast<size_t>(w) * h;
  std::vector<double> row_sum(n, 0.0);
  std::vector<int32_t> row_number(n, 0);
#pragma omp parallel for num_threads(threads) schedule(static)
  for (int64_t yy = 0; yy < h; ++yy) {
    const size_t row = static_cast<size_t>(yy) * w;
    for (int x = 0; x < w; ++x) {
      double sum = 0.0;
      int32_t number = 0;
      for (int qx = std::max(0, x - r); qx <= std::min(w - 1, x + r); ++qx) {
        if (!valid[row + qx]) continue;
        sum += value[row + qx];
        ++number;
      }
      row_sum[row + x] = sum;
      row_number[row + x] = number;
    }
  }
  std::vector<float> out(n, kNone);
#pragma omp parallel for num_threads(threads) schedule(static)
  for (int64_t yy = 0; yy < h; ++yy) {
    const int y = static_cast<int>(yy);
    for (int x = 0; x < w; ++x) {
      const size_t centre = static_cast<size_t>(y) * w + x;
      if (!valid[centre]) continue;
      double sum = 0.0;
      int64_t number = 0;
      for (int qy = std::max(0, y - r); qy <= std::min(h - 1, y + r); ++qy) {
        sum += row_sum[static_cast<size_t>(qy) * w + x];
        number += row_number[static_cast<size_t>(qy) * w + x];
      }
      out[centre] = static_cast<float>(sum / static_cast<double>(number));
    }
  }
  return out;
}

// The focus value of every pixel of one slice (kNone where the slice does not cover it).
std::vector<float> FocusValues(MergeMethod method, const Image& image, const Image& count,
                               const Image* variance, int window_radius, int threads) {
  const int w = image.width(), h = image.height();
  const size_t n = static_cast<size_t>(w) * h;
  std::vector<uint8_t> covered(n);
  for (int y = 0; y < h; ++y) {
    const uint32_t* c = count.At<uint32_t>(0, y);
    for (int x = 0; x < w; ++x) covered[static_cast<size_t>(y) * w + x] = c[x] > 0;
  }
  const std::vector<float> luminance = Luminance(image);
  std::vector<double> energy(n, 0.0);
#pragma omp parallel for num_threads(threads) schedule(static)
  for (int64_t yy = 0; yy < h; ++yy) {
    const int y = static_cast<int>(yy);
    for (int x = 0; x < w; ++x) {
      const size_t centre = static_cast<size_t>(y) * w + x;
      if (!covered[centre]) continue;
      const float own = luminance[centre];
      auto tap = [&](int dx, int dy) {
        const int qx = std::clamp(x + dx, 0, w - 1), qy = std::clamp(y + dy, 0, h - 1);
        const size_t q = static_cast<size_t>(qy) * w + qx;
        return covered[q] ? static_cast<double>(luminance[q]) : static_cast<double>(own);
      };
      const double gx = (tap(1, -1) + 2.0 * tap(1, 0) + tap(1, 1)) -
                        (tap(-1, -1) + 2.0 * tap(-1, 0) + tap(-1, 1));
      const double gy = (tap(-1, 1) + 2.0 * tap(0, 1) + tap(1, 1)) -
                        (tap(-1, -1) + 2.0 * tap(0, -1) + tap(1, -1));
      energy[centre] = gx * gx + gy * gy;
    }
  }
  if (method == MergeMethod::kSobel) {
    std::vector<float> out(n, kNone);
    for (size_t i = 0; i < n; ++i) {
      if (covered[i]) out[i] = static_cast<float>(std::sqrt(energy[i]));
    }
    return out;
  }
  if (method == MergeMethod::kImproved) return WindowMean(energy, covered, w, h, window_radius, threads);
  // Robust: sharpness per unit of disagreement between the views, window energy over window
  // variance. Both scale with the square of the image values, so the ratio does not depend on
  // the views' units; in-focus texture has high energy and low variance, occluders and defocus
  // raise the variance.
  std::vector<double> spread(n, 0.0);
  std::vector<uint8_t> agreeing(n, 0);
  for (int y = 0; y < h; ++y) {
    const uint32_t* c = count.At<uint32_t>(0, y);
    const float* v = variance->At<float>(0, y);
    for (int x = 0; x < w; ++x) {
      const size_t i = static_cast<size_t>(y) * w + x;
      agreeing[i] = c[x] >= 2;
      spread[i] = v[x];
    }
  }
  std::vector<float> sharp = WindowMean(energy, covered, w, h, window_radius, threads);
  const std::vector<float> disagreement =
      WindowMean(spread, agreeing, w, h, window_radius, threads);
  for (size_t i = 0; i < n; ++i) {
    if (sharp[i] == kNone || disagreement[i] == kNone) {
      sharp[i] = kNone;
      continue;
    }
    const double e = sharp[i];
    sharp[i] = static_cast<float>(e / (static_cast<double>(disagreement[i]) + 1e-12 * (1.0 + e)));
  }
  return sharp;
}

// Per-pixel focus state folded over the slices in order.
class FocusAccumulator {
 public:
  FocusAccumulator(const PinholeCamera& camera, int channels, int slices)
      : w_(camera.width), h_(camera.height), slices_(slices),
        best_(Size(), kNone), before_(Size(), kNone), after_(Size(), kNone),
        last_(Size(), kNone), best_index_(Size(), -1), covered_slices_(Size(), 0),
        sum_(Size(), 0.0), guide_(camera.width, camera.height, channels, PixelType::kF32) {}

  void Add(int index, const Image& image, const std::vector<float>& focus) {
    const int channels = image.channels();
    for (int y = 0; y < h_; ++y) {
      const float* in = image.At<float>(0, y);
      float* guide = guide_.At<float>(0, y);
      for (int x = 0; x < w_; ++x) {
        const size_t i = static_cast<size_t>(y) * w_ + x;
        const float f = focus[i];
        if (best_index_[i] == index - 1 && index > 0) after_[i] = f;
        if (f != kNone) {
          sum_[i] += f;
          ++covered_slices_[i];
          if (best_index_[i] < 0 || f > best_[i]) {
            best_[i] = f;
            best_index_[i] = index;
            before_[i] = index > 0 ? last_[i] : kNone;
            after_[i] = kNone;
            for (int c = 0; c < channels; ++c) guide[x * channels + c] = in[x * channels + c];
          }
        }
        last_[i] = f;
      }
    }
  }

  // Fractional slice (-1 where uncovered), confidence, and the number of uncovered pixels.
  int64_t Finish(bool refine, std::vector<float>* slice, std::vector<float>* confidence) const {
    slice->assign(Size(), -1.0f);
    confidence->assign(Size(), 0.0f);
    int64_t uncovered = 0;
    for (size_t i = 0; i < Size(); ++i) {
      if (best_index_[i] < 0) {
        ++uncovered;
        continue;
      }
      const double best = best_[i];
      const double mean = sum_[i] / covered_slices_[i];
      const double scale = std::max(std::abs(best), std::abs(mean));
      (*confidence)[i] = scale > 0.0 ? static_cast<float>(std::clamp((best - mean) / scale, 0.0, 1.0)) : 0.0f;
      double offset = 0.0;
      if (refine && before_[i] != kNone && after_[i] != kNone) {
        // Vertex of the parabola through (-1, before), (0, best), (1, after).
        const double a = before_[i], c = after_[i];
        const double curvature = a - 2.0 * best + c;
        if (curvature < 0.0) offset = std::clamp(0.5 * (a - c) / curvature, -0.5, 0.5);
      }
      (*slice)[i] = static_cast<float>(std::clamp(best_index_[i] + offset, 0.0,
                                                  static_cast<double>(slices_ - 1)));
    }
    return uncovered;
  }

  const Image& guide() const { return guide_; }

 private:
  size_t Size() const { return static_cast<size_t>(w_) * h_; }

  int w_, h_, slices_;
  std::vector<float> best_, before_, after_, last_;
  std::vector<int32_t> best_index_, covered_slices_;
  std::vector<double> sum_;
  Image guide_;  // the sharpest slice's pixels (sobel's image, the smoothing guide)
};

// Joint bilateral smoothing of the fractional slice map, weighted by confidence.
void SmoothSlices(const MergeOptions& options, const Image& guide_image,
                  const std::vector<float>& confidence, std::vector<float>* slice, int threads) {
  if (options.smoothing_sigma <= 0.0 || options.smoothing_iterations <= 0) return;
  const int w = guide_image.width(), h = guide_image.height();
  const std::vector<float> guide = Luminance(guide_image);
  // Contrast of the guide: its 1st to 99th percentile over covered pixels.
  std::vector<float> values;
  for (size_t i = 0; i < guide.size(); ++i) {
    if ((*slice)[i] >= 0.0f) values.push_back(guide[i]);
  }
  if (values.empty()) return;
  auto percentile = [&](double p) {
    const size_t k = static_cast<size_t>(p * (values.size() - 1));
    std::nth_element(values.begin(), values.begin() + k, values.end());
    return values[k];
  };
  const double contrast = percentile(0.99) - percentile(0.01);
  const double range_sigma = options.edge_sigma * contrast;
  // Range weights from a table over |difference| in [0, 4 range_sigma).
  constexpr int kTable = 1024;
  std::vector<float> range_weight(kTable + 1);
  for (int k = 0; k <= kTable; ++k) {
    const double d = 4.0 * k / kTable;
    range_weight[static_cast<size_t>(k)] = k == kTable ? 0.0f : static_cast<float>(std::exp(-0.5 * d * d));
  }
  const double to_table = range_sigma > 0.0 ? kTable / (4.0 * range_sigma) : 0.0;  // 0: flat
  const int radius = static_cast<int>(std::ceil(2.0 * options.smoothing_sigma));
  // Per pass, a neighbour's weight is base[q] * spatial * range: base is its confidence (0 for
  // pixels without a slice), range a table lookup on the scaled guide difference (contrast 0:
  // every difference is 0, the weight 1). Single precision, fixed order: deterministic.
  const size_t n = slice->size();
  std::vector<float> scaled(n), base(n), next(n);
  for (size_t i = 0; i < n; ++i) scaled[i] = static_cast<float>(guide[i] * to_table);
  // Each pass filters along rows, then along columns (the separable approximation of the 2-D
  // joint bilateral filter, Pham & van Vliet 2005): 2 (2 radius + 1) taps instead of
  // (2 radius + 1)^2, so the fixed cost stays small next to the per-slice work.
  std::vector<float> spatial_1d(static_cast<size_t>(2 * radius + 1));
  for (int d = -radius; d <= radius; ++d) {
    spatial_1d[static_cast<size_t>(d + radius)] =
        static_cast<float>(std::exp(-0.5 * d * d / (options.smoothing_sigma * options.smoothing_sigma)));
  }
  const auto filter = [&](bool along_rows) {
    const std::vector<float>& current = *slice;
    for (size_t i = 0; i < n; ++i) base[i] = current[i] >= 0.0f && confidence[i] > 0.0f ? confidence[i] : 0.0f;
#pragma omp parallel for num_threads(threads) schedule(static)
    for (int64_t yy = 0; yy < h; ++yy) {
      const int y = static_cast<int>(yy);
      for (int x = 0; x < w; ++x) {
        const size_t p = static_cast<size_t>(y) * w + x;
        next[p] = current[p];
        if (current[p] < 0.0f) continue;
        const float own = scaled[p];
        const int centre = along_rows ? x : y, extent = along_rows ? w : h;
        const int lo = std::max(0, centre - radius), hi = std::min(extent - 1, centre + radius);
        const ptrdiff_t step = along_rows ? 1 : w;
        float weights = 0.0f, sum = 0.0f;
        for (int t = lo; t <= hi; ++t) {
          const size_t q = static_cast<size_t>(static_cast<ptrdiff_t>(p) + (t - centre) * step);
          const float difference = std::abs(scaled[q] - own);
          const int k = difference < static_cast<float>(kTable) ? static_cast<int>(difference) : kTable;
          const float weight = base[q] * spatial_1d[static_cast<size_t>(t - centre + radius)] *
                               range_weight[static_cast<size_t>(k)];
          weights += weight;
          sum += weight * current[q];
        }
        if (weights > 0.0f) next[p] = sum / weights;
      }
    }
    slice->swap(next);
  };
  for (int pass = 0; pass < options.smoothing_iterations; ++pass) {
    filter(true);
    filter(false);
  }
}

// Depth of every pixel on the plane of its fractional slice.
Image DepthOfSlices(const PinholeCamera& camera, const Rigid3d& cam_from_world,
                    const std::vector<Plane>& planes, const std::vector<float>& slice, int threads) {
  Image depth(camera.width, camera.height, 1, PixelType::kF32);
  const Vec3d center = cam_from_world.Center();
  const Mat3d world_from_cam = glm::transpose(cam_from_world.rotation);
  const int last = static_cast<int>(planes.size()) - 1;
#pragma omp parallel for num_threads(threads) schedule(static)
  for (int64_t yy = 0; yy < camera.height; ++yy) {
    const int y = static_cast<int>(yy);
    float* row = depth.At<float>(0, y);
    for (int x = 0; x < camera.width; ++x) {
      const float z = slice[static_cast<size_t>(y) * camera.width + x];
      if (z < 0.0f) continue;
      const int i0 = std::min(static_cast<int>(z), last);
      const double fraction = z - i0;
      const Plane plane = i0 == last || fraction == 0.0
                              ? planes[static_cast<size_t>(i0)]
                              : InterpolatePlane(planes[static_cast<size_t>(i0)],
                                                 planes[static_cast<size_t>(i0 + 1)], fraction, center);
      const Vec3d normal = glm::normalize(plane.normal);
      const Vec3d direction = world_from_cam * camera.Unproject(Vec2d(x + 0.5, y + 0.5));
      const double f = glm::dot(normal, direction);
      const double t = f != 0.0 ? glm::dot(normal, plane.point - center) / f : 0.0;
      row[x] = t > 0.0 && std::isfinite(t) ? static_cast<float>(t) : 0.0f;
    }
  }
  return depth;
}

Image ToImage(const std::vector<float>& values, int w, int h) {
  Image image(w, h, 1, PixelType::kF32);
  for (int y = 0; y < h; ++y) {
    std::copy(values.begin() + static_cast<ptrdiff_t>(y) * w,
              values.begin() + static_cast<ptrdiff_t>(y + 1) * w, image.At<float>(0, y));
  }
  return image;
}

// Pixels where the re-integration saw nothing keep the guide (sharpest slice) value.
void FillUncovered(const Image& count, const Image& guide, Image* image) {
  const int channels = image->channels();
  for (int y = 0; y < image->height(); ++y) {
    const uint32_t* c = count.At<uint32_t>(0, y);
    float* out = image->At<float>(0, y);
    const float* g = guide.At<float>(0, y);
    for (int x = 0; x < image->width(); ++x) {
      if (c[x] > 0) continue;
      for (int k = 0; k < channels; ++k) out[x * channels + k] = g[x * channels + k];
    }
  }
}

// What the stack-merge and the pipeline share after the slices are folded in.
struct Folded {
  std::vector<float> slice, confidence;
  int64_t uncovered = 0;
};

Folded Refine(const FocusAccumulator& accumulator, const MergeOptions& options, int threads) {
  Folded folded;
  const bool refine = options.method != MergeMethod::kSobel;
  folded.uncovered = accumulator.Finish(refine, &folded.slice, &folded.confidence);
  if (refine) SmoothSlices(options, accumulator.guide(), folded.confidence, &folded.slice, threads);
  return folded;
}

MergeResult Assemble(const Folded& folded, const PinholeCamera& camera,
                     const Rigid3d& cam_from_world, const std::vector<Plane>& planes, int threads) {
  MergeResult result;
  result.slice = ToImage(folded.slice, camera.width, camera.height);
  result.confidence = ToImage(folded.confidence, camera.width, camera.height);
  result.depth = DepthOfSlices(camera, cam_from_world, planes, folded.slice, threads);
  result.uncovered_pixels = folded.uncovered;
  return result;
}

// Re-integrates on the merged depth (plain or robust mean).
// The grazing test measures against the first slice's plane.
void Reintegrate(const LightField& light_field, const IntegralOptions& render,
                 const Plane& first_plane, const MergeOptions& options, const Image& guide,
                 MergeResult* result, ProgressSink* progress) {
  SurfaceIntegralOptions surface = options.robust;
  surface.robust = options.method == MergeMethod::kRobust;
  IntegralOptions on_depth = render;
  on_depth.focal_plane = first_plane;
  on_depth.variance = false;
  on_depth.num_threads = options.num_threads;
  SurfaceIntegralResult integral =
      RenderIntegralOnDepth(light_field, on_depth, result->depth, surface, progress);
  result->image = std::move(integral.integral.image);
  FillUncovered(integral.integral.count, guide, &result->image);
  result->fallback_pixels = integral.fallback_pixels;
}

}  // namespace

MergeMethod ParseMergeMethod(const std::string& name, const std::string& option) {
  if (name == "sobel") return MergeMethod::kSobel;
  if (name == "improved") return MergeMethod::kImproved;
  if (name == "robust") return MergeMethod::kRobust;
  ThrowInvalid(option + ": unknown merge method '" + name + "' (sobel, improved or robust)");
}

const char* MergeMethodName(MergeMethod method) {
  switch (method) {
    case MergeMethod::kSobel: return "sobel";
    case MergeMethod::kImproved: return "improved";
    default: return "robust";
  }
}

void MergeOptions::Check() const {
  if (window_radius < 0 || window_radius > 32) {
    ThrowInvalid("window_radius: must be 0..32 pixels (got " + std::to_string(window_radius) + ")");
  }
  if (!(smoothing_sigma >= 0.0 && smoothing_sigma <= 16.0)) {
    ThrowInvalid("smoothing_sigma: must be in [0, 16] pixels (got " + FormatNumber(smoothing_sigma) + ")");
  }
  if (!(edge_sigma > 0.0) || !std::isfinite(edge_sigma)) {
    ThrowInvalid("edge_sigma: must be a finite number > 0 (got " + FormatNumber(edge_sigma) + ")");
  }
  if (smoothing_iterations < 0 || smoothing_iterations > 20) {
    ThrowInvalid("smoothing_iterations: must be 0..20 (got " + std::to_string(smoothing_iterations) + ")");
  }
  CheckThreadCount(num_threads);
  robust.Check();
}

void AllInFocusOptions::Check(int view_count) const {
  stack.Check(view_count);
  merge.Check();
  if (merge.method == MergeMethod::kRobust && stack.render.aperture_radius == 0.0) {
    ThrowInvalid("aperture_radius: 0 (one view a pixel) leaves method robust no variance to "
                 "work with; use a wider aperture");
  }
}

MergeResult MergeFocalStack(const FocalStack& stack, const MergeOptions& options,
                            const LightField* light_field, ProgressSink* progress) {
  options.Check();
  stack.Check("focal stack");
  if (options.method == MergeMethod::kRobust) {
    if (stack.render.aperture_radius == 0.0) {
      ThrowInvalid("method robust: the stack was rendered with aperture_radius 0 (one view a "
                   "pixel, no variance); robust needs a wider aperture");
    }
    if (stack.variances.empty()) {
      ThrowInvalid("method robust: the stack has no variance images (render it with variance)");
    }
    if (light_field == nullptr) {
      ThrowInvalid("method robust: needs the light field the stack was rendered from (the rays "
                   "are re-integrated)");
    }
  }
  const int threads = ResolveThreadCount(options.num_threads);
  const Timer timer;
  ProgressStart(progress, "merge", stack.size());
  FocusAccumulator accumulator(stack.camera, stack.images.front().channels(), stack.size());
  for (int i = 0; i < stack.size(); ++i) {
    if (ProgressCancelled(progress)) throw Cancelled();
    const size_t k = static_cast<size_t>(i);
    const std::vector<float> focus =
        FocusValues(options.method, stack.images[k], stack.counts[k],
                    stack.variances.empty() ? nullptr : &stack.variances[k],
                    options.window_radius, threads);
    accumulator.Add(i, stack.images[k], focus);
    ProgressAdvance(progress, 1);
  }
  const Folded folded = Refine(accumulator, options, threads);
  MergeResult result = Assemble(folded, stack.camera, stack.cam_from_world, stack.planes, threads);
  if (options.method == MergeMethod::kSobel) {
    result.image = accumulator.guide().Clone();
  } else if (options.method == MergeMethod::kImproved) {
    // Linear blend of the two slices around the smoothed fractional slice.
    const Image& guide = accumulator.guide();
    const int channels = guide.channels(), last = stack.size() - 1;
    result.image = Image(stack.camera.width, stack.camera.height, channels, PixelType::kF32);
    for (int y = 0; y < stack.camera.height; ++y) {
      float* out = result.image.At<float>(0, y);
      const float* g = guide.At<float>(0, y);
      for (int x = 0; x < stack.camera.width; ++x) {
        const float z = folded.slice[static_cast<size_t>(y) * stack.camera.width + x];
        if (z < 0.0f) continue;
        const int i0 = std::min(static_cast<int>(z), last), i1 = std::min(i0 + 1, last);
        const double fraction = z - i0;
        const bool has0 = stack.counts[static_cast<size_t>(i0)].At<uint32_t>(x, y)[0] > 0;
        const bool has1 = stack.counts[static_cast<size_t>(i1)].At<uint32_t>(x, y)[0] > 0;
        const float* a = stack.images[static_cast<size_t>(i0)].At<float>(x, y);
        const float* b = stack.images[static_cast<size_t>(i1)].At<float>(x, y);
        for (int c = 0; c < channels; ++c) {
          double value;
          if (has0 && has1) {
            value = (1.0 - fraction) * a[c] + fraction * b[c];
          } else if (has0 || has1) {
            value = has0 ? a[c] : b[c];
          } else {
            value = g[x * channels + c];
          }
          out[x * channels + c] = static_cast<float>(value);
        }
      }
    }
  }
  result.seconds_merge = timer.Seconds();
  if (options.method == MergeMethod::kRobust) {
    const Timer render_timer;
    Reintegrate(*light_field, stack.render, stack.planes.front(), options, accumulator.guide(),
                &result, progress);
    result.seconds_render = render_timer.Seconds();
  }
  return result;
}

MergeResult RenderAllInFocus(const LightField& light_field, const AllInFocusOptions& options,
                             ProgressSink* progress) {
  options.Check(static_cast<int>(light_field.views.size()));
  AllInFocusOptions run = options;
  run.stack.render.variance = options.merge.method == MergeMethod::kRobust;
  const int threads = ResolveThreadCount(options.merge.num_threads);
  const PinholeCamera camera = VirtualCamera(light_field, run.stack.render);
  const Rigid3d cam_from_world = VirtualCamFromWorld(light_field, run.stack.render);
  {
    // Streaming keeps one slice and the merge state (best image, focus, depth, confidence,
    // slice, counts): about twice a slice plus 24 bytes a pixel, whatever the number of slices.
    const uint64_t channels = static_cast<uint64_t>(light_field.views.front().image.channels());
    CheckMemoryBudget(
        SaturatingProduct({static_cast<uint64_t>(camera.width),
                           static_cast<uint64_t>(camera.height),
                           2 * (channels * 4 + 8) + 24}),
        "width/height: " + std::to_string(camera.width) + " x " + std::to_string(camera.height) +
            " pixels",
        "one slice and the merge state, estimated");
  }
  std::unique_ptr<FocusAccumulator> accumulator;
  std::vector<Plane> planes;
  double seconds_merge = 0.0;
  const Timer timer;
  RenderFocalStackSlices(
      light_field, run.stack,
      [&](int index, const Plane& plane, IntegralResult& slice) {
        const Timer merge_timer;
        if (!accumulator) {
          accumulator = std::make_unique<FocusAccumulator>(camera, slice.image.channels(),
                                                           run.stack.slices);
        }
        planes.push_back(plane);
        const std::vector<float> focus =
            FocusValues(run.merge.method, slice.image, slice.count,
                        run.stack.render.variance ? &slice.variance : nullptr,
                        run.merge.window_radius, threads);
        accumulator->Add(index, slice.image, focus);
        seconds_merge += merge_timer.Seconds();
      },
      progress);
  const double seconds_stack = timer.Seconds() - seconds_merge;
  const Timer refine_timer;
  const Folded folded = Refine(*accumulator, run.merge, threads);
  MergeResult result = Assemble(folded, camera, cam_from_world, planes, threads);
  seconds_merge += refine_timer.Seconds();
  if (run.merge.method == MergeMethod::kSobel) {
    result.image = accumulator->guide().Clone();
    result.seconds_render = seconds_stack;
  } else {
    const Timer render_timer;
    const IntegralOptions render = WithResolvedCamera(light_field, run.stack.render);
    Reintegrate(light_field, render, planes.front(), run.merge, accumulator->guide(), &result,
                progress);
    result.seconds_render = seconds_stack + render_timer.Seconds();
  }
  result.seconds_merge = seconds_merge;
  return result;
}

}  // namespace aos
