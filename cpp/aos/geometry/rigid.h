#pragma once
// Basic geometry: vectors and matrices are GLM double types; rigid transforms are named by what
// they map (cam_from_world maps a point in world coordinates to camera coordinates).
//
// Frames and units
// - Metres and radians inside; degrees only at the user's edge, and named so (fov_deg).
// - Camera axes follow OpenCV: x right, y down, z forward (the viewing direction).
// - GLM matrices are column-major: m[col][row]. Use MatFromRows()/Row() to avoid mistakes.
#include <array>
#include <iosfwd>
#include <optional>
#include <string>

#include <glm/glm.hpp>

namespace aos {

using Vec2d = glm::dvec2;
using Vec3d = glm::dvec3;
using Mat3d = glm::dmat3;

// Builds a matrix from its rows.
Mat3d MatFromRows(const Vec3d& row0, const Vec3d& row1, const Vec3d& row2);
// Row r (0..2) of m.
Vec3d Row(const Mat3d& m, int r);

// A rigid transform x_b = rotation * x_a + translation, named b_from_a where used.
struct Rigid3d {
  Mat3d rotation{1.0};
  Vec3d translation{0.0};

  Vec3d operator*(const Vec3d& point) const { return rotation * point + translation; }
  Rigid3d Inverse() const;
  // For cam_from_world: the camera centre in world coordinates, -R^T t.
  Vec3d Center() const { return -(glm::transpose(rotation) * translation); }

  // From the 3x4 matrix [R | t] given row by row (12 numbers).
  static Rigid3d FromMatrix3x4(const std::array<double, 12>& rows);
  std::array<double, 12> ToMatrix3x4() const;
};

std::ostream& operator<<(std::ostream& stream, const Rigid3d& transform);

// Describes why `transform` is not a valid rigid transform (a non-finite entry, a rotation that is
// not orthonormal within `tolerance` = max |R^T R - I|, or a reflection), or nullopt if it is one.
std::optional<std::string> DescribeInvalidRigid(const Rigid3d& transform, double tolerance = 1e-5);

// A camera at `eye` looking at `target`; `up` is the world direction that appears up in the image
// (image y points down, so camera y = -up projected onto the image plane). Throws
// std::invalid_argument if eye == target or up is parallel to the viewing direction.
Rigid3d LookAt(const Vec3d& eye, const Vec3d& target, const Vec3d& up);

// The same with the default up: +z, or +y when the camera looks (within 1 degree) straight
// along the z axis (a nadir view: image top towards +y, as NadirCamFromWorld).
Rigid3d LookAt(const Vec3d& eye, const Vec3d& target);

// A nadir-looking camera (looking down -z, image top towards +y) centred at `position`.
Rigid3d NadirCamFromWorld(const Vec3d& position);

// A plane through `point` with normal `normal` (any length > 0; the side does not matter).
struct Plane {
  Vec3d point{0.0};
  Vec3d normal{0.0, 0.0, 1.0};
  // The horizontal plane z = height.
  static Plane AtHeight(double height) { return Plane{Vec3d(0, 0, height), Vec3d(0, 0, 1)}; }
  // The plane `distance` metres in front of a camera along its optical axis ("focus 35 m below
  // the drone"): perpendicular to the axis, or horizontal (z = const through that point) when
  // `horizontal`. Throws std::invalid_argument for a distance that is not > 0 and finite.
  static Plane InFrontOf(const Rigid3d& cam_from_world, double distance, bool horizontal);
};

}  // namespace aos
