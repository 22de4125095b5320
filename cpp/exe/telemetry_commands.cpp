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
                                        c.options.camera_file};
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
  report.Set("max_convergence_deg", result.max_convergence_deg);
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
  report.Line("altitude outliers replaced by the running median: %zu; meridian convergence "
              "applied up to %.3f degrees",
              result.altitude_outliers.size(), result.max_convergence_deg);
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
  flags.Threads();
  flags.Force();
  flags.InputFolder("frames");
  flags.Input("--telemetry-file");
  flags.Input("--camera-file");
  flags.Output("--output");
  // Every other field of the tables (tools/vocabulary.py NOT_ON_THE_CLI: why not those).
  flags.Remaining(c->options);
  return [c, flags] { return RunImportTelemetry(*c, flags); };
}

}  // namespace aos::cli
