#pragma once
// Similarity transforms (scale, rotation, translation) and their estimation from point pairs:
// the step that geo-references a structure-from-motion model (arbitrary frame and scale) with
// GPS or surveyed positions (e.g. UTM metres).
//
// Contract
// - Sim3d maps x_b = scale * rotation * x_a + translation; name it b_from_a where used
//   (world_from_model). scale > 0, rotation proper (det +1).
// - EstimateSimilarity(src, dst) finds dst_from_src minimising sum |dst_i - (s R src_i + t)|^2 by
//   Umeyama's closed form (S. Umeyama, "Least-squares estimation of transformation parameters
//   between two point patterns", PAMI 1991), with the reflection case excluded. Both sets are
//   moved to their centroids in double first (centroid = first point + mean offset from it), so
//   UTM-sized coordinates (5e6 m) lose nothing beyond their own rounding (~1e-9 m).
// - Refused with std::invalid_argument "<where>: <reason>": fewer than 3 pairs, sizes that
//   differ, non-finite coordinates, and degenerate sets, judged per set (src, then dst) by
//     * spread: the RMS distance from the centroid must be >= kMinRelativeSpread (1e-9) times the
//       largest absolute coordinate of the set (and > 0). Below that, the rounding of the
//       coordinates themselves (1.1e-16 relative) exceeds ~1e-7 of the spread. At UTM northings
//       (5e6 m) the smallest accepted spread is 5 mm;
//     * width: sqrt(lambda2 / lambda1) >= kMinRelativeWidth (1e-4), lambda1 >= lambda2 the two
//       largest eigenvalues of the set's scatter matrix (the RMS extent across the main axis over
//       the extent along it). Collinear points leave the rotation about their line free; near
//       it, forming the covariance costs precision: the rotation about the main axis carries
//       about 2.2e-16 / width^2 rad of rounding error (2e-8 rad at the threshold).
//     Coplanar sets (e.g. cameras flown at one altitude) are fine. The cross-covariance must
//     determine a rotation as well (its second singular value >= kMinRelativeWidth^2 of its
//     first, which exact data meets when the sets pass the width test).
// - The RMS residual is sqrt(mean |dst_i - (s R src_i + t)|^2), in dst units. With independent
//   Gaussian noise of sigma per axis on dst, its expected value is about
//   sigma * sqrt((3 n - 7) / n) (7 degrees of freedom fitted).
#include <iosfwd>
#include <string>
#include <vector>

#include "aos/geometry/rigid.h"

namespace aos {

struct Sim3d {
  double scale = 1.0;
  Mat3d rotation{1.0};
  Vec3d translation{0.0};

  Vec3d operator*(const Vec3d& point) const { return scale * (rotation * point) + translation; }
  // a_from_b for this b_from_a.
  Sim3d Inverse() const;
};

std::ostream& operator<<(std::ostream& stream, const Sim3d& transform);

// Refusal thresholds of EstimateSimilarity (see above).
constexpr double kMinRelativeSpread = 1e-9;
constexpr double kMinRelativeWidth = 1e-4;

struct SimilarityResult {
  Sim3d dst_from_src;
  double rms_residual = 0.0;  // dst units (metres for UTM)
  double max_residual = 0.0;  // largest single residual, dst units
};

// Least-squares similarity dst_i ~ dst_from_src * src_i over pairs i (see above). `where` prefixes
// error messages ("geo-reference").
SimilarityResult EstimateSimilarity(const std::vector<Vec3d>& src, const std::vector<Vec3d>& dst,
                                    const std::string& where);

// The shape of a point set: centroid, principal axes (columns of `axes`, by decreasing extent)
// and the RMS extent along each; width = rms_extent[1] / rms_extent[0] (0 for points on a line).
struct PointSetShape {
  Vec3d centroid{0.0};
  Mat3d axes{1.0};
  Vec3d rms_extent{0.0};
  double width = 0.0;
};
PointSetShape ShapeOf(const std::vector<Vec3d>& points);

// dst_from_src for pairs that lie (nearly) on a line, where the points cannot fix the rotation
// about it: the lines' directions are matched (oriented by the order of the points along them),
// the scale is the least-squares ratio of the positions along them, and the rotation about the
// line is chosen so that the direction `src_down` (in src, e.g. the cameras' mean viewing
// direction) maps as near as possible to `dst_down` (e.g. straight down). Throws
// std::invalid_argument "<where>: ..." when src_down or dst_down lies within 10 degrees of the
// line (nothing then fixes the rotation about it), or for fewer than 2 pairs.
SimilarityResult EstimateSimilarityOnLine(const std::vector<Vec3d>& src,
                                          const std::vector<Vec3d>& dst, const Vec3d& src_down,
                                          const Vec3d& dst_down, const std::string& where);

// A camera pose after its world is mapped by new_world_from_world (x' = s R x + t): the returned
// cam_from_new_world has rotation R_c R^T and translation s t_c - R_c R^T t, so that the camera
// centre maps as c' = s R c + t and a world point x and its image x' land on the same pixel
// (camera coordinates are scaled by s, which leaves the projection unchanged; units become those
// of the new world). Throws std::invalid_argument if scale is not > 0 and finite.
Rigid3d TransformCamFromWorld(const Sim3d& new_world_from_world, const Rigid3d& cam_from_world);

}  // namespace aos
