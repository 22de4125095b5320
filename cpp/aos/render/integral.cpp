#include "aos/render/integral.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <exception>
#include <limits>
#include <string>

#include <omp.h>

#include "aos/render/focal_surface.h"
#include "aos/render/integral_kernels.h"
#include "aos/render/masked_mean.h"
#include "aos/render/surface_integral.h"
#include "aos/util/error.h"
#include "aos/util/math.h"
#include "aos/util/memory.h"
#include "aos/util/parallel.h"

// How it works
// For a planar focal surface the map from an output pixel to a view pixel is a homography H_i
// (composed in double precision relative to the virtual camera centre, so UTM-sized coordinates
// lose nothing). Along an output row, the homogeneous view coordinates (U, V, W) are linear in the
// column x. Every admission test is turned into a set of columns per row, solved exactly once per
// (view, row): visibility in the view (W > 0, 0 <= U <= w W, 0 <= V <= h W) is linear in x; the
// grazing-angle and aperture tests are quadratic in x (conics in the output image). The inner
// loop then runs over whole spans without a single test: one reciprocal, a bilinear sample from
// the view (stored with a replicated 1-pixel border, so the taps never leave memory) and a
// double-precision accumulation. The per-pixel view count is kept as a difference array per row
// (+1 at a span's start, -1 past its end), so counting costs nothing per sample.
//
// Work is split into tiles of whole rows (up to 512 columns wide) so the span computation happens
// once per row and view, and each thread's accumulators stay in cache.

namespace aos {
namespace {

using internal::RowLine;
using internal::SpanKernel;

constexpr int kMaxTileWidth = 512;
// A tile's accumulators (double sums of its rows): 128 KiB, in L2. Taller tiles restart each view
// (its first rows' cache misses, the span set-up) less often: on F0 32 rows take about 10% less
// time than 16 (docs/benchmarks.md), while 64 gain nothing more.
constexpr size_t kTileAccumulatorBytes = 128 * 1024;
// Tiles are made shorter where needed so that every thread gets at least this many.
constexpr int kMinTilesPerThread = 4;
constexpr int kMaxSpans = 4;
// How many rows ahead of the current one a view's pixels are prefetched.
constexpr int kPrefetchRows = 2;

// A set of disjoint half-open column ranges [begin, end), ascending.
struct Spans {
  std::array<std::pair<int, int>, kMaxSpans> range;
  int size = 0;

  static Spans Single(int begin, int end) {
    Spans spans;
    if (begin < end) spans.range[spans.size++] = {begin, end};
    return spans;
  }
  bool empty() const { return size == 0; }
  void ClampAll(int begin, int end) {
    int kept = 0;
    for (int i = 0; i < size; ++i) {
      const int b = std::max(range[i].first, begin), e = std::min(range[i].second, end);
      if (b < e) range[kept++] = {b, e};
    }
    size = kept;
  }
};

// ceil/floor of a value clamped to [lo, hi] first (no overflow on huge values, NaN gives lo
// resp. hi). Done with truncation: without SSE4.1, std::ceil/std::floor are library calls, and
// these run several times per view and row.
int CeilClamped(double value, int lo, int hi) {
  if (!(value > lo)) return lo;
  if (value > hi) return hi;
  const int truncated = static_cast<int>(value);
  return truncated < value ? truncated + 1 : truncated;
}
int FloorClamped(double value, int lo, int hi) {
  if (!(value < hi)) return hi;
  if (value < lo) return lo;
  const int truncated = static_cast<int>(value);
  return truncated > value ? truncated - 1 : truncated;
}

// Restricts `spans` to the integer columns x with a + b x >= 0.
void ApplyLinear(double a, double b, Spans& spans, int x0, int x1) {
  if (spans.empty()) return;
  if (b == 0.0) {
    if (!(a >= 0.0)) spans.size = 0;
    return;
  }
  const double root = -a / b;
  if (b > 0.0) {
    spans.ClampAll(CeilClamped(root, x0, x1), x1);
  } else {
    spans.ClampAll(x0, FloorClamped(root, x0 - 1, x1 - 1) + 1);
  }
}

// Restricts `spans` to the integer columns x in [x0, x1) with A x^2 + B x + C <= 0.
void ApplyQuadratic(double A, double B, double C, Spans& spans, int x0, int x1) {
  if (spans.empty()) return;
  const double extent = std::max(std::abs(static_cast<double>(x0)), std::abs(static_cast<double>(x1))) + 1.0;
  if (!(std::abs(A) * extent * extent > 1e-12 * (std::abs(B) * extent + std::abs(C)))) {
    ApplyLinear(-C, -B, spans, x0, x1);  // negligible curvature over this row: B x + C <= 0
    return;
  }
  const double discriminant = B * B - 4.0 * A * C;
  if (A > 0.0) {
    if (discriminant < 0.0) {
      spans.size = 0;
      return;
    }
  } else if (discriminant <= 0.0) {
    return;  // A < 0 and no real roots: the inequality holds everywhere
  }
  const double q = -0.5 * (B + std::copysign(std::sqrt(discriminant), B));
  double r1 = q / A;
  double r2 = q != 0.0 ? C / q : r1;
  if (r1 > r2) std::swap(r1, r2);
  const int lo = CeilClamped(r1, x0 - 1, x1 + 1);
  const int hi = FloorClamped(r2, x0 - 2, x1) + 1;  // exclusive end of [r1, r2]
  if (A > 0.0) {
    spans.ClampAll(lo, hi);  // inside the roots
    return;
  }
  // Outside the roots: (-inf, r1] and [r2, inf). Split every span into its two parts.
  Spans result;
  const int left_end = FloorClamped(r1, x0 - 2, x1) + 1;
  const int right_begin = CeilClamped(r2, x0 - 1, x1 + 1);
  for (int i = 0; i < spans.size; ++i) {
    const auto [b, e] = spans.range[i];
    const int left_e = std::min(e, left_end);
    if (b < left_e && result.size < kMaxSpans) result.range[result.size++] = {b, left_e};
    const int right_b = std::max(b, right_begin);
    if (right_b < e && result.size < kMaxSpans) result.range[result.size++] = {right_b, e};
  }
  spans = result;
}

// A vector-valued linear function of the column: value(x) = v0 + x v1.
struct LinearVec {
  Vec3d v0{0.0}, v1{0.0};
};

// Coefficients (A, B, C) of |g0 + x g1|^2 * s - (k0 + x k1)^2 * t.
std::array<double, 3> QuadraticOf(const LinearVec& g, double s, double k0, double k1, double t) {
  return {s * glm::dot(g.v1, g.v1) - t * k1 * k1,
          2.0 * (s * glm::dot(g.v0, g.v1) - t * k0 * k1),
          s * glm::dot(g.v0, g.v0) - t * k0 * k0};
}

// Everything about one view that does not depend on the output pixel.
struct ViewSetup {
  const Image* image = nullptr;
  Mat3d H{1.0};        // output pixel (x+0.5, y+0.5, 1) -> (U, V, W), W > 0 in front of the view
  double width = 0.0;  // view image size, pixels
  double height = 0.0;
  double w_min = 0.0;  // W must exceed this (relative guard against the view's principal plane)
  Vec3d b{0.0};        // view centre minus virtual camera centre, metres
  double e = 0.0;      // signed distance of the view centre from the focal plane, metres
  double lens_b = 0.0; // component of b along the virtual optical axis, metres
  ViewQuadratic quadratic;  // RenderIntegralWithQuadratic: the view's scores
};

// The virtual pixel ray of a row: D(x) = d0 + x d1 (world direction, unnormalised), and
// f(x) = n . D(x), the component along the focal plane normal.
struct RowRay {
  LinearVec direction;
  double f0 = 0.0, f1 = 0.0;
};

struct Geometry {
  Vec3d center{0.0};   // virtual camera centre (local frame)
  Vec3d normal{0.0};   // unit focal plane normal
  Vec3d lens_axis{0.0};  // unit optical axis of the virtual camera (normal of the lens plane)
  double h = 0.0;      // n . (plane point - centre): signed distance of the plane, metres
  double sign_h = 1.0;
  Mat3d world_from_pixel{1.0};  // R_v^T K_v^-1: output pixel -> world ray direction
};

// World direction of the ray through pixel centre k (0..3) of the corners of the pixel block
// [x0, x1) x [y0, y1): bit 0 picks the right column, bit 1 the bottom row.
Vec3d CornerRay(const Geometry& g, int k, int x0, int x1, int y0, int y1) {
  const double px = (k & 1) ? x1 - 0.5 : x0 + 0.5;
  const double py = (k & 2) ? y1 - 0.5 : y0 + 0.5;
  return g.world_from_pixel * Vec3d(px, py, 1.0);
}

enum class Mode { kAverage, kNearest };

struct Tile {
  int x0, x1, y0, y1;
};

// Per-tile working memory of one thread.
struct TileBuffers {
  std::vector<double> sum;        // rows x width x channels
  std::vector<double> sum_squares;  // rows x width: sum over channels of samples^2 (variance)
  std::vector<double> quad;         // rows x width: sum of the views' quadratic scores
  std::vector<int32_t> count_diff;  // rows x (width + 1)
  std::vector<double> best;       // nearest mode: best squared lens-plane distance per pixel
  std::vector<int32_t> best_view; // nearest mode: the view (position in the selection) chosen
  std::vector<uint8_t> view_used;
};

RowLine MakeRowLine(const Mat3d& H, int y) {
  const double py = y + 0.5;
  RowLine line;
  // H * (x + 0.5, py, 1): column 0 is the slope in x.
  line.du = H[0][0];
  line.dv = H[0][1];
  line.dw = H[0][2];
  line.u0 = 0.5 * H[0][0] + py * H[1][0] + H[2][0];
  line.v0 = 0.5 * H[0][1] + py * H[1][1] + H[2][1];
  line.w0 = 0.5 * H[0][2] + py * H[1][2] + H[2][2];
  return line;
}

// Asks the memory system for the view pixels a later row's span will read, so their cache misses
// overlap with the current row's work instead of stalling its loads: the sampled points of a row
// lie on a segment in the view; touch it once per cache line it crosses (and at least once per
// view row), in both tap rows.
void PrefetchSpan(const Image& image, const RowLine& line, int xa, int xb) {
  const double wa = line.w0 + line.dw * xa, wb = line.w0 + line.dw * (xb - 1);
  if (!(wa > 0.0 && wb > 0.0)) return;
  // Tap positions (pixel-index space) of the span's first and last samples, clamped into the
  // bordered image; the points between lie on the segment joining them.
  const double x_max = image.width() - 1.0, y_max = image.height() - 1.0;
  const double xa_s = std::clamp((line.u0 + line.du * xa) / wa - 0.5, -1.0, x_max);
  const double ya_s = std::clamp((line.v0 + line.dv * xa) / wa - 0.5, -1.0, y_max);
  const double xb_s = std::clamp((line.u0 + line.du * (xb - 1)) / wb - 0.5, -1.0, x_max);
  const double yb_s = std::clamp((line.v0 + line.dv * (xb - 1)) / wb - 0.5, -1.0, y_max);
  const ptrdiff_t value_bytes = static_cast<ptrdiff_t>(PixelTypeSize(image.type()));
  const ptrdiff_t pixel_bytes = value_bytes * image.channels();
  const ptrdiff_t row_bytes = image.row_stride() * value_bytes;
  const double dx = std::abs(xb_s - xa_s), dy = std::abs(yb_s - ya_s);
  if (!(std::isfinite(dx) && std::isfinite(dy))) return;
  const double length = std::max(dx * pixel_bytes / 64.0, dy);
  const int steps = std::min(64, static_cast<int>(length) + 1);
  const double step_x = (xb_s - xa_s) / steps, step_y = (yb_s - ya_s) / steps;
  const auto* base = static_cast<const char*>(image.RawAt(0, 0));
  double x = xa_s, y = ya_s;
  for (int k = 0; k <= steps; ++k, x += step_x, y += step_y) {
    // x, y >= -1 (up to rounding of the steps), so truncating s + 1 gives floor(s) + 1.
    const ptrdiff_t column = static_cast<ptrdiff_t>(std::max(x, -1.0) + 1.0) - 1;
    const ptrdiff_t row = static_cast<ptrdiff_t>(std::max(y, -1.0) + 1.0) - 1;
    const char* address = base + row * row_bytes + column * pixel_bytes;
    __builtin_prefetch(address, 0, 3);
    __builtin_prefetch(address + row_bytes, 0, 3);
  }
}

// Nearest mode: per pixel keep the sample of the view whose line to the focal point crosses the
// lens plane nearest to the virtual camera centre. `fixed_distance2` >= 0 is that distance for a
// view centred on the lens plane (the same for every pixel); negative computes it per pixel.
// Returns the number of pixels that had no view before.
int NearestSpan(const Image& image, int32_t view, const RowLine& line,
                const LinearVec& lens_offset, double m0, double m1, double fixed_distance2,
                int xa, int xb, int x0, double* sum, double* best, int32_t* best_view) {
  const int channels = image.channels();
  int newly_covered = 0;
  for (int x = xa; x < xb; ++x) {
    double distance2 = fixed_distance2;
    if (distance2 < 0.0) {
      const double m = m0 + m1 * x;
      if (m == 0.0) continue;
      const Vec3d n = lens_offset.v0 + static_cast<double>(x) * lens_offset.v1;
      distance2 = glm::dot(n, n) / (m * m);
    }
    double& current = best[x - x0];
    if (!(distance2 < current)) continue;
    current = distance2;
    newly_covered += best_view[x - x0] < 0;
    best_view[x - x0] = view;
    const double w = line.w0 + line.dw * x;
    // Clamped like the span kernels' positions (NaN gives -1).
    double sx = (line.u0 + line.du * x) / w - 0.5;
    double sy = (line.v0 + line.dv * x) / w - 0.5;
    sx = std::min(sx > -1.0 ? sx : -1.0, image.width() - 0.5);
    sy = std::min(sy > -1.0 ? sy : -1.0, image.height() - 0.5);
    const int ix = static_cast<int>(std::floor(sx));
    const int iy = static_cast<int>(std::floor(sy));
    const double ax = sx - ix, ay = sy - iy;
    for (int c = 0; c < channels; ++c) {
      const double p00 = image.Value(ix, iy, c), p01 = image.Value(ix + 1, iy, c);
      const double p10 = image.Value(ix, iy + 1, c), p11 = image.Value(ix + 1, iy + 1, c);
      const double top = p00 + ax * (p01 - p00);
      const double bottom = p10 + ax * (p11 - p10);
      sum[static_cast<ptrdiff_t>(x - x0) * channels + c] = top + ay * (bottom - top);
    }
  }
  return newly_covered;
}

class IntegralRenderer {
 public:
  // `plane`: the focal plane (options.focal_surface's, moved by its offset).
  // `quadratic`: one per view, for RenderIntegralWithQuadratic (nullptr: none).
  IntegralRenderer(const LightField& light_field, const IntegralOptions& options,
                   const Plane& plane, const std::vector<ViewQuadratic>* quadratic = nullptr)
      : light_field_(light_field), options_(options), plane_(plane), quadratic_(quadratic) {}

  IntegralResult Run(ProgressSink* progress);
  // The integrated quadratic scores (after Run, with `quadratic`).
  Image TakeScores() { return std::move(scores_); }

 private:
  void SetUpGeometry();
  void SetUpViews();
  void RenderTile(const Tile& tile, TileBuffers& buffers);
  bool TileRejects(const ViewSetup& view, const Tile& tile) const;

  const LightField& light_field_;
  const IntegralOptions& options_;
  const Plane plane_;
  Rigid3d cam_from_world_;
  PinholeCamera camera_;
  Geometry geometry_;
  std::vector<ViewSetup> views_;
  Mode mode_ = Mode::kAverage;
  int channels_ = 1;
  double full_range_ = 255.0;  // of the views' pixel type (a masked light field's weights)
  double sin2_min_angle_ = 0.0;
  IntegralResult result_;
  const std::vector<ViewQuadratic>* quadratic_ = nullptr;
  Image scores_;
};

void IntegralRenderer::SetUpGeometry() {
  cam_from_world_ = VirtualCamFromWorld(light_field_, options_);
  camera_ = VirtualCamera(light_field_, options_);
  Geometry& g = geometry_;
  g.center = cam_from_world_.Center();
  g.normal = glm::normalize(plane_.normal);
  g.lens_axis = Row(cam_from_world_.rotation, 2);
  g.world_from_pixel = glm::transpose(cam_from_world_.rotation) * glm::inverse(camera_.K());
  const Vec3d to_plane = plane_.point - g.center;
  g.h = glm::dot(g.normal, to_plane);
  g.sign_h = g.h < 0.0 ? -1.0 : 1.0;
  const double scale = std::max(1.0, glm::length(to_plane));
  // Written as !(a > b) so that NaN fails the checks too.
  if (!(std::abs(g.h) > 1e-9 * scale)) {
    ThrowInvalid("focal_surface: the plane contains the virtual camera centre, so the camera's rays run along "
                 "it (parallel) or meet it only at the centre");
  }
  // A pixel's ray meets the plane in front iff sign(h) (n . D) > 0, a linear function of the
  // pixel; over the image it is largest at a corner pixel, so test the four corners.
  bool any_in_front = false;
  for (int k = 0; k < 4; ++k) {
    const Vec3d direction = CornerRay(g, k, 0, camera_.width, 0, camera_.height);
    any_in_front = any_in_front || g.sign_h * glm::dot(g.normal, direction) > 0.0;
  }
  if (!any_in_front) {
    // Above every view as well (relative altitudes against a terrain's heights): say so.
    const std::string behind =
        SurfaceBehindTheCameras(FocalSurface::FromPlane(plane_), light_field_);
    ThrowInvalid("focal_surface: the plane lies behind the virtual camera: no pixel's ray meets it in front "
                 "(check its height or normal and the camera pose)" +
                 (behind.empty() ? std::string() : "; " + behind));
  }
}

void IntegralRenderer::SetUpViews() {
  std::vector<int> selection = options_.view_indices;
  if (selection.empty()) {
    selection.resize(light_field_.views.size());
    for (size_t i = 0; i < selection.size(); ++i) selection[i] = static_cast<int>(i);
  }
  // Ascending view order: nearest mode breaks ties towards the lower view index.
  std::sort(selection.begin(), selection.end());
  const Geometry& g = geometry_;
  channels_ = light_field_.views[static_cast<size_t>(selection.front())].image.channels();
  full_range_ =
      PixelTypeFullRange(light_field_.views[static_cast<size_t>(selection.front())].image.type());
  const Mat3d K_v_inverse = glm::inverse(camera_.K());
  const Mat3d R_v_t = glm::transpose(cam_from_world_.rotation);
  // (n . D) x_cam = (h R_i + tau_i n^T) D, with D = R_v^T K_v^-1 p and tau_i = R_i (c - C_i);
  // the sign of h makes W = |n . D| z_i, positive exactly in front of the view.
  for (int index : selection) {
    const View& view = light_field_.views[static_cast<size_t>(index)];
    CheckView(view, "view " + std::to_string(index) + (view.name.empty() ? "" : " (" + view.name + ")"));
    if (view.image.channels() != channels_) {
      ThrowInvalid("view " + std::to_string(index) + ": has " +
                   std::to_string(view.image.channels()) + " channels but the first selected view has " +
                   std::to_string(channels_));
    }
    ViewSetup setup;
    setup.image = &view.image;
    if (quadratic_ != nullptr) setup.quadratic = (*quadratic_)[static_cast<size_t>(index)];
    setup.width = view.camera.width;
    setup.height = view.camera.height;
    const Vec3d view_center = view.cam_from_world.Center();
    setup.b = view_center - g.center;
    setup.e = glm::dot(g.normal, setup.b) - g.h;
    setup.lens_b = glm::dot(g.lens_axis, setup.b);
    const Mat3d& R_i = view.cam_from_world.rotation;
    const Vec3d tau = R_i * (-setup.b);
    // tau n^T as a GLM matrix: column j is tau * n[j].
    const Mat3d tau_n(tau * g.normal.x, tau * g.normal.y, tau * g.normal.z);
    const Mat3d M = g.h * R_i + tau_n;
    setup.H = g.sign_h * (view.camera.Pinhole().K() * M * R_v_t * K_v_inverse);
    double norm = 0.0;
    for (int c = 0; c < 3; ++c) {
      for (int r = 0; r < 3; ++r) norm = std::max(norm, std::abs(setup.H[c][r]));
    }
    setup.w_min = 1e-12 * norm;
    views_.push_back(setup);
  }
  result_.views_selected = static_cast<int>(views_.size());
}

bool IntegralRenderer::TileRejects(const ViewSetup& view, const Tile& tile) const {
  // Each admission test is linear in (x, y) and a linear function is negative on a rectangle
  // iff it is negative at its four corners.
  const double xs[2] = {tile.x0 + 0.5, tile.x1 - 0.5};
  const double ys[2] = {tile.y0 + 0.5, tile.y1 - 0.5};
  bool all_negative[5] = {true, true, true, true, true};
  for (double x : xs) {
    for (double y : ys) {
      const Vec3d uvw = view.H * Vec3d(x, y, 1.0);
      const double tests[5] = {uvw.z - view.w_min, uvw.x, view.width * uvw.z - uvw.x, uvw.y,
                               view.height * uvw.z - uvw.y};
      for (int t = 0; t < 5; ++t) all_negative[t] = all_negative[t] && tests[t] < 0.0;
    }
  }
  for (bool negative : all_negative) {
    if (negative) return true;
  }
  return false;
}

void IntegralRenderer::RenderTile(const Tile& tile, TileBuffers& buffers) {
  const Geometry& g = geometry_;
  const int tile_width = tile.x1 - tile.x0;
  const int rows = tile.y1 - tile.y0;
  const size_t row_values = static_cast<size_t>(tile_width) * channels_;
  buffers.sum.assign(row_values * rows + internal::kSpanPadding, 0.0);
  buffers.count_diff.assign(static_cast<size_t>(tile_width + 1) * rows, 0);
  if (options_.variance) {
    buffers.sum_squares.assign(static_cast<size_t>(tile_width) * rows + internal::kSpanPadding, 0.0);
  }
  if (quadratic_ != nullptr) {
    buffers.quad.assign(static_cast<size_t>(tile_width) * rows + internal::kSpanPadding, 0.0);
  }
  if (mode_ == Mode::kNearest) {
    buffers.best.assign(static_cast<size_t>(tile_width) * rows,
                        std::numeric_limits<double>::infinity());
    buffers.best_view.assign(static_cast<size_t>(tile_width) * rows, -1);
  }

  // The virtual rays of each row, and the columns whose ray meets the plane in front.
  std::vector<RowRay> row_rays(static_cast<size_t>(rows));
  std::vector<Spans> row_valid(static_cast<size_t>(rows));
  for (int r = 0; r < rows; ++r) {
    const double py = tile.y0 + r + 0.5;
    RowRay& ray = row_rays[static_cast<size_t>(r)];
    ray.direction.v1 = g.world_from_pixel * Vec3d(1.0, 0.0, 0.0);
    ray.direction.v0 = g.world_from_pixel * Vec3d(0.5, py, 1.0);
    ray.f0 = glm::dot(g.normal, ray.direction.v0);
    ray.f1 = glm::dot(g.normal, ray.direction.v1);
    Spans valid = Spans::Single(tile.x0, tile.x1);
    // sign(h) f(x) > 0 (the ray meets the plane in front); a tiny margin keeps W well defined.
    const double margin = 1e-12 * (std::abs(ray.f0) + std::abs(ray.f1) * tile.x1 + 1e-300);
    ApplyLinear(g.sign_h * ray.f0 - margin, g.sign_h * ray.f1, valid, tile.x0, tile.x1);
    row_valid[static_cast<size_t>(r)] = valid;
  }

  // Focal points of the tile's four corner pixels (relative to the virtual centre), to skip the
  // grazing test for views that pass it on the whole tile: the admitted focal points form a disk
  // on the plane, the tile's focal points a convex quadrilateral inside its corners' hull.
  bool corners_valid = true;
  Vec3d corners[4];
  for (int k = 0; k < 4; ++k) {
    const Vec3d direction = CornerRay(g, k, tile.x0, tile.x1, tile.y0, tile.y1);
    const double f = glm::dot(g.normal, direction);
    corners_valid = corners_valid && g.sign_h * f > 0.0;
    corners[k] = corners_valid ? (g.h / f) * direction : Vec3d(0.0);
  }

  const bool finite_aperture = std::isfinite(options_.aperture_radius) && mode_ == Mode::kAverage;
  const double r2 = options_.aperture_radius * options_.aperture_radius;
  // A view centred on the lens plane crosses it at its own centre for every pixel.
  const auto on_lens_plane_of = [](const ViewSetup& view) {
    return std::abs(view.lens_b) <= 1e-12 * (glm::length(view.b) + 1.0);
  };
  // Views in index order; in nearest mode with every view on the lens plane (the virtual camera
  // on the flight plane), in order of their fixed lens-plane distance, ties by index: the first
  // view that sees a pixel is then its nearest, each pixel is sampled once, and the tile is done
  // as soon as every pixel has a view.
  std::vector<size_t> order(views_.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  bool sorted_nearest = mode_ == Mode::kNearest;
  for (const ViewSetup& view : views_) sorted_nearest = sorted_nearest && on_lens_plane_of(view);
  if (sorted_nearest) {
    std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
      return glm::dot(views_[a].b, views_[a].b) < glm::dot(views_[b].b, views_[b].b);
    });
  }
  int64_t uncovered = static_cast<int64_t>(tile_width) * rows;
  for (size_t k = 0; k < order.size() && (!sorted_nearest || uncovered > 0); ++k) {
    const size_t view_index = order[k];
    const ViewSetup& view = views_[view_index];
    if (TileRejects(view, tile)) continue;
    const Image& image = *view.image;
    // The first rows of the next view are not covered by the row-ahead prefetch below.
    if (k + 1 < order.size()) {
      const ViewSetup& next = views_[order[k + 1]];
      for (int r = 0; r < std::min(rows, kPrefetchRows); ++r) {
        PrefetchSpan(*next.image, MakeRowLine(next.H, tile.y0 + r), tile.x0, tile.x1);
      }
    }
    const SpanKernel kernel = internal::SelectSpanKernel(image);
    const internal::SquaresKernel squares_kernel =
        options_.variance ? internal::SelectSquaresKernel(image) : nullptr;
    const internal::QuadraticKernel quadratic_kernel =
        quadratic_ != nullptr ? internal::SelectQuadraticKernel(image) : nullptr;
    const bool on_lens_plane = on_lens_plane_of(view);
    if (finite_aperture && on_lens_plane && glm::dot(view.b, view.b) > r2) continue;
    bool grazing_test = sin2_min_angle_ > 0.0;
    if (grazing_test && corners_valid) {
      bool all_inside = true;
      for (const Vec3d& corner : corners) {
        const Vec3d to_view = view.b - corner;
        all_inside = all_inside && sin2_min_angle_ * glm::dot(to_view, to_view) < 0.999 * view.e * view.e;
      }
      grazing_test = !all_inside;
    }
    bool used = false;
    for (int r = 0; r < rows; ++r) {
      Spans spans = row_valid[static_cast<size_t>(r)];
      if (spans.empty()) continue;
      const int y = tile.y0 + r;
      const RowLine line = MakeRowLine(view.H, y);
      ApplyLinear(line.w0 - view.w_min, line.dw, spans, tile.x0, tile.x1);
      ApplyLinear(line.u0, line.du, spans, tile.x0, tile.x1);
      ApplyLinear(view.width * line.w0 - line.u0, view.width * line.dw - line.du, spans, tile.x0,
                  tile.x1);
      ApplyLinear(line.v0, line.dv, spans, tile.x0, tile.x1);
      ApplyLinear(view.height * line.w0 - line.v0, view.height * line.dw - line.dv, spans,
                  tile.x0, tile.x1);
      if (spans.empty()) continue;
      const RowRay& ray = row_rays[static_cast<size_t>(r)];
      if (grazing_test) {
        // sin^2(angle) |C_i - X|^2 <= e^2, times f^2: |f b - h D|^2 s - e^2 f^2 <= 0.
        const LinearVec g_vec{ray.f0 * view.b - g.h * ray.direction.v0,
                              ray.f1 * view.b - g.h * ray.direction.v1};
        const auto q = QuadraticOf(g_vec, sin2_min_angle_, ray.f0, ray.f1, view.e * view.e);
        ApplyQuadratic(q[0], q[1], q[2], spans, tile.x0, tile.x1);
        if (spans.empty()) continue;
      }
      // Where the line from the focal point through the view centre crosses the lens plane,
      // relative to the virtual centre: N / M with N = h [D (a.b) - b (a.D)],
      // M = (a.b) f - h (a.D), a the optical axis (all scaled by f to stay linear in x).
      LinearVec lens_offset;
      double m0 = 0.0, m1 = 0.0;
      if ((finite_aperture && !on_lens_plane) || mode_ == Mode::kNearest) {
        const double a_d0 = glm::dot(g.lens_axis, ray.direction.v0);
        const double a_d1 = glm::dot(g.lens_axis, ray.direction.v1);
        lens_offset.v0 = g.h * (view.lens_b * ray.direction.v0 - a_d0 * view.b);
        lens_offset.v1 = g.h * (view.lens_b * ray.direction.v1 - a_d1 * view.b);
        m0 = view.lens_b * ray.f0 - g.h * a_d0;
        m1 = view.lens_b * ray.f1 - g.h * a_d1;
        if (finite_aperture) {
          const auto q = QuadraticOf(lens_offset, 1.0, m0, m1, r2);
          ApplyQuadratic(q[0], q[1], q[2], spans, tile.x0, tile.x1);
          if (spans.empty()) continue;
        }
      }
      double* sum_row = buffers.sum.data() + row_values * r;
      int32_t* diff_row = buffers.count_diff.data() + static_cast<size_t>(tile_width + 1) * r;
      if (r + kPrefetchRows < rows) {
        PrefetchSpan(image, MakeRowLine(view.H, y + kPrefetchRows), spans.range[0].first,
                     spans.range[spans.size - 1].second);
      }
      for (int s = 0; s < spans.size; ++s) {
        const auto [xa, xb] = spans.range[s];
        if (mode_ == Mode::kNearest) {
          const size_t row_offset = static_cast<size_t>(tile_width) * r;
          uncovered -= NearestSpan(image, static_cast<int32_t>(view_index), line, lens_offset, m0,
                                   m1, sorted_nearest ? glm::dot(view.b, view.b) : -1.0, xa, xb,
                                   tile.x0, sum_row, buffers.best.data() + row_offset,
                                   buffers.best_view.data() + row_offset);
        } else {
          if (squares_kernel != nullptr) {
            squares_kernel(image, line, xa, xb, tile.x0, sum_row,
                           buffers.sum_squares.data() + static_cast<size_t>(tile_width) * r);
          } else if (quadratic_kernel != nullptr) {
            quadratic_kernel(image, line, xa, xb, tile.x0, sum_row,
                             buffers.quad.data() + static_cast<size_t>(tile_width) * r,
                             view.quadratic.centre, view.quadratic.scale,
                             view.quadratic.one_sided ? 0.0f
                                                      : -std::numeric_limits<float>::infinity());
          } else {
            kernel(image, line, xa, xb, tile.x0, sum_row);
          }
          diff_row[xa - tile.x0] += 1;
          diff_row[xb - tile.x0] -= 1;
          used = true;
        }
      }
    }
    if (used) buffers.view_used[view_index] = 1;
  }

  // Normalise into the output.
  for (int r = 0; r < rows; ++r) {
    const int y = tile.y0 + r;
    const double* sum_row = buffers.sum.data() + row_values * r;
    const int32_t* diff_row = buffers.count_diff.data() + static_cast<size_t>(tile_width + 1) * r;
    float* out = result_.image.At<float>(tile.x0, y);
    uint32_t* count_out = result_.count.At<uint32_t>(tile.x0, y);
    int64_t count = 0;
    for (int i = 0; i < tile_width; ++i) {
      if (mode_ == Mode::kNearest) {
        const int32_t chosen = buffers.best_view[static_cast<size_t>(tile_width) * r + i];
        count = chosen >= 0 ? 1 : 0;
        if (chosen >= 0) buffers.view_used[static_cast<size_t>(chosen)] = 1;
      } else {
        count += diff_row[i];
      }
      count_out[i] = static_cast<uint32_t>(count);
      if (options_.variance) {
        // Population variance, mean over channels; 0 for fewer than two samples (nearest mode
        // keeps one sample a pixel).
        double variance = 0.0;
        if (count >= 2 && mode_ == Mode::kAverage) {
          const double n = static_cast<double>(count);
          double mean_squares = 0.0;
          for (int c = 0; c < channels_; ++c) {
            const double mean = sum_row[i * channels_ + c] / n;
            mean_squares += mean * mean;
          }
          const double squares = buffers.sum_squares[static_cast<size_t>(tile_width) * r + i];
          if (light_field_.masked) {
            // The valid samples' variance from the double sums (masked_mean.h); the weight
            // channel's squares, full range x w for binary weights, are left out.
            const double* pixel_sums = sum_row + static_cast<size_t>(i) * channels_;
            variance = internal::MaskedVariance(
                pixel_sums, squares - full_range_ * pixel_sums[channels_ - 1], channels_,
                full_range_);
          } else {
            variance = std::max(0.0, (squares / n - mean_squares) / channels_);
          }
        }
        result_.variance.At<float>(tile.x0, y)[i] = static_cast<float>(variance);
      }
      if (quadratic_ != nullptr) {
        const double quad = buffers.quad[static_cast<size_t>(tile_width) * r + i];
        scores_.At<float>(tile.x0, y)[i] =
            count > 0 ? static_cast<float>(quad / static_cast<double>(count)) : 0.0f;
      }
      // Divide (rather than multiply by a reciprocal) so the result is the correctly rounded
      // mean of the double sums.
      for (int c = 0; c < channels_; ++c) {
        out[i * channels_ + c] =
            count > 0 ? static_cast<float>(sum_row[i * channels_ + c] / static_cast<double>(count))
                      : 0.0f;
      }
    }
  }
}

IntegralResult IntegralRenderer::Run(ProgressSink* progress) {
  options_.Check(static_cast<int>(light_field_.views.size()));
  SetUpGeometry();
  mode_ = options_.aperture_radius == 0.0 ? Mode::kNearest : Mode::kAverage;
  const double min_angle = DegToRad(options_.min_view_angle_deg);
  sin2_min_angle_ = std::sin(min_angle) * std::sin(min_angle);
  SetUpViews();

  const int width = camera_.width, height = camera_.height;
  // The outputs dominate (the tile accumulators are a few MiB per thread): refuse a size the
  // machine cannot hold before allocating it.
  CheckMemoryBudget(
      SaturatingProduct({static_cast<uint64_t>(width), static_cast<uint64_t>(height),
                         static_cast<uint64_t>(channels_) * 4 + 4 + (options_.variance ? 4 : 0) +
                             (quadratic_ != nullptr ? 4 : 0)}),
      "width/height: " + std::to_string(width) + " x " + std::to_string(height) + " pixels",
      "a float32 image of " + std::to_string(channels_) + " channel(s), a uint32 count map" +
          (options_.variance ? std::string(", a float32 variance map") : std::string()));
  result_.image = Image(width, height, channels_, PixelType::kF32);
  result_.count = Image(width, height, 1, PixelType::kU32);
  if (options_.variance) result_.variance = Image(width, height, 1, PixelType::kF32);
  if (quadratic_ != nullptr) scores_ = Image(width, height, 1, PixelType::kF32);
  result_.cam_from_world = cam_from_world_;

  // Tiles of whole rows (at most kMaxTileWidth columns), enough rows to fill the accumulators,
  // but at least kMinTilesPerThread tiles a thread. The tiling changes no output value: every
  // pixel adds its views' samples in view order whatever tile it is in.
  const int threads = ResolveThreadCount(options_.num_threads);
  const int tile_width = std::min(width, kMaxTileWidth);
  const int column_tiles = (width + tile_width - 1) / tile_width;
  const int64_t rows_for_threads =
      static_cast<int64_t>(height) * column_tiles / (static_cast<int64_t>(kMinTilesPerThread) * threads);
  const int tile_rows = static_cast<int>(std::clamp<int64_t>(
      std::min<int64_t>(static_cast<int64_t>(kTileAccumulatorBytes /
                                             (sizeof(double) * static_cast<size_t>(tile_width) * channels_)),
                        rows_for_threads),
      1, 64));
  std::vector<Tile> tiles;
  for (int y = 0; y < height; y += tile_rows) {
    for (int x = 0; x < width; x += tile_width) {
      tiles.push_back(Tile{x, std::min(width, x + tile_width), y, std::min(height, y + tile_rows)});
    }
  }

  ProgressStart(progress, "render", static_cast<int64_t>(tiles.size()));
  std::vector<TileBuffers> buffers(static_cast<size_t>(threads));  // one per thread
  ParallelForPerThread(static_cast<int64_t>(tiles.size()), threads, progress,
                       [&](int64_t t, int thread) {
                         TileBuffers& mine = buffers[static_cast<size_t>(thread)];
                         if (mine.view_used.empty()) mine.view_used.assign(views_.size(), 0);
                         RenderTile(tiles[static_cast<size_t>(t)], mine);
                       });
  std::vector<uint8_t> view_used(views_.size(), 0);
  for (const TileBuffers& mine : buffers) {
    for (size_t i = 0; i < mine.view_used.size(); ++i) view_used[i] |= mine.view_used[i];
  }

  for (uint8_t used : view_used) result_.views_used += used;
  for (int y = 0; y < height; ++y) {
    const uint32_t* count = result_.count.At<uint32_t>(0, y);
    for (int x = 0; x < width; ++x) {
      result_.samples += count[x];
      result_.uncovered_pixels += count[x] == 0;
    }
  }
  if (light_field_.masked) {
    internal::DivideByMaskWeight(result_, PixelTypeFullRange(views_.front().image->type()));
  }
  return std::move(result_);
}

}  // namespace

PinholeCamera VirtualCamera(const LightField& light_field, const IntegralOptions& options) {
  const bool from_view = options.pose_view >= 0 &&
                         options.pose_view < static_cast<int>(light_field.views.size());
  if (from_view) {
    const PinholeCamera view =
        light_field.views[static_cast<size_t>(options.pose_view)].camera.Pinhole();
    const int width = options.width > 0 ? options.width : view.width;
    const int height = options.height > 0 ? options.height : view.height;
    const double fov_deg = options.fov_deg > 0.0 ? options.fov_deg : view.FovXDeg();
    return PinholeCamera::FromFov(width, height, fov_deg);
  }
  return PinholeCamera::FromFov(options.width > 0 ? options.width : kDefaultSize,
                                options.height > 0 ? options.height : kDefaultSize,
                                options.fov_deg > 0.0 ? options.fov_deg : kDefaultFovDeg);
}

IntegralOptions WithResolvedCamera(const LightField& light_field, const IntegralOptions& options) {
  IntegralOptions resolved = options;
  const PinholeCamera camera = VirtualCamera(light_field, options);
  resolved.cam_from_world = VirtualCamFromWorld(light_field, options);
  resolved.fov_deg = camera.FovXDeg();
  resolved.width = camera.width;
  resolved.height = camera.height;
  resolved.pose_view = -1;
  return resolved;
}

Rigid3d VirtualCamFromWorld(const LightField& light_field, const IntegralOptions& options) {
  if (options.pose_view < 0) return options.cam_from_world;
  const View& view = light_field.views.at(static_cast<size_t>(options.pose_view));
  if (auto problem = DescribeInvalidRigid(view.cam_from_world)) {
    ThrowInvalid("pose_view: view " + std::to_string(options.pose_view) +
                 (view.name.empty() ? "" : " (" + view.name + ")") + ": cam_from_world: " +
                 *problem);
  }
  return view.cam_from_world;
}

void IntegralOptions::Check(int view_count) const {
  CheckFieldRanges(*this);  // the table's ranges (integral.h)
  if (view_count <= 0) ThrowInvalid("view selection is empty: the light field has no views");
  if (pose_view < -1 || pose_view >= view_count) {
    ThrowInvalid("pose_view: no view " + std::to_string(pose_view) + " (the light field has " +
                 std::to_string(view_count) + " views)");
  }
  if (pose_view < 0) {
    if (auto problem = DescribeInvalidRigid(cam_from_world)) {
      ThrowInvalid("cam_from_world: " + *problem);
    }
  }
  std::vector<uint8_t> seen(static_cast<size_t>(view_count), 0);
  for (int index : view_indices) {
    if (index < 0 || index >= view_count) {
      ThrowInvalid("view_indices: no view " + std::to_string(index) + " (the light field has " +
                   std::to_string(view_count) + " views)");
    }
    if (seen[static_cast<size_t>(index)]++) {
      ThrowInvalid("view_indices: view " + std::to_string(index) + " is listed twice");
    }
  }
}

Vec3d GrazingNormal(const LightField& light_field, const IntegralOptions& options) {
  const FocalSurface& surface = options.focal_surface;
  if (surface.kind() == FocalSurfaceKind::kPlane) return glm::normalize(surface.plane().normal);
  return ResolveSurfacePlacement(surface, light_field, options.view_indices, 0.0).up;
}

void DropThinPixels(int min_view_count, IntegralResult* out) {
  if (min_view_count <= 1) return;
  IntegralResult& result = *out;
  const uint32_t least = static_cast<uint32_t>(min_view_count);
  Image& count = result.count;
  for (int y = 0; y < count.height(); ++y) {
    for (int x = 0; x < count.width(); ++x) {
      uint32_t& n = count.At<uint32_t>(x, y)[0];
      if (n == 0 || n >= least) continue;
      result.samples -= n;
      ++result.uncovered_pixels;
      n = 0;
      float* pixel = result.image.At<float>(x, y);
      for (int c = 0; c < result.image.channels(); ++c) pixel[c] = 0.0f;
      if (!result.variance.empty()) result.variance.At<float>(x, y)[0] = 0.0f;
    }
  }
}

namespace {

// Whether view `i` is among options.view_indices (every view where they are empty).
bool IsSelected(const IntegralOptions& options, size_t i) {
  return options.view_indices.empty() ||
         std::find(options.view_indices.begin(), options.view_indices.end(),
                   static_cast<int>(i)) != options.view_indices.end();
}

// Whether a selected view has a lens model (then renders take the per-sample path).
bool SelectedLensViews(const LightField& light_field, const IntegralOptions& options) {
  for (size_t i = 0; i < light_field.views.size(); ++i) {
    if (IsSelected(options, i) && !light_field.views[i].camera.IsPinhole()) return true;
  }
  return false;
}

// The focal plane of the homography route: the surface's plane moved by surface_offset.
Plane OffsetPlane(const LightField& light_field, const IntegralOptions& options) {
  Plane plane = options.focal_surface.plane();
  if (options.surface_offset != 0.0) {
    const SurfacePlacement placed = ResolveSurfacePlacement(
        options.focal_surface, light_field, options.view_indices, options.surface_offset);
    plane.point += placed.offset * placed.up;
  }
  return plane;
}

}  // namespace

bool QuadraticIntegralSupported(const LightField& light_field, const IntegralOptions& options) {
  if (light_field.views.empty() || light_field.masked || options.variance ||
      !(options.aperture_radius > 0.0) ||
      options.focal_surface.kind() != FocalSurfaceKind::kPlane ||
      SelectedLensViews(light_field, options)) {
    return false;
  }
  for (size_t i = 0; i < light_field.views.size(); ++i) {
    if (IsSelected(options, i) && light_field.views[i].image.channels() != 1) return false;
  }
  return true;
}

QuadraticIntegralResult RenderIntegralWithQuadratic(const LightField& light_field,
                                                    const IntegralOptions& options,
                                                    const std::vector<ViewQuadratic>& per_view,
                                                    ProgressSink* progress) {
  options.Check(static_cast<int>(light_field.views.size()));
  if (per_view.size() != light_field.views.size()) {
    ThrowInvalid("per_view: " + std::to_string(per_view.size()) + " quadratics for " +
                 std::to_string(light_field.views.size()) + " views");
  }
  if (!QuadraticIntegralSupported(light_field, options)) {
    ThrowInvalid("options: the integral of per-view quadratic scores needs an unmasked light "
                 "field of 1-channel pinhole views, a focal plane, aperture_radius > 0 and no "
                 "variance");
  }
  IntegralRenderer renderer(light_field, options, OffsetPlane(light_field, options), &per_view);
  QuadraticIntegralResult result;
  result.integral = renderer.Run(progress);
  result.scores = renderer.TakeScores();
  // min_view_count: the scores follow the image's uncovered pixels.
  DropThinPixels(options.min_view_count, &result.integral);
  for (int y = 0; y < result.scores.height(); ++y) {
    const uint32_t* count = result.integral.count.At<uint32_t>(0, y);
    float* row = result.scores.At<float>(0, y);
    for (int x = 0; x < result.scores.width(); ++x) {
      if (count[x] == 0) row[x] = 0.0f;
    }
  }
  return result;
}

IntegralResult RenderIntegral(const LightField& light_field, const IntegralOptions& options,
                              ProgressSink* progress) {
  // One route for every surface: a plane over pinhole views takes the homography kernel; any
  // other surface, or views with a lens model (sampled through the lens directly: one resampling,
  // no rectified copy), take the per-sample path on the surface's depth map.
  options.Check(static_cast<int>(light_field.views.size()));
  const bool lens_views = SelectedLensViews(light_field, options);
  const FocalSurface& surface = options.focal_surface;
  const bool is_plane = surface.kind() == FocalSurfaceKind::kPlane;
  // The placement (up from the views) is resolved only where it is needed: an offset, or a
  // surface other than a plane.
  const auto placement = [&] {
    return ResolveSurfacePlacement(surface, light_field, options.view_indices,
                                   options.surface_offset);
  };
  if (is_plane && !lens_views) {
    IntegralRenderer renderer(light_field, options, OffsetPlane(light_field, options));
    IntegralResult result = renderer.Run(progress);
    DropThinPixels(options.min_view_count, &result);
    return result;
  }
  const PinholeCamera camera = VirtualCamera(light_field, options);
  const Rigid3d cam_from_world = VirtualCamFromWorld(light_field, options);
  const SurfacePlacement placed = placement();
  const Image depth = surface.DepthFor(camera, cam_from_world, placed, options.num_threads);
  if (is_plane) {
    bool any_in_front = false;
    for (int y = 0; y < camera.height && !any_in_front; ++y) {
      for (int x = 0; x < camera.width && !any_in_front; ++x) {
        any_in_front = depth.At<float>(x, y)[0] > 0.0f;
      }
    }
    if (!any_in_front) {
      const std::string behind = SurfaceBehindTheCameras(surface, light_field);
      ThrowInvalid("focal_surface: the plane lies behind the virtual camera or contains its "
                   "centre: no pixel's ray meets it in front" +
                   (behind.empty() ? std::string() : "; " + behind));
    }
  }
  // RenderIntegralOnDepth applies min_view_count.
  return RenderIntegralOnDepth(light_field, options, depth, SurfaceIntegralOptions{}, progress)
      .integral;
}

}  // namespace aos
