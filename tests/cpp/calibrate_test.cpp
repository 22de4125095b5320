// Calibration from synthetic checkerboard frames rendered through a known lens model.
#include "aos/calib/calibrate.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "aos/util/error.h"

namespace aos {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;

constexpr int kColumns = 9, kRows = 6;
constexpr double kSquare = 0.04;

Mat3d Rotation(double ax_deg, double ay_deg) {
  const double a = ax_deg * M_PI / 180.0, b = ay_deg * M_PI / 180.0;
  const Mat3d rx = MatFromRows(Vec3d(1, 0, 0), Vec3d(0, std::cos(a), -std::sin(a)),
                               Vec3d(0, std::sin(a), std::cos(a)));
  const Mat3d ry = MatFromRows(Vec3d(std::cos(b), 0, std::sin(b)), Vec3d(0, 1, 0),
                               Vec3d(-std::sin(b), 0, std::cos(b)));
  return ry * rx;
}

// The board (squares of kSquare, inner corners at (c, r) kSquare) with a white margin of one
// square, on grey, seen through `lens` with the board frame at camera_from_board; 4 x 4
// samples per pixel.
Image BoardFrame(const LensCamera& lens, const Mat3d& rotation, const Vec3d& translation) {
  Image image(lens.width, lens.height, 1, PixelType::kU8);
  const Vec3d normal = rotation * Vec3d(0, 0, 1);
  const Mat3d board_from_camera = glm::transpose(rotation);
  for (int y = 0; y < lens.height; ++y) {
    for (int x = 0; x < lens.width; ++x) {
      double sum = 0.0;
      for (int k = 0; k < 16; ++k) {
        Vec3d ray;
        double value = 128.0;
        if (lens.Unproject(Vec2d(x + (k % 4 + 0.5) / 4.0, y + (k / 4 + 0.5) / 4.0), &ray)) {
          const double denominator = glm::dot(normal, ray);
          const double t = denominator != 0.0 ? glm::dot(normal, translation) / denominator : -1.0;
          if (t > 0.0) {
            const Vec3d p = board_from_camera * (t * ray - translation);
            const double u = p.x / kSquare, v = p.y / kSquare;
            if (u >= -2.0 && u < kColumns + 1.0 && v >= -2.0 && v < kRows + 1.0) {
              value = 255.0;
              if (u >= -1.0 && u < kColumns && v >= -1.0 && v < kRows) {
                value = ((static_cast<int>(std::floor(u)) + static_cast<int>(std::floor(v))) & 1) ? 255.0 : 0.0;
              }
            }
          }
        }
        sum += value;
      }
      image.At<uint8_t>(x, y)[0] = static_cast<uint8_t>(std::lround(sum / 16.0));
    }
  }
  return image;
}

std::vector<Image> BoardFrames(const LensCamera& lens, std::vector<std::string>* names,
                               double distance) {
  std::vector<Image> frames;
  const double angles[][2] = {{0, 0}, {25, 0}, {-25, 0}, {0, 25}, {0, -25}, {20, 20}, {-20, 15}, {15, -20}};
  int index = 0;
  for (const auto& a : angles) {
    const Mat3d rotation = Rotation(a[0], a[1]);
    const Vec3d centre_in_board(0.5 * (kColumns - 1) * kSquare, 0.5 * (kRows - 1) * kSquare, 0.0);
    const Vec3d translation = Vec3d(0.02 * (index % 3 - 1), 0.015 * (index % 2), distance) -
                              rotation * centre_in_board;
    frames.push_back(BoardFrame(lens, rotation, translation));
    names->push_back("board_" + std::to_string(index++) + ".png");
  }
  return frames;
}

// The largest distance, over a 20-pixel grid of [x0, x1] x [y0, y1], between a pixel and where
// `fitted` projects the ray that `truth` unprojects from it (failed rays count as infinite).
double WorstMappingErrorPx(const LensCamera& truth, const LensCamera& fitted, int x0, int x1,
                           int y0, int y1) {
  double worst = 0.0;
  for (int y = y0; y <= y1; y += 20) {
    for (int x = x0; x <= x1; x += 20) {
      Vec3d ray;
      Vec2d back;
      if (!truth.Unproject(Vec2d(x, y), &ray) || !fitted.Project(ray, &back)) {
        return std::numeric_limits<double>::infinity();
      }
      worst = std::max(worst, glm::length(back - Vec2d(x, y)));
    }
  }
  return worst;
}

TEST(Calibrate, RecoversAFisheyeLens) {
  LensCamera truth;
  truth.model = LensModel::kFisheye;
  truth.width = 640;
  truth.height = 480;
  truth.fx = 260.0;
  truth.fy = 258.0;
  truth.cx = 321.5;
  truth.cy = 241.5;
  truth.distortion = {0.05, -0.02, 0.004, -0.0005, 0.0};
  truth.Finalize("truth");
  std::vector<std::string> names;
  const std::vector<Image> frames = BoardFrames(truth, &names, 0.3);
  CalibrateOptions options;
  options.model = LensModel::kFisheye;
  options.pattern_columns = kColumns;
  options.pattern_rows = kRows;
  options.square_size_m = kSquare;
  const CalibrationResult result = Calibrate(frames, names, options);
  EXPECT_EQ(result.frames_used.size(), 8u);
  EXPECT_LT(result.rms_px, 0.15);
  EXPECT_NEAR(result.camera.fx, truth.fx, 0.01 * truth.fx);
  EXPECT_NEAR(result.camera.cx, truth.cx, 1.0);
  // The mapping where the boards were seen (their corners reach about 40 degrees off-axis).
  EXPECT_LT(WorstMappingErrorPx(truth, result.camera, 170, 470, 140, 340), 0.5);
}

TEST(Calibrate, RecoversARadialTangentialLens) {
  LensCamera truth;
  truth.model = LensModel::kRadTan;
  truth.width = 640;
  truth.height = 480;
  truth.fx = 520.0;
  truth.fy = 515.0;
  truth.cx = 322.5;
  truth.cy = 236.5;
  truth.distortion = {-0.18, 0.06, 0.0012, -0.0008, 0.0};
  truth.Finalize("truth");
  std::vector<std::string> names;
  std::vector<Image> frames = BoardFrames(truth, &names, 0.55);
  frames.push_back(Image(640, 480, 1, PixelType::kU8));  // black: no board
  names.push_back("blank.png");
  CalibrateOptions options;
  options.pattern_columns = kColumns;
  options.pattern_rows = kRows;
  options.square_size_m = kSquare;
  const CalibrationResult result = Calibrate(frames, names, options);
  EXPECT_EQ(result.frames_used.size(), 8u);
  EXPECT_THAT(result.frames_rejected, ElementsAre("blank.png"));
  // Synthetic corners are exact up to the 4 x 4 supersampled rendering (edges quantised to
  // 1/4 pixel and 8-bit grey) and sub-pixel refinement: RMS ~0.1 px; parameters to a fraction of
  // a percent.
  EXPECT_LT(result.rms_px, 0.15);
  const LensCamera& c = result.camera;
  EXPECT_NEAR(c.fx, truth.fx, 0.005 * truth.fx);
  EXPECT_NEAR(c.fy, truth.fy, 0.005 * truth.fy);
  EXPECT_NEAR(c.cx, truth.cx, 1.0);
  EXPECT_NEAR(c.cy, truth.cy, 1.0);
  EXPECT_NEAR(c.distortion[0], truth.distortion[0], 0.02);
  EXPECT_NEAR(c.distortion[1], truth.distortion[1], 0.05);
  // Whatever the individual coefficients, the recovered model must map like the true one where
  // the boards constrained it (their corners span about 400 x 300 pixels around the centre;
  // outside, the polynomial is extrapolated).
  EXPECT_LT(WorstMappingErrorPx(truth, c, 130, 510, 100, 380), 0.5);
}

TEST(Calibrate, RecoversAnOmnidirectionalLens) {
  // Mei's unified model with xi = 1 (cv::omnidir's initial guess) and modest distortion: the
  // frame spans about 172 degrees across (86 degrees either side), 137 down, 200 corner to corner.
  LensCamera truth;
  truth.model = LensModel::kOmnidir;
  truth.width = 640;
  truth.height = 480;
  truth.fx = 360.0;
  truth.fy = 358.0;
  truth.cx = 322.5;
  truth.cy = 238.5;
  truth.xi = 1.0;
  truth.distortion = {-0.06, 0.01, 0.0006, -0.0004, 0.0};
  truth.Finalize("truth");
  // Boards facing the camera from a spread of directions (pitch about x, yaw about y, degrees),
  // some tilted, so that together they reach 82 degrees off-axis; each lies whole in the frame
  // with its lines only moderately bent, as omnidir's initialisation (a per-board fit with
  // xi = 1, no distortion) needs.
  struct BoardPose {
    double pitch_deg, yaw_deg, tilt_x_deg, tilt_y_deg, distance_m;
  };
  const BoardPose poses[] = {{0, 0, 0, 0, 0.3},      {0, 0, 20, -15, 0.28},  {0, 45, 0, 0, 0.3},
                             {0, -45, 0, 0, 0.3},    {35, 0, 0, 0, 0.3},     {-35, 0, 0, 0, 0.3},
                             {30, 40, 10, 0, 0.3},   {-30, -40, 0, 10, 0.3}, {-30, 40, 0, -10, 0.3},
                             {30, -40, -10, 0, 0.3}, {5, 58, 0, 0, 0.42},    {-5, -58, 0, 0, 0.42}};
  const Vec3d centre_in_board(0.5 * (kColumns - 1) * kSquare, 0.5 * (kRows - 1) * kSquare, 0.0);
  std::vector<Image> frames;
  std::vector<std::string> names;
  std::vector<Rigid3d> cam_from_boards;
  for (const BoardPose& pose : poses) {
    const Vec3d direction = Rotation(pose.pitch_deg, pose.yaw_deg) * Vec3d(0, 0, 1);
    Rigid3d cam_from_board;
    cam_from_board.rotation =
        Rotation(pose.pitch_deg + pose.tilt_x_deg, pose.yaw_deg + pose.tilt_y_deg);
    cam_from_board.translation =
        pose.distance_m * direction - cam_from_board.rotation * centre_in_board;
    frames.push_back(BoardFrame(truth, cam_from_board.rotation, cam_from_board.translation));
    names.push_back("board_" + std::to_string(names.size()) + ".png");
    cam_from_boards.push_back(cam_from_board);
  }
  CalibrateOptions options;
  options.model = LensModel::kOmnidir;
  options.pattern_columns = kColumns;
  options.pattern_rows = kRows;
  options.square_size_m = kSquare;
  const CalibrationResult result = Calibrate(frames, names, options);
  // Every board is found and kept by omnidir's initialisation.
  EXPECT_EQ(result.frames_used, names);
  EXPECT_TRUE(result.frames_rejected.empty());
  // Corners as exact as in the other models' tests (measured: 0.082 px).
  EXPECT_LT(result.rms_px, 0.15);
  const LensCamera& c = result.camera;
  // xi and fx trade off along a shallow valley of the cost (xi 0.97 with fx 354 fits these
  // boards as well as the truth does), so each alone is checked loosely; their combination
  // fx / (1 + xi), the focal length on the axis (r = tan(theta / 2) with xi = 1), is pinned down
  // (measured: 0.07 % off).
  EXPECT_NEAR(c.xi, truth.xi, 0.1);
  EXPECT_NEAR(c.fx, truth.fx, 0.03 * truth.fx);
  EXPECT_NEAR(c.fy, truth.fy, 0.03 * truth.fy);
  EXPECT_NEAR(c.fx / (1.0 + c.xi), truth.fx / (1.0 + truth.xi), 0.005 * truth.fx / 2.0);
  EXPECT_NEAR(c.fy / (1.0 + c.xi), truth.fy / (1.0 + truth.xi), 0.005 * truth.fy / 2.0);
  EXPECT_NEAR(c.cx, truth.cx, 1.0);
  EXPECT_NEAR(c.cy, truth.cy, 1.0);
  // The mapping, ray to pixel, where the boards were seen: a quarter-square grid over each
  // board's inner corners. Measured: 0.36 px at worst, 0.19 px on average, nearly all of it a
  // common shift of the principal point by (0.17, 0.05) px, as weakly fixed as in the radtan and
  // fisheye tests (0.1 - 0.25 px there).
  double worst = 0.0, sum = 0.0, widest_deg = 0.0;
  int count = 0;
  for (const Rigid3d& cam_from_board : cam_from_boards) {
    for (double v = 0.0; v <= kRows - 1; v += 0.25) {
      for (double u = 0.0; u <= kColumns - 1; u += 0.25) {
        const Vec3d point = cam_from_board * Vec3d(u * kSquare, v * kSquare, 0.0);
        Vec2d expected, got;
        ASSERT_TRUE(truth.Project(point, &expected));
        ASSERT_TRUE(c.Project(point, &got));
        worst = std::max(worst, glm::length(got - expected));
        sum += glm::length(got - expected);
        ++count;
        widest_deg = std::max(widest_deg, std::acos(glm::normalize(point).z) * 180.0 / M_PI);
      }
    }
  }
  EXPECT_GT(widest_deg, 80.0);
  EXPECT_LT(worst, 0.5);
  EXPECT_LT(sum / count, 0.25);
}

TEST(Calibrate, TooFewFramesListsThoseWithoutTheBoard) {
  std::vector<Image> frames(2, Image(64, 48, 1, PixelType::kU8));
  CalibrateOptions options;
  try {
    Calibrate(frames, {"a.png", "b.png"}, options);
    FAIL();
  } catch (const std::invalid_argument& error) {
    EXPECT_THAT(error.what(), HasSubstr("at least 3 are needed (not found in: a.png, b.png)"));
  }
  options.square_size_m = 0.0;
  EXPECT_THROW(Calibrate(frames, {"a.png", "b.png"}, options), std::invalid_argument);
}

}  // namespace
}  // namespace aos
