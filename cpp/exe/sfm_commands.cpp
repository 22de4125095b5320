// Pose commands: poses (COLMAP from frames), import-colmap (an existing COLMAP model), ground
// (where the ground is, from the reconstructed points or a given terrain).
#include <algorithm>
#include <cmath>
#include <memory>

#include "aos/geometry/heightfield.h"
#include "aos/geometry/mesh.h"
#include "aos/render/focal_surface.h"
#include "aos/sfm/ground.h"

#include "aos/lightfield/formats.h"
#include "aos/metrics/resolution.h"
#include "aos/sfm/colmap_pipeline.h"
#include "aos/util/file_util.h"
#include "aos/util/math.h"
#include "commands.h"
#include "progress_bar.h"

namespace aos::cli {
namespace {

struct PosesCommand {
  std::string frames_dir;  // poses: the frames; import-colmap: the frames folder COLMAP was given
  std::string model_dir;   // import-colmap: the COLMAP model folder
  std::string output;
  std::string points_output;  // PLY of the reconstructed points (world coordinates), optional
  PosesOptions options;
};

// --points-output: the model's points in world coordinates (origin + local), for `ground`.
void AddPointsOutputFlag(CLI::App* command, PosesCommand& c) {
  command->add_option("--points-output", c.points_output,
                      "Also write the reconstructed 3-D points as a PLY file (world coordinates: "
                      "light-field origin + local), for `aos-render ground`");
  Flags(command).Output("--points-output");
}

void WritePoints(const PosesCommand& c, const PosesResult& result, Report& report) {
  if (c.points_output.empty()) return;
  std::vector<Vec3d> world;
  world.reserve(result.point_positions.size());
  for (const Vec3d& p : result.point_positions) world.push_back(result.light_field.origin + p);
  WritePly(c.points_output, world, {}, Common().force);
  report.Set("points_output", c.points_output);
  report.Line("wrote %s: %zu points", c.points_output.c_str(), world.size());
}

// The geo-referencing flags, shared by poses and import-colmap.
void AddPositionFlags(Flags& flags, PosesOptions& options) {
  flags.Field(options, "positions_file");
  flags.Field(options, "positions_crs");
  flags.Field(options, "exif_positions");
  flags.Field(options, "min_registered_fraction");
  flags.Input("--positions-file");
}

// The scene-scale check against the flight height, shared by poses and import-colmap.
void AddScaleFlags(Flags& flags, PosesOptions& options) {
  flags.Field(options, "flight_height_m");
  flags.Field(options, "max_scale_deviation");
}

// Warnings, then the light field and what the user needs to judge the poses.
void ReportPoses(const PosesResult& result, const std::string& output, Report& report) {
  for (const std::string& warning : result.warnings) Warn(warning);
  report.Set("output", output);
  report.Set("frames", result.frames.size());
  report.Set("registered", result.registered.size());
  report.Set("unregistered", result.unregistered);
  report.Set("points", result.points);
  report.Set("mean_reprojection_error_px", result.mean_reprojection_error_px);
  report.Set("georeferenced", result.georeferenced);
  report.Set("median_depth", result.median_depth);
  report.Set("pose_error", result.pose_error);
  report.Set("focal_prior_px", result.focal_prior_px);
  report.Set("focal_deviation", result.focal_deviation);
  report.Set("scale_deviation", result.scale_deviation);
  report.Set("implausible", result.implausible);
  report.Set("warnings", result.warnings);
  report.Set("order", result.order);
  report.Set("time_source", result.time_source);
  report.Line("wrote %s: %zu of %zu frames registered, %zu points, mean reprojection error "
              "%.3f px",
              output.c_str(), result.registered.size(), result.frames.size(), result.points,
              result.mean_reprojection_error_px);
  report.Line("order: %s", result.order == "time"
                               ? ("capture time (" + result.time_source + ")").c_str()
                               : "frame names, natural order (2 before 10)");
  const char* unit = result.georeferenced ? " m" : " (model units: not geo-referenced)";
  if (result.georeferenced) {
    report.Set("world_frame", result.world_frame);
    report.Set("crs", result.light_field.crs);
    report.Set("georeference_rms_m", result.georeference_rms_m);
    report.Set("origin", std::vector<double>{result.light_field.origin.x,
                                             result.light_field.origin.y,
                                             result.light_field.origin.z});
    report.Line("geo-referenced by %d positions (%s): RMS %.3f m; origin %.3f %.3f %.3f",
                result.georeference_frames, result.world_frame.c_str(),
                result.georeference_rms_m, result.light_field.origin.x,
                result.light_field.origin.y, result.light_field.origin.z);
  }
  report.Line("pose error e = %.4g%s at the median depth %.4g%s", result.pose_error, unit,
              result.median_depth, unit);
  if (result.georeferenced && !result.light_field.views.empty() && result.median_depth > 0.0) {
    ResolutionOptions resolution;
    resolution.distance_m = result.median_depth;
    resolution.pose_error_m = result.pose_error;
    const ResolutionResult r = SamplingResolution(result.light_field.views[0].camera, resolution);
    report.Set("effective_sample_size_m", r.effective_sample_size_m);
    report.Line("sampling at that depth: p = %.2f cm, p' = p + 2e = %.2f cm (%.1f samples/m^2)",
                100.0 * r.sample_size_m, 100.0 * r.effective_sample_size_m,
                r.effective_samples_per_m2);
  }
  Report& stages = report.Nested("stage_seconds");
  for (const auto& stage : result.stages) {
    stages.Set(stage.name, stage.seconds);
    report.Line("  %-9s %7.1f s", stage.name.c_str(), stage.seconds);
  }
  if (!result.workspace.empty()) {
    report.Set("workspace", result.workspace);
    report.Line("COLMAP workspace kept in %s", result.workspace.c_str());
  }
}

int RunPoses(PosesCommand& c, const Flags& flags) {
  ProgressBar progress(Common().quiet);
  // The frames folder (every file in it), the camera and the positions are inputs.
  CheckOutputPath(c.output, {c.frames_dir, c.options.camera_file, c.options.positions_file},
                  "output");
  RefuseExisting(c.output, "output");
  if (!c.points_output.empty()) {
    CheckOutputPath(c.points_output, {c.frames_dir, c.options.camera_file, c.options.positions_file, c.output},
                    "--points-output");
    RefuseExisting(c.points_output, "--points-output");
  }
  const PosesResult result =
      flags.NamingFlags([&] { return EstimatePoses(c.frames_dir, c.options, &progress); });
  progress.Finish();
  WriteLightField(c.output, result.light_field);
  Report report("poses");
  // What the preset made of the COLMAP settings (the same call EstimatePoses makes).
  const PosesOptions used = WithPreset(c.options);
  report.Set("preset", used.preset);
  const std::string pairs =
      used.matcher == "spatial"      ? std::to_string(used.spatial_neighbors) + " neighbours"
      : used.matcher == "sequential" ? "overlap " + std::to_string(used.sequential_overlap)
                                     : "all pairs";
  report.Line("preset %s: %s matching (%s), features on frames of <= %d px (first octave %d), "
              "<= %d a frame",
              used.preset.c_str(), used.matcher.c_str(), pairs.c_str(), used.max_image_size,
              used.sift_first_octave, used.max_num_features);
  ReportPoses(result, c.output, report);
  WritePoints(c, result, report);
  report.Print();
  return 0;
}

int RunImportColmap(PosesCommand& c, const Flags& flags) {
  ProgressBar progress(Common().quiet);
  // The model folder (cameras, images, points3D), the frames folder and the positions are inputs.
  const std::vector<std::string> inputs{c.model_dir, c.frames_dir, c.options.positions_file};
  CheckOutputPath(c.output, inputs, "output");
  RefuseExisting(c.output, "output");
  if (!c.points_output.empty()) {
    CheckOutputPath(c.points_output, inputs, "--points-output");
    RefuseExisting(c.points_output, "--points-output");
  }
  const PosesResult result =
      flags.NamingFlags([&] {
        return ImportColmapPoses(c.model_dir, c.frames_dir, c.options, &progress);
      });
  progress.Finish();
  CheckOutputPath(c.output, inputs, "output");  // again: the model may have changed meanwhile
  WriteLightField(c.output, result.light_field);
  Report report("import-colmap");
  ReportPoses(result, c.output, report);
  WritePoints(c, result, report);
  report.Print();
  return 0;
}

}  // namespace

CommandRunner DefinePoses(CLI::App* command) {
  auto c = std::make_shared<PosesCommand>();
  Flags flags(command);
  PosesOptions& options = c->options;
  command->add_option("frames", c->frames_dir, "Folder of frames (never modified)")->required();
  command->add_option("-o,--output", c->output, "Light-field file to write (JSON)")->required();
  flags.Field(options, "workspace");
  flags.Field(options, "matcher");
  flags.Field(options, "sequential_overlap");
  flags.Field(options, "spatial_neighbors");
  flags.Field(options, "preset");
  flags.Field(options, "camera_file");
  flags.Field(options, "camera_model");
  flags.Field(options, "fov_deg");
  flags.Field(options, "max_focal_deviation");
  AddScaleFlags(flags, options);
  flags.Field(options, "allow_implausible");
  AddPositionFlags(flags, options);
  flags.Field(options, "max_image_size");
  flags.Field(options, "max_num_features");
  flags.Field(options, "sift_first_octave");
  flags.Field(options, "colmap");
  flags.Threads(options);
  flags.Force();
  flags.InputFolder("frames");
  flags.Input("--camera-file");
  flags.Output("--output");
  flags.OutputFolder("--workspace");
  AddPointsOutputFlag(command, *c);
  // Every other field of the tables (tools/vocabulary.py NOT_ON_THE_CLI: why not those).
  flags.Remaining(c->options);
  return [c, flags] { return RunPoses(*c, flags); };
}

CommandRunner DefineImportColmap(CLI::App* command) {
  auto c = std::make_shared<PosesCommand>();
  Flags flags(command);
  command->add_option("model", c->model_dir, "COLMAP model folder (e.g. sparse/0)")->required();
  command->add_option("--images-dir,--images", c->frames_dir,
                      "The frames folder COLMAP was given (--images is its old name)")
      ->required();
  command->add_option("-o,--output", c->output, "Light-field file to write (JSON)")->required();
  AddPositionFlags(flags, c->options);
  AddScaleFlags(flags, c->options);
  flags.Field(c->options, "allow_implausible");
  flags.Threads();
  flags.Force();
  flags.InputFolder("model");
  flags.InputFolder("--images-dir");
  flags.Output("--output");
  AddPointsOutputFlag(command, *c);
  // Every other field of the tables (tools/vocabulary.py NOT_ON_THE_CLI: why not those).
  flags.Remaining(c->options, {"colmap", "workspace", "matcher", "sequential_overlap",
                                 "spatial_neighbors", "preset", "camera_file", "camera_model",
                                 "fov_deg", "max_image_size", "max_num_features",
                                 "sift_first_octave", "max_focal_deviation", "num_threads"});
  return [c, flags] { return RunImportColmap(*c, flags); };
}

// ---- ground ----

namespace {

struct GroundCommand {
  std::string light_field_path;
  std::string points_path;  // reconstructed points (PLY/OBJ, world coordinates)
  std::string terrain_path; // or a given terrain (mesh or DEM): the flight's height above it
  std::string output;       // DEM GeoTIFF of the estimate
  GroundOptions options;
};

// Median, min and max of the views' heights above the ground (NaN heights skipped).
void ReportHeights(const std::vector<double>& heights, Report& report) {
  std::vector<double> valid;
  for (double h : heights) {
    if (std::isfinite(h)) valid.push_back(h);
  }
  report.Set("views_over_ground", valid.size());
  if (valid.empty()) {
    Warn("no view lies over the ground estimate: the flight's height above it is unknown");
    return;
  }
  std::sort(valid.begin(), valid.end());
  const double median = valid[valid.size() / 2];
  Report& above = report.Nested("height_above_ground_m");
  above.Set("min", valid.front());
  above.Set("median", median);
  above.Set("max", valid.back());
  report.Line("the views fly %.2f m above the ground (median; %.2f .. %.2f m, %zu of %zu views)",
              median, valid.front(), valid.back(), valid.size(), heights.size());
}

int RunGround(GroundCommand& c, const Flags& flags) {
  if (c.points_path.empty() == c.terrain_path.empty()) {
    ThrowUsage("give either --points (the reconstructed points: estimate the ground) or "
               "--terrain (a known terrain: the flight's height above it)");
  }
  if (!c.terrain_path.empty() && !c.output.empty()) {
    ThrowUsage("-o: the ground is estimated from --points only (--terrain is already a ground)");
  }
  if (!c.points_path.empty() && c.output.empty()) {
    ThrowUsage("-o: give the DEM GeoTIFF to write the ground estimate to");
  }
  if (!c.output.empty()) {
    CheckOutputPath(c.output, {c.light_field_path, c.points_path}, "output");
    RefuseExisting(c.output, "output");
    CheckHeightfieldOutputName(c.output);  // before the points are read
  }
  LoadOptions load;
  load.load_images = false;
  const LightField light_field = LoadLightField(c.light_field_path, load).light_field;
  Report report("ground");
  std::vector<Vec2d> centres;
  std::vector<double> centre_z;
  for (const View& view : light_field.views) {
    const Vec3d centre = light_field.origin + view.cam_from_world.Center();
    centres.emplace_back(centre.x, centre.y);
    centre_z.push_back(centre.z);
  }
  FocalSurface ground_surface = FocalSurface::FromPlane(Plane::AtHeight(0.0));
  if (!c.points_path.empty()) {
    std::vector<Vec3d> points = ReadPoints(c.points_path);
    for (Vec3d& p : points) p -= light_field.origin;
    const int up_sign = GroundUpSign(points, light_field);
    ProgressBar progress(Common().quiet);
    const GroundResult ground =
        flags.NamingFlags([&] { return EstimateGround(points, up_sign, c.options, &progress); });
    progress.Finish();
    if (up_sign < 0) {
      Warn(c.output + ": the light field's z axis points down (the cameras fly at smaller z than "
           "the ground), so the DEM holds the frame's z values, which grow downwards: not "
           "elevations. It is right as a --focal-surface for this light field; GIS tools will "
           "read its heights upside down");
    }
    Heightfield dem = GroundHeightfield(ground, light_field.origin, light_field.crs);
    WriteHeightfield(c.output, dem, Common().force);
    report.Set("output", c.output);
    report.Set("points", ground.points);
    report.Set("up", up_sign > 0 ? "+z" : "-z");
    report.Set("cells", static_cast<long long>(ground.width) * ground.height);
    report.Set("measured_cells", ground.measured_cells);
    report.Set("plane_rms_m", ground.plane_rms_m);
    const Vec3d world_point = light_field.origin + ground.plane.point;
    report.Set("plane_point", std::vector<double>{world_point.x, world_point.y, world_point.z});
    report.Set("plane_normal", std::vector<double>{ground.plane.normal.x, ground.plane.normal.y,
                                                   ground.plane.normal.z});
    const double tilt_deg = RadToDeg(std::acos(std::min(1.0, std::abs(ground.plane.normal.z))));
    report.Line("wrote %s: %d x %d cells of %.3g m, %d measured from %zu points (up is %s)",
                c.output.c_str(), ground.width, ground.height, ground.cell_size_m,
                ground.measured_cells, ground.points, up_sign > 0 ? "+z" : "-z");
    report.Line("ground plane: through %.3f %.3f %.3f (world), tilted %.2f degrees, RMS %.3f m "
                "over %d cells",
                world_point.x, world_point.y, world_point.z, tilt_deg, ground.plane_rms_m,
                ground.plane_cells);
    ground_surface = FocalSurface::FromHeightfield(std::move(dem), c.output);
  } else {
    ground_surface = InCrs(FocalSurface::Read(c.terrain_path), light_field.crs);
    report.Set("terrain", c.terrain_path);
  }
  const SurfacePlacement placement =
      ResolveSurfacePlacement(ground_surface, light_field, {}, 0.0);
  const std::vector<double> ground_z = ground_surface.HeightsAt(centres, placement);
  std::vector<double> heights(ground_z.size());
  for (size_t i = 0; i < heights.size(); ++i) {
    heights[i] = placement.up.z * (centre_z[i] - ground_z[i]);
  }
  ReportHeights(heights, report);
  report.Print();
  return 0;
}

}  // namespace

CommandRunner DefineGround(CLI::App* command) {
  auto c = std::make_shared<GroundCommand>();
  Flags flags(command);
  command->add_option("lightfield", c->light_field_path, "Light-field file (aos JSON or JKU poses)")
      ->required();
  command->add_option("--points", c->points_path,
                      "Reconstructed points (PLY/OBJ, world coordinates), e.g. from `poses "
                      "--points-output`: estimate the ground from them");
  command->add_option("--terrain", c->terrain_path,
                      "A known terrain (mesh or DEM raster): report the flight's height above it");
  command->add_option("-o,--output", c->output, "DEM GeoTIFF to write the estimate to");
  GroundOptions& options = c->options;
  flags.Field(options, "cell_size_m");
  flags.Field(options, "quantile");
  flags.Field(options, "min_points_per_cell");
  flags.Field(options, "outlier_sigmas");
  flags.Field(options, "max_step_m");
  flags.Threads();
  flags.Force();
  flags.Input("lightfield");
  flags.Input("--points");
  flags.Input("--terrain");
  flags.Output("--output");
  // Every other field of the tables (tools/vocabulary.py NOT_ON_THE_CLI: why not those).
  flags.Remaining(c->options);
  return [c, flags] { return RunGround(*c, flags); };
}

}  // namespace aos::cli
