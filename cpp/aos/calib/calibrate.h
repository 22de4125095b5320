#pragma once
// Lens calibration from checkerboard frames with OpenCV: cv::calibrateCamera (radtan),
// cv::fisheye::calibrate (fisheye) and cv::omnidir::calibrate (omnidir, contrib ccalib).
//
// Contract
// - The board has pattern_columns x pattern_rows inner corners, square_size_m apart, on the plane
//   z = 0 of its own frame. Corners are found with cv::findChessboardCorners and refined to
//   sub-pixel accuracy (cv::cornerSubPix); frames where the board is not found are listed in
//   frames_rejected, not fatal; at least 3 frames must be used.
// - The result is a LensCamera in aos's pixel convention (cx = OpenCV's cx + 0.5), with the RMS
//   reprojection error in pixels as OpenCV reports it and the frames used.
//
// Throws std::invalid_argument naming the option, or listing the frames when too few were found.
#include <string>
#include <vector>

#include "aos/geometry/lens.h"
#include "aos/image/image.h"
#include "aos/util/progress.h"
#include "aos/util/option_fields.h"

namespace aos {

struct CalibrateOptions {
  LensModel model = LensModel::kRadTan;
  // Inner corners of the checkerboard per row and per column (>= 2 each).
  int pattern_columns = 9;
  int pattern_rows = 6;
  // Side of one square, metres (> 0).
  double square_size_m = 0.025;

  void Check() const;
  // The field table (util/option_fields.h): every field once, in declaration order.
  template <class Visit>
  static void Fields(Visit&& field) {
    using O = CalibrateOptions;
    field(OptionField("model", &O::model, "", Range::Any(),
                      "Lens model to fit: pinhole, radtan (cv::calibrateCamera), fisheye "
                      "(cv::fisheye::calibrate) or omnidir (cv::omnidir::calibrate, Mei's "
                      "model)."));
    field(OptionField("pattern_columns", &O::pattern_columns, "", Range::Any(),
                      "Inner corners of the checkerboard per row (>= 2)."));
    field(OptionField("pattern_rows", &O::pattern_rows, "", Range::Any(),
                      "Inner corners of the checkerboard per column (>= 2)."));
    field(OptionField("square_size_m", &O::square_size_m, "m", Range::Any(),
                      "Side of one square, metres (> 0)."));
  }
};

struct CalibrationResult {
  LensCamera camera;
  double rms_px = 0.0;
  std::vector<std::string> frames_used;
  std::vector<std::string> frames_rejected;  // the board was not found
};

// `frames` and `names` in the same order (names are for the lists and the errors); every frame
// of the same size; any type and channel count (converted to 8-bit grey for detection).
CalibrationResult Calibrate(const std::vector<Image>& frames, const std::vector<std::string>& names,
                            const CalibrateOptions& options, ProgressSink* progress = nullptr);

// The record a camera file keeps of its calibration (camera_file.h's calibration_json):
// {"rms_px", "frames_used", "frames_rejected", "pattern": "COLUMNSxROWS", "square_size_m"}
// (the last two only with `options`). The CLI and Python both record calibrations this way.
std::string CalibrationRecordJson(const CalibrationResult& result,
                                  const CalibrateOptions* options = nullptr);

}  // namespace aos
