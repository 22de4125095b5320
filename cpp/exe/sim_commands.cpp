// Simulation commands: simulate, demo.
#include <filesystem>
#include <limits>
#include <memory>

#include "aos/metrics/quality.h"
#include "aos/sim/scene.h"
#include "aos/sim/simulator.h"
#include "aos/util/file_util.h"
#include "commands.h"
#include "progress_bar.h"
#include "render_output.h"

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
  flags.Threads(c->options.num_threads);
  command->add_flag("--print-scene", c->print_scene,
                    "Print the scene with every field written out and exit");
  return [c, flags] { return RunSimulate(*c, flags); };
}

namespace {

struct DemoCommand {
  std::string output_dir = "aos-demo";
  std::string scene_path;
  int grid = 0;
  SimulateOptions options;
  ImageOutputOptions image;
};

int RunDemo(DemoCommand& c, const Flags& flags) {
  const Scene scene = LoadSceneOrDefault(c.scene_path, c.grid);
  CheckOutputFolder(c.output_dir);  // before any work
  CheckImageOutput(c.image, "x.png");
  ProgressBar progress(Common().quiet);
  const SimulationResult simulation =
      flags.NamingFlags([&] { return Simulate(scene, c.options, &progress); });
  progress.Finish();
  Report report("demo");
  ReportStats(simulation, report);
  WriteSimulation(simulation, scene, c.output_dir);
  int files = 0;
  for (const auto& entry : fs::recursive_directory_iterator(c.output_dir)) {
    files += entry.is_regular_file() ? 1 : 0;
  }
  report.Line("wrote %s (%zu views of %s, ground truth in truth/)", c.output_dir.c_str(),
              simulation.light_field.views.size(), scene.source.c_str());

  // Renders from the truth camera: one view (radius 0), the integral focused on the ground, and
  // one focused inside the occluders; each compared with the ground truth.
  const GroundTruth& truth = simulation.truth;
  IntegralOptions options;
  options.cam_from_world = truth.cam_from_world;
  options.fov_deg = truth.camera.FovXDeg();
  options.width = truth.camera.width;
  options.height = truth.camera.height;
  options.num_threads = c.options.num_threads;
  struct Job {
    std::string name;
    double height;
    double radius;
  };
  const double ground = truth.ground_height_at_center;
  std::vector<Job> jobs{{"single_view", ground, 0.0},
                        {"integral_ground", ground, std::numeric_limits<double>::infinity()}};
  if (scene.has_voxels) {
    jobs.push_back({"integral_occluders", scene.voxels.center[2],
                    std::numeric_limits<double>::infinity()});
  }
  const PixelType views_type = simulation.light_field.views.front().image.type();
  for (const Job& job : jobs) {
    options.focal_plane = Plane::AtHeight(job.height);
    options.aperture_radius = job.radius;
    const IntegralResult result = RenderIntegral(simulation.light_field, options, &progress);
    progress.Finish();
    const std::string base = (fs::path(c.output_dir) / job.name).string();
    RenderOutput out;
    out.output = base + (views_type == PixelType::kF32 ? ".tif" : ".png");
    out.count = base + "_count.png";
    out.image = c.image;
    Report& entry = report.Nested(job.name);
    WriteRenderOutput(result, out, views_type, {}, entry);
    files += 2;
    const QualityResult quality = CompareImages(result.image, truth.ground, nullptr, {});
    entry.Set("focal_height", job.height);
    entry.Set("psnr_db", quality.psnr_db);
    entry.Set("ssim", quality.ssim);
    report.Result("  %-20s focal plane z = %6.2f m: PSNR %6.2f dB, SSIM %.3f against the ground "
                  "truth",
                  job.name.c_str(), job.height, quality.psnr_db, quality.ssim);
  }
  report.Set("output_dir", c.output_dir);
  report.Set("files", files);
  report.Line("demo: %d files in %s (open %s/integral_ground.png: the ground seen through the "
              "occluders; truth/ground.png is the truth)",
              files, c.output_dir.c_str(), c.output_dir.c_str());
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
  flags.Threads(c->options.num_threads);
  AddImageOutputFlags(flags, c->image);
  return [c, flags] { return RunDemo(*c, flags); };
}

}  // namespace aos::cli
