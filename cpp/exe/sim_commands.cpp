// Simulation commands: simulate, demo.
#include <filesystem>
#include <limits>
#include <memory>

#include "aos/demo/demo.h"
#include "aos/metrics/quality.h"
#include "aos/sim/scene.h"
#include "aos/sim/simulator.h"
#include "aos/util/file_util.h"
#include "commands.h"
#include "progress_bar.h"

namespace fs = std::filesystem;

namespace aos::cli {
namespace {

// A scene file or the built-in default, and a grid override (handy for quick runs).
Scene LoadSceneOrDefault(const std::string& path, int grid) {
  Scene scene = path.empty() ? DefaultScene() : LoadScene(path);
  if (grid > 0) {
    if (!scene.sampling.positions.empty()) {
      ThrowUsage("--grid: the scene lists explicit sampling.positions; a grid does not apply");
    }
    scene.sampling.grid = grid;
    scene.Check();
  }
  return scene;
}

void ReportStats(const SimulationResult& result, Report& report) {
  const SimulationStats& s = result.stats;
  const double rays = static_cast<double>(s.primary_rays);
  if (!Common().quiet && !Common().json) {
    std::fprintf(stderr,
                 "simulated %lld views: %lld primary rays in %.2f s (%.1f M rays/s), %lld shadow "
                 "rays, %lld truth rays, %lld blocked-fraction rays; %lld voxels, %lld trees "
                 "(%lld leaves)\n",
                 static_cast<long long>(s.views), static_cast<long long>(s.primary_rays),
                 s.seconds_views, s.seconds_views > 0 ? rays / s.seconds_views * 1e-6 : 0.0,
                 static_cast<long long>(s.shadow_rays), static_cast<long long>(s.truth_rays),
                 static_cast<long long>(s.blocked_fraction_rays),
                 static_cast<long long>(s.voxels), static_cast<long long>(s.trees),
                 static_cast<long long>(s.leaf_quads));
  }
  report.Set("views", static_cast<long long>(s.views));
  report.Set("primary_rays", static_cast<long long>(s.primary_rays));
  report.Set("seconds_views", s.seconds_views);
}

struct SimulateCommand {
  std::string scene_path;
  std::string output_dir;
  int grid = 0;
  SimulateOptions options;
  bool print_scene = false;
};

int RunSimulate(SimulateCommand& c, const Flags& flags) {
  const Scene scene = LoadSceneOrDefault(c.scene_path, c.grid);
  if (c.print_scene) {
    std::fputs(SceneToJson(scene).c_str(), stdout);
    return 0;
  }
  if (c.output_dir.empty()) ThrowUsage("--output-dir: required (a new or empty folder)");
  CheckOutputFolder(c.output_dir);  // before any work
  ProgressBar progress(Common().quiet);
  const SimulationResult result =
      flags.NamingFlags([&] { return Simulate(scene, c.options, &progress); });
  progress.Finish();
  Report report("simulate");
  ReportStats(result, report);
  WriteSimulation(result, scene, c.output_dir);
  report.Set("output_dir", c.output_dir);
  report.Set("ground_height_at_center", result.truth.ground_height_at_center);
  report.Line("wrote %s: %zu views, lightfield.json, truth/ (focal plane z = %s m)",
              c.output_dir.c_str(), result.light_field.views.size(),
              FormatNumber(result.truth.ground_height_at_center).c_str());
  report.Print();
  return 0;
}

}  // namespace

CommandRunner DefineSimulate(CLI::App* command) {
  auto c = std::make_shared<SimulateCommand>();
  Flags flags(command);
  command->add_option("scene", c->scene_path,
                      "Scene file (JSON); omitted = the built-in default scene");
  command->add_option("-o,--output-dir", c->output_dir,
                      "Output folder; must not exist or be empty");
  command->add_option("--grid", c->grid, "Override sampling.grid (views per side, >= 1)")
      ->check(AtLeast(1));
  flags.Threads(c->options);
  command->add_flag("--print-scene", c->print_scene,
                    "Print the scene with every field written out and exit");
  flags.Input("scene");
  flags.OutputFolder("--output-dir");
  // Every other field of the tables (tools/vocabulary.py NOT_ON_THE_CLI: why not those).
  flags.Remaining(c->options);
  return [c, flags] { return RunSimulate(*c, flags); };
}

namespace {

struct DemoCommand {
  std::string output_dir = "aos-demo";
  std::string scene_path;
  int grid = 0;
  DemoOptions options;
};

int RunDemo(DemoCommand& c, const Flags& flags) {
  const Scene scene = LoadSceneOrDefault(c.scene_path, c.grid);
  CheckDemoFolder(c.output_dir);  // before any work
  ProgressBar progress(Common().quiet);
  const DemoResult result =
      flags.NamingFlags([&] { return aos::RunDemo(scene, c.options, &progress); });
  progress.Finish();
  Report report("demo");
  ReportStats(result.simulation, report);
  const std::vector<std::string> files = WriteDemo(result, c.output_dir);
  report.Line("wrote %s (%zu views of %s, ground truth in truth/)", c.output_dir.c_str(),
              result.simulation.light_field.views.size(), scene.source.c_str());
  if (result.target_blocked_fraction >= 0) {
    report.Set("target_blocked_fraction", result.target_blocked_fraction);
    report.Result("  the occluders block %.0f %% of the views' rays to the target",
                  100.0 * result.target_blocked_fraction);
  }
  for (const DemoRender& r : result.renders) {
    Report& entry = report.Nested(r.name);
    entry.Set("focal_height", r.focal_height);
    entry.Set("psnr_db", r.quality.psnr_db);
    entry.Set("ssim", r.quality.ssim);
    std::string target;
    if (r.visibility.has_target) {
      entry.Set("target_standout_fraction", r.visibility.standout_fraction);
      entry.Set("target_contrast_to_noise", r.visibility.contrast_to_noise);
      char text[96];
      std::snprintf(text, sizeof(text), "; target stands out %3.0f %%, contrast/noise %.2f",
                    100.0 * r.visibility.standout_fraction, r.visibility.contrast_to_noise);
      target = text;
    }
    report.Result("  %-20s focal plane z = %6.2f m: PSNR %6.2f dB, SSIM %.3f against the ground "
                  "truth%s",
                  r.name.c_str(), r.focal_height, r.quality.psnr_db, r.quality.ssim,
                  target.c_str());
  }
  report.Set("output_dir", c.output_dir);
  report.Set("files", files.size());
  report.Set("seconds_total", result.seconds_total);
  report.Line("demo: %zu files in %s in %.1f s; open %s/index.html", files.size(),
              c.output_dir.c_str(), result.seconds_total, c.output_dir.c_str());
  report.Print();
  return 0;
}

}  // namespace

CommandRunner DefineDemo(CLI::App* command) {
  auto c = std::make_shared<DemoCommand>();
  Flags flags(command);
  command->add_option("-o,--output-dir", c->output_dir, "Output folder; must not exist or be empty")
      ->capture_default_str();
  command->add_option("--scene", c->scene_path, "A scene file instead of the built-in default");
  command->add_option("--grid", c->grid, "Override sampling.grid (views per side, >= 1)")
      ->check(AtLeast(1));
  DemoOptions& options = c->options;
  flags.Field(options, "all_in_focus_slices");
  flags.Field(options, "target_margin_m");
  flags.Threads(options);
  flags.Input("--scene");
  flags.OutputFolder("--output-dir");
  // Every other field of the tables (tools/vocabulary.py NOT_ON_THE_CLI: why not those).
  flags.Remaining(c->options);
  return [c, flags] { return RunDemo(*c, flags); };
}

}  // namespace aos::cli
