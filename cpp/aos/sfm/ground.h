#pragma once
// Where is the ground? An estimate from a sparse point cloud (COLMAP's reconstructed points, in
// the light field's local frame): a robust plane, and a coarse elevation model by a
// lower-envelope fit, since trees, people and vehicles stand above the ground and the ground is
// the lowest surface the cameras saw.
//
// Contract
// - The local frame's z axis is vertical; `up_sign` says which way is up: +1 for z up
//   (geo-referenced light fields, the simulator), -1 for z down (JKU/F0). GroundUpSign picks it
//   from the data: the side of the points' median height on which the camera centres lie.
//   "Height" below is up_sign * z (metres above the frame's zero), converted back to z in the
//   results.
// - Cells: the points' horizontal bounding box is cut into square cells of cell_size_m
//   (columns along x, rows along y, row 0 at the smallest y); a cell with at least
//   min_points_per_cell points gets the `quantile` of its heights (0 = the lowest point; the
//   default 0.1 tolerates a few points below the ground, which matching errors produce).
// - Plane: least squares through the cell values, refitted twice through the cells at or below
//   the previous fit (the lower envelope), then repeatedly (up to 50 times, until no
//   change) refitted through all the cells except those lying more than `outlier_sigmas` robust sigmas ABOVE it:
//   cells whose lowest points are canopy (no ground seen) sit above the ground, never below, so
//   only those are dropped, and sigma (1.4826 x the median distance of the kept cells at or
//   below the plane, at least 0.05 m) is taken from the side canopy cannot reach.
//   Its normal points up; plane_rms_m is the RMS residual of the kept cells.
// - Elevation model: the cell values; a cell more than outlier_sigmas robust sigmas above the
//   plane (a candidate) whose residual from the plane exceeds by more than max_step_m the median
//   residual of the nearest ring of measured non-candidate cells is a canopy cell and is dropped
//   (a block of canopy cells is judged against the ground around it; a hill, whose flanks rise
//   with it, stays). Dropped and empty cells are filled from their measured neighbours
//   (mean of the plane residuals of the measured cells within the nearest ring that has any,
//   added to the plane), so the model covers the whole box; `measured` marks the cells that
//   kept their own value.
//
// Throws std::invalid_argument naming the field for bad options, an extent of more than 4e6
// cells, and for fewer than 3 measured cells (too few points to say where the ground is) or non-finite points.
#include <cstdint>
#include <string>
#include <vector>

#include "aos/geometry/heightfield.h"
#include "aos/geometry/rigid.h"
#include "aos/lightfield/lightfield.h"
#include "aos/util/progress.h"
#include "aos/util/option_fields.h"

namespace aos {

struct GroundOptions {
  // Side of a cell of the elevation model, metres, > 0.
  double cell_size_m = 5.0;
  // Height quantile of a cell's points taken as its ground, [0, 1).
  double quantile = 0.1;
  // Fewest points for a cell to be measured, >= 1.
  int min_points_per_cell = 3;
  // Cells this many robust sigmas above the plane are canopy candidates, > 0.
  double outlier_sigmas = 3.0;
  // A canopy candidate is dropped when it is also this far above its neighbours, metres, >= 0.
  double max_step_m = 2.0;

  void Check() const;
  // The field table (util/option_fields.h): every field once, in declaration order.
  template <class Visit>
  static void Fields(Visit&& field) {
    using O = GroundOptions;
    field(OptionField("cell_size_m", &O::cell_size_m, "m", Range::Any(),
                      "Side of a DEM cell, metres, > 0."));
    field(OptionField("quantile", &O::quantile, "", Range::Any(),
                      "Height quantile of a cell's points taken as its ground, [0, 1)."));
    field(OptionField("min_points_per_cell", &O::min_points_per_cell, "", Range::Any(),
                      "Fewest points for a cell to be measured, >= 1."));
    field(OptionField("outlier_sigmas", &O::outlier_sigmas, "", Range::Any(),
                      "Cells this many robust sigmas above the plane are canopy candidates, > "
                      "0."));
    field(OptionField("max_step_m", &O::max_step_m, "m", Range::Any(),
                      "A candidate this far above the ground around it is canopy, metres, >= "
                      "0."));
  }
};

struct GroundResult {
  int up_sign = 1;            // +1: z up; -1: z down
  Plane plane;                // robust ground plane (local frame), normal pointing up
  double plane_rms_m = 0.0;   // RMS residual of the cells the plane kept
  int plane_cells = 0;        // cells the plane kept
  // Elevation model, row-major, row 0 at y = min_y: z (local frame) of the cell centres.
  double min_x = 0.0, min_y = 0.0;  // local frame corner of cell (0, 0)
  double cell_size_m = 0.0;
  int width = 0, height = 0;
  std::vector<float> z;
  std::vector<uint8_t> measured;  // 1 where the cell kept its own value
  int measured_cells = 0;
  size_t points = 0;              // points used

  // z of the elevation model at local (x, y), bilinear between cell centres (clamped at the
  // edges).
  double ZAt(double x, double y) const;
};

// +1 if the camera centres lie above the points' median z (z up), else -1.
int GroundUpSign(const std::vector<Vec3d>& points, const LightField& light_field);

// `progress` is polled for cancellation (aos::Cancelled) while cells are binned, judged and
// filled, and gets one "ground" stage of a unit per row of cells.
GroundResult EstimateGround(const std::vector<Vec3d>& points, int up_sign,
                            const GroundOptions& options = {}, ProgressSink* progress = nullptr);

// The elevation model as a height field (a DEM GeoTIFF with WriteHeightfield): world coordinates
// (origin + local), row 0 at the largest y (north up for a geo-referenced frame), world z as
// heights (for a z-down frame these are the frame's z values, as its meshes hold them); every
// cell valid. crs_wkt is stored as given (WKT, or a user string GDAL takes, e.g. "EPSG:32633").
Heightfield GroundHeightfield(const GroundResult& ground, const Vec3d& origin,
                              const std::string& crs_wkt = "");

}  // namespace aos
