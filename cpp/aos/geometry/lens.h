#pragma once
// Lens models: the pinhole camera extended with OpenCV's distortion models, each with project
// (point in the camera frame -> pixel) and unproject (pixel -> unit ray).
//
// Contract
// - Pixel coordinates follow pinhole.h: continuous, pixel centres at +0.5 (OpenCV's centres are
//   at integers: cx_aos = cx_opencv + 0.5, likewise cy). Camera axes: x right, y down, z forward.
// - kPinhole: u = fx X/Z + cx, v = fy Y/Z + cy (distortion ignored).
// - kRadTan (OpenCV's default model; cv::projectPoints): x = X/Z, y = Y/Z, r^2 = x^2 + y^2,
//   x' = x (1 + k1 r^2 + k2 r^4 + k3 r^6) + 2 p1 x y + p2 (r^2 + 2 x^2),
//   y' = y (1 + k1 r^2 + k2 r^4 + k3 r^6) + p1 (r^2 + 2 y^2) + 2 p2 x y; u = fx x' + cx.
//   distortion = {k1, k2, p1, p2, k3}. Valid where Z > 0 and r <= max_radius (see below).
// - kFisheye (cv::fisheye, equidistant): theta = atan2(sqrt(X^2 + Y^2), Z),
//   theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8),
//   (x', y') = theta_d (X, Y) / sqrt(X^2 + Y^2); u = fx x' + cx. distortion = {k1, k2, k3, k4, 0}.
//   Rays up to theta_max (below pi) are valid, including beyond 90 degrees.
// - kOmnidir (cv::omnidir, Mei's unified model): X_s = X / |X|; x = X_s.x / (X_s.z + xi),
//   y = X_s.y / (X_s.z + xi); then the radial-tangential distortion with {k1, k2, p1, p2} (k3 = 0);
//   u = fx x' + skew y' + cx, v = fy y' + cy. Valid where X_s.z + xi > 0 (with xi > 1, rays beyond
//   90 degrees) and the distorted radius stays monotonic.
// - Invertibility: the radial distortion must be increasing over the valid field, so that project
//   is one-to-one there. Finalize() finds the largest undistorted radius (radtan, omnidir) or
//   angle (fisheye) up to which it is (max_radius / theta_max); points beyond do not project
//   (Project returns false) and pixels beyond their image do not unproject: the edge of a
//   fisheye's or omni lens's image circle. A radtan (perspective) lens must cover its frame: a
//   fold inside the frame is an error (with tangential terms: a border pixel without a ray).
//   Unproject inverts the radial part by a bracketed 1-D Newton iteration, then solves the full
//   distortion by Newton's method with backtracking (no step leaves the valid radius or raises
//   the residual) to 1e-15, and returns false where it does not converge.
//
// Throws std::invalid_argument naming the field for bad parameters (non-finite, fx <= 0,
// xi < 0, a radtan distortion that folds inside the frame).
#include <array>
#include <string>

#include "aos/geometry/pinhole.h"
#include "aos/geometry/rigid.h"
#include "aos/util/option_fields.h"

namespace aos {

enum class LensModel { kPinhole, kRadTan, kFisheye, kOmnidir };

// What code outside the model's own maths needs to know of a lens model, in one table
// (kLensModels, one row per model, in enum order): adding a model adds a row here, its maths in
// lens.cpp and its tests; names, parameters, the CLI, the bindings and the COLMAP mapping read
// the row.
struct LensModelTraits {
  LensModel model;
  const char* name;  // as files, the CLI and Python spell it
  // The coefficients the model reads from LensCamera::distortion, in that order (the rest are 0).
  int distortion_count;
  std::array<const char*, 5> distortion_names;
  bool has_xi;        // Mei's xi (and skew) are parameters
  // A plain pinhole: no distortion, so a frame maps to any plane by a homography (the exact
  // plane kernels of integral.h apply; every other model takes the lens path).
  bool pinhole;
  // Its rays stay within 90 degrees of the axis, so one frame is a perspective image
  // (homographies approximate its local maps; surface_integral.h).
  bool perspective;
  // COLMAP's camera model for it ("" = COLMAP has none; rectify the frames first). A radtan
  // lens with k3 != 0 takes FULL_OPENCV.
  const char* colmap_model;
  const char* opencv_calibration;  // the OpenCV function that calibrates it
};
inline constexpr LensModelTraits kLensModels[] = {
    {LensModel::kPinhole, "pinhole", 0, {}, false, true, true, "PINHOLE", "cv::calibrateCamera"},
    {LensModel::kRadTan, "radtan", 5, {"k1", "k2", "p1", "p2", "k3"}, false, false, true,
     "OPENCV", "cv::calibrateCamera"},
    {LensModel::kFisheye, "fisheye", 4, {"k1", "k2", "k3", "k4"}, false, false, false,
     "OPENCV_FISHEYE", "cv::fisheye::calibrate"},
    {LensModel::kOmnidir, "omnidir", 4, {"k1", "k2", "p1", "p2"}, true, false, false, "",
     "cv::omnidir::calibrate"},
};
// The row of `model`.
constexpr const LensModelTraits& TraitsOf(LensModel model) {
  return kLensModels[static_cast<int>(model)];
}
// The index in LensCamera::distortion of coefficient `name` ("k1", "p2", ...) for `model`, or -1
// if the model has none of that name.
int DistortionIndex(LensModel model, const std::string& name);

// "pinhole", "radtan", "fisheye", "omnidir"; throws std::invalid_argument naming `where`.
LensModel ParseLensModel(const std::string& name, const std::string& where);
const char* LensModelName(LensModel model);
template <>
struct EnumNames<LensModel> {  // the names of kLensModels (lens.cpp asserts they agree)
  static constexpr std::pair<LensModel, const char*> kValues[] = {
      {LensModel::kPinhole, "pinhole"}, {LensModel::kRadTan, "radtan"},
      {LensModel::kFisheye, "fisheye"}, {LensModel::kOmnidir, "omnidir"}};
};

struct LensCamera {
  LensModel model = LensModel::kPinhole;
  int width = 0;    // pixels (> 0)
  int height = 0;
  double fx = 0.0;  // pixels (> 0)
  double fy = 0.0;
  double cx = 0.0;  // continuous coordinates (pixel centres at +0.5)
  double cy = 0.0;
  double skew = 0.0;  // omnidir only (OpenCV's s)
  double xi = 0.0;    // omnidir only, >= 0
  std::array<double, 5> distortion{0, 0, 0, 0, 0};  // see above, per model

  // Derived by Finalize(): the valid field.
  double max_radius = 0.0;  // radtan/omnidir: largest normalised undistorted radius
  double theta_max = 0.0;   // fisheye: largest ray angle from the axis, radians

  static LensCamera FromPinhole(const PinholeCamera& camera);
  // The row of kLensModels for `model`.
  const LensModelTraits& traits() const { return TraitsOf(model); }
  // Whether this is a plain pinhole (traits().pinhole): the exact plane kernels apply.
  bool IsPinhole() const { return traits().pinhole; }
  // The pinhole part (size, fx, fy, cx, cy): the whole camera for kPinhole, the intrinsics a
  // lens model shares with its pinhole for the others (skew, xi and distortion dropped).
  PinholeCamera Pinhole() const { return PinholeCamera{width, height, fx, fy, cx, cy}; }

  // Validates the parameters and computes the valid field. Throws std::invalid_argument
  // "<where>: <field>: <reason>".
  void Finalize(const std::string& where);

  // Pixel of a point in the camera frame; false where the point is outside the valid field.
  bool Project(const Vec3d& point_in_cam, Vec2d* pixel) const;
  // Unit ray through `pixel`; false where no valid ray maps there.
  bool Unproject(const Vec2d& pixel, Vec3d* ray) const;

  // The distortion in normalised coordinates (radtan/omnidir): undistorted -> distorted.
  Vec2d Distort(const Vec2d& undistorted) const;

  // The largest angle from the optical axis within which every ray projects (Project
  // succeeds), radians, in (0, pi]: pi / 2 for a pinhole, theta_max for a fisheye, and for the
  // radial-tangential part of radtan and omnidir lenses also the angle whose undistorted radius
  // is max_radius. Requires Finalize().
  double ValidAngle() const;

  // The field table (util/option_fields.h) of the parameters, what `aos-render camera` sets
  // (its flags come from these rows); the derived valid field is not listed.
  template <class Visit>
  static void Fields(Visit&& field) {
    using O = LensCamera;
    field(OptionField("model", &O::model, "", Range::Any(),
                      "Lens model: pinhole, radtan, fisheye or omnidir (docs/lens-models.md)."));
    field(OptionField("width", &O::width, "px", Range::AtLeast(1), "Image width, pixels."));
    field(OptionField("height", &O::height, "px", Range::AtLeast(1), "Image height, pixels."));
    field(OptionField("fx", &O::fx, "px", Range::Any(), "Focal length, pixels (> 0)."));
    field(OptionField("fy", &O::fy, "px", Range::Any(),
                      "Focal length along y, pixels (> 0; `camera` takes fx when not given)."));
    field(OptionField("cx", &O::cx, "px", Range::Any(),
                      "Principal point x, pixels, aos's convention: pixel centres at +0.5, so "
                      "OpenCV's cx + 0.5 (`camera` takes width / 2 when not given)."));
    field(OptionField("cy", &O::cy, "px", Range::Any(),
                      "Principal point y, pixels, as cx (OpenCV's cy + 0.5; `camera` takes "
                      "height / 2 when not given)."));
    field(OptionField("distortion", &O::distortion, "", Range::Any(),
                      "Distortion coefficients in the model's order (radtan k1, k2, p1, p2, k3; "
                      "fisheye k1..k4; omnidir k1, k2, p1, p2), the rest 0."));
    field(OptionField("xi", &O::xi, "", Range::Any(), "omnidir only: Mei's xi (>= 0)."));
    field(OptionField("skew", &O::skew, "", Range::Any(), "omnidir only: skew (OpenCV's s)."));
  }

  // Whether `other` has the same model and parameters (size, intrinsics, skew, xi, distortion);
  // the derived valid field follows from them.
  bool SameParameters(const LensCamera& other) const {
    return model == other.model && width == other.width && height == other.height &&
           fx == other.fx && fy == other.fy && cx == other.cx && cy == other.cy &&
           skew == other.skew && xi == other.xi && distortion == other.distortion;
  }
};

// A centred lens camera of `model` whose horizontal field of view is `fov_deg`, defined through
// the lens's radial map: the ray at fov_deg / 2 off the axis lands on the image's left and right
// edges (fx = fy = width / 2 / r(fov / 2)). Valid up to the model's own limit (a pinhole or
// radial-tangential lens below 180 degrees, a fisheye or omnidirectional one up to 360), and only
// where the lens is invertible. Throws std::invalid_argument "<where>.fov_deg: ..." or
// "<where>.distortion: ..." naming what is wrong.
LensCamera LensFromFov(LensModel model, int width, int height, double fov_deg,
                       const std::array<double, 5>& distortion, double xi,
                       const std::string& where);

}  // namespace aos
