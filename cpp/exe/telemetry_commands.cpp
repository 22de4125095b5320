// import-telemetry: poses from GPS and gimbal telemetry (a CSV log, OpenDroneMap's geo.txt or the
// frames' EXIF/XMP tags), no structure from motion (sfm/telemetry.h); export-odm: a light field's
// poses as OpenDroneMap's geo.txt (sfm/odm.h).
#include <filesystem>
#include <memory>

#include "aos/lightfield/formats.h"
#include "aos/sfm/odm.h"
#include "aos/sfm/telemetry.h"
#include "aos/sfm/video.h"
#include "aos/util/file_util.h"
#include "commands.h"
#include "progress_bar.h"

namespace aos::cli {
namespace {

namespace fs = std::filesystem;

struct TelemetryCommand {
  std::string frames_dir;
  std::string output;
  TelemetryOptions options;
};

// The warnings and report of a telemetry import: every assumption the poses rest on, one line
// each (import-telemetry, import-video).
void ReportTelemetry(const TelemetryResult& result, const std::string& output, Report& report) {
  for (const std::string& warning : result.warnings) Warn(warning);
  for (const AltitudeOutlier& outlier : result.altitude_outliers) {
    Warn("altitude outlier: " + outlier.frame + ": " + FormatNumber(outlier.altitude_m) +
         " m replaced by the running median " + FormatNumber(outlier.median_m) + " m");
  }
  const LightField& light_field = result.light_field;
  report.Set("output", output);
  report.Set("source", result.source);
  report.Set("views", light_field.views.size());
  report.Set("crs", light_field.crs);
  report.Set("origin",
             std::vector<double>{light_field.origin.x, light_field.origin.y, light_field.origin.z});
  report.Set("order", result.order);
  report.Set("time_source", result.time_source);
  report.Set("yaw_reference", result.yaw_reference);
  report.Set("declination_deg", result.declination_deg);
  report.Set("max_convergence_deg", result.max_convergence_deg);
  report.Set("altitude_source", result.altitude_source);
  report.Set("altitude_reference", result.altitude_reference);
  report.Set("takeoff_height_m", result.takeoff_height_m);
  report.Set("takeoff_height_from", result.takeoff_height_from);
  std::vector<std::string> outlier_frames;
  std::vector<double> outlier_altitudes, outlier_medians;
  for (const AltitudeOutlier& outlier : result.altitude_outliers) {
    outlier_frames.push_back(outlier.frame);
    outlier_altitudes.push_back(outlier.altitude_m);
    outlier_medians.push_back(outlier.median_m);
  }
  Report& outliers = report.Nested("altitude_outliers");
  outliers.Set("frames", outlier_frames);
  outliers.Set("altitude_m", outlier_altitudes);
  outliers.Set("median_m", outlier_medians);
  report.Set("warnings", result.warnings);
  report.Line("wrote %s: %zu views posed from %s telemetry, %s, origin %.3f %.3f %.3f",
              output.c_str(), light_field.views.size(),
              result.source == "csv"   ? "CSV"
              : result.source == "odm" ? "OpenDroneMap geo.txt"
                                       : "EXIF/XMP",
              light_field.crs.c_str(), light_field.origin.x, light_field.origin.y,
              light_field.origin.z);
  report.Line("order: %s", result.order == "time"
                               ? ("capture time (" + result.time_source + ")").c_str()
                               : "frame names, natural order (2 before 10)");
  if (result.yaw_reference == "grid") {
    report.Line("yaw: from grid north, as given (no meridian convergence)");
  } else if (result.yaw_reference == "magnetic") {
    report.Line("yaw: from magnetic north, plus the declination %s degrees; then true to grid "
                "north by the meridian convergence, up to %.3f degrees",
                FormatNumber(result.declination_deg).c_str(), result.max_convergence_deg);
  } else {
    report.Line("yaw: from true north, turned to grid north by the meridian convergence, up to "
                "%.3f degrees", result.max_convergence_deg);
  }
  if (result.altitude_reference == "takeoff") {
    report.Line("altitude: %s above the take-off point, plus its height %s m (%s)",
                result.altitude_source.c_str(), FormatNumber(result.takeoff_height_m).c_str(),
                result.takeoff_height_from.c_str());
  } else {
    report.Line("altitude: %s, taken as world heights (absolute)", result.altitude_source.c_str());
  }
  report.Line("altitude outliers replaced by the running median: %zu",
              result.altitude_outliers.size());
  report.Set("grey", light_field.grey);
  if (light_field.grey) report.Line("frames: integrated as grey (recorded in the light field)");
  report.Set("radiometric", result.radiometric);
  if (light_field.radiometry) {
    report.Set("kelvin_per_unit", light_field.radiometry->kelvin_per_unit);
    report.Set("kelvin_offset", light_field.radiometry->kelvin_offset);
    report.Set("first_frame_median_c", result.first_frame_median_c);
    report.Set("first_frame_low_c", result.first_frame_low_c);
    report.Set("first_frame_high_c", result.first_frame_high_c);
    const std::string from =
        result.radiometric == "flir"
            ? "FLIR radiometric frames converted to 16-bit frames in " +
                  fs::path(light_field.views.front().image_path).parent_path().string()
            : std::string("16-bit counts, linear calibration");
    report.Line("temperatures: %s (%s); the first frame spans %.2f .. %.2f C (1st..99th "
                "percentile), median %.2f C",
                from.c_str(), light_field.radiometry->Describe().c_str(),
                result.first_frame_low_c, result.first_frame_high_c,
                result.first_frame_median_c);
  }
}

int RunImportTelemetry(TelemetryCommand& c, const Flags& flags) {
  const std::vector<std::string> inputs{c.frames_dir, c.options.telemetry_file,
                                        c.options.camera_file, c.options.dem};
  CheckOutputPath(c.output, inputs, "output");
  RefuseExisting(c.output, "output");
  ProgressBar progress(Common().quiet);
  const TelemetryResult result = flags.NamingFlags(
      [&] { return ImportTelemetry(c.frames_dir, c.options, &progress, /*commit_frames=*/false); });
  progress.Finish();
  // The temperature frames into place (the light field's writer checks its frames exist), then
  // the light field; if that fails, the new folder goes again: an error leaves neither.
  if (result.pending_temperature_frames) result.pending_temperature_frames->Commit();
  try {
    WriteLightField(c.output, result.light_field);
  } catch (...) {
    if (result.pending_temperature_frames) {
      std::error_code ignored;
      fs::remove_all(c.options.temperature_frames_dir, ignored);
    }
    throw;
  }
  Report report("import-telemetry");
  ReportTelemetry(result, c.output, report);
  report.Print();
  return 0;
}

struct VideoCommand {
  std::string video;
  std::string output_dir;
  VideoFramesOptions options;
  TelemetryOptions telemetry;
};

int RunImportVideo(VideoCommand& c, const Flags& flags) {
  flags.NamingFlags([&] { c.options.Check(); });
  CheckOutputFolder(c.output_dir);
  ProgressBar progress(Common().quiet);
  const VideoImportResult imported = flags.NamingFlags(
      [&] { return ImportVideo(c.video, c.output_dir, c.options, c.telemetry, &progress); });
  progress.Finish();
  const VideoFramesResult& frames = imported.frames;
  const TelemetryResult& result = imported.telemetry;
  const std::string& output = imported.light_field_path;
  Report report("import-video");
  report.Set("video_frames", static_cast<long long>(frames.video_frames));
  report.Set("fps", frames.fps);
  report.Set("frames_taken", frames.frames.size());
  report.Set("srt_samples", frames.srt_samples);
  report.Set("srt_skipped_blocks", frames.srt_skipped_blocks);
  report.Set("yaw_from", frames.yaw_from);
  report.Set("pitch_from", frames.pitch_from);
  report.Set("altitude_from", frames.altitude_from);
  report.Line("%s: %zu of %lld frames taken (%s), %dx%d at %.3f fps; %d SRT blocks with a "
              "position (%d without, skipped)",
              c.video.c_str(), frames.frames.size(), static_cast<long long>(frames.video_frames),
              c.options.frame_every_m == 0.0
                  ? ("every " + FormatNumber(c.options.frame_every_s) + " s").c_str()
                  : ("every " + FormatNumber(c.options.frame_every_m) + " m of flight").c_str(),
              frames.width, frames.height, frames.fps, frames.srt_samples,
              frames.srt_skipped_blocks);
  report.Line("orientation: yaw from the %s; pitch from the %s", frames.yaw_from.c_str(),
              frames.pitch_from.c_str());
  ReportTelemetry(result, output, report);
  report.Print();
  return 0;
}

struct ExportOdmCommand {
  std::string light_field_path;
  std::string output;
};

int RunExportOdm(ExportOdmCommand& c) {
  LoadOptions load;
  load.load_images = false;
  const LightField light_field = LoadLightField(c.light_field_path, load).light_field;
  CheckOutputPath(c.output, {c.light_field_path}, "output");
  RefuseExisting(c.output, "output");
  WriteOdmGeo(c.output, light_field, /*overwrite=*/true);
  Report report("export-odm");
  report.Set("output", c.output);
  report.Set("views", light_field.views.size());
  report.Set("crs", light_field.crs);
  report.Line("wrote %s: %zu views in %s (OpenDroneMap geo.txt: image x y z yaw pitch roll, "
              "yaw from true north, pitch -90 = nadir)",
              c.output.c_str(), light_field.views.size(), light_field.crs.c_str());
  report.Print();
  return 0;
}

struct CheckGcpCommand {
  std::string light_field_path;
  std::string gcp_file;
};

int RunCheckGcp(CheckGcpCommand& c) {
  LoadOptions load;
  load.load_images = false;
  const LightField light_field = LoadLightField(c.light_field_path, load).light_field;
  const OdmGcpFile gcps = ReadOdmGcp(c.gcp_file);
  const GcpCheckResult result = CheckGcps(light_field, gcps, c.gcp_file);
  Report report("check-gcp");
  std::vector<double> lines, views;
  std::vector<std::string> images, names;
  std::vector<double> error_px, ground_m;
  for (const GcpResidual& r : result.residuals) {
    lines.push_back(r.line);
    images.push_back(r.image);
    names.push_back(r.name);
    views.push_back(r.view);
    error_px.push_back(r.error_px);
    ground_m.push_back(r.ground_error_norm_m);
    report.Line("line %d: %s in %s (view %d): predicted (%.2f, %.2f), marked (%.2f, %.2f): "
                "%.2f px, %s m on the ground",
                r.line, r.name.empty() ? "point" : r.name.c_str(), r.image.c_str(), r.view,
                r.predicted.x, r.predicted.y, r.observed.x, r.observed.y, r.error_px,
                std::isfinite(r.ground_error_norm_m) ? FormatNumber(r.ground_error_norm_m).c_str()
                                                     : "-");
  }
  Report& sightings = report.Nested("sightings");
  sightings.Set("line", lines);
  sightings.Set("image", images);
  sightings.Set("name", names);
  sightings.Set("view", views);
  sightings.Set("error_px", error_px);
  sightings.Set("ground_error_norm_m", ground_m);
  report.Set("gcp_crs", gcps.crs);
  report.Set("crs", light_field.crs);
  report.Set("rms_px", result.rms_px);
  report.Set("max_px", result.max_px);
  report.Set("rms_ground_m", result.rms_ground_m);
  report.Set("max_ground_m", result.max_ground_m);
  report.Result("%zu sightings: RMS %.2f px (max %.2f), on the ground RMS %s m (max %s); GCPs in "
                "%s, light field in %s (ODM pixel + 0.5 = aos pixel)",
                result.residuals.size(), result.rms_px, result.max_px,
                FormatNumber(result.rms_ground_m).c_str(),
                FormatNumber(result.max_ground_m).c_str(), gcps.crs.c_str(),
                light_field.crs.c_str());
  report.Print();
  return 0;
}

}  // namespace

CommandRunner DefineCheckGcp(CLI::App* command) {
  auto c = std::make_shared<CheckGcpCommand>();
  Flags flags(command);
  command->add_option("lightfield", c->light_field_path, "Light-field file (JSON; a CRS needed)")
      ->required();
  command->add_option("gcp_file", c->gcp_file,
                      "OpenDroneMap gcp_list.txt: projection, then geo_x geo_y geo_z im_x im_y "
                      "image_name [gcp_name]")
      ->required();
  flags.Input("lightfield");
  flags.Input("gcp_file");
  return [c] { return RunCheckGcp(*c); };
}

CommandRunner DefineExportOdm(CLI::App* command) {
  auto c = std::make_shared<ExportOdmCommand>();
  Flags flags(command);
  command->add_option("lightfield", c->light_field_path, "Light-field file (JSON; a CRS needed)")
      ->required();
  command->add_option("-o,--output", c->output, "geo.txt to write")->required();
  flags.Force();
  flags.Input("lightfield");
  flags.Output("--output");
  return [c] { return RunExportOdm(*c); };
}

CommandRunner DefineImportVideo(CLI::App* command) {
  auto c = std::make_shared<VideoCommand>();
  Flags flags(command);
  command->add_option("video", c->video, "Drone video (MP4, MOV, AVI: what OpenCV decodes)")
      ->required();
  command->add_option("-o,--output", c->output_dir,
                      "New folder: frames/, telemetry.csv and lightfield.json")
      ->required();
  flags.Field(c->options, "srt_file");
  command->add_option("--srt", c->options.srt_file, "Same as --srt-file");
  flags.Shorthand("srt_file", "--srt");
  flags.Field(c->options, "frame_every_s");
  flags.Field(c->options, "frame_every_m");
  flags.Field(c->options, "srt_altitude");
  flags.Field(c->options, "fixed_pitch_deg");
  flags.Field(c->options, "srt_offset_s");
  Flags telemetry = flags.At("telemetry.");
  telemetry.Remaining(c->telemetry, {"telemetry_file", "frame_interval_s", "time_offset_s",
                                     "altitude", "radiometric", "kelvin_per_count",
                                     "kelvin_offset", "temperature_frames_dir"});
  flags.Threads();
  flags.Input("video");
  flags.Input("--srt-file");
  flags.OutputFolder("--output");
  return [c, flags] { return RunImportVideo(*c, flags); };
}

CommandRunner DefineImportTelemetry(CLI::App* command) {
  auto c = std::make_shared<TelemetryCommand>();
  Flags flags(command);
  TelemetryOptions& options = c->options;
  command->add_option("frames", c->frames_dir, "Folder of frames (never modified)")->required();
  command->add_option("-o,--output", c->output, "Light-field file to write (JSON)")->required();
  flags.Field(options, "telemetry_file");
  flags.Field(options, "camera_file");
  flags.Field(options, "fov_deg");
  flags.Field(options, "altitude");
  flags.Field(options, "altitude_window");
  flags.Field(options, "max_altitude_deviation_m");
  flags.Field(options, "max_distance_from_centre_m");
  flags.Field(options, "frame_interval_s");
  flags.Field(options, "time_offset_s");
  flags.Field(options, "yaw_reference");
  flags.Field(options, "magnetic_declination_deg");
  flags.Field(options, "altitude_reference");
  flags.Field(options, "takeoff_height_m");
  flags.Field(options, "dem");
  flags.Field(options, "home_latitude_deg");
  flags.Field(options, "home_longitude_deg");
  flags.Field(options, "grey");
  flags.Field(options, "radiometric");
  flags.Field(options, "kelvin_per_count");
  flags.Field(options, "kelvin_offset");
  flags.Field(options, "temperature_frames_dir");
  flags.Threads();
  flags.Force();
  flags.InputFolder("frames");
  flags.Input("--telemetry-file");
  flags.Input("--camera-file");
  flags.Input("--dem");
  flags.Output("--output");
  flags.OutputFolder("--temperature-frames-dir");
  // Every other field of the tables (tools/vocabulary.py NOT_ON_THE_CLI: why not those).
  flags.Remaining(c->options);
  return [c, flags] { return RunImportTelemetry(*c, flags); };
}

}  // namespace aos::cli
