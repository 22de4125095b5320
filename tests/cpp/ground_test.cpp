// Ground estimation (sfm/ground.h) against an analytic terrain: a sloped plane with a bump,
// sampled with noise, under trees whose crowns hide the ground completely in some cells.
#include "aos/sfm/ground.h"

#include "aos/geometry/mesh.h"
#include "temp_folder.h"

#include <cmath>
#include <random>
#include <stdexcept>

#include <gtest/gtest.h>

namespace aos {
namespace {

// Ground height (z up) of the test terrain: a 6 % / 3 % slope and a 1.5 m hill of 15 m radius.
double TerrainZ(double x, double y) {
  const double r2 = (x - 60.0) * (x - 60.0) + (y - 40.0) * (y - 40.0);
  return 2.0 + 0.06 * x + 0.03 * y + 1.5 * std::exp(-r2 / (2.0 * 15.0 * 15.0));
}

// Ground points (sigma 5 cm) over [0, 100] x [0, 80], except under the crowns; crown points
// 4-18 m above the ground. Cells of the crown block at x in [20, 35], y in [20, 35] see no
// ground at all. z_sign -1 mirrors z (a z-down frame).
std::vector<Vec3d> ForestPoints(double z_sign, bool with_trees = true) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> ux(0.0, 100.0), uy(0.0, 80.0), u01(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, 0.05);
  std::vector<Vec3d> points;
  for (int i = 0; i < 12000; ++i) {
    const double x = ux(rng), y = uy(rng);
    const bool hidden = x >= 20 && x <= 35 && y >= 20 && y <= 35;
    if (with_trees && (hidden || u01(rng) < 0.4)) {
      points.emplace_back(x, y, z_sign * (TerrainZ(x, y) + 4.0 + 14.0 * u01(rng)));
    } else {
      points.emplace_back(x, y, z_sign * (TerrainZ(x, y) + noise(rng)));
    }
  }
  return points;
}

TEST(Ground, PlaneAndElevationModelFollowTheTerrainUnderTheTrees) {
  for (double z_sign : {1.0, -1.0}) {
    SCOPED_TRACE(z_sign > 0 ? "z up" : "z down");
    const std::vector<Vec3d> points = ForestPoints(z_sign);
    const GroundResult ground = EstimateGround(points, static_cast<int>(z_sign));
    EXPECT_EQ(ground.up_sign, static_cast<int>(z_sign));
    // The plane's normal points up.
    EXPECT_GT(z_sign * ground.plane.normal.z, 0.99);
    // Elevation model: every cell within 0.35 m of the terrain at its centre (the cell's
    // 0.1-quantile of 5 cm noise sits ~6 cm low; the hill curves by < 0.3 m across a 5 m cell;
    // the hidden block is filled from the ring around it, where the slope is planar to 0.1 m).
    double worst = 0.0;
    for (int j = 0; j < ground.height; ++j) {
      for (int i = 0; i < ground.width; ++i) {
        const double x = ground.min_x + (i + 0.5) * ground.cell_size_m;
        const double y = ground.min_y + (j + 0.5) * ground.cell_size_m;
        worst = std::max(worst, std::abs(z_sign * ground.z[static_cast<size_t>(j) * ground.width + i] - TerrainZ(x, y)));
      }
    }
    EXPECT_LT(worst, 0.35);
    // The hidden block (3 x 3 cells) is not measured; nearly everything else is.
    const int total = ground.width * ground.height;
    EXPECT_GE(ground.measured_cells, total - 12);
    EXPECT_LE(ground.measured_cells, total - 4);
    // ZAt interpolates the model.
    EXPECT_NEAR(z_sign * ground.ZAt(70.0, 20.0), TerrainZ(70.0, 20.0), 0.35);
  }
}

TEST(Ground, RobustPlaneIgnoresCanopyCells) {
  // Flat ground at z = 3 plus a canopy-only block: the plane stays on the ground.
  std::vector<Vec3d> points;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0.0, 50.0), u01(0.0, 1.0);
  for (int i = 0; i < 4000; ++i) {
    const double x = u(rng), y = u(rng);
    const bool canopy = x < 20 && y < 20;
    points.emplace_back(x, y, canopy ? 15.0 + 3.0 * u01(rng) : 3.0);
  }
  const GroundResult ground = EstimateGround(points, 1);
  EXPECT_NEAR(ground.plane.normal.z, 1.0, 1e-9);
  EXPECT_NEAR(ground.plane.point.z, 3.0, 1e-9);
  EXPECT_LT(ground.plane_rms_m, 1e-9);
  // The canopy block is dropped from the model and filled at the ground's height.
  EXPECT_NEAR(ground.ZAt(5.0, 5.0), 3.0, 1e-6);
}

TEST(Ground, UpSignComesFromTheCameras) {
  LightField light_field;
  View view;
  view.cam_from_world.translation = Vec3d(0.0, 0.0, -30.0);  // centre at z = 30 (identity R)
  light_field.views.push_back(view);
  EXPECT_EQ(GroundUpSign(ForestPoints(1.0), light_field), 1);
  light_field.views[0].cam_from_world.translation = Vec3d(0.0, 0.0, 30.0);  // centre z = -30
  EXPECT_EQ(GroundUpSign(ForestPoints(-1.0), light_field), -1);
}

TEST(Ground, BadInputIsRefusedNamingTheField) {
  const std::vector<Vec3d> points = ForestPoints(1.0, false);
  auto message = [&](GroundOptions options, std::vector<Vec3d> p) {
    try {
      EstimateGround(p, 1, options);
    } catch (const std::invalid_argument& error) {
      return std::string(error.what());
    }
    return std::string("no error");
  };
  GroundOptions options;
  options.cell_size_m = 0.0;
  EXPECT_NE(message(options, points).find("cell_size_m"), std::string::npos);
  options = {};
  options.quantile = 1.0;
  EXPECT_NE(message(options, points).find("quantile"), std::string::npos);
  options = {};
  options.cell_size_m = 0.01;
  EXPECT_NE(message(options, points).find("4e6 cells"), std::string::npos);
  std::vector<Vec3d> bad = points;
  bad[5].z = std::nan("");
  EXPECT_NE(message({}, bad).find("point 5 is not finite"), std::string::npos);
  EXPECT_NE(message({}, {Vec3d(0.0), Vec3d(1.0)}).find("too few"), std::string::npos);
  // Three points in one cell: one measured cell, not three.
  EXPECT_NE(message({}, {Vec3d(0.0), Vec3d(1.0), Vec3d(2.0)}).find("only 1 cells"), std::string::npos);
  EXPECT_THROW(EstimateGround(points, 0), std::invalid_argument);
}

TEST(Ground, TheElevationModelBecomesANorthUpHeightfieldInWorldCoordinates) {
  const GroundResult ground = EstimateGround(ForestPoints(1.0), 1);
  const Vec3d origin(500000.0, 5300000.0, 200.0);
  const Heightfield dem = GroundHeightfield(ground, origin, "EPSG:32633");
  ASSERT_EQ(dem.width, ground.width);
  ASSERT_EQ(dem.height, ground.height);
  EXPECT_EQ(dem.crs_wkt, "EPSG:32633");
  EXPECT_LT(dem.geotransform[5], 0.0);  // north up
  // Every raster pixel holds the model's z at its world centre, plus the origin.
  for (int row = 0; row < dem.height; ++row) {
    for (int column = 0; column < dem.width; ++column) {
      const double x = dem.CenterX(column) - origin.x, y = dem.CenterY(row) - origin.y;
      EXPECT_NEAR(dem.At(column, row), origin.z + ground.ZAt(x, y), 1e-3);
    }
  }
  EXPECT_NO_THROW(dem.Check("dem"));
}

class GroundFiles : public testing_util::TempFolderTest {};

TEST_F(GroundFiles, PointsRoundTripThroughPlyExactly) {
  const std::vector<Vec3d> points = {{500000.125, 5300000.5, 201.25}, {-1e-9, 3.0, 1e6}};
  WritePly(Path("points.ply"), points);
  EXPECT_EQ(ReadPoints(Path("points.ply")), points);
  EXPECT_THROW(WritePly(Path("points.ply"), points), std::invalid_argument);  // exists
  WritePly(Path("points.ply"), points, {}, true);
  // With triangles: a mesh ReadMesh reads back.
  const std::vector<Vec3d> corners = {{0, 0, 1}, {1, 0, 1}, {0, 1, 1}};
  WritePly(Path("mesh.ply"), corners, {{0, 1, 2}});
  const Mesh mesh = ReadMesh(Path("mesh.ply"));
  EXPECT_EQ(mesh.vertices, corners);
  ASSERT_EQ(mesh.triangles.size(), 1u);
  EXPECT_EQ(mesh.triangles[0], (std::array<int, 3>{0, 1, 2}));
  // A point cloud is not a mesh, but ReadPoints takes any mesh's vertices.
  EXPECT_THROW(ReadMesh(Path("points.ply")), std::invalid_argument);
  EXPECT_EQ(ReadPoints(Path("mesh.ply")), corners);
}

}  // namespace
}  // namespace aos
