// import-telemetry: poses from GPS and gimbal telemetry (a CSV log or the frames' EXIF/XMP tags),
// no structure from motion (sfm/telemetry.h).
#include <memory>

#include "aos/lightfield/formats.h"
#include "aos/sfm/telemetry.h"
#include "aos/util/file_util.h"
#include "commands.h"
#include "progress_bar.h"

namespace aos::cli {
namespace {

struct TelemetryCommand {
  std::string frames_dir;
  std::string output;
  TelemetryOptions options;
};

int RunImportTelemetry(TelemetryCommand& c, const Flags& flags) {
  const std::vector<std::string> inputs{c.frames_dir, c.options.telemetry_file,
                                        c.options.camera_file, c.options.dem};
  CheckOutputPath(c.output, inputs, "output");
  RefuseExisting(c.output, "output");
  ProgressBar progress(Common().quiet);
  const TelemetryResult result =
      flags.NamingFlags([&] { return ImportTelemetry(c.frames_dir, c.options, &progress); });
  progress.Finish();
  WriteLightField(c.output, result.light_field);
  Report report("import-telemetry");
  for (const std::string& warning : result.warnings) Warn(warning);
  for (const AltitudeOutlier& outlier : result.altitude_outliers) {
    Warn("altitude outlier: " + outlier.frame + ": " + FormatNumber(outlier.altitude_m) +
         " m replaced by the running median " + FormatNumber(outlier.median_m) + " m");
  }
  const LightField& light_field = result.light_field;
  report.Set("output", c.output);
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
              c.output.c_str(), light_field.views.size(),
              result.source == "csv" ? "CSV" : "EXIF/XMP", light_field.crs.c_str(),
              light_field.origin.x, light_field.origin.y, light_field.origin.z);
  // Every assumption the poses rest on, one line each.
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
  report.Line("altitude outliers replaced by the running median: %zu", result.altitude_outliers.size());
  report.Print();
  return 0;
}

}  // namespace

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
  flags.Threads();
  flags.Force();
  flags.InputFolder("frames");
  flags.Input("--telemetry-file");
  flags.Input("--camera-file");
  flags.Input("--dem");
  flags.Output("--output");
  // Every other field of the tables (tools/vocabulary.py NOT_ON_THE_CLI: why not those).
  flags.Remaining(c->options);
  return [c, flags] { return RunImportTelemetry(*c, flags); };
}

}  // namespace aos::cli
