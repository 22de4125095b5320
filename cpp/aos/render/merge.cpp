#include "aos/render/merge.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <atomic>
#include <functional>
#include <limits>
#include <memory>
#include <utility>
#include <vector>

#include <omp.h>

#include "aos/util/error.h"
#include "aos/util/math.h"
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

// Squared Sobel gradient of `luminance` at covered pixel (x, y) of a w x h image; taps off the
// image are clamped to its edge, uncovered taps take the centre's value (no edge at a hole).
double SobelEnergyAt(const std::vector<float>& luminance, const std::vector<uint8_t>& covered,
                     int w, int h, int x, int y) {
  const float own = luminance[static_cast<size_t>(y) * w + x];
  auto tap = [&](int dx, int dy) {
    const int qx = std::clamp(x + dx, 0, w - 1), qy = std::clamp(y + dy, 0, h - 1);
    const size_t q = static_cast<size_t>(qy) * w + qx;
    return covered[q] ? static_cast<double>(luminance[q]) : static_cast<double>(own);
  };
  const double gx = (tap(1, -1) + 2.0 * tap(1, 0) + tap(1, 1)) -
                    (tap(-1, -1) + 2.0 * tap(-1, 0) + tap(-1, 1));
  const double gy = (tap(-1, 1) + 2.0 * tap(0, 1) + tap(1, 1)) -
                    (tap(-1, -1) + 2.0 * tap(0, -1) + tap(1, -1));
  return gx * gx + gy * gy;
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
      energy[centre] = SobelEnergyAt(luminance, covered, w, h, x, y);
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
        last_(Size(), kNone), last_index_(Size(), -1), best_index_(Size(), -1),
        covered_slices_(Size(), 0),
        sum_(Size(), 0.0), guide_(camera.width, camera.height, channels, PixelType::kF32) {}

  void Add(int index, const Image& image, const std::vector<float>& focus) {
    const int channels = image.channels();
    for (int y = 0; y < h_; ++y) {
      const float* in = image.At<float>(0, y);
      for (int x = 0; x < w_; ++x) {
        const size_t i = static_cast<size_t>(y) * w_ + x;
        AddOne(index, i, focus[i], in + static_cast<size_t>(x) * channels);
      }
    }
  }

  // Add for a slice that has focus values only on `pixels` (indices y * width + x; `focus` is
  // read there only): the other pixels are folded as if their value were kNone (no value, and
  // no neighbour for the parabola), without visiting them.
  void AddAt(int index, const Image& image, const std::vector<int32_t>& pixels,
             const std::vector<float>& focus) {
    for (const int32_t p : pixels) {
      const size_t i = static_cast<size_t>(p);
      AddOne(index, i, focus[i], image.At<float>(static_cast<int>(p % w_), static_cast<int>(p / w_)));
    }
  }

  // Slice `index`'s focus value f at pixel i (y * width + x), its sample `in` (the guide's
  // channels): Add's and AddAt's work on one pixel. Calls for different pixels touch disjoint
  // state.
  void AddOne(int index, size_t i, float f, const float* in) {
    if (best_index_[i] == index - 1 && index > 0) after_[i] = f;
    if (f != kNone) {
      sum_[i] += f;
      ++covered_slices_[i];
      if (best_index_[i] < 0 || f > best_[i]) {
        best_[i] = f;
        best_index_[i] = index;
        before_[i] = index > 0 && last_index_[i] == index - 1 ? last_[i] : kNone;
        after_[i] = kNone;
        const int channels = guide_.channels();
        float* guide = guide_.At<float>(static_cast<int>(i % static_cast<size_t>(w_)),
                                        static_cast<int>(i / static_cast<size_t>(w_)));
        for (int c = 0; c < channels; ++c) guide[c] = in[c];
      }
    }
    last_[i] = f;
    last_index_[i] = index;
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
      if (refine) Vertex(i, &offset);
      (*slice)[i] = static_cast<float>(std::clamp(best_index_[i] + offset, 0.0,
                                                  static_cast<double>(slices_ - 1)));
    }
    return uncovered;
  }

  // The vertex of the parabola through pixel i's best slice and its two neighbours, as an
  // offset from the best slice clamped to [-1/2, 1/2]; false (offset 0) where a neighbour has
  // no value or the three values are not strictly concave.
  bool Vertex(size_t i, double* offset) const {
    *offset = 0.0;
    if (best_index_[i] < 0 || before_[i] == kNone || after_[i] == kNone) return false;
    // Vertex of the parabola through (-1, before), (0, best), (1, after).
    const double a = before_[i], b = best_[i], c = after_[i];
    const double curvature = a - 2.0 * b + c;
    if (!(curvature < 0.0)) return false;
    *offset = std::clamp(0.5 * (a - c) / curvature, -0.5, 0.5);
    return true;
  }

  const Image& guide() const { return guide_; }
  // The best slice of every pixel so far (-1: none).
  const std::vector<int32_t>& best_index() const { return best_index_; }

 private:
  size_t Size() const { return static_cast<size_t>(w_) * h_; }

  int w_, h_, slices_;
  std::vector<float> best_, before_, after_, last_;
  std::vector<int32_t> last_index_;  // the slice last_ came from (-1: none yet)
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

// `confidence` (coarse-to-fine), when given, replaces the accumulator's on covered pixels.
Folded Refine(const FocusAccumulator& accumulator, const MergeOptions& options, int threads,
              const std::vector<float>* confidence = nullptr) {
  Folded folded;
  const bool refine = options.method != MergeMethod::kSobel;
  folded.uncovered = accumulator.Finish(refine, &folded.slice, &folded.confidence);
  if (confidence != nullptr) {
    for (size_t i = 0; i < folded.slice.size(); ++i) {
      if (folded.slice[i] >= 0.0f) folded.confidence[i] = (*confidence)[i];
    }
  }
  if (refine) SmoothSlices(options, accumulator.guide(), folded.confidence, &folded.slice, threads);
  return folded;
}

MergeResult Assemble(const Folded& folded, const PinholeCamera& camera,
                     const Rigid3d& cam_from_world, const SliceFocus& focus, int threads) {
  MergeResult result;
  result.slice = ToImage(folded.slice, camera.width, camera.height);
  result.confidence = ToImage(folded.confidence, camera.width, camera.height);
  result.depth = focus.DepthOfSlices(camera, cam_from_world, folded.slice, threads);
  result.uncovered_pixels = folded.uncovered;
  return result;
}

// Re-integrates on the merged depth (plain or robust mean).
// The grazing test measures against the first slice's plane (for a surface: the horizontal).
void Reintegrate(const LightField& light_field, const IntegralOptions& render,
                 const SliceFocus& focus, const MergeOptions& options, const Image& guide,
                 MergeResult* result, ProgressSink* progress) {
  SurfaceIntegralOptions surface = options.robust;
  surface.robust = options.method == MergeMethod::kRobust;
  IntegralOptions on_depth = render;
  // The depth gives the focal points; the surface gives only the grazing normal.
  on_depth.focal_surface = FocalSurface::FromPlane(focus.GrazingPlane());
  on_depth.surface_offset = 0.0;
  on_depth.variance = false;
  on_depth.num_threads = options.num_threads;
  SurfaceIntegralResult integral =
      RenderIntegralOnDepth(light_field, on_depth, result->depth, surface, progress);
  result->image = std::move(integral.integral.image);
  FillUncovered(integral.integral.count, guide, &result->image);
  result->fallback_pixels = integral.fallback_pixels;
}

// ---- coarse-to-fine (AllInFocusOptions::coarse_to_fine) ----
//
// The coarse stack has 1/factor the width and height; its pixel (cx, cy) lies over the block
// of output pixels [cx factor, (cx + 1) factor) x [cy factor, ...) (the coarse camera has the
// field of view of the rounded-up size and square pixels, so blocks and coarse pixels coincide
// up to under a coarse pixel). Blocks are the unit whose slices the coarse pass chooses.
//
// The fine pass renders its (slice, pixel) pairs as packed focal points, many slices in one
// RenderIntegralAtPoints call (the depth path's rules: equal to the plane render up to float
// rounding): a render call has a fixed cost per view that small or sparse slices would pay
// once each otherwise. Packed block-major (each block's slices together), a tile of points is a
// compact patch of the image and the renderer culls most views per tile by its bounding box.

// Where the coarse focus curve has a concave peak, the full slices taken are those within
// kFineMargin full slices of its vertex (interpolated between the coarse slices' full indices),
// inside the coarse slices on either side of the peak: on the merge study's scenes the full
// stack's peak lies within half a slice of that vertex nearly everywhere, so the band holds it
// and both parabola neighbours (1.5 = 1 + 1/2); 4 or 5 slices instead of 2 factor + 1.
constexpr double kFineMargin = 1.5;

// Whether the fine pass packs its points block by block (the default) rather than slice by
// slice (internal::SetCoarseToFineBlockPacking; tests compare the two).
std::atomic<bool> g_block_packing{true};
// Whether the coarse stack renders through packed points (the default) rather than slice by
// slice through RenderIntegral (internal::SetCoarseToFineCoarsePoints; tests compare the two).
std::atomic<bool> g_coarse_points{true};
// Coarse pixels whose slices are packed together (coarse stack through packed points).
constexpr size_t kCoarseGroup = 16;

// Points packed per render call, at most (bounds the memory whatever the number of slices).
constexpr size_t kPackedPoints = size_t{1} << 21;
constexpr int kPackedWidth = 64;

// The cells of a width x height grid (y * width + x) in Morton (Z) order: consecutive cells stay
// near each other, so a tile of packed points covers a compact patch of the ground (the
// renderer culls views per tile by the tile's bounding box).
std::vector<int32_t> MortonOrder(int width, int height) {
  const auto spread = [](uint32_t v) {
    uint64_t x = v;
    x = (x | (x << 16)) & 0x0000FFFF0000FFFFull;
    x = (x | (x << 8)) & 0x00FF00FF00FF00FFull;
    x = (x | (x << 4)) & 0x0F0F0F0F0F0F0F0Full;
    x = (x | (x << 2)) & 0x3333333333333333ull;
    x = (x | (x << 1)) & 0x5555555555555555ull;
    return x;
  };
  std::vector<std::pair<uint64_t, int32_t>> keyed;
  keyed.reserve(static_cast<size_t>(width) * height);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      keyed.emplace_back(spread(static_cast<uint32_t>(x)) | (spread(static_cast<uint32_t>(y)) << 1),
                         y * width + x);
    }
  }
  std::sort(keyed.begin(), keyed.end());
  std::vector<int32_t> order(keyed.size());
  for (size_t k = 0; k < keyed.size(); ++k) order[k] = keyed[k].second;
  return order;
}

// The coarse stack's slice indices (into the full stack): every factor-th slice and the last.
std::vector<int> CoarseSliceIndices(int slices, int factor) {
  std::vector<int> indices;
  for (int i = 0; i < slices; i += factor) indices.push_back(i);
  if (indices.back() != slices - 1) indices.push_back(slices - 1);
  return indices;
}

// The focal points of slice `slice` on pixels `list` (indices y * width + x of `camera`): point
// j goes to out[positions[j]], or out[first + j] without positions; a ray that misses the plane
// or surface leaves its point as it was (NaN: count 0). `slice_of` is scratch (surfaces).
void SlicePoints(const SliceFocus& focus, const PinholeCamera& camera,
                 const Rigid3d& cam_from_world, int slice, const std::vector<int32_t>& list,
                 const int32_t* positions, size_t first, Vec3d* out,
                 std::vector<float>* slice_of, int threads) {
  const Vec3d centre = cam_from_world.Center();
  const Mat3d world_from_cam = glm::transpose(cam_from_world.rotation);
  const auto slot = [&](size_t j) -> Vec3d& {
    return out[positions != nullptr ? static_cast<size_t>(positions[j]) : first + j];
  };
  if (focus.surface) {
    slice_of->assign(static_cast<size_t>(camera.width) * camera.height, -1.0f);
    for (const int32_t p : list) (*slice_of)[static_cast<size_t>(p)] = static_cast<float>(slice);
    const Image depth = focus.DepthOfSlices(camera, cam_from_world, *slice_of, threads);
    for (size_t j = 0; j < list.size(); ++j) {
      const int x = list[j] % camera.width, y = list[j] / camera.width;
      const double z = depth.At<float>(x, y)[0];
      if (z > 0.0 && std::isfinite(z)) {
        slot(j) = z * (world_from_cam * camera.Unproject(Vec2d(x + 0.5, y + 0.5)));
      }
    }
    return;
  }
  // A plane: where each pixel's ray meets it (DepthOfSlices' arithmetic, kept in double).
  const Plane& plane = focus.planes[static_cast<size_t>(slice)];
  const Vec3d unit = glm::normalize(plane.normal);
  const double height = glm::dot(unit, plane.point - centre);
  const int64_t count = static_cast<int64_t>(list.size());
#pragma omp parallel for num_threads(threads) schedule(static) if (threads > 1)
  for (int64_t j = 0; j < count; ++j) {
    const int x = list[static_cast<size_t>(j)] % camera.width;
    const int y = list[static_cast<size_t>(j)] / camera.width;
    const Vec3d direction = world_from_cam * camera.Unproject(Vec2d(x + 0.5, y + 0.5));
    const double f = glm::dot(unit, direction);
    const double t = f != 0.0 ? height / f : 0.0;
    if (t > 0.0 && std::isfinite(t)) slot(static_cast<size_t>(j)) = t * direction;
  }
}

// The depth path's options for packed slices (the plane render's rules).
PointIntegralOptions PackedOptions(const IntegralOptions& resolved, const Rigid3d& cam_from_world,
                                   const Vec3d& normal, bool variance) {
  PointIntegralOptions at_points;
  // The aperture, whole (lens_tolerance_px included: it was left at its default before).
  static_cast<ApertureOptions&>(at_points) = resolved;
  at_points.aperture = PointIntegralOptions::Aperture::kLensPlane;
  at_points.lens_center = cam_from_world.Center();
  at_points.lens_axis = Row(cam_from_world.rotation, 2);
  at_points.surface_normal = normal;
  at_points.variance = variance;
  return at_points;
}

// Renders slice `slices[k]`'s pixels `pixels(k)` (indices y * width + x of `camera`) for every
// k in one call per kPackedPoints points, handing each slice to `on_slice(k, packed, first)`:
// its pixels are packed row-major at positions first, first + 1, ... of the result
// (kPackedWidth wide). Slices are handed over in order. Rays that miss a slice's plane or
// surface give count 0.
using PackedSink =
    std::function<void(size_t k, const SurfaceIntegralResult& packed, size_t first)>;
using PixelLists = std::function<const std::vector<int32_t>&(size_t k)>;
void RenderPackedSlices(const LightField& light_field, const IntegralOptions& resolved,
                        const PinholeCamera& camera, const Rigid3d& cam_from_world,
                        const SliceFocus& focus, const std::vector<int>& slices,
                        const PixelLists& pixels, bool variance,
                        int threads, const PackedSink& on_slice, ProgressSink* progress) {
  const Vec3d centre = cam_from_world.Center();
  const size_t n = slices.size();
  std::vector<float> slice_of;  // surfaces: DepthOfSlices' per-pixel slice
  size_t k0 = 0;
  while (k0 < n) {
    if (ProgressCancelled(progress)) throw Cancelled();
    // A chunk: consecutive slices with one grazing normal, up to kPackedPoints points.
    const Vec3d normal = focus.surface ? focus.GrazingPlane().normal
                                       : focus.planes[static_cast<size_t>(slices[k0])].normal;
    size_t k1 = k0, total = 0;
    while (k1 < n && (k1 == k0 || total + pixels(k1).size() <= kPackedPoints) &&
           (focus.surface || focus.planes[static_cast<size_t>(slices[k1])].normal == normal)) {
      total += pixels(k1).size();
      ++k1;
    }
    FocalPoints points;
    points.width = kPackedWidth;
    points.height = static_cast<int>(std::max<size_t>(1, (total + kPackedWidth - 1) / kPackedWidth));
    points.reference = centre;
    points.points.assign(static_cast<size_t>(points.width) * points.height,
                         Vec3d(std::numeric_limits<double>::quiet_NaN()));
    std::vector<size_t> first(k1 - k0 + 1, 0);
    for (size_t k = k0; k < k1; ++k) {
      const std::vector<int32_t>& list = pixels(k);
      first[k - k0 + 1] = first[k - k0] + list.size();
      SlicePoints(focus, camera, cam_from_world, slices[k], list, nullptr, first[k - k0],
                  points.points.data(), &slice_of, threads);
    }
    const PointIntegralOptions at_points =
        PackedOptions(resolved, cam_from_world, normal, variance);
    SurfaceIntegralResult packed;
    try {
      packed = RenderIntegralAtPoints(light_field, points, at_points);
    } catch (const std::invalid_argument& error) {
      ThrowInvalid("slice " + std::to_string(slices[k0]) + ": " + error.what());
    }
    for (size_t k = k0; k < k1; ++k) on_slice(k, packed, first[k - k0]);
    k0 = k1;
  }
}

struct CoarseChoice {
  int blocks_x = 0, blocks_y = 0;
  // The coarse stack's confidence (over all its slices) of every block, 0 where uncovered.
  std::vector<float> confidence;
  // Block b takes the full slices first[b] .. last[b] (its focus values come from those).
  std::vector<int32_t> first, last;
};

// Renders the coarse stack (every factor-th slice) and chooses every block's slices: the full
// slices from the coarse slice before its coarse pixel's focus maximum to the one after it (a
// focus curve sampled every factor-th slice has its peak within one sample of the sampled
// maximum), narrowed to kFineMargin around the vertex where the coarse peak is concave. A
// coarse pixel that no coarse slice covers gives its block every slice (the coarse pass knows
// nothing there).
CoarseChoice ChooseSlices(const LightField& light_field, const AllInFocusOptions& run,
                          const IntegralOptions& resolved, const PinholeCamera& camera,
                          const SliceFocus& focus, int threads, ProgressSink* progress) {
  const int factor = run.coarse_to_fine, slices = run.stack.slices;
  IntegralOptions coarse = resolved;
  coarse.width = std::max(1, (camera.width + factor - 1) / factor);
  coarse.height = std::max(1, (camera.height + factor - 1) / factor);
  // The field of view widened to the rounded-up size: a coarse pixel stays factor output pixels
  // wide (the coarse image reaches under factor - 1 pixels past the output's edges, centred).
  coarse.fov_deg = 2.0 * std::atan(std::tan(0.5 * resolved.fov_deg * kPi / 180.0) *
                                   coarse.width * factor / camera.width) * 180.0 / kPi;
  const PinholeCamera coarse_camera = VirtualCamera(light_field, coarse);
  const std::vector<int> indices = CoarseSliceIndices(slices, factor);
  const int coarse_slices = static_cast<int>(indices.size());
  // The focus window covers about the same ground as the full-resolution one.
  const int coarse_radius = std::max(1, (run.merge.window_radius + factor - 1) / factor);
  const bool variance = run.merge.method == MergeMethod::kRobust;
  ProgressStart(progress, "coarse stack", coarse_slices);
  FocusAccumulator accumulator(coarse_camera, light_field.views.front().image.channels(),
                               coarse_slices);
  // Every coarse slice in one call of packed points (below), or, where they exceed one call's
  // bound or the planes' normals differ, each a whole (small) image: the plane render (span
  // kernels) or, for a surface, RenderIntegral's surface path.
  coarse.variance = variance;
  const int cw = coarse_camera.width, ch = coarse_camera.height;
  const size_t coarse_pixels = static_cast<size_t>(cw) * ch;
  const size_t groups = (coarse_pixels + kCoarseGroup - 1) / kCoarseGroup;
  bool one_normal = true;
  for (int k = 0; k < coarse_slices && !focus.surface; ++k) {
    one_normal = one_normal && focus.planes[static_cast<size_t>(indices[static_cast<size_t>(k)])]
                                       .normal == focus.planes[0].normal;
  }
  const bool packed_route = g_coarse_points &&
                            one_normal && groups * kCoarseGroup * coarse_slices <= kPackedPoints;
  const Rigid3d cam_from_world = VirtualCamFromWorld(light_field, coarse);
  if (packed_route) {
    // Every coarse slice in one render call of packed points: groups of kCoarseGroup coarse
    // pixels in Morton order, each group's slices one after another. A tile of points is then a
    // small patch of the image on every slice, and each view's pixels under it (the patch and
    // its parallax across the slices) stay in cache from one slice to the next; rendered slice
    // by slice, each slice streamed every view's footprint from memory again (a coarse pixel
    // is factor view pixels wide, so neighbouring coarse pixels share no view pixels).
    const std::vector<int32_t> order = MortonOrder(cw, ch);
    FocalPoints points;
    points.width = kPackedWidth;
    const size_t total = groups * kCoarseGroup * static_cast<size_t>(coarse_slices);
    points.height = static_cast<int>((total + kPackedWidth - 1) / kPackedWidth);
    points.reference = cam_from_world.Center();
    points.points.assign(static_cast<size_t>(points.width) * points.height,
                         Vec3d(std::numeric_limits<double>::quiet_NaN()));
    // The slices' points, a slice per thread at a time (each writes its own places).
    std::vector<std::vector<int32_t>> places(static_cast<size_t>(threads));
    std::vector<std::vector<float>> slice_of(static_cast<size_t>(threads));
    ParallelForPerThread(coarse_slices, threads, nullptr, [&](int64_t index, int thread) {
      const size_t k = static_cast<size_t>(index);
      std::vector<int32_t>& at = places[static_cast<size_t>(thread)];
      at.resize(coarse_pixels);
      for (size_t m = 0; m < coarse_pixels; ++m) {
        at[m] = static_cast<int32_t>((m / kCoarseGroup) * kCoarseGroup * coarse_slices +
                                     k * kCoarseGroup + m % kCoarseGroup);
      }
      SlicePoints(focus, coarse_camera, cam_from_world, indices[k], order, at.data(), 0,
                  points.points.data(), &slice_of[static_cast<size_t>(thread)], 1);
    });
    const Vec3d normal = focus.surface ? focus.GrazingPlane().normal : focus.planes[0].normal;
    SurfaceIntegralResult packed;
    try {
      packed = RenderIntegralAtPoints(light_field, points,
                                      PackedOptions(coarse, cam_from_world, normal, variance));
    } catch (const std::invalid_argument& error) {
      ThrowInvalid("coarse slices: " + std::string(error.what()));
    }
    const int channels = packed.integral.image.channels();
    // Each coarse slice's image and focus values, a slice per thread at a time, then folded
    // in slice order.
    std::vector<Image> images(static_cast<size_t>(coarse_slices));
    std::vector<std::vector<float>> values(static_cast<size_t>(coarse_slices));
    ParallelForPerThread(coarse_slices, threads, progress, [&](int64_t index, int) {
      const int k = static_cast<int>(index);
      IntegralResult slice;
      slice.image = Image(cw, ch, channels, PixelType::kF32);
      slice.count = Image(cw, ch, 1, PixelType::kU32);
      if (variance) slice.variance = Image(cw, ch, 1, PixelType::kF32);
      for (size_t m = 0; m < coarse_pixels; ++m) {
        const size_t at = (m / kCoarseGroup) * kCoarseGroup * coarse_slices +
                          static_cast<size_t>(k) * kCoarseGroup + m % kCoarseGroup;
        const int px = static_cast<int>(at % kPackedWidth), py = static_cast<int>(at / kPackedWidth);
        const int x = order[m] % cw, y = order[m] / cw;
        const float* in = packed.integral.image.At<float>(px, py);
        float* out = slice.image.At<float>(x, y);
        for (int c = 0; c < channels; ++c) out[c] = in[c];
        *slice.count.At<uint32_t>(x, y) = *packed.integral.count.At<uint32_t>(px, py);
        if (variance) *slice.variance.At<float>(x, y) = *packed.integral.variance.At<float>(px, py);
      }
      values[static_cast<size_t>(k)] =
          FocusValues(run.merge.method, slice.image, slice.count,
                      variance ? &slice.variance : nullptr, coarse_radius, 1);
      images[static_cast<size_t>(k)] = std::move(slice.image);
    });
    for (int k = 0; k < coarse_slices; ++k) {
      accumulator.Add(k, images[static_cast<size_t>(k)], values[static_cast<size_t>(k)]);
    }
  }
  for (int k = 0; k < coarse_slices && !packed_route; ++k) {
    if (ProgressCancelled(progress)) throw Cancelled();
    const int i = indices[static_cast<size_t>(k)];
    if (focus.surface) {
      coarse.surface_offset = focus.offsets[static_cast<size_t>(i)];
    } else {
      coarse.focal_surface = FocalSurface::FromPlane(focus.planes[static_cast<size_t>(i)]);
    }
    IntegralResult slice;
    try {
      slice = RenderIntegral(light_field, coarse);
    } catch (const std::invalid_argument& error) {
      ThrowInvalid("slice " + std::to_string(i) + ": " + error.what());
    }
    const std::vector<float> values =
        FocusValues(run.merge.method, slice.image, slice.count,
                    variance ? &slice.variance : nullptr, coarse_radius, threads);
    accumulator.Add(k, slice.image, values);
    ProgressAdvance(progress, 1);
  }
  const std::vector<int32_t>& best = accumulator.best_index();
  CoarseChoice choice;
  std::vector<float> coarse_slice;
  accumulator.Finish(false, &coarse_slice, &choice.confidence);
  choice.blocks_x = coarse_camera.width;
  choice.blocks_y = coarse_camera.height;
  const size_t blocks = static_cast<size_t>(choice.blocks_x) * choice.blocks_y;
  choice.first.resize(blocks);
  choice.last.resize(blocks);
  for (size_t block = 0; block < blocks; ++block) {
    const int b = best[block];
    choice.first[block] = b < 0 ? 0 : indices[static_cast<size_t>(std::max(0, b - 1))];
    choice.last[block] =
        b < 0 ? slices - 1 : indices[static_cast<size_t>(std::min(coarse_slices - 1, b + 1))];
    double offset = 0.0;
    if (b < 0 || !accumulator.Vertex(block, &offset)) continue;
    // A concave coarse peak: its vertex, in full slices (between b's neighbours the coarse
    // slices are evenly spaced but for the last), +- kFineMargin full slices, inside the band.
    const size_t from = static_cast<size_t>(offset < 0.0 ? b - 1 : b);
    const double fraction = offset < 0.0 ? 1.0 + offset : offset;
    const double peak = indices[from] + fraction * (indices[from + 1] - indices[from]);
    choice.first[block] = std::max(choice.first[block],
                                   static_cast<int32_t>(std::floor(peak - kFineMargin)));
    choice.last[block] = std::min(choice.last[block],
                                  static_cast<int32_t>(std::ceil(peak + kFineMargin)));
  }
  return choice;
}

// Direct window mean of `value` at (x, y) over the valid pixels of the (2r+1)^2 window, in
// WindowMean's order (each row's sum, then the rows'), so it equals WindowMean's value bit for
// bit; kNone if the centre is not valid.
float WindowMeanAt(const std::vector<double>& value, const std::vector<uint8_t>& valid, int w,
                   int h, int r, int x, int y) {
  const size_t centre = static_cast<size_t>(y) * w + x;
  if (!valid[centre]) return kNone;
  double sum = 0.0;
  int64_t number = 0;
  for (int qy = std::max(0, y - r); qy <= std::min(h - 1, y + r); ++qy) {
    const size_t row = static_cast<size_t>(qy) * w;
    double row_sum = 0.0;
    int32_t row_number = 0;
    for (int qx = std::max(0, x - r); qx <= std::min(w - 1, x + r); ++qx) {
      if (!valid[row + qx]) continue;
      row_sum += value[row + qx];
      ++row_number;
    }
    sum += row_sum;
    number += row_number;
  }
  return static_cast<float>(sum / static_cast<double>(number));
}

// The fine pass of RenderAllInFocus with coarse_to_fine: slice i is rendered at full resolution
// only on the blocks that take it; its focus values (FocusValues' arithmetic, pixel by pixel,
// the pixels not rendered counting as uncovered) enter the fold there; elsewhere the slice has
// no focus value, as a slice that does not cover a pixel. Returns the fraction of the full
// stack's pixels rendered.
double FoldCoarseToFine(const LightField& light_field, const AllInFocusOptions& run,
                        const IntegralOptions& resolved, const PinholeCamera& camera,
                        const Rigid3d& cam_from_world, const SliceFocus& focus,
                        const CoarseChoice& choice, int threads,
                        std::unique_ptr<FocusAccumulator>* accumulator, double* seconds_merge,
                        double* seconds_render, ProgressSink* progress) {
  const int w = camera.width, h = camera.height, slices = run.stack.slices;
  const int factor = run.coarse_to_fine, r = run.merge.window_radius;
  const MergeMethod method = run.merge.method;
  const size_t pixels = static_cast<size_t>(w) * h;
  const int channels = light_field.views.front().image.channels();
  const bool variance = method == MergeMethod::kRobust;
  *accumulator = std::make_unique<FocusAccumulator>(camera, channels, slices);
  const Timer list_timer;
  // Every slice's pixels, block by block in Morton order (packed points stay near each other),
  // and each one's place in the block-major packing: block after block in Morton order, each
  // block's slices one after another.
  std::vector<int> indices(static_cast<size_t>(slices));
  std::vector<std::vector<int32_t>> lists(static_cast<size_t>(slices));
  std::vector<std::vector<int32_t>> places(static_cast<size_t>(slices));
  int64_t rendered = 0;
  int32_t place = 0;
  const std::vector<int32_t> block_order = MortonOrder(choice.blocks_x, choice.blocks_y);
  std::vector<int32_t> block_place;  // the first place of each block (in block_order)
  block_place.reserve(block_order.size());
  for (const int32_t block : block_order) {
    block_place.push_back(place);
    const int bx = block % choice.blocks_x, by = block / choice.blocks_x;
    for (int i = choice.first[static_cast<size_t>(block)];
         i <= choice.last[static_cast<size_t>(block)]; ++i) {
      std::vector<int32_t>& list = lists[static_cast<size_t>(i)];
      std::vector<int32_t>& at = places[static_cast<size_t>(i)];
      for (int y = by * factor; y < std::min(h, (by + 1) * factor); ++y) {
        for (int x = bx * factor; x < std::min(w, (bx + 1) * factor); ++x) {
          list.push_back(y * w + x);
          if (static_cast<size_t>(place) < kPackedPoints) at.push_back(place++);
        }
      }
    }
  }
  for (int i = 0; i < slices; ++i) {
    indices[static_cast<size_t>(i)] = i;
    rendered += static_cast<int64_t>(lists[static_cast<size_t>(i)].size());
  }
  *seconds_merge += list_timer.Seconds();
  // One slice's working images (read at its pixels and their neighbours only).
  struct SliceScratch {
    std::vector<float> luminance;
    std::vector<double> energy, spread;
    std::vector<uint8_t> covered, agreeing;
    std::vector<float> values;
    Image image;
  };
  const auto make_scratch = [&](SliceScratch* s) {
    s->luminance.assign(pixels, 0.0f);
    s->energy.assign(pixels, 0.0);
    s->spread.assign(pixels, 0.0);
    s->covered.assign(pixels, 0);
    s->agreeing.assign(pixels, 0);
    s->values.assign(pixels, kNone);
    s->image = Image(w, h, channels, PixelType::kF32);
  };
  // Slice i's focus values on its pixels lists[i] into s.values (its samples into s.image):
  // `in` holds pixel j of the list (image index p) at position(j, p); `inner` threads.
  const auto slice_values = [&](int i, const IntegralResult& in, const auto& position,
                                SliceScratch& s, int inner) {
    const size_t k = static_cast<size_t>(i);
    const std::vector<int32_t>& list = lists[k];
    for (size_t j = 0; j < list.size(); ++j) {
      const size_t p = static_cast<size_t>(list[j]);
      const auto [px, py] = position(j, p);
      const uint32_t n = in.count.At<uint32_t>(px, py)[0];
      const float* sample = in.image.At<float>(px, py);
      float* out = s.image.At<float>(static_cast<int>(p % w), static_cast<int>(p / w));
      float sum = 0.0f;
      for (int c = 0; c < channels; ++c) {
        out[c] = sample[c];
        sum += sample[c];
      }
      s.covered[p] = n > 0;
      s.agreeing[p] = n >= 2;
      s.luminance[p] = sum / static_cast<float>(channels);
      if (variance) s.spread[p] = in.variance.At<float>(px, py)[0];
    }
    const int64_t count = static_cast<int64_t>(list.size());
    // Sobel energy (FocusValues' arithmetic; pixels not rendered are uncovered).
#pragma omp parallel for num_threads(inner) schedule(static) if (inner > 1)
    for (int64_t j = 0; j < count; ++j) {
      const size_t p = static_cast<size_t>(list[static_cast<size_t>(j)]);
      const int x = static_cast<int>(p % w), y = static_cast<int>(p / w);
      if (!s.covered[p]) continue;
      s.energy[p] = SobelEnergyAt(s.luminance, s.covered, w, h, x, y);
    }
#pragma omp parallel for num_threads(inner) schedule(static) if (inner > 1)
    for (int64_t j = 0; j < count; ++j) {
      const size_t p = static_cast<size_t>(list[static_cast<size_t>(j)]);
      const int x = static_cast<int>(p % w), y = static_cast<int>(p / w);
      if (!s.covered[p]) continue;
      if (method == MergeMethod::kSobel) {
        s.values[p] = static_cast<float>(std::sqrt(s.energy[p]));
        continue;
      }
      const float sharp = WindowMeanAt(s.energy, s.covered, w, h, r, x, y);
      if (method == MergeMethod::kImproved) {
        s.values[p] = sharp;
        continue;
      }
      const float disagreement = WindowMeanAt(s.spread, s.agreeing, w, h, r, x, y);
      if (disagreement == kNone) continue;
      const double e = sharp;
      s.values[p] = static_cast<float>(e / (static_cast<double>(disagreement) + 1e-12 * (1.0 + e)));
    }
  };
  // Back to the empty state for the next slice (only the pixels slice i touched).
  const auto clear = [&](int i, SliceScratch& s) {
    for (const int32_t p : lists[static_cast<size_t>(i)]) {
      s.covered[static_cast<size_t>(p)] = 0;
      s.agreeing[static_cast<size_t>(p)] = 0;
      s.values[static_cast<size_t>(p)] = kNone;
    }
  };
  ProgressStart(progress, "focal stack", slices);
  bool one_normal = true;
  for (int i = 0; i < slices && !focus.surface; ++i) {
    one_normal = one_normal && focus.planes[static_cast<size_t>(i)].normal == focus.planes[0].normal;
  }
  if (g_block_packing && one_normal && static_cast<size_t>(rendered) <= kPackedPoints) {
    // Block-major: one render call for every (slice, pixel) pair, so that each tile of packed
    // points covers a compact patch of the image (about 50 blocks at factor 4) and the renderer's
    // view culling by the tile's bounding box keeps only the views that see that patch. Packed
    // slice by slice, a tile held about 256 blocks of one slice, which on a scene whose focus
    // jumps (F0) lie all over the image, so nearly every view was tested on every point. Each
    // pair's samples and their order are the same either way (test: merge_test
    // CoarseToFineBlockPackingEqualsSlicePacking).
    Timer render_timer;
    FocalPoints points;
    points.width = kPackedWidth;
    points.height = static_cast<int>(
        std::max<int64_t>(1, (rendered + kPackedWidth - 1) / kPackedWidth));
    points.reference = cam_from_world.Center();
    points.points.assign(static_cast<size_t>(points.width) * points.height,
                         Vec3d(std::numeric_limits<double>::quiet_NaN()));
    // The slices' points, a slice per thread at a time (each writes its own places).
    std::vector<std::vector<float>> slice_of(static_cast<size_t>(threads));
    ParallelForPerThread(slices, threads, nullptr, [&](int64_t index, int thread) {
      const size_t i = static_cast<size_t>(index);
      if (lists[i].empty()) return;
      SlicePoints(focus, camera, cam_from_world, static_cast<int>(i), lists[i],
                  places[i].data(), 0, points.points.data(), &slice_of[static_cast<size_t>(thread)],
                  1);
    });
    const Vec3d normal = focus.surface ? focus.GrazingPlane().normal : focus.planes[0].normal;
    SurfaceIntegralResult packed;
    try {
      packed = RenderIntegralAtPoints(light_field, points,
                                      PackedOptions(resolved, cam_from_world, normal, variance));
    } catch (const std::invalid_argument& error) {
      ThrowInvalid("fine slices: " + std::string(error.what()));
    }
    *seconds_render += render_timer.Seconds();
    const Timer fold_timer;
    // Every pair's focus value, at its place: the slices in parallel, each thread with its own
    // scratch (a slice's values read that slice only; the same arithmetic as slice by slice).
    std::vector<float> packed_values(static_cast<size_t>(rendered), kNone);
    std::vector<SliceScratch> scratch(static_cast<size_t>(threads));
    ParallelForPerThread(slices, threads, progress, [&](int64_t index, int thread) {
      const int i = static_cast<int>(index);
      const std::vector<int32_t>& at = places[static_cast<size_t>(i)];
      if (at.empty()) return;
      SliceScratch& mine = scratch[static_cast<size_t>(thread)];
      if (mine.values.empty()) make_scratch(&mine);
      slice_values(i, packed.integral, [&](size_t j, size_t) {
        return std::pair<int, int>(at[j] % kPackedWidth, at[j] / kPackedWidth);
      }, mine, 1);
      const std::vector<int32_t>& list = lists[static_cast<size_t>(i)];
      for (size_t j = 0; j < list.size(); ++j) {
        packed_values[static_cast<size_t>(at[j])] = mine.values[static_cast<size_t>(list[j])];
      }
      clear(i, mine);
    });
    // Then folded block by block in parallel: a pixel lies in one block, whose slices follow
    // one another in ascending order in the packing, so each pixel folds its slices in the
    // order (and with the values) of AddAt slice by slice (test: merge_test
    // CoarseToFineBlockPackingEqualsSlicePacking).
    FocusAccumulator& fold_into = **accumulator;
    const int64_t blocks = static_cast<int64_t>(block_order.size());
#pragma omp parallel for num_threads(threads) schedule(static)
    for (int64_t b = 0; b < blocks; ++b) {
      const int32_t block = block_order[static_cast<size_t>(b)];
      const int bx = block % choice.blocks_x, by = block / choice.blocks_x;
      size_t at = static_cast<size_t>(block_place[static_cast<size_t>(b)]);
      for (int i = choice.first[static_cast<size_t>(block)];
           i <= choice.last[static_cast<size_t>(block)]; ++i) {
        for (int y = by * factor; y < std::min(h, (by + 1) * factor); ++y) {
          for (int x = bx * factor; x < std::min(w, (bx + 1) * factor); ++x, ++at) {
            fold_into.AddOne(i, static_cast<size_t>(y) * w + x, packed_values[at],
                             packed.integral.image.At<float>(static_cast<int>(at % kPackedWidth),
                                                             static_cast<int>(at / kPackedWidth)));
          }
        }
      }
    }
    *seconds_merge += fold_timer.Seconds();
    return static_cast<double>(rendered) / (static_cast<double>(pixels) * slices);
  }
  // Surfaces, lens views: packed points through the depth path, many slices a call, each
  // slice folded in turn.
  SliceScratch shared;
  make_scratch(&shared);
  const auto fold = [&](int i, const IntegralResult& in, const auto& position) {
    slice_values(i, in, position, shared, threads);
    (*accumulator)->AddAt(i, shared.image, lists[static_cast<size_t>(i)], shared.values);
    clear(i, shared);
  };
  Timer render_timer;
  RenderPackedSlices(
      light_field, resolved, camera, cam_from_world, focus, indices,
      [&](size_t k) -> const std::vector<int32_t>& { return lists[k]; }, variance, threads,
      [&](size_t k, const SurfaceIntegralResult& packed, size_t first) {
        if (k == 0 || first == 0) *seconds_render += render_timer.Seconds();
        const Timer fold_timer;
        if (!lists[k].empty()) {
          fold(static_cast<int>(k), packed.integral, [&](size_t j, size_t) {
            return std::pair<int, int>(static_cast<int>((first + j) % kPackedWidth),
                                       static_cast<int>((first + j) / kPackedWidth));
          });
        }
        ProgressAdvance(progress, 1);
        *seconds_merge += fold_timer.Seconds();
        render_timer = Timer();
      },
      progress);
  return static_cast<double>(rendered) / (static_cast<double>(pixels) * slices);
}

}  // namespace

namespace internal {
void SetCoarseToFineBlockPacking(bool enabled) { g_block_packing = enabled; }
void SetCoarseToFineCoarsePoints(bool enabled) { g_coarse_points = enabled; }
}  // namespace internal

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
  CheckFieldRanges(*this);  // the table's ranges (merge.h)
  robust.Check();
}

void AllInFocusOptions::Check(int view_count) const {
  stack.Check(view_count);
  merge.Check();
  CheckFieldRanges(*this);
  if (coarse_to_fine > 0 && stack.render.min_view_count > 1) {
    ThrowInvalid("min_view_count: the coarse-to-fine all-in-focus does not apply it (its passes "
                 "integrate at points); give coarse_to_fine 0 or min_view_count 0");
  }
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
  MergeResult result = Assemble(folded, stack.camera, stack.cam_from_world, stack.focus, threads);
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
    Reintegrate(*light_field, stack.render, stack.focus, options, accumulator.guide(),
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
  const SliceFocus focus = ResolveSliceFocus(light_field, run.stack);
  double seconds_merge = 0.0;
  const Timer timer;
  double rendered_fraction = 1.0;
  double seconds_fine_render = -1.0;  // coarse-to-fine: its own render timer
  std::vector<float> coarse_confidence;  // coarse-to-fine: per output pixel
  if (run.coarse_to_fine > 0) {
    const IntegralOptions resolved = WithResolvedCamera(light_field, run.stack.render);
    const CoarseChoice choice =
        ChooseSlices(light_field, run, resolved, camera, focus, threads, progress);
    seconds_fine_render = timer.Seconds();  // the coarse stack counts as rendering
    // The fine fold sees only the slices near each pixel's focus, so its own confidence (best
    // against the mean of the curve) would compare the peak with its shoulders; the coarse
    // stack's curve spans every slice, and the confidence is a ratio within one curve.
    coarse_confidence.resize(static_cast<size_t>(camera.width) * camera.height);
    for (int y = 0; y < camera.height; ++y) {
      for (int x = 0; x < camera.width; ++x) {
        coarse_confidence[static_cast<size_t>(y) * camera.width + x] =
            choice.confidence[static_cast<size_t>(y / run.coarse_to_fine) * choice.blocks_x +
                              x / run.coarse_to_fine];
      }
    }
    rendered_fraction = FoldCoarseToFine(light_field, run, resolved, camera, cam_from_world,
                                         focus, choice, threads, &accumulator, &seconds_merge,
                                         &seconds_fine_render, progress);
  } else {
  RenderFocalStackSlices(
      light_field, run.stack,
      [&](int index, IntegralResult& slice) {
        const Timer merge_timer;
        if (!accumulator) {
          accumulator = std::make_unique<FocusAccumulator>(camera, slice.image.channels(),
                                                           run.stack.slices);
        }
        const std::vector<float> focus =
            FocusValues(run.merge.method, slice.image, slice.count,
                        run.stack.render.variance ? &slice.variance : nullptr,
                        run.merge.window_radius, threads);
        accumulator->Add(index, slice.image, focus);
        seconds_merge += merge_timer.Seconds();
      },
      progress);
  }
  const double seconds_stack =
      seconds_fine_render >= 0.0 ? seconds_fine_render : timer.Seconds() - seconds_merge;
  const Timer refine_timer;
  const Folded folded = Refine(*accumulator, run.merge, threads,
                               coarse_confidence.empty() ? nullptr : &coarse_confidence);
  MergeResult result = Assemble(folded, camera, cam_from_world, focus, threads);
  seconds_merge += refine_timer.Seconds();
  if (run.merge.method == MergeMethod::kSobel) {
    result.image = accumulator->guide().Clone();
    result.seconds_render = seconds_stack;
  } else {
    const Timer render_timer;
    const IntegralOptions render = WithResolvedCamera(light_field, run.stack.render);
    Reintegrate(light_field, render, focus, run.merge, accumulator->guide(), &result,
                progress);
    result.seconds_render = seconds_stack + render_timer.Seconds();
  }
  result.seconds_merge = seconds_merge;
  result.rendered_fraction = rendered_fraction;
  return result;
}

}  // namespace aos
