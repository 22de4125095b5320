#include "aos/geometry/rigid.h"

#include <cmath>
#include <ostream>

#include "aos/util/error.h"
#include "aos/util/math.h"

namespace aos {

Mat3d MatFromRows(const Vec3d& row0, const Vec3d& row1, const Vec3d& row2) {
  return glm::transpose(Mat3d(row0, row1, row2));
}

Vec3d Row(const Mat3d& m, int r) { return Vec3d(m[0][r], m[1][r], m[2][r]); }

Rigid3d Rigid3d::Inverse() const {
  const Mat3d rotation_t = glm::transpose(rotation);
  return Rigid3d{rotation_t, -(rotation_t * translation)};
}

Rigid3d Rigid3d::FromMatrix3x4(const std::array<double, 12>& m) {
  Rigid3d result;
  result.rotation = MatFromRows(Vec3d(m[0], m[1], m[2]), Vec3d(m[4], m[5], m[6]),
                                Vec3d(m[8], m[9], m[10]));
  result.translation = Vec3d(m[3], m[7], m[11]);
  return result;
}

std::array<double, 12> Rigid3d::ToMatrix3x4() const {
  std::array<double, 12> m{};
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) m[4 * r + c] = rotation[c][r];
    m[4 * r + 3] = translation[r];
  }
  return m;
}

std::ostream& operator<<(std::ostream& stream, const Rigid3d& transform) {
  const auto m = transform.ToMatrix3x4();
  stream << "Rigid3d([";
  for (int r = 0; r < 3; ++r) {
    stream << (r ? ", [" : "[") << m[4 * r] << ", " << m[4 * r + 1] << ", " << m[4 * r + 2]
           << ", " << m[4 * r + 3] << "]";
  }
  return stream << "])";
}

std::optional<std::string> DescribeInvalidRigid(const Rigid3d& transform, double tolerance) {
  for (double value : transform.ToMatrix3x4()) {
    if (!std::isfinite(value)) return std::string("has a non-finite entry (NaN or infinity)");
  }
  const Mat3d gram = glm::transpose(transform.rotation) * transform.rotation;
  double deviation = 0.0;
  for (int c = 0; c < 3; ++c) {
    for (int r = 0; r < 3; ++r) {
      deviation = std::max(deviation, std::abs(gram[c][r] - (r == c ? 1.0 : 0.0)));
    }
  }
  if (deviation > tolerance) {
    return "rotation is not orthonormal (max |R^T R - I| = " + FormatNumber(deviation) + ")";
  }
  if (glm::determinant(transform.rotation) < 0.0) {
    return std::string("rotation is a reflection (det R = -1)");
  }
  return std::nullopt;
}

Rigid3d LookAt(const Vec3d& eye, const Vec3d& target, const Vec3d& up) {
  const Vec3d forward = target - eye;
  const double length = glm::length(forward);
  if (!(length > 0.0) || !std::isfinite(length)) {
    ThrowInvalid("look-at: eye and target must be distinct finite points");
  }
  const Vec3d z = forward / length;
  // Camera y points down the image, so it is -up (made orthogonal); x = y cross z.
  Vec3d x = glm::cross(-up, z);
  const double x_length = glm::length(x);
  if (!(x_length > 1e-9 * glm::length(up))) {
    ThrowInvalid("look-at: the up vector is parallel to the viewing direction");
  }
  x /= x_length;
  const Vec3d y = glm::cross(z, x);
  Rigid3d cam_from_world;
  cam_from_world.rotation = MatFromRows(x, y, z);
  cam_from_world.translation = -(cam_from_world.rotation * eye);
  return cam_from_world;
}

Rigid3d LookAt(const Vec3d& eye, const Vec3d& target) {
  const Vec3d forward = target - eye;
  const double length = glm::length(forward);
  const bool along_z = length > 0.0 && std::abs(forward.z) / length > std::cos(DegToRad(1.0));
  return LookAt(eye, target, along_z ? Vec3d(0, 1, 0) : Vec3d(0, 0, 1));
}

Plane Plane::InFrontOf(const Rigid3d& cam_from_world, double distance, bool horizontal) {
  if (!(distance > 0.0) || !std::isfinite(distance)) {
    ThrowInvalid("focal_distance: must be > 0 metres (got " + FormatNumber(distance) + ")");
  }
  const Vec3d axis = Row(cam_from_world.rotation, 2);  // optical axis in the world
  const Vec3d point = cam_from_world.Center() + distance * axis;
  return Plane{point, horizontal ? Vec3d(0, 0, 1) : axis};
}

Rigid3d NadirCamFromWorld(const Vec3d& position) {
  return LookAt(position, position - Vec3d(0, 0, 1), Vec3d(0, 1, 0));
}

}  // namespace aos
