// `aos-render plan`: flight planning (plan/flight_plan.h). The flags fill FlightPlanOptions, the
// same struct aos.plan_flight fills; every output is checked before planning and written only
// when the plan is accepted (an error or an interrupt writes nothing). The plan's size is
// bounded (max_waypoints, the battery, the memory budget) before it is generated.
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "aos/image/image_io.h"
#include "aos/plan/flight_plan.h"
#include "aos/plan/preview.h"
#include "aos/sim/scene.h"
#include "aos/util/file_util.h"
#include "commands.h"
#include "progress_bar.h"

namespace aos::cli {
namespace {

struct PlanCommand {
  FlightPlanOptions options;
  std::string csv, geojson, kml, png;
  std::string simulate, preview_png;  // --simulate SCENE, --preview-png PATH
  int png_size = 800;
};

std::array<double, 2> ParsePair(const std::string& text, const std::string& option) {
  const std::vector<double> numbers = ParseNumbers(text, option, 2);
  return {numbers[0], numbers[1]};
}

// "X,Y;X,Y;..." (or LAT,LON pairs).
std::vector<std::array<double, 2>> ParseVertices(const std::string& text) {
  std::vector<std::array<double, 2>> out;
  size_t start = 0;
  while (start <= text.size()) {
    const size_t end = std::min(text.find(';', start), text.size());
    const std::string pair = text.substr(start, end - start);
    if (!pair.empty()) out.push_back(ParsePair(pair, "--vertices"));
    start = end + 1;
  }
  return out;
}

int RunPlan(const PlanCommand& c, const Flags& flags) {
  for (const auto& [path, what] : {std::pair{c.csv, "--csv"}, std::pair{c.geojson, "--geojson"},
                                   std::pair{c.kml, "--kml"}, std::pair{c.png, "--png"}}) {
    if (!path.empty()) RefuseExisting(path, what);
  }
  if (!c.preview_png.empty()) RefuseExisting(c.preview_png, "--preview-png");
  if (c.png_size < 64) ThrowUsage("--png-size: must be >= 64 pixels");
  if (!c.preview_png.empty() && c.simulate.empty()) ThrowUsage("--preview-png needs --simulate SCENE");
  std::unique_ptr<Scene> scene;
  if (!c.simulate.empty()) scene = std::make_unique<Scene>(LoadScene(c.simulate));
  // One progress sink for every stage: SIGINT/SIGTERM stop the plan, the preview and the exports
  // (aos::Cancelled; nothing is written).
  ProgressBar progress(Common().quiet);
  const FlightPlanResult r = flags.NamingFlags([&] { return PlanFlight(c.options, &progress); });
  PlanPreviewResult preview;
  if (scene) {
    preview = PreviewFlightPlan(r, *scene, -1, &progress);
    progress.Finish();
  }
  // Everything that can refuse runs before the first file is written.
  const std::string csv = c.csv.empty() ? "" : FlightPlanCsv(r, &progress);
  const std::string geojson = c.geojson.empty() ? "" : FlightPlanGeoJson(r, &progress);
  const std::string kml = c.kml.empty() ? "" : FlightPlanKml(r, &progress);
  Image map;
  if (!c.png.empty()) map = FlightPlanMap(c.options, r, c.png_size, &progress);
  if (ProgressCancelled(&progress)) throw Cancelled();
  if (!c.csv.empty()) WriteTextFileAtomic(c.csv, csv);
  if (!c.geojson.empty()) WriteTextFileAtomic(c.geojson, geojson);
  if (!c.kml.empty()) WriteTextFileAtomic(c.kml, kml);
  if (!c.png.empty()) WriteImage(c.png, map);
  if (!c.preview_png.empty()) {
    WriteImageOptions write;
    write.units = preview.truth.type();
    write.description = "aos plan preview: integral image on the ground";
    WriteImage(c.preview_png, preview.integral, write);
  }
  for (const std::string& warning : r.warnings) Warn(warning);

  Report report("plan");
  report.Set("images", static_cast<long long>(r.images));
  report.Set("lines", static_cast<long long>(r.lines));
  report.Set("length_m", r.length_m);
  report.Set("flight_time_s", r.flight_time_s);
  report.Set("frames_per_minute", r.frames_per_minute);
  report.Set("battery_fraction", r.battery_fraction);
  report.Set("aperture_area_m2", r.aperture_area_m2);
  report.Set("aperture_radius_m", r.aperture_radius_m);
  report.Set("min_step_m", r.min_step_m);
  report.Set("max_step_m", r.max_step_m);
  report.Set("min_agl_m", r.min_agl_m);
  report.Set("max_agl_m", r.max_agl_m);
  report.Set("eq2_samples_per_m2", r.eq2_samples_per_m2);
  report.Set("eq2_sample_size_m", r.eq2_sample_size_m);
  report.Set("crs", r.crs);
  report.Set("warnings", r.warnings);
  report.Result("%lld images on %lld lines, %.1f m, %.1f min (%.1f frames/min, %.0f%% of the "
                "battery)",
                static_cast<long long>(r.images), static_cast<long long>(r.lines), r.length_m,
                r.flight_time_s / 60.0, r.frames_per_minute, 100.0 * r.battery_fraction);
  report.Result("aperture %.1f m^2 (radius %.1f m); steps %.2f .. %.2f m; %.1f .. %.1f m above "
                "ground; Eq. 2: %.1f samples/m^2 (%.2f cm)",
                r.aperture_area_m2, r.aperture_radius_m, r.min_step_m, r.max_step_m, r.min_agl_m,
                r.max_agl_m, r.eq2_samples_per_m2, 100.0 * r.eq2_sample_size_m);
  if (scene) {
    Report& p = report.Nested("preview");
    p.Set("scene", c.simulate);
    p.Set("views", static_cast<long long>(preview.views));
    p.Set("visible_fraction", preview.visible_fraction);
    p.Set("psnr_db", preview.psnr_db);
    p.Set("ssim", preview.ssim);
    p.Set("single_view_psnr_db", preview.single_view_psnr_db);
    if (preview.has_target) p.Set("contrast_to_noise", preview.contrast_to_noise);
    report.Result("preview over %s: %.1f%% of the rays reach the ground; integral on the ground "
                  "PSNR %.2f dB, SSIM %.3f (one view: %.2f dB)%s",
                  c.simulate.c_str(), 100.0 * preview.visible_fraction, preview.psnr_db,
                  preview.ssim, preview.single_view_psnr_db,
                  preview.has_target
                      ? (", target contrast-to-noise " + FormatNumber(std::round(preview.contrast_to_noise * 100) / 100)).c_str()
                      : "");
  }
  for (const auto& [path, what] : {std::pair{c.csv, "waypoints (CSV)"},
                                   std::pair{c.geojson, "waypoints (GeoJSON, WGS84)"},
                                   std::pair{c.kml, "waypoints (KML, WGS84)"},
                                   std::pair{c.png, "map"},
                                   std::pair{c.preview_png, "preview (integral image)"}}) {
    if (!path.empty()) report.Line("wrote %s: %s", path.c_str(), what);
  }
  report.Print();
  return 0;
}

}  // namespace

CommandRunner DefinePlan(CLI::App* command) {
  auto c = std::make_shared<PlanCommand>();
  FlightPlanOptions& o = c->options;
  Flags flags(command);
  flags.Field(o, "shape");
  flags.Field(o, "coordinates");
  flags.Field(o, "crs");
  flags.Field(o, "center");
  flags.Field(o, "radius_m");
  flags.Field(o, "sector_start_deg");
  flags.Field(o, "sector_angle_deg");
  flags.Field(o, "width_m");
  flags.Field(o, "length_m");
  flags.Field(o, "vertices", [&o](const std::string& text) { o.vertices = ParseVertices(text); },
              " On the command line 'X,Y;X,Y;...' (or LAT,LON pairs).");
  flags.Field(o, "pattern");
  flags.Field(o, "spacing_m");
  flags.Field(o, "along_spacing_m");
  flags.Field(o, "outer_scale");
  flags.Field(o, "heading_deg");
  flags.Field(o, "min_shots_per_line");
  flags.Field(o, "altitude_m");
  flags.Field(o, "altitude_mode");
  flags.Field(o, "dem");
  flags.Field(o, "ground_height_m");
  flags.Field(o, "terrain_up");
  flags.Field(o, "min_clearance_m");
  flags.Field(o, "ground_speed_mps");
  flags.Field(o, "hover_s");
  flags.Field(o, "battery_min");
  flags.Field(o, "max_waypoints");
  flags.Field(o, "image_width");
  flags.Field(o, "image_height");
  flags.Field(o, "fov_deg");
  command->add_option("--csv", c->csv,
                      "Write the waypoints as CSV (index,latitude,longitude,altitude_agl_m,x_m,"
                      "y_m,z_m,ground_z_m,line)");
  command->add_option("--geojson", c->geojson, "Write the waypoints and path as GeoJSON (WGS84)");
  command->add_option("--kml", c->kml, "Write the waypoints and path as KML (WGS84)");
  command->add_option("--png", c->png,
                      "Write a map of the plan (over the DEM's hillshade, or blank) with a scale "
                      "bar");
  command->add_option("--png-size", c->png_size, "Longer side of the map, pixels")
      ->capture_default_str();
  command->add_option("--simulate", c->simulate,
                      "Preview: fly the plan in the simulator over this scene (docs/scenes.md, "
                      "e.g. scenes/forest.json) and report what it reveals");
  command->add_option("--preview-png", c->preview_png,
                      "Write the preview's integral image on the ground (needs --simulate)");
  flags.Force();
  flags.Input("--dem");
  flags.Input("--simulate");
  for (const char* output : {"--csv", "--geojson", "--kml", "--png", "--preview-png"}) {
    flags.Output(output);
  }
  // Every other field of the tables (tools/vocabulary.py NOT_ON_THE_CLI: why not those).
  flags.Remaining(c->options);
  return [c, flags] { return RunPlan(*c, flags); };
}

}  // namespace aos::cli
