#include "aos/geometry/pinhole.h"

#include <cmath>

#include "aos/util/error.h"
#include "aos/util/math.h"

namespace aos {

PinholeCamera PinholeCamera::FromFov(int width, int height, double fov_deg) {
  if (!(width > 0 && height > 0)) {
    ThrowInvalid("camera: width and height must be positive (got " + std::to_string(width) + "x" +
                 std::to_string(height) + ")");
  }
  if (!(fov_deg > 0.0 && fov_deg < 180.0)) {
    ThrowInvalid("fov_deg: a pinhole field of view must be in (0, 180) degrees (got " +
                 FormatNumber(fov_deg) + ")");
  }
  PinholeCamera camera;
  camera.width = width;
  camera.height = height;
  camera.fx = 0.5 * width / std::tan(0.5 * DegToRad(fov_deg));
  camera.fy = camera.fx;
  camera.cx = 0.5 * width;
  camera.cy = 0.5 * height;
  return camera;
}

Mat3d PinholeCamera::K() const {
  return MatFromRows(Vec3d(fx, 0, cx), Vec3d(0, fy, cy), Vec3d(0, 0, 1));
}

double PinholeCamera::FovXDeg() const { return RadToDeg(2.0 * std::atan(0.5 * width / fx)); }

void PinholeCamera::Check(const std::string& where) const {
  if (!(width > 0 && height > 0)) {
    ThrowInvalid(Where(where, "camera width/height must be positive (got " +
                                  std::to_string(width) + "x" + std::to_string(height) + ")"));
  }
  if (width > kMaxImageSide || height > kMaxImageSide) {
    ThrowInvalid(Where(where, "camera width/height must be at most " +
                                  std::to_string(kMaxImageSide) + " pixels (got " +
                                  std::to_string(width) + "x" + std::to_string(height) + ")"));
  }
  const char* names[] = {"fx", "fy", "cx", "cy"};
  const double values[] = {fx, fy, cx, cy};
  for (int i = 0; i < 4; ++i) {
    if (!std::isfinite(values[i])) {
      ThrowInvalid(Where(where, std::string("camera ") + names[i] + " is not finite"));
    }
  }
  if (!(fx > 0.0 && fy > 0.0)) {
    ThrowInvalid(Where(where, "camera fx and fy must be positive (got fx=" + FormatNumber(fx) +
                                  ", fy=" + FormatNumber(fy) + ")"));
  }
}

}  // namespace aos
