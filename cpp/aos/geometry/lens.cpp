#include "aos/geometry/lens.h"

#include <iterator>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include "aos/util/error.h"
#include "aos/util/math.h"

namespace aos {
namespace {

// Derivative of the radial map r -> r (1 + k1 r^2 + k2 r^4 + k3 r^6).
double RadialSlope(const std::array<double, 5>& d, double r) {
  const double r2 = r * r;
  return 1.0 + r2 * (3.0 * d[0] + r2 * (5.0 * d[1] + r2 * 7.0 * d[4]));
}

// Derivative of the fisheye map theta -> theta (1 + k1 theta^2 + ... + k4 theta^8).
double FisheyeSlope(const std::array<double, 5>& d, double t) {
  const double t2 = t * t;
  return 1.0 + t2 * (3.0 * d[0] + t2 * (5.0 * d[1] + t2 * (7.0 * d[2] + t2 * 9.0 * d[3])));
}

double FisheyeDistort(const std::array<double, 5>& d, double t) {
  const double t2 = t * t;
  return t * (1.0 + t2 * (d[0] + t2 * (d[1] + t2 * (d[2] + t2 * d[3]))));
}

// The first x in (0, limit] where slope(x) <= 0, or `limit` if there is none (scanned in
// `steps` steps, then bisected).
template <typename Slope>
double FirstFold(Slope slope, double limit, int steps) {
  double previous = 0.0;
  for (int i = 1; i <= steps; ++i) {
    const double x = limit * i / steps;
    if (slope(x) <= 0.0) {
      double lo = previous, hi = x;
      for (int k = 0; k < 60; ++k) {
        const double mid = 0.5 * (lo + hi);
        (slope(mid) > 0.0 ? lo : hi) = mid;
      }
      return lo;
    }
    previous = x;
  }
  return limit;
}

}  // namespace

namespace {
constexpr bool SameText(const char* a, const char* b) {
  while (*a != '\0' && *a == *b) ++a, ++b;
  return *a == *b;
}
constexpr bool TraitsInEnumOrder() {
  for (int i = 0; i < 4; ++i) {
    if (static_cast<int>(kLensModels[i].model) != i) return false;
    if (!SameText(kLensModels[i].name, EnumNames<LensModel>::kValues[i].second)) return false;
  }
  return true;
}
static_assert(std::size(kLensModels) == 4 && TraitsInEnumOrder(),
              "kLensModels: one row per LensModel, in enum order, named as EnumNames says");
}  // namespace

LensModel ParseLensModel(const std::string& name, const std::string& where) {
  std::string names;
  for (const LensModelTraits& traits : kLensModels) {
    if (name == traits.name) return traits.model;
    names += (names.empty() ? "" : ", ") + std::string(traits.name);
  }
  ThrowInvalid(where + ": unknown lens model '" + name + "' (" + names + ")");
}

const char* LensModelName(LensModel model) { return TraitsOf(model).name; }

int DistortionIndex(LensModel model, const std::string& name) {
  const LensModelTraits& traits = TraitsOf(model);
  for (int i = 0; i < traits.distortion_count; ++i) {
    if (name == traits.distortion_names[static_cast<size_t>(i)]) return i;
  }
  return -1;
}

LensCamera LensCamera::FromPinhole(const PinholeCamera& camera) {
  LensCamera lens;
  lens.width = camera.width;
  lens.height = camera.height;
  lens.fx = camera.fx;
  lens.fy = camera.fy;
  lens.cx = camera.cx;
  lens.cy = camera.cy;
  lens.Finalize("pinhole camera");
  return lens;
}

Vec2d LensCamera::Distort(const Vec2d& p) const {
  const std::array<double, 5>& d = distortion;
  const double k3 = model == LensModel::kOmnidir ? 0.0 : d[4];
  const double x = p.x, y = p.y, r2 = x * x + y * y;
  const double radial = 1.0 + r2 * (d[0] + r2 * (d[1] + r2 * k3));
  return Vec2d(x * radial + 2.0 * d[2] * x * y + d[3] * (r2 + 2.0 * x * x),
               y * radial + d[2] * (r2 + 2.0 * y * y) + 2.0 * d[3] * x * y);
}

void LensCamera::Finalize(const std::string& where) {
  if (width <= 0 || height <= 0) ThrowInvalid(where + ": width/height: must be positive");
  if (width > kMaxImageSide || height > kMaxImageSide) {
    ThrowInvalid(where + ": width/height: must be at most " + std::to_string(kMaxImageSide) +
                 " pixels (got " + std::to_string(width) + "x" + std::to_string(height) + ")");
  }
  const double values[] = {fx, fy, cx, cy, skew, xi, distortion[0], distortion[1],
                           distortion[2], distortion[3], distortion[4]};
  for (double value : values) {
    if (!std::isfinite(value)) ThrowInvalid(where + ": parameters must be finite");
  }
  if (!(fx > 0.0) || !(fy > 0.0)) ThrowInvalid(where + ": fx/fy: must be > 0");
  if (model == LensModel::kOmnidir && xi < 0.0) {
    ThrowInvalid(where + ": xi: must be >= 0 (got " + FormatNumber(xi) +
                 "); the unified model is not invertible otherwise");
  }
  if (model == LensModel::kFisheye && distortion[4] != 0.0) {
    ThrowInvalid(where + ": distortion: the fisheye model has k1..k4 only (fifth value must be 0)");
  }
  if (model != LensModel::kOmnidir && (skew != 0.0 || xi != 0.0)) {
    ThrowInvalid(where + ": skew/xi: only the omnidir model has them");
  }
  // The frame's largest distorted normalised radius (its corners), to tell whether a fold of the
  // distortion lies inside the image.
  double frame_radius = 0.0;
  for (double u : {0.0, static_cast<double>(width)}) {
    for (double v : {0.0, static_cast<double>(height)}) {
      const double y = (v - cy) / fy;
      const double x = (u - cx - skew * y) / fx;
      frame_radius = std::max(frame_radius, std::hypot(x, y));
    }
  }
  max_radius = std::numeric_limits<double>::infinity();
  theta_max = kPi;
  switch (model) {
    case LensModel::kPinhole:
      theta_max = 0.5 * kPi;
      break;
    case LensModel::kRadTan:
    case LensModel::kOmnidir: {
      std::array<double, 5> d = distortion;
      if (model == LensModel::kOmnidir) d[4] = 0.0;
      const double fold = FirstFold([&](double r) { return RadialSlope(d, r); }, 1e3, 200000);
      if (fold < 1e3) {
        max_radius = fold;
        const double folded_at = fold * (1.0 + fold * fold * (d[0] + fold * fold * (d[1] + fold * fold * d[4])));
        // A perspective lens must cover its frame; a fold inside it is an error. Omnidirectional
        // images end at their image circle: beyond the fold is simply not imaged (masked).
        if (model == LensModel::kRadTan && folded_at < frame_radius) {
          ThrowInvalid(where + ": distortion: folds the image (the radial distortion stops "
                               "increasing at normalised radius " + FormatNumber(fold) +
                       ", inside the frame); the model is not invertible there");
        }
      }
      if (model == LensModel::kRadTan) {
        theta_max = 0.5 * kPi;
        // With tangential terms the covered region is not a disk: every pixel of the frame's
        // border must still have a ray (the region is simply connected, so then all do).
        if (d[2] != 0.0 || d[3] != 0.0) {
          const auto check = [&](double u, double v) {
            Vec3d ray;
            if (!Unproject(Vec2d(u, v), &ray)) {
              ThrowInvalid(where + ": distortion: folds the image (with its tangential terms "
                                   "p1, p2, no ray maps to pixel (" + FormatNumber(u) + ", " +
                           FormatNumber(v) + ") of the frame); the model is not invertible there");
            }
          };
          // At most kBorderSamples + 1 points per edge, corners included (a whole-pixel walk
          // would take minutes for the largest frames).
          constexpr int64_t kBorderSamples = 4096;
          const auto walk = [&](int64_t length, const auto& point) {
            const int64_t steps = std::min<int64_t>(length, kBorderSamples);
            for (int64_t i = 0; i <= steps; ++i) point(static_cast<double>(length) * i / steps);
          };
          walk(width, [&](double u) {
            check(u, 0.0);
            check(u, height);
          });
          walk(height, [&](double v) {
            check(0.0, v);
            check(width, v);
          });
        }
      } else {
        // Unified model: injective on the sphere where 1 + xi cos(theta) > 0 and
        // cos(theta) + xi > 0.
        theta_max = xi == 0.0 ? 0.5 * kPi : std::acos(-std::min(xi, 1.0 / xi));
      }
      break;
    }
    case LensModel::kFisheye: {
      // The image circle ends where the distortion stops increasing (or at 180 degrees):
      // pixels beyond it have no ray (masked), as for any circular fisheye frame.
      theta_max = FirstFold([&](double t) { return FisheyeSlope(distortion, t); }, kPi, 100000);
      if (theta_max >= kPi) theta_max = kPi * (1.0 - 1e-9);
      break;
    }
  }
}

bool LensCamera::Project(const Vec3d& p, Vec2d* pixel) const {
  switch (model) {
    case LensModel::kPinhole:
      if (!(p.z > 0.0)) return false;
      *pixel = Vec2d(fx * p.x / p.z + cx, fy * p.y / p.z + cy);
      return true;
    case LensModel::kRadTan: {
      if (!(p.z > 0.0)) return false;
      const Vec2d n(p.x / p.z, p.y / p.z);
      // sqrt rather than hypot (several times slower; no overflow at camera-frame magnitudes).
      if (!(std::sqrt(n.x * n.x + n.y * n.y) <= max_radius)) return false;
      const Vec2d d = Distort(n);
      *pixel = Vec2d(fx * d.x + cx, fy * d.y + cy);
      return true;
    }
    case LensModel::kFisheye: {
      const double r = std::sqrt(p.x * p.x + p.y * p.y);
      const double theta = std::atan2(r, p.z);
      if (!(theta <= theta_max) || (r == 0.0 && !(p.z > 0.0))) return false;
      const double scale = r > 0.0 ? FisheyeDistort(distortion, theta) / r : 0.0;
      *pixel = Vec2d(fx * scale * p.x + cx, fy * scale * p.y + cy);
      return true;
    }
    case LensModel::kOmnidir: {
      const double length = glm::length(p);
      if (!(length > 0.0)) return false;
      const Vec3d s = p / length;
      // The angle test (theta < theta_max) as cos(theta) > cos(theta_max). The cosine is kept
      // per thread for the last theta_max seen (renders project one lens many times; about a
      // third of this function's time otherwise); the same value as computing it each time.
      thread_local double cached_theta_max = std::numeric_limits<double>::quiet_NaN();
      thread_local double cached_cos = 0.0;
      if (!(theta_max == cached_theta_max)) {
        cached_cos = std::cos(theta_max);
        cached_theta_max = theta_max;
      }
      if (!(s.z > cached_cos)) return false;
      const double denominator = s.z + xi;
      if (!(denominator > 0.0)) return false;
      const Vec2d n(s.x / denominator, s.y / denominator);
      if (!(std::sqrt(n.x * n.x + n.y * n.y) <= max_radius)) return false;
      const Vec2d d = Distort(n);
      *pixel = Vec2d(fx * d.x + skew * d.y + cx, fy * d.y + cy);
      return true;
    }
  }
  return false;
}

bool LensCamera::Unproject(const Vec2d& pixel, Vec3d* ray) const {
  const double yd = (pixel.y - cy) / fy;
  const double xd = (pixel.x - cx - skew * yd) / fx;
  if (!std::isfinite(xd) || !std::isfinite(yd)) return false;
  if (model == LensModel::kPinhole) {
    *ray = glm::normalize(Vec3d(xd, yd, 1.0));
    return true;
  }
  if (model == LensModel::kFisheye) {
    const double theta_d = std::hypot(xd, yd);
    if (theta_d == 0.0) {
      *ray = Vec3d(0.0, 0.0, 1.0);
      return true;
    }
    if (!(theta_d <= FisheyeDistort(distortion, theta_max))) return false;
    // Newton on theta (the map is increasing on [0, theta_max]), kept inside the bracket.
    double lo = 0.0, hi = theta_max, theta = std::min(theta_d, theta_max);
    for (int i = 0; i < 100; ++i) {
      const double f = FisheyeDistort(distortion, theta) - theta_d;
      if (f > 0.0) hi = theta; else lo = theta;
      double next = theta - f / FisheyeSlope(distortion, theta);
      if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
      if (std::abs(next - theta) <= 1e-15 * (1.0 + theta)) {
        theta = next;
        break;
      }
      theta = next;
    }
    const double s = std::sin(theta) / theta_d;
    *ray = Vec3d(s * xd, s * yd, std::cos(theta));
    return true;
  }
  // radtan and omnidir: undo the radial-tangential distortion. Start from the radial part's
  // inverse (increasing on [0, max_radius]: a bracketed 1-D Newton), then Newton's method on
  // the full map with backtracking, so no step overshoots past the fold or raises the residual.
  const std::array<double, 5>& d = distortion;
  const double k3 = model == LensModel::kOmnidir ? 0.0 : d[4];
  const auto radial_of = [&](double r) {
    const double r2 = r * r;
    return r * (1.0 + r2 * (d[0] + r2 * (d[1] + r2 * k3)));
  };
  const double r_limit = std::isfinite(max_radius) ? max_radius : 1e3;
  const double rd = std::hypot(xd, yd);
  Vec2d p(xd, yd);
  if (rd > 0.0) {
    double lo = 0.0, hi = r_limit, r = std::min(rd, r_limit);
    if (radial_of(r_limit) <= rd) {
      r = r_limit;
    } else {
      for (int i = 0; i < 200; ++i) {
        const double f = radial_of(r) - rd;
        if (f > 0.0) hi = r; else lo = r;
        double next = r - f / RadialSlope(d, r);
        if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
        if (std::abs(next - r) <= 1e-15 * (1.0 + r)) {
          r = next;
          break;
        }
        r = next;
      }
    }
    p = Vec2d(xd, yd) * (r / rd);
  }
  const Vec2d target(xd, yd);
  const auto residual = [&](const Vec2d& q) { return glm::length(Distort(q) - target); };
  const double tolerance = 1e-15 * (1.0 + std::abs(xd) + std::abs(yd));
  double error = residual(p);
  bool converged = error <= tolerance;
  for (int i = 0; i < 100 && !converged; ++i) {
    const Vec2d f = Distort(p) - target;
    const double x = p.x, y = p.y, r2 = x * x + y * y;
    const double radial = 1.0 + r2 * (d[0] + r2 * (d[1] + r2 * k3));
    const double radial1 = 2.0 * d[0] + r2 * (4.0 * d[1] + r2 * 6.0 * k3);
    const double a = radial + radial1 * x * x + 2.0 * d[2] * y + 6.0 * d[3] * x;
    const double b = radial1 * x * y + 2.0 * d[2] * x + 2.0 * d[3] * y;
    const double c = radial + radial1 * y * y + 6.0 * d[2] * y + 2.0 * d[3] * x;
    const double det = a * c - b * b;
    if (!(std::abs(det) > 1e-300)) break;
    const Vec2d step((c * f.x - b * f.y) / det, (a * f.y - b * f.x) / det);
    // Backtracking: halve the step until it stays inside the valid radius and lowers the error.
    double scale = 1.0;
    bool improved = false;
    for (int k = 0; k < 60; ++k, scale *= 0.5) {
      const Vec2d candidate = p - scale * step;
      if (!(std::hypot(candidate.x, candidate.y) <= r_limit)) continue;
      const double candidate_error = residual(candidate);
      if (candidate_error < error || candidate_error <= tolerance) {
        p = candidate;
        error = candidate_error;
        improved = true;
        break;
      }
    }
    converged = error <= tolerance;
    if (!improved) break;
  }
  if (!converged) converged = error <= 1e-12 * (1.0 + rd);  // rounding floor near the fold
  if (!converged || !(std::hypot(p.x, p.y) <= max_radius * (1.0 + 1e-12))) return false;
  if (model == LensModel::kRadTan) {
    *ray = glm::normalize(Vec3d(p.x, p.y, 1.0));
    return true;
  }
  // Lift onto the unit sphere (the root with 1 + xi cos(theta) > 0).
  const double r2 = p.x * p.x + p.y * p.y;
  const double discriminant = 1.0 + (1.0 - xi * xi) * r2;
  if (!(discriminant >= 0.0)) return false;
  const double factor = (xi + std::sqrt(discriminant)) / (r2 + 1.0);
  const Vec3d s(factor * p.x, factor * p.y, factor - xi);
  if (!(s.z > std::cos(theta_max) - 1e-12)) return false;
  *ray = glm::normalize(s);
  return true;
}

LensCamera LensFromFov(LensModel model, int width, int height, double fov_deg,
                       const std::array<double, 5>& distortion, double xi,
                       const std::string& where) {
  const auto fail = [&](const std::string& field, const std::string& reason) {
    ThrowInvalid(where + "." + field + ": " + reason);
  };
  const bool wide = model == LensModel::kFisheye || model == LensModel::kOmnidir;
  const double limit = wide ? 360.0 : 180.0;
  if (!(fov_deg > 0.0 && (wide ? fov_deg <= limit : fov_deg < limit))) {
    fail("fov_deg", "a " + std::string(LensModelName(model)) + " lens's field of view must be in " +
                        "(0, " + FormatNumber(limit) + (wide ? "]" : ")") + " degrees (got " +
                        FormatNumber(fov_deg) + ")");
  }
  LensCamera lens;
  lens.model = model;
  lens.width = width;
  lens.height = height;
  lens.distortion = distortion;
  if (model == LensModel::kOmnidir) lens.xi = xi;
  // The normalised radius that the ray at half the field of view maps to (radial part only):
  // the focal length puts it at the image's left and right edges.
  const double half = DegToRad(0.5 * fov_deg);
  const std::array<double, 5>& d = distortion;
  double undistorted = 0.0, radius = 0.0;
  switch (model) {
    case LensModel::kPinhole:
    case LensModel::kRadTan:
      undistorted = std::tan(half);
      break;
    case LensModel::kFisheye:
      radius = half * (1.0 + half * half * (d[0] + half * half * (d[1] + half * half *
                                                                  (d[2] + half * half * d[3]))));
      break;
    case LensModel::kOmnidir: {
      const double denominator = std::cos(half) + xi;
      if (!(denominator > 0.0)) {
        fail("fov_deg", FormatNumber(fov_deg) + " degrees is beyond what an omnidir lens with xi = " +
                            FormatNumber(xi) + " images (cos(fov/2) + xi must be > 0)");
      }
      undistorted = std::sin(half) / denominator;
      break;
    }
  }
  if (model == LensModel::kPinhole) radius = undistorted;
  if (model == LensModel::kRadTan || model == LensModel::kOmnidir) {
    const double r2 = undistorted * undistorted;
    const double k3 = model == LensModel::kRadTan ? d[4] : 0.0;
    radius = undistorted * (1.0 + r2 * (d[0] + r2 * (d[1] + r2 * k3)));
  }
  if (!(radius > 0.0) || !std::isfinite(radius)) {
    fail("distortion", "maps the edge of the field of view (fov_deg / 2 = " +
                           FormatNumber(0.5 * fov_deg) + " degrees) to radius " +
                           FormatNumber(radius) + " (must be > 0)");
  }
  lens.fx = lens.fy = 0.5 * width / radius;
  lens.cx = 0.5 * width;
  lens.cy = 0.5 * height;
  lens.Finalize(where);
  // The field of view must lie where the lens is invertible.
  const bool beyond_angle = wide && half > lens.theta_max;
  const bool beyond_radius = (model == LensModel::kRadTan || model == LensModel::kOmnidir) &&
                             undistorted > lens.max_radius;
  if (beyond_angle || beyond_radius) {
    fail("fov_deg", "half the field of view (" + FormatNumber(0.5 * fov_deg) +
                        " degrees) is beyond the lens's valid field (its distortion stops "
                        "increasing before it)");
  }
  return lens;
}

double LensCamera::ValidAngle() const {
  switch (model) {
    case LensModel::kPinhole: return 0.5 * kPi;
    case LensModel::kFisheye: return theta_max;
    case LensModel::kRadTan:
      return std::isfinite(max_radius) ? std::atan(max_radius) : 0.5 * kPi;
    case LensModel::kOmnidir: {
      // The undistorted radius sin(t) / (cos(t) + xi) increases with t below theta_max (its
      // derivative is (1 + xi cos t) / (cos t + xi)^2 > 0 there): bisection.
      if (!std::isfinite(max_radius)) return theta_max;
      const auto radius = [&](double t) { return std::sin(t) / (std::cos(t) + xi); };
      if (radius(theta_max * (1.0 - 1e-12)) <= max_radius) return theta_max;
      double lo = 0.0, hi = theta_max;
      for (int i = 0; i < 100; ++i) {
        const double mid = 0.5 * (lo + hi);
        (radius(mid) <= max_radius ? lo : hi) = mid;
      }
      return lo;
    }
  }
  return 0.0;
}

}  // namespace aos
