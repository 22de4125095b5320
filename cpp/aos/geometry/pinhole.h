#pragma once
// The pinhole camera and the pixel convention used everywhere in aos.
//
// Pixel convention (the only one): continuous pixel coordinates (u, v) have their origin at the
// top-left corner of the image; u grows to the right, v downwards; the pixel in column i and row
// j covers [i, i+1) x [j, j+1), so its centre is at (i + 0.5, j + 0.5). A camera's principal point
// (cx, cy) is in the same coordinates: the image centre is (width / 2, height / 2).
//
// Projection of a point in camera coordinates (x right, y down, z forward, metres):
//   u = fx * x / z + cx,   v = fy * y / z + cy,   defined for z > 0 only.
#include <string>

#include "aos/geometry/rigid.h"

namespace aos {

// The largest image side aos accepts anywhere (cameras, frames, renders), pixels.
inline constexpr int kMaxImageSide = 65536;

struct PinholeCamera {
  int width = 0;    // image width, pixels (1 .. kMaxImageSide)
  int height = 0;   // image height, pixels (1 .. kMaxImageSide)
  double fx = 0.0;  // focal length in pixels along u (> 0)
  double fy = 0.0;  // focal length in pixels along v (> 0)
  double cx = 0.0;  // principal point u, pixels (continuous coordinates, see above)
  double cy = 0.0;  // principal point v, pixels

  // Square pixels, principal point at the image centre, `fov_deg` the full horizontal field of
  // view across the width (0 < fov_deg < 180). Throws std::invalid_argument otherwise.
  static PinholeCamera FromFov(int width, int height, double fov_deg);

  // The intrinsic matrix K, mapping camera coordinates to homogeneous pixels.
  Mat3d K() const;
  // Horizontal field of view, degrees.
  double FovXDeg() const;
  Vec2d Project(const Vec3d& point_in_cam) const {
    return Vec2d(fx * point_in_cam.x / point_in_cam.z + cx, fy * point_in_cam.y / point_in_cam.z + cy);
  }
  // The ray direction (z = 1) through continuous pixel coordinates `pixel`.
  Vec3d Unproject(const Vec2d& pixel) const {
    return Vec3d((pixel.x - cx) / fx, (pixel.y - cy) / fy, 1.0);
  }

  // Throws std::invalid_argument naming `where` if a field is out of range or not finite.
  void Check(const std::string& where) const;
};

}  // namespace aos
