#include "aos/calib/calibrate.h"

#include <algorithm>
#include <cmath>

#include <nlohmann/json.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/ccalib/omnidir.hpp>
#include <opencv2/imgproc.hpp>

#include "aos/util/error.h"

namespace aos {
namespace {

// 8-bit grey view of a frame (luminance = mean of the channels), scaled by its type's range.
cv::Mat Grey8(const Image& image) {
  cv::Mat grey(image.height(), image.width(), CV_8U);
  const double scale = 255.0 / PixelTypeFullRange(image.type());
  for (int y = 0; y < image.height(); ++y) {
    for (int x = 0; x < image.width(); ++x) {
      double sum = 0.0;
      for (int c = 0; c < image.channels(); ++c) sum += image.Value(x, y, c);
      grey.at<uint8_t>(y, x) = cv::saturate_cast<uint8_t>(scale * sum / image.channels());
    }
  }
  return grey;
}

}  // namespace

void CalibrateOptions::Check() const {
  // "pattern: " first: the CLI's --pattern sets both fields.
  if (pattern_columns < 2) {
    ThrowInvalid("pattern: pattern_columns must be at least 2 inner corners (got " +
                 std::to_string(pattern_columns) + ")");
  }
  if (pattern_rows < 2) {
    ThrowInvalid("pattern: pattern_rows must be at least 2 inner corners (got " +
                 std::to_string(pattern_rows) + ")");
  }
  if (!(square_size_m > 0.0) || !std::isfinite(square_size_m)) {
    ThrowInvalid("square_size_m: must be a finite number > 0 metres");
  }
}

CalibrationResult Calibrate(const std::vector<Image>& frames, const std::vector<std::string>& names,
                            const CalibrateOptions& options, ProgressSink* progress) {
  options.Check();
  if (frames.empty()) ThrowInvalid("frames: none given");
  if (names.size() != frames.size()) ThrowInvalid("frames: names and frames differ in number");
  const cv::Size pattern(options.pattern_columns, options.pattern_rows);
  const cv::Size size(frames.front().width(), frames.front().height());
  std::vector<cv::Point3d> board;
  for (int r = 0; r < options.pattern_rows; ++r) {
    for (int c = 0; c < options.pattern_columns; ++c) {
      board.emplace_back(c * options.square_size_m, r * options.square_size_m, 0.0);
    }
  }
  CalibrationResult result;
  std::vector<std::vector<cv::Point3d>> object_points;
  std::vector<std::vector<cv::Point2d>> image_points;
  ProgressStart(progress, "find corners", static_cast<int64_t>(frames.size()));
  for (size_t i = 0; i < frames.size(); ++i) {
    if (ProgressCancelled(progress)) throw Cancelled();
    if (frames[i].width() != size.width || frames[i].height() != size.height) {
      ThrowInvalid(names[i] + ": is " + std::to_string(frames[i].width()) + "x" +
                   std::to_string(frames[i].height()) + ", the first frame " +
                   std::to_string(size.width) + "x" + std::to_string(size.height));
    }
    const cv::Mat grey = Grey8(frames[i]);
    std::vector<cv::Point2f> corners;
    const bool found = cv::findChessboardCorners(
        grey, pattern, corners, cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE);
    if (!found) {
      result.frames_rejected.push_back(names[i]);
    } else {
      cv::cornerSubPix(grey, corners, cv::Size(5, 5), cv::Size(-1, -1),
                       cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 100, 1e-4));
      std::vector<cv::Point2d> points(corners.begin(), corners.end());
      image_points.push_back(points);
      object_points.push_back(board);
      result.frames_used.push_back(names[i]);
    }
    ProgressAdvance(progress, 1);
  }
  if (image_points.size() < 3) {
    std::string list;
    for (const std::string& name : result.frames_rejected) list += (list.empty() ? "" : ", ") + name;
    ThrowInvalid("frames: the board (" + std::to_string(pattern.width) + "x" +
                 std::to_string(pattern.height) + " inner corners) was found in " +
                 std::to_string(image_points.size()) + " frames; at least 3 are needed (not found "
                 "in: " + list + ")");
  }
  LensCamera& camera = result.camera;
  camera.model = options.model;
  camera.width = size.width;
  camera.height = size.height;
  cv::Matx33d K = cv::Matx33d::eye();
  std::vector<cv::Mat> rvecs, tvecs;
  switch (options.model) {
    case LensModel::kPinhole:
    case LensModel::kRadTan: {
      cv::Mat D;
      int flags = 0;
      if (TraitsOf(options.model).pinhole) {
        flags = cv::CALIB_FIX_K1 | cv::CALIB_FIX_K2 | cv::CALIB_FIX_K3 | cv::CALIB_ZERO_TANGENT_DIST;
      }
      std::vector<std::vector<cv::Point3f>> object_f;
      std::vector<std::vector<cv::Point2f>> image_f;
      for (const auto& v : object_points) object_f.emplace_back(v.begin(), v.end());
      for (const auto& v : image_points) image_f.emplace_back(v.begin(), v.end());
      result.rms_px = cv::calibrateCamera(object_f, image_f, size, K, D, rvecs, tvecs, flags);
      // A pinhole reads none of D (its coefficients were held at zero anyway).
      const int count = std::min(TraitsOf(options.model).distortion_count, static_cast<int>(D.total()));
      for (int k = 0; k < count; ++k) camera.distortion[static_cast<size_t>(k)] = D.at<double>(k);
      break;
    }
    case LensModel::kFisheye: {
      cv::Vec4d D;
      result.rms_px = cv::fisheye::calibrate(
          object_points, image_points, size, K, D, rvecs, tvecs,
          cv::fisheye::CALIB_RECOMPUTE_EXTRINSIC | cv::fisheye::CALIB_FIX_SKEW,
          cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 200, 1e-10));
      for (int k = 0; k < 4; ++k) camera.distortion[static_cast<size_t>(k)] = D[k];
      break;
    }
    case LensModel::kOmnidir: {
      std::vector<cv::Mat> object_mats, image_mats;
      for (const auto& v : object_points) object_mats.push_back(cv::Mat(v, true).reshape(3, 1));
      for (const auto& v : image_points) image_mats.push_back(cv::Mat(v, true).reshape(2, 1));
      cv::Mat K_mat, D_mat, xi_mat, used;
      // omnidir's Gauss-Newton takes damped steps (the fraction 1 - 0.99^(k+1) of step k), so it
      // creeps along the shallow valley where xi and the focal length trade off: 300 steps left
      // fx 2 % short of the optimum on a 172-degree lens (calibrate_test); it converged within 600.
      // The relative-change criterion (1e-10) ends it once converged.
      result.rms_px = cv::omnidir::calibrate(
          object_mats, image_mats, size, K_mat, xi_mat, D_mat, rvecs, tvecs, 0,
          cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 2000, 1e-10), used);
      K = cv::Matx33d(K_mat);
      camera.xi = xi_mat.at<double>(0);
      for (int k = 0; k < 4; ++k) camera.distortion[static_cast<size_t>(k)] = D_mat.at<double>(k);
      camera.skew = K(0, 1);
      // omnidir uses only some frames (`used` holds their indices); report those.
      if (!used.empty()) {
        std::vector<std::string> kept;
        for (int k = 0; k < static_cast<int>(used.total()); ++k) {
          kept.push_back(result.frames_used[static_cast<size_t>(used.at<int>(k))]);
        }
        result.frames_used = kept;
      }
      break;
    }
  }
  camera.fx = K(0, 0);
  camera.fy = K(1, 1);
  camera.cx = K(0, 2) + 0.5;
  camera.cy = K(1, 2) + 0.5;
  camera.Finalize("calibrated camera");
  return result;
}

std::string CalibrationRecordJson(const CalibrationResult& result,
                                  const CalibrateOptions* options) {
  nlohmann::ordered_json record;
  record["rms_px"] = result.rms_px;
  record["frames_used"] = result.frames_used;
  record["frames_rejected"] = result.frames_rejected;
  if (options != nullptr) {
    record["pattern"] = std::to_string(options->pattern_columns) + "x" +
                        std::to_string(options->pattern_rows);
    record["square_size_m"] = options->square_size_m;
  }
  return record.dump();
}

}  // namespace aos
