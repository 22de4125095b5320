#include "aos/geometry/similarity.h"

#include <algorithm>
#include <cmath>
#include <ostream>

#include <opencv2/core.hpp>

#include "aos/util/error.h"
#include "aos/util/math.h"

namespace aos {
namespace {

cv::Matx33d ToCv(const Mat3d& m) {
  cv::Matx33d result;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) result(r, c) = m[c][r];
  }
  return result;
}

Mat3d FromCv(const cv::Mat& m) {
  Mat3d result;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) result[c][r] = m.at<double>(r, c);
  }
  return result;
}

struct Svd3 {
  Mat3d u;
  Vec3d singular_values;  // descending
  Mat3d v;                // m = u diag(singular_values) v^T
};

Svd3 Decompose(const Mat3d& m) {
  cv::Mat w, u, vt;
  cv::SVD::compute(cv::Mat(ToCv(m)), w, u, vt, cv::SVD::FULL_UV);
  Svd3 svd;
  svd.u = FromCv(u);
  svd.v = glm::transpose(FromCv(vt));
  svd.singular_values = Vec3d(w.at<double>(0), w.at<double>(1), w.at<double>(2));
  return svd;
}

// One point set moved to its centroid, with what the degeneracy checks need.
struct CentredSet {
  Vec3d centroid{0.0};
  std::vector<Vec3d> offsets;  // point - centroid
  double rms_spread = 0.0;     // sqrt(mean |offset|^2)
};

CentredSet Centre(const std::vector<Vec3d>& points, const char* name, const std::string& where) {
  double largest_coordinate = 0.0;
  for (size_t i = 0; i < points.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      if (!std::isfinite(points[i][k])) {
        ThrowInvalid(Where(where, std::string(name) + " point " + std::to_string(i) +
                                      " is not finite"));
      }
      largest_coordinate = std::max(largest_coordinate, std::abs(points[i][k]));
    }
  }
  // Offsets from the first point are (nearly) exact for nearby points however large the
  // coordinates; their mean then moves the origin to the centroid.
  const Vec3d first = points[0];
  Vec3d mean_offset(0.0);
  for (const Vec3d& point : points) mean_offset += point - first;
  mean_offset /= static_cast<double>(points.size());
  CentredSet set;
  set.centroid = first + mean_offset;
  set.offsets.reserve(points.size());
  Mat3d scatter(0.0);
  double sum_squares = 0.0;
  for (const Vec3d& point : points) {
    const Vec3d offset = (point - first) - mean_offset;
    set.offsets.push_back(offset);
    sum_squares += glm::dot(offset, offset);
    scatter += glm::outerProduct(offset, offset);
  }
  set.rms_spread = std::sqrt(sum_squares / static_cast<double>(points.size()));
  if (!(set.rms_spread > 0.0) || set.rms_spread < kMinRelativeSpread * largest_coordinate) {
    ThrowInvalid(Where(where, std::string(name) + " points are coincident: their RMS spread " +
                                  FormatNumber(set.rms_spread) + " is below " +
                                  FormatNumber(kMinRelativeSpread) +
                                  " of their largest coordinate " +
                                  FormatNumber(largest_coordinate) +
                                  " (too small to resolve a transform)"));
  }
  const Vec3d eigenvalues = Decompose(scatter).singular_values;  // scatter is symmetric PSD
  const double width = std::sqrt(std::max(eigenvalues[1], 0.0) / eigenvalues[0]);
  if (!(width >= kMinRelativeWidth)) {
    ThrowInvalid(Where(where, std::string(name) + " points are collinear: their extent across " +
                                  "the main axis is " + FormatNumber(width) +
                                  " of the extent along it (needs >= " +
                                  FormatNumber(kMinRelativeWidth) +
                                  "); the rotation about that axis is undetermined"));
  }
  return set;
}

}  // namespace

Sim3d Sim3d::Inverse() const {
  Sim3d inverse;
  inverse.scale = 1.0 / scale;
  inverse.rotation = glm::transpose(rotation);
  inverse.translation = -(inverse.scale * (inverse.rotation * translation));
  return inverse;
}

std::ostream& operator<<(std::ostream& stream, const Sim3d& transform) {
  stream << "Sim3d(scale=" << transform.scale << ", rotation=[";
  for (int r = 0; r < 3; ++r) {
    const Vec3d row = Row(transform.rotation, r);
    stream << (r ? ", [" : "[") << row.x << ", " << row.y << ", " << row.z << "]";
  }
  const Vec3d& t = transform.translation;
  return stream << "], translation=[" << t.x << ", " << t.y << ", " << t.z << "])";
}

SimilarityResult EstimateSimilarity(const std::vector<Vec3d>& src, const std::vector<Vec3d>& dst,
                                    const std::string& where) {
  if (src.size() != dst.size()) {
    ThrowInvalid(Where(where, "got " + std::to_string(src.size()) + " source points but " +
                                  std::to_string(dst.size()) + " target points"));
  }
  if (src.size() < 3) {
    ThrowInvalid(Where(where, "a similarity transform needs at least 3 point pairs (got " +
                                  std::to_string(src.size()) + ")"));
  }
  const CentredSet a = Centre(src, "source", where);
  const CentredSet b = Centre(dst, "target", where);
  const double n = static_cast<double>(src.size());

  // Cross-covariance (1/n) sum b_i a_i^T = U D V^T; R = U S V^T with S = diag(1, 1, +-1) keeping
  // det R = +1; scale = trace(D S) / variance(a); t = centroid_b - scale R centroid_a.
  Mat3d covariance(0.0);
  for (size_t i = 0; i < src.size(); ++i) {
    covariance += glm::outerProduct(b.offsets[i], a.offsets[i]);
  }
  covariance /= n;
  const Svd3 svd = Decompose(covariance);
  const Vec3d& d = svd.singular_values;
  if (!(d[0] > 0.0) || !(d[1] >= kMinRelativeWidth * kMinRelativeWidth * d[0])) {
    ThrowInvalid(Where(where, "the point pairs do not determine a rotation (singular values of "
                              "the cross-covariance " + FormatNumber(d[0]) + ", " +
                              FormatNumber(d[1]) + ", " + FormatNumber(d[2]) + ")"));
  }
  const double sign = glm::determinant(svd.u) * glm::determinant(svd.v) < 0.0 ? -1.0 : 1.0;
  Mat3d s(1.0);
  s[2][2] = sign;
  SimilarityResult result;
  Sim3d& sim = result.dst_from_src;
  sim.rotation = svd.u * s * glm::transpose(svd.v);
  const double variance_a = a.rms_spread * a.rms_spread;
  sim.scale = (d[0] + d[1] + sign * d[2]) / variance_a;
  if (!(sim.scale > 0.0) || !std::isfinite(sim.scale)) {
    ThrowInvalid(Where(where, "the best-fitting scale is not positive (" +
                                  FormatNumber(sim.scale) + "); the point pairs do not match"));
  }
  sim.translation = b.centroid - sim.scale * (sim.rotation * a.centroid);

  // Residuals in centred coordinates: the same numbers without the large offsets.
  double sum_squares = 0.0;
  for (size_t i = 0; i < src.size(); ++i) {
    const Vec3d residual = sim.scale * (sim.rotation * a.offsets[i]) - b.offsets[i];
    const double squared = glm::dot(residual, residual);
    sum_squares += squared;
    result.max_residual = std::max(result.max_residual, std::sqrt(squared));
  }
  result.rms_residual = std::sqrt(sum_squares / n);
  return result;
}

Rigid3d TransformCamFromWorld(const Sim3d& new_world_from_world, const Rigid3d& cam_from_world) {
  const Sim3d& sim = new_world_from_world;
  if (!(sim.scale > 0.0) || !std::isfinite(sim.scale)) {
    ThrowInvalid("similarity transform: scale must be positive and finite (got " +
                 FormatNumber(sim.scale) + ")");
  }
  // x_cam = R_c x + t_c and x = R^T (x' - t) / s; the camera frame is scaled by s with the world:
  // s x_cam = R_c R^T x' + (s t_c - R_c R^T t).
  Rigid3d result;
  result.rotation = cam_from_world.rotation * glm::transpose(sim.rotation);
  result.translation = sim.scale * cam_from_world.translation - result.rotation * sim.translation;
  return result;
}

PointSetShape ShapeOf(const std::vector<Vec3d>& points) {
  PointSetShape shape;
  if (points.empty()) return shape;
  const Vec3d first = points[0];
  Vec3d mean_offset(0.0);
  for (const Vec3d& point : points) mean_offset += point - first;
  mean_offset /= static_cast<double>(points.size());
  shape.centroid = first + mean_offset;
  Mat3d scatter(0.0);
  for (const Vec3d& point : points) {
    const Vec3d offset = (point - first) - mean_offset;
    scatter += glm::outerProduct(offset, offset);
  }
  const Svd3 svd = Decompose(scatter);  // symmetric PSD: u = v = the principal axes
  shape.axes = svd.u;
  for (int k = 0; k < 3; ++k) {
    shape.rms_extent[k] = std::sqrt(std::max(svd.singular_values[k], 0.0) / points.size());
  }
  shape.width = shape.rms_extent[0] > 0.0 ? shape.rms_extent[1] / shape.rms_extent[0] : 0.0;
  return shape;
}

namespace {

// The rotation by `angle` radians about the unit `axis` (Rodrigues).
Mat3d AxisAngle(const Vec3d& axis, double angle) {
  const double c = std::cos(angle), s = std::sin(angle);
  const Mat3d k = MatFromRows(Vec3d(0.0, -axis.z, axis.y), Vec3d(axis.z, 0.0, -axis.x),
                              Vec3d(-axis.y, axis.x, 0.0));
  return Mat3d(1.0) + s * k + (1.0 - c) * (k * k);
}

// The smallest rotation taking unit `from` to unit `to`.
Mat3d RotationBetween(const Vec3d& from, const Vec3d& to) {
  const Vec3d cross = glm::cross(from, to);
  const double sine = glm::length(cross), cosine = glm::dot(from, to);
  if (sine < 1e-12) {
    if (cosine > 0.0) return Mat3d(1.0);
    // Opposite: half a turn about any axis perpendicular to `from`.
    Vec3d other = std::abs(from.x) < 0.9 ? Vec3d(1, 0, 0) : Vec3d(0, 1, 0);
    return AxisAngle(glm::normalize(glm::cross(from, other)), kPi);
  }
  return AxisAngle(cross / sine, std::atan2(sine, cosine));
}

}  // namespace

SimilarityResult EstimateSimilarityOnLine(const std::vector<Vec3d>& src,
                                          const std::vector<Vec3d>& dst, const Vec3d& src_down,
                                          const Vec3d& dst_down, const std::string& where) {
  if (src.size() != dst.size() || src.size() < 2) {
    ThrowInvalid(Where(where, "a line needs at least 2 pairs of points"));
  }
  const PointSetShape a = ShapeOf(src), b = ShapeOf(dst);
  const Vec3d src_axis = a.axes[0];
  Vec3d dst_axis = b.axes[0];
  double along_product = 0.0, along_src_squares = 0.0;
  for (size_t i = 0; i < src.size(); ++i) {
    along_product += glm::dot(src[i] - a.centroid, src_axis) * glm::dot(dst[i] - b.centroid, dst_axis);
    along_src_squares += std::pow(glm::dot(src[i] - a.centroid, src_axis), 2);
  }
  if (along_product < 0.0) {  // the two lines run opposite ways
    dst_axis = -dst_axis;
    along_product = -along_product;
  }
  if (!(along_src_squares > 0.0) || !(along_product > 0.0)) {
    ThrowInvalid(Where(where, "the points do not spread along a line"));
  }
  const double scale = along_product / along_src_squares;
  const Mat3d align = RotationBetween(src_axis, dst_axis);
  // The rotation about the line: the down directions' parts across it made parallel.
  const auto across = [&](const Vec3d& direction) {
    const Vec3d unit = glm::normalize(direction);
    return unit - glm::dot(unit, dst_axis) * dst_axis;
  };
  const Vec3d mapped_down = across(align * src_down);
  const Vec3d target_down = across(dst_down);
  const double min_across = std::sin(DegToRad(10.0));
  if (!(glm::length(mapped_down) >= min_across) || !(glm::length(target_down) >= min_across)) {
    ThrowInvalid(Where(where, "the points lie on a line and the cameras look along it, so "
                              "nothing fixes the rotation about the line; give positions off "
                              "the line (fly a second line)"));
  }
  const double angle = std::atan2(glm::dot(dst_axis, glm::cross(mapped_down, target_down)),
                                  glm::dot(mapped_down, target_down));
  SimilarityResult result;
  result.dst_from_src.scale = scale;
  result.dst_from_src.rotation = AxisAngle(dst_axis, angle) * align;
  result.dst_from_src.translation = b.centroid - scale * (result.dst_from_src.rotation * a.centroid);
  double sum = 0.0;
  for (size_t i = 0; i < src.size(); ++i) {
    const double residual = glm::length(dst[i] - result.dst_from_src * src[i]);
    sum += residual * residual;
    result.max_residual = std::max(result.max_residual, residual);
  }
  result.rms_residual = std::sqrt(sum / src.size());
  return result;
}

}  // namespace aos
