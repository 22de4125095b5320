#include "aos/sfm/ground.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "aos/util/error.h"
#include "aos/util/math.h"

namespace aos {
namespace {

double Median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  const size_t mid = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(mid), values.end());
  double median = values[mid];
  if (values.size() % 2 == 0) {
    median = 0.5 * (median + *std::max_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(mid)));
  }
  return median;
}

// Height = a + b x + c y, least squares over the kept samples (relative to (x0, y0)).
struct PlaneFit {
  double a = 0.0, b = 0.0, c = 0.0;
  double x0 = 0.0, y0 = 0.0;
  double At(double x, double y) const { return a + b * (x - x0) + c * (y - y0); }
};

bool FitPlane(const std::vector<Vec3d>& samples, const std::vector<uint8_t>& keep, PlaneFit* fit) {
  double sx = 0, sy = 0, n = 0;
  for (size_t i = 0; i < samples.size(); ++i) {
    if (!keep[i]) continue;
    sx += samples[i].x;
    sy += samples[i].y;
    n += 1;
  }
  if (n < 3) return false;
  fit->x0 = sx / n;
  fit->y0 = sy / n;
  // Normal equations in centred coordinates (3x3, symmetric).
  Mat3d A(0.0);
  Vec3d rhs(0.0);
  for (size_t i = 0; i < samples.size(); ++i) {
    if (!keep[i]) continue;
    const Vec3d row(1.0, samples[i].x - fit->x0, samples[i].y - fit->y0);
    for (int r = 0; r < 3; ++r) {
      for (int k = 0; k < 3; ++k) A[k][r] += row[r] * row[k];
      rhs[r] += row[r] * samples[i].z;
    }
  }
  if (!(std::abs(glm::determinant(A)) > 1e-12 * A[0][0] * A[1][1] * A[2][2])) {
    // Collinear cells: a horizontal plane at the mean height.
    fit->a = rhs[0] / A[0][0];
    fit->b = fit->c = 0.0;
    return true;
  }
  const Vec3d solution = glm::inverse(A) * rhs;
  fit->a = solution[0];
  fit->b = solution[1];
  fit->c = solution[2];
  return true;
}

}  // namespace

void GroundOptions::Check() const {
  if (!(cell_size_m > 0.0 && std::isfinite(cell_size_m))) {
    ThrowInvalid("cell_size_m: must be > 0 metres (got " + FormatNumber(cell_size_m) + ")");
  }
  if (!(quantile >= 0.0 && quantile < 1.0)) {
    ThrowInvalid("quantile: must be in [0, 1) (got " + FormatNumber(quantile) + ")");
  }
  if (min_points_per_cell < 1) {
    ThrowInvalid("min_points_per_cell: must be >= 1 (got " + std::to_string(min_points_per_cell) + ")");
  }
  if (!(outlier_sigmas > 0.0 && std::isfinite(outlier_sigmas))) {
    ThrowInvalid("outlier_sigmas: must be > 0 (got " + FormatNumber(outlier_sigmas) + ")");
  }
  if (!(max_step_m >= 0.0 && std::isfinite(max_step_m))) {
    ThrowInvalid("max_step_m: must be >= 0 metres (got " + FormatNumber(max_step_m) + ")");
  }
}

double GroundResult::ZAt(double x, double y) const {
  if (width <= 0 || height <= 0) return std::numeric_limits<double>::quiet_NaN();
  const double u = std::clamp((x - min_x) / cell_size_m - 0.5, 0.0, width - 1.0);
  const double v = std::clamp((y - min_y) / cell_size_m - 0.5, 0.0, height - 1.0);
  const int i = std::min(static_cast<int>(u), std::max(width - 2, 0));
  const int j = std::min(static_cast<int>(v), std::max(height - 2, 0));
  const int i1 = std::min(i + 1, width - 1), j1 = std::min(j + 1, height - 1);
  const double fu = u - i, fv = v - j;
  auto at = [&](int a, int b) { return static_cast<double>(z[static_cast<size_t>(b) * width + a]); };
  const double top = at(i, j) + fu * (at(i1, j) - at(i, j));
  const double bottom = at(i, j1) + fu * (at(i1, j1) - at(i, j1));
  return top + fv * (bottom - top);
}

int GroundUpSign(const std::vector<Vec3d>& points, const LightField& light_field) {
  if (points.empty() || light_field.views.empty()) {
    ThrowInvalid("ground: needs points and views to tell which way is up");
  }
  std::vector<double> zs;
  zs.reserve(points.size());
  for (const Vec3d& p : points) zs.push_back(p.z);
  const double median = Median(zs);
  double cameras = 0.0;
  for (const View& view : light_field.views) cameras += view.cam_from_world.Center().z;
  cameras /= static_cast<double>(light_field.views.size());
  return cameras >= median ? 1 : -1;
}

GroundResult EstimateGround(const std::vector<Vec3d>& points, int up_sign,
                            const GroundOptions& options, ProgressSink* progress) {
  options.Check();
  // Polled every 65536 items of the loops below (and every row of the fill).
  const auto poll = [progress](size_t item) {
    if ((item & 0xFFFF) == 0 && ProgressCancelled(progress)) throw Cancelled();
  };
  if (up_sign != 1 && up_sign != -1) ThrowInvalid("up_sign: must be +1 or -1");
  double min_x = std::numeric_limits<double>::infinity(), min_y = min_x;
  double max_x = -min_x, max_y = -min_x;
  for (size_t i = 0; i < points.size(); ++i) {
    poll(i);
    const Vec3d& p = points[i];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
      ThrowInvalid("points: point " + std::to_string(i) + " is not finite");
    }
    min_x = std::min(min_x, p.x);
    min_y = std::min(min_y, p.y);
    max_x = std::max(max_x, p.x);
    max_y = std::max(max_y, p.y);
  }
  if (points.size() < 3) {
    ThrowInvalid("points: " + std::to_string(points.size()) + " points are too few to find the ground");
  }
  const double cell = options.cell_size_m;
  const double cells_x = std::floor((max_x - min_x) / cell) + 1.0;
  const double cells_y = std::floor((max_y - min_y) / cell) + 1.0;
  if (cells_x * cells_y > 4e6) {
    ThrowInvalid("cell_size_m: " + FormatNumber(cell) + " m cuts the points' extent (" +
                 FormatNumber(max_x - min_x) + " x " + FormatNumber(max_y - min_y) +
                 " m) into more than 4e6 cells");
  }
  GroundResult result;
  result.up_sign = up_sign;
  result.min_x = min_x;
  result.min_y = min_y;
  result.cell_size_m = cell;
  result.width = static_cast<int>(cells_x);
  result.height = static_cast<int>(cells_y);
  result.points = points.size();
  const size_t count = static_cast<size_t>(result.width) * static_cast<size_t>(result.height);

  // Heights (up_sign * z) per cell.
  std::vector<std::vector<double>> heights(count);
  for (size_t n = 0; n < points.size(); ++n) {
    poll(n);
    const Vec3d& p = points[n];
    const int i = std::min(static_cast<int>((p.x - min_x) / cell), result.width - 1);
    const int j = std::min(static_cast<int>((p.y - min_y) / cell), result.height - 1);
    heights[static_cast<size_t>(j) * result.width + i].push_back(up_sign * p.z);
  }
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> value(count, nan);
  std::vector<Vec3d> samples;  // (x, y, height) per measured cell
  std::vector<size_t> sample_cell;
  for (size_t k = 0; k < count; ++k) {
    poll(k);
    std::vector<double>& h = heights[k];
    if (static_cast<int>(h.size()) < options.min_points_per_cell) continue;
    std::sort(h.begin(), h.end());
    const double position = options.quantile * static_cast<double>(h.size() - 1);
    const size_t lower = static_cast<size_t>(position);
    const size_t upper = std::min(lower + 1, h.size() - 1);
    value[k] = h[lower] + (position - static_cast<double>(lower)) * (h[upper] - h[lower]);
    const int i = static_cast<int>(k % static_cast<size_t>(result.width));
    const int j = static_cast<int>(k / static_cast<size_t>(result.width));
    samples.emplace_back(min_x + (i + 0.5) * cell, min_y + (j + 0.5) * cell, value[k]);
    sample_cell.push_back(k);
  }
  if (samples.size() < 3) {
    ThrowInvalid("points: only " + std::to_string(samples.size()) + " cells of " +
                 FormatNumber(cell) + " m hold " + std::to_string(options.min_points_per_cell) +
                 "+ points (need 3): too few to find the ground (a smaller cell_size_m or "
                 "min_points_per_cell may help)");
  }

  // Robust plane: drop the cells far above it, refit.
  std::vector<uint8_t> keep(samples.size(), 1);
  PlaneFit fit;
  double sigma = 0.0;
  // Start from the lower envelope: two fits on the cells at or below the previous fit (canopy
  // pulls a first fit up, and then hides among the cells near it).
  for (int iteration = 0; iteration < 2; ++iteration) {
    if (!FitPlane(samples, keep, &fit)) break;
    std::vector<uint8_t> lower(samples.size(), 0);
    size_t n = 0;
    for (size_t i = 0; i < samples.size(); ++i) {
      lower[i] = keep[i] && samples[i].z - fit.At(samples[i].x, samples[i].y) <= 0.0;
      n += lower[i];
    }
    if (n < 3) break;
    keep = lower;
  }
  for (int iteration = 0; iteration < 50; ++iteration) {
    if (!FitPlane(samples, keep, &fit)) break;
    // The spread of the ground cells, from the kept cells at or below the plane: canopy cells
    // only ever lie above it, so they cannot inflate it.
    std::vector<double> below;
    for (size_t i = 0; i < samples.size(); ++i) {
      const double r = samples[i].z - fit.At(samples[i].x, samples[i].y);
      if (keep[i] && r <= 0.0) below.push_back(-r);
    }
    sigma = std::max(1.4826 * Median(below), 0.05);
    bool changed = false;
    for (size_t i = 0; i < samples.size(); ++i) {
      const bool above = samples[i].z - fit.At(samples[i].x, samples[i].y) > options.outlier_sigmas * sigma;
      const uint8_t k = above ? 0 : 1;
      changed = changed || k != keep[i];
      keep[i] = k;
    }
    if (!changed) break;
  }
  double squares = 0.0;
  for (size_t i = 0; i < samples.size(); ++i) {
    if (!keep[i]) continue;
    const double r = samples[i].z - fit.At(samples[i].x, samples[i].y);
    squares += r * r;
    ++result.plane_cells;
  }
  result.plane_rms_m = std::sqrt(squares / std::max(result.plane_cells, 1));
  // height h = up_sign z = a + b (x - x0) + c (y - y0): in z coordinates the plane
  // up_sign z - a - b dx - c dy = 0 has the normal (-b, -c, up_sign), which points up (its dot
  // product with the up direction up_sign e_z is 1).
  result.plane = Plane{Vec3d(fit.x0, fit.y0, up_sign * fit.a),
                       glm::normalize(Vec3d(-fit.b, -fit.c, static_cast<double>(up_sign)))};

  // Elevation model: drop canopy cells (far above the plane, and more than max_step_m above the
  // nearest cells that are not: a block of canopy cells is judged against the ground around it).
  std::vector<uint8_t> measured(count, 0);
  std::vector<double> residual(count, nan);
  std::vector<uint8_t> candidate(count, 0);
  for (size_t s = 0; s < samples.size(); ++s) {
    const size_t k = sample_cell[s];
    measured[k] = 1;
    residual[k] = value[k] - fit.At(samples[s].x, samples[s].y);
    candidate[k] = residual[k] > options.outlier_sigmas * sigma;
  }
  const int max_ring = std::max(result.width, result.height);
  // Mean residual of the cells passing `use` in the nearest ring around (i, j) holding any; NaN
  // when none does.
  auto ring_residual = [&](int i, int j, auto use, bool median) {
    std::vector<double> found;
    for (int ring = 1; ring <= max_ring && found.empty(); ++ring) {
      for (int b = std::max(j - ring, 0); b <= std::min(j + ring, result.height - 1); ++b) {
        for (int a = std::max(i - ring, 0); a <= std::min(i + ring, result.width - 1); ++a) {
          if (std::max(std::abs(a - i), std::abs(b - j)) != ring) continue;
          const size_t m = static_cast<size_t>(b) * result.width + a;
          if (use(m)) found.push_back(residual[m]);
        }
      }
    }
    if (found.empty()) return nan;
    if (median) return Median(found);
    double sum = 0.0;
    for (double r : found) sum += r;
    return sum / static_cast<double>(found.size());
  };
  std::vector<uint8_t> drop(count, 0);
  for (size_t k = 0; k < count; ++k) {
    poll(k);
    if (!candidate[k]) continue;
    const int i = static_cast<int>(k % static_cast<size_t>(result.width));
    const int j = static_cast<int>(k / static_cast<size_t>(result.width));
    const double around = ring_residual(i, j, [&](size_t m) { return measured[m] && !candidate[m]; }, true);
    if (!std::isfinite(around) || residual[k] - around > options.max_step_m) drop[k] = 1;
  }
  for (size_t k = 0; k < count; ++k) {
    if (drop[k]) measured[k] = 0;
  }
  // Fill from the nearest ring of measured cells (their mean residual from the plane).
  result.z.assign(count, 0.0f);
  result.measured = measured;
  ProgressStart(progress, "ground", result.height);
  for (int j = 0; j < result.height; ++j) {
    if (ProgressCancelled(progress)) throw Cancelled();
    ProgressAdvance(progress, 1);
    for (int i = 0; i < result.width; ++i) {
      const size_t k = static_cast<size_t>(j) * result.width + i;
      double height = value[k];
      if (measured[k]) {
        ++result.measured_cells;
      } else {
        const double around = ring_residual(i, j, [&](size_t m) { return measured[m] != 0; }, false);
        height = fit.At(min_x + (i + 0.5) * cell, min_y + (j + 0.5) * cell) +
                 (std::isfinite(around) ? around : 0.0);
      }
      result.z[k] = static_cast<float>(up_sign * height);
    }
  }
  return result;
}

Heightfield GroundHeightfield(const GroundResult& ground, const Vec3d& origin,
                              const std::string& crs_wkt) {
  Heightfield heightfield;
  heightfield.width = ground.width;
  heightfield.height = ground.height;
  const double cell = ground.cell_size_m;
  heightfield.geotransform = {origin.x + ground.min_x, cell, 0.0,
                              origin.y + ground.min_y + ground.height * cell, 0.0, -cell};
  heightfield.crs_wkt = crs_wkt;
  heightfield.heights.resize(ground.z.size());
  for (int row = 0; row < ground.height; ++row) {
    const int grid_row = ground.height - 1 - row;
    for (int column = 0; column < ground.width; ++column) {
      heightfield.heights[static_cast<size_t>(row) * ground.width + column] = static_cast<float>(
          origin.z + ground.z[static_cast<size_t>(grid_row) * ground.width + column]);
    }
  }
  return heightfield;
}

}  // namespace aos
