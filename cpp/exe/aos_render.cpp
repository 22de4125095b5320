// aos-render: the command-line front end. Subcommands fill the core's Options structs (the same
// ones Python fills), run the algorithm with a progress bar, and write outputs atomically.
// Exit codes: 0 success, 1 bad input or failure (one line on stderr), 2 bad command line (an
// unknown flag, or a value out of range: UsageError), 130 interrupted (SIGINT, SIGTERM, SIGHUP).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "aos/calib/calibrate.h"
#include "aos/demo/demo.h"
#include "aos/sfm/colmap_pipeline.h"
#include "aos/image/image_io.h"
#include "aos/image/preview.h"
#include "aos/lightfield/camera_file.h"
#include "aos/lightfield/formats.h"
#include "aos/metrics/quality.h"
#include "aos/metrics/resolution.h"
#include "aos/render/focal_stack.h"
#include "aos/render/integral.h"
#include "aos/render/merge.h"
#include "aos/render/rectify.h"
#include "aos/sim/scene.h"
#include "aos/sim/simulator.h"
#include "aos/util/error.h"
#include "aos/util/file_util.h"
#include "aos/util/version.h"
#include "progress_bar.h"

namespace fs = std::filesystem;

namespace aos::cli {
namespace {

// A mistake on the command line found while interpreting the values (out of range, malformed
// lists, unknown names): exit code 2, like the parser's own errors.
class UsageError : public std::invalid_argument {
 public:
  explicit UsageError(const std::string& message) : std::invalid_argument(OneLine(message)) {}
};

[[noreturn]] void ThrowUsage(const std::string& message) { throw UsageError(message); }

// -q / --quiet, on every command: no progress and no report lines ("wrote ..."); errors and
// warnings still go to stderr, and a command's result (metrics, resolution) still prints.
bool g_quiet = false;

// printf to stdout unless -q.
__attribute__((format(printf, 1, 2))) void Say(const char* format, ...) {
  if (g_quiet) return;
  va_list arguments;
  va_start(arguments, format);
  std::vfprintf(stdout, format, arguments);
  va_end(arguments);
}

void AddQuiet(CLI::App* command) {
  command->add_flag("-q,--quiet", g_quiet, "No progress and no report lines (errors and warnings "
                                           "still print)");
}

// --force, on every command that writes files: an output file that exists is refused unless
// given (it is then replaced atomically, when the new one is complete). Output folders are never
// replaced, --force or not: removing a tree is left to the user.
bool g_force = false;

void AddForce(CLI::App* command) {
  command->add_flag("--force", g_force, "Replace output files that exist (refused otherwise)");
}

// Old spellings kept for one release (CHANGELOG.md): the option accepts both names, and using
// the old one prints a warning naming the new one. One line per renamed flag.
struct DeprecatedSpelling {
  const char* command;
  const char* old_flag;
  const char* new_flag;
};
constexpr DeprecatedSpelling kDeprecatedSpellings[] = {
    {"import-colmap", "--images", "--images-dir"},
    {"poses", "--fov-deg", "--frames-fov-deg"},
    {"rectify", "--fov-deg", "--rectified-fov-deg"},
    {"resolution", "--fov-deg", "--lens-fov-deg"},
    {"metrics", "--window-radius", "--ssim-window-radius"},
};

// Warns for each old spelling on the command line (after the subcommand; also --old=value).
void WarnDeprecatedSpellings(int argc, char** argv) {
  if (argc < 2) return;
  const std::string command = argv[1];
  for (int i = 2; i < argc; ++i) {
    const std::string argument = argv[i];
    for (const DeprecatedSpelling& spelling : kDeprecatedSpellings) {
      const std::string old_flag = spelling.old_flag;
      if (command == spelling.command &&
          (argument == old_flag || argument.rfind(old_flag + "=", 0) == 0)) {
        std::fprintf(stderr, "warning: %s is deprecated; use %s\n", spelling.old_flag,
                     spelling.new_flag);
      }
    }
  }
}

// Refuses an existing `path` (a file, a folder or a link, dangling or not) unless --force.
void RefuseExisting(const std::string& path, const std::string& what) {
  std::error_code error;
  const fs::file_status status = fs::symlink_status(path, error);
  if (error || !fs::exists(status)) return;
  if (fs::is_directory(fs::status(path, error))) {
    ThrowInvalid(path + ": " + what + " is a folder; give a file name");
  }
  if (!g_force) {
    ThrowInvalid(path + ": " + what + " exists; give --force to replace it (nothing was written)");
  }
}

// Runs `interpret` (which reads a flag's value) and turns its std::invalid_argument into a
// UsageError.
template <class Interpret>
auto AsUsage(Interpret&& interpret) -> decltype(interpret()) {
  try {
    return interpret();
  } catch (const UsageError&) {
    throw;
  } catch (const std::invalid_argument& error) {
    throw UsageError(error.what());
  }
}

// A validator for whole-number flags: refuses values below `minimum` with a plain message (the
// parser then exits with code 2).
CLI::Validator AtLeast(long long minimum) {
  return CLI::Validator(
      [minimum](std::string& text) -> std::string {
        char* end = nullptr;
        const long long value = std::strtoll(text.c_str(), &end, 10);
        if (end == text.c_str() || *end != '\0') return "'" + text + "' is not a whole number";
        if (value < minimum) {
          return "must be >= " + std::to_string(minimum) + " (got " + text + ")";
        }
        return std::string();
      },
      "INT>=" + std::to_string(minimum));
}

// "a,b,c" -> numbers; throws std::invalid_argument naming the option.
std::vector<double> ParseNumbers(const std::string& text, const std::string& option) {
  std::vector<double> values;
  std::stringstream stream(text);
  std::string item;
  while (std::getline(stream, item, ',')) {
    values.push_back(AsUsage([&] { return ParseNumberText(item, option); }));
  }
  return values;
}

std::vector<double> ParseNumbers(const std::string& text, const std::string& option,
                                 size_t count) {
  std::vector<double> values = ParseNumbers(text, option);
  if (values.size() != count) {
    ThrowUsage(option + ": expected " + std::to_string(count) +
                 " comma-separated numbers (got '" + text + "')");
  }
  return values;
}

// "0:10,15,20:30" (half-open ranges and single indices) -> indices, each checked against
// [0, view_count) before any range is expanded.
std::vector<int> ParseViewList(const std::string& text, int view_count) {
  std::vector<int> indices;
  std::stringstream stream(text);
  std::string item;
  auto to_index = [&](const std::string& part, int fallback, int upper) {
    if (part.empty()) return fallback;
    const double value = AsUsage([&] { return ParseNumberText(part, "--views"); });
    if (value != std::floor(value)) ThrowUsage("--views: '" + part + "' is not an integer");
    if (value < 0 || value > upper) {
      ThrowUsage("--views: index " + part + " is outside 0.." + std::to_string(upper) +
                   " (the light field has " + std::to_string(view_count) + " views)");
    }
    return static_cast<int>(value);
  };
  while (std::getline(stream, item, ',')) {
    if (item.empty()) continue;
    const size_t colon = item.find(':');
    if (colon == std::string::npos) {
      indices.push_back(to_index(item, 0, view_count - 1));
    } else {
      const int begin = to_index(item.substr(0, colon), 0, view_count);
      const int end = to_index(item.substr(colon + 1), view_count, view_count);
      if (begin > end) ThrowUsage("--views: range '" + item + "' runs backwards");
      for (int i = begin; i < end; ++i) indices.push_back(i);
    }
  }
  if (indices.empty()) {
    ThrowUsage("--views: the selection '" + text + "' is empty (view selection is empty)");
  }
  return indices;
}

// Options::Check() errors start with the field's name ("fov_deg: ..."); on the command line,
// also name the flag. Errors about files (which start with the path) are left alone, except the
// loader's own request for LoadOptions::fov_deg.
[[noreturn]] void RethrowNamingFlags(const std::invalid_argument& error,
                                     const std::vector<std::pair<std::string, std::string>>& flags) {
  const std::string message = error.what();
  for (const auto& [field, flag] : flags) {
    const bool names_field = message.rfind(field + ":", 0) == 0 ||
                             message.rfind(field + "/", 0) == 0 ||
                             message.find("(LoadOptions::" + field + ")") != std::string::npos;
    if (names_field) throw UsageError(message + " [option " + flag + "]");
  }
  throw;
}

const std::vector<std::pair<std::string, std::string>> kLoadFlags{
    {"fov_deg", "--frames-fov-deg"}, {"num_threads", "--threads"}};
const std::vector<std::pair<std::string, std::string>> kRenderFlags{
    {"fov_deg", "--fov-deg"},
    {"width", "--width/--height"},
    {"aperture_radius", "--aperture-radius"},
    {"min_view_angle_deg", "--min-view-angle-deg"},
    {"num_threads", "--threads"},
    {"pose_view", "--pose-view"},
    {"view_indices", "--views"},
    {"focal_plane", "--focal-height/--focal-plane"},
    {"cam_from_world", "--cam-from-world/--look-at"}};

double ParseRadius(const std::string& text) {
  if (text == "inf" || text == "infinity") return std::numeric_limits<double>::infinity();
  return AsUsage([&] { return ParseNumberText(text, "--aperture-radius"); });
}

// The value range that maps onto the integer codes of an 8/16-bit output.
std::pair<double, double> ResolveRange(const std::string& spec, const IntegralResult& result,
                                       PixelType views_type) {
  if (spec == "views") return {0.0, PixelTypeFullRange(views_type)};
  if (spec == "minmax") {
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (int y = 0; y < result.image.height(); ++y) {
      for (int x = 0; x < result.image.width(); ++x) {
        if (*result.count.At<uint32_t>(x, y) == 0) continue;
        for (int c = 0; c < result.image.channels(); ++c) {
          const double value = result.image.At<float>(x, y)[c];
          lo = std::min(lo, value);
          hi = std::max(hi, value);
        }
      }
    }
    if (!(hi > lo)) return {std::isfinite(lo) ? lo : 0.0, std::isfinite(lo) ? lo + 1.0 : 1.0};
    return {lo, hi};
  }
  const std::vector<double> values = ParseNumbers(spec, "--range", 2);
  return {values[0], values[1]};
}

struct OutputOptions {
  std::string output;
  std::string count;
  std::string sample_type = "auto";
  std::string range = "views";
};

void AddOutputOptions(CLI::App* command, OutputOptions& out, bool with_output) {
  if (with_output) {
    command->add_option("-o,--output", out.output,
                        "Output image; the extension picks the format: .exr/.tif (float32, as "
                        "rendered), .png (8/16-bit, normalised by --range)")
        ->required();
    command->add_option("--count", out.count,
                        "Also write the per-pixel count of contributing views (.tif uint32, "
                        ".png 16-bit, .exr float)");
  }
  command->add_option("--sample-type", out.sample_type,
                      "Sample type of the output: auto, uint8, uint16, float32")
      ->capture_default_str();
  command->add_option("--range", out.range,
                      "Value range mapped onto 0..max code for 8/16-bit outputs: 'views' (the "
                      "views' native range: 0..255 for 8-bit, 0..65535 for 16-bit, 0..1 for "
                      "float), 'minmax' (the covered pixels' min..max), or LO,HI")
      ->capture_default_str();
}

// Checks the output paths before any work: folders exist, no output is an input, the two
// outputs differ, and each extension can hold its samples. Throws std::invalid_argument.
void CheckOutputs(const OutputOptions& out, const std::string& image_path,
                  const std::string& count_path, const std::vector<std::string>& inputs) {
  CheckOutputPath(image_path, inputs, "output");
  RefuseExisting(image_path, "output");
  if (out.range != "views" && out.range != "minmax") {
    const std::vector<double> range = ParseNumbers(out.range, "--range", 2);
    if (!(range[1] > range[0])) {
      ThrowUsage("--range: expected LO,HI with HI > LO (got '" + out.range + "')");
    }
  }
  WriteImageOptions write;
  write.sample_type = AsUsage([&] { return ParseSampleType(out.sample_type); });
  AsUsage([&] { return ResolveSampleType(image_path, Image(1, 1, 1, PixelType::kF32), write); });
  if (count_path.empty()) return;
  CheckOutputPath(count_path, inputs, "count");
  if (fs::weakly_canonical(fs::absolute(count_path)) ==
      fs::weakly_canonical(fs::absolute(image_path))) {
    ThrowInvalid(count_path + ": --count and --output name the same file");
  }
  RefuseExisting(count_path, "count");
  ResolveSampleType(count_path, Image(1, 1, 1, PixelType::kU32), WriteImageOptions{});
}

// Writes the image (and count map) of `result`: both go to temporary files first and are moved
// into place only when both are complete, so a failure leaves neither. Prints one line each.
void WriteOutputs(const IntegralResult& result, const std::string& image_path,
                  const std::string& count_path, const OutputOptions& out, PixelType views_type,
                  const std::vector<std::string>& inputs) {
  CheckOutputs(out, image_path, count_path, inputs);
  WriteImageOptions write;
  write.sample_type = ParseSampleType(out.sample_type);
  write.units = views_type;  // renders keep the views' units (image_io.h states the rule)
  const auto [lo, hi] = ResolveRange(out.range, result, views_type);
  write.range_min = lo;
  write.range_max = hi;
  const SampleType type = ResolveSampleType(image_path, result.image, write);
  std::string how;
  if (type == SampleType::kF32) {
    how = "float32, values as rendered";
  } else {
    how = std::string(SampleTypeName(type)) + ", values " + FormatNumber(lo) + ".." +
          FormatNumber(hi) + " mapped to 0.." + (type == SampleType::kU8 ? "255" : "65535");
  }
  write.description = "aos integral image (" + how + ")";
  PendingFile image_file(image_path);
  WriteImage(image_file.TempPath(), result.image, write);
  std::optional<PendingFile> count_file;
  if (!count_path.empty()) {
    count_file.emplace(count_path);
    WriteImageOptions count_write;
    count_write.description = "aos count map: views contributing to each pixel";
    WriteImage(count_file->TempPath(), result.count, count_write);
  }
  std::vector<PendingFile*> files{&image_file};
  if (count_file) files.push_back(&*count_file);
  CommitTogether(files);
  Say("wrote %s (%dx%d, %s)\n", image_path.c_str(), result.image.width(),
              result.image.height(), how.c_str());
  if (count_file) {
    Say("wrote %s (count of contributing views per pixel)\n", count_path.c_str());
  }
}

struct IntegralCommand {
  std::string light_field_path;
  LoadOptions load;
  IntegralOptions options;
  std::string look_at;
  std::string cam_from_world;
  std::string aperture_radius = "inf";
  double focal_height = 0.0;
  std::string focal_plane;
  double focal_distance = 0.0;
  bool horizontal = false;
  std::string views;
  OutputOptions out;
};

// The light field and the virtual camera: shared by integral, stack and allinfocus.
// `with_plane` adds --focal-height/--focal-plane (integral only).
void AddRenderArgs(CLI::App* command, IntegralCommand& c, bool with_plane) {
  command->add_option("lightfield", c.light_field_path,
                      "Light-field file: aos JSON, or a JKU-ICG/AOS poses.json")
      ->required();
  command->add_option("--frames-fov-deg", c.load.fov_deg,
                      "Horizontal field of view of the frames, degrees (JKU poses.json only)");
  command->add_option("--images-dir", c.load.images_dir,
                      "Folder of the frames (JKU poses.json; default: ../images beside it)");
  auto* pose_view = command->add_option("--pose-view", c.options.pose_view,
                                        "Virtual camera = the pose of view K (0-based)")
                        ->check(AtLeast(0));
  auto* look_at = command->add_option("--look-at", c.look_at,
                                      "Virtual camera at EX,EY,EZ looking at TX,TY,TZ (optional "
                                      "up UX,UY,UZ; default 0,0,1, or 0,1,0 looking straight "
                                      "down or up)");
  auto* pose = command->add_option("--cam-from-world", c.cam_from_world,
                                   "Virtual camera pose as 12 numbers: the 3x4 matrix [R|t] "
                                   "row by row (local frame -> camera, OpenCV axes)");
  pose_view->excludes(look_at)->excludes(pose);
  look_at->excludes(pose);
  command->add_option("--fov-deg", c.options.fov_deg,
                      "Horizontal field of view of the virtual camera, degrees; 0 = the pose "
                      "view's, else 50")
      ->capture_default_str();
  command->add_option("--width", c.options.width,
                      "Output width, pixels; 0 = the pose view's, else 512")
      ->capture_default_str();
  command->add_option("--height", c.options.height,
                      "Output height, pixels; 0 = the pose view's, else 512")
      ->capture_default_str();
  command->add_option("--aperture-radius", c.aperture_radius,
                      "Radius of the virtual aperture, metres; 0 = pinhole (nearest view), "
                      "inf = every view")
      ->capture_default_str();
  if (with_plane) {
    auto* height = command->add_option("--focal-height", c.focal_height,
                                       "Horizontal focal plane z = H (local frame, metres)")
                       ->capture_default_str();
    auto* plane = command->add_option("--focal-plane", c.focal_plane,
                                      "Focal plane through PX,PY,PZ with normal NX,NY,NZ");
    auto* distance = command->add_option(
        "--focal-distance", c.focal_distance,
        "Focal plane D metres in front of the virtual camera, perpendicular to its axis (e.g. "
        "35 for 'focus 35 m below the drone')");
    auto* horizontal = command->add_flag("--horizontal", c.horizontal,
                                         "With --focal-distance: the horizontal plane through "
                                         "that point instead");
    height->excludes(plane)->excludes(distance);
    plane->excludes(distance);
    horizontal->needs(distance);
  }
  command->add_option("--views", c.views,
                      "Views to integrate: indices and half-open ranges, e.g. 0:100,150 "
                      "(default: all)");
  command->add_option("--min-view-angle-deg", c.options.min_view_angle_deg,
                      "Ignore rays meeting the focal plane at less than this angle, degrees")
      ->capture_default_str();
  command->add_option("--threads", c.options.num_threads, "Worker threads; -1 = all cores")
      ->capture_default_str();
  AddQuiet(command);
}

void AddIntegral(CLI::App& app, IntegralCommand& c) {
  CLI::App* command = app.add_subcommand(
      "integral", "Render an integral image (Eq. 1) of a light field onto a focal plane");
  AddRenderArgs(command, c, true);
  AddOutputOptions(command, c.out, true);
  AddForce(command);
}

// Loads the light field and fills c.options' virtual camera (pose, aperture, views) from the
// command line; the focal plane is left to the caller.
LoadResult LoadAndResolveCamera(IntegralCommand& c, ProgressBar& progress) {
  c.load.num_threads = c.options.num_threads;
  LoadResult loaded;
  try {
    loaded = LoadLightField(c.light_field_path, c.load, &progress);
  } catch (const std::invalid_argument& error) {
    RethrowNamingFlags(error, kLoadFlags);
  }
  progress.Finish();
  for (const std::string& note : loaded.notes) std::fprintf(stderr, "note: %s\n", note.c_str());
  IntegralOptions& options = c.options;
  if (!c.look_at.empty()) {
    const std::vector<double> v = ParseNumbers(c.look_at, "--look-at");
    if (v.size() != 6 && v.size() != 9) ThrowUsage("--look-at: expected 6 or 9 numbers");
    const Vec3d eye(v[0], v[1], v[2]), target(v[3], v[4], v[5]);
    options.cam_from_world = AsUsage([&] {
      return v.size() == 9 ? LookAt(eye, target, Vec3d(v[6], v[7], v[8])) : LookAt(eye, target);
    });
  } else if (!c.cam_from_world.empty()) {
    const std::vector<double> v = ParseNumbers(c.cam_from_world, "--cam-from-world", 12);
    std::array<double, 12> m{};
    std::copy(v.begin(), v.end(), m.begin());
    options.cam_from_world = Rigid3d::FromMatrix3x4(m);
  } else if (options.pose_view < 0) {
    ThrowUsage("no virtual camera pose: give --pose-view, --look-at or --cam-from-world");
  }
  options.aperture_radius = ParseRadius(c.aperture_radius);
  if (!c.views.empty()) {
    options.view_indices =
        ParseViewList(c.views, static_cast<int>(loaded.light_field.views.size()));
  }
  return loaded;
}

int RunIntegral(IntegralCommand& c) {
  ProgressBar progress(g_quiet);
  // Refuse bad outputs (an input, a missing folder, a format that cannot hold the samples)
  // before spending time on loading; the frames are checked again once known.
  CheckOutputs(c.out, c.out.output, c.out.count, {c.light_field_path});
  const LoadResult loaded = LoadAndResolveCamera(c, progress);
  const LightField& light_field = loaded.light_field;
  IntegralOptions& options = c.options;
  if (!c.focal_plane.empty()) {
    const std::vector<double> v = ParseNumbers(c.focal_plane, "--focal-plane", 6);
    options.focal_plane = Plane{Vec3d(v[0], v[1], v[2]), Vec3d(v[3], v[4], v[5])};
  } else if (c.focal_distance != 0.0) {
    const Rigid3d cam_from_world = VirtualCamFromWorld(light_field, options);
    options.focal_plane = AsUsage([&] {
      return Plane::InFrontOf(cam_from_world, c.focal_distance, c.horizontal);
    });
  } else {
    options.focal_plane = Plane::AtHeight(c.focal_height);
  }
  std::vector<std::string> inputs{c.light_field_path};
  for (const View& view : light_field.views) inputs.push_back(view.image_path);
  // Check outputs against the frames before rendering; WriteOutputs checks again.
  CheckOutputs(c.out, c.out.output, c.out.count, inputs);
  IntegralResult result;
  try {
    result = RenderIntegral(light_field, options, &progress);
  } catch (const std::invalid_argument& error) {
    RethrowNamingFlags(error, kRenderFlags);
  }
  progress.Finish();
  if (!g_quiet) std::fprintf(stderr,
               "integrated %d of %d selected views: %lld samples, %lld of %lld pixels uncovered\n",
               result.views_used, result.views_selected, static_cast<long long>(result.samples),
               static_cast<long long>(result.uncovered_pixels),
               static_cast<long long>(result.image.width()) * result.image.height());
  const PixelType views_type = light_field.views.front().image.type();
  WriteOutputs(result, c.out.output, c.out.count, c.out, views_type, inputs);
  return 0;
}

// Scene selection shared by `simulate` and `demo`: a scene file or the built-in default, and a
// grid override (handy for quick runs).
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

void PrintStats(const SimulationResult& result) {
  const SimulationStats& s = result.stats;
  const double rays = static_cast<double>(s.primary_rays);
  std::fprintf(stderr,
               "simulated %lld views: %lld primary rays in %.2f s (%.1f M rays/s), %lld shadow "
               "rays, %lld truth rays, %lld blocked-fraction rays; %lld voxels, %lld trees "
               "(%lld leaves)\n",
               static_cast<long long>(s.views), static_cast<long long>(s.primary_rays),
               s.seconds_views, s.seconds_views > 0 ? rays / s.seconds_views * 1e-6 : 0.0,
               static_cast<long long>(s.shadow_rays), static_cast<long long>(s.truth_rays),
               static_cast<long long>(s.blocked_fraction_rays), static_cast<long long>(s.voxels),
               static_cast<long long>(s.trees), static_cast<long long>(s.leaf_quads));
}

struct SimulateCommand {
  std::string scene_path;
  std::string output_dir;
  int grid = 0;
  SimulateOptions options;
  bool print_scene = false;
};

void AddSimulate(CLI::App& app, SimulateCommand& c) {
  CLI::App* command = app.add_subcommand(
      "simulate",
      "Simulate a scene (docs/scenes.md): write its views, the light field (recorded poses) and "
      "the ground truth into a new folder");
  command->add_option("scene", c.scene_path,
                      "Scene file (JSON); omitted = the built-in default scene");
  command->add_option("-o,--output-dir", c.output_dir,
                      "Output folder; must not exist or be empty");
  command->add_option("--grid", c.grid, "Override sampling.grid (views per side, >= 1)")
      ->check(AtLeast(1));
  command->add_option("--threads", c.options.num_threads, "Worker threads; -1 = all cores")
      ->capture_default_str();
  command->add_flag("--print-scene", c.print_scene,
                    "Print the scene with every field written out and exit");
  AddQuiet(command);
}

int RunSimulate(SimulateCommand& c) {
  const Scene scene = LoadSceneOrDefault(c.scene_path, c.grid);
  if (c.print_scene) {
    std::fputs(SceneToJson(scene).c_str(), stdout);
    return 0;
  }
  if (c.output_dir.empty()) ThrowUsage("--output-dir: required (a new or empty folder)");
  CheckOutputFolder(c.output_dir);  // before any work
  ProgressBar progress(g_quiet);
  SimulationResult result;
  try {
    result = Simulate(scene, c.options, &progress);
  } catch (const std::invalid_argument& error) {
    RethrowNamingFlags(error, {{"num_threads", "--threads"}});
  }
  progress.Finish();
  if (!g_quiet) PrintStats(result);
  WriteSimulation(result, scene, c.output_dir);
  Say("wrote %s: %zu views, lightfield.json, truth/ (focal plane z = %s m)\n",
              c.output_dir.c_str(), result.light_field.views.size(),
              FormatNumber(result.truth.ground_height_at_center).c_str());
  return 0;
}

struct DemoCommand {
  std::string output_dir = "aos-demo";
  std::string scene_path;
  int grid = 0;
  DemoOptions options;
};

void AddDemo(CLI::App& app, DemoCommand& c) {
  CLI::App* command = app.add_subcommand(
      "demo",
      "Simulate the built-in default scene (a red person-sized target on a forest floor under "
      "procedural trees, RGB), render a single view, integral images and an all-in-focus image "
      "from above, score them against the ground truth, and write it all with an index.html");
  command->add_option("-o,--output-dir", c.output_dir, "Output folder; must not exist or be empty")
      ->capture_default_str();
  command->add_option("--scene", c.scene_path, "A scene file instead of the built-in default");
  command->add_option("--grid", c.grid, "Override sampling.grid (views per side, >= 1)")
      ->check(AtLeast(1));
  command->add_option("--all-in-focus-slices", c.options.all_in_focus_slices,
                      "Slices of the all-in-focus stack (ground to the top of the occluders); "
                      "0 = no all-in-focus image")
      ->capture_default_str();
  command->add_option("--target-margin", c.options.target_margin_m,
                      "Ring of ground around each target used as its surroundings in the "
                      "visibility figures, metres")
      ->capture_default_str();
  command->add_option("--threads", c.options.num_threads, "Worker threads; -1 = all cores")
      ->capture_default_str();
  AddQuiet(command);
}

int RunDemo(DemoCommand& c) {
  const Scene scene = LoadSceneOrDefault(c.scene_path, c.grid);
  CheckDemoFolder(c.output_dir);  // before any work
  ProgressBar progress(g_quiet);
  DemoResult result;
  try {
    result = aos::RunDemo(scene, c.options, &progress);
  } catch (const std::invalid_argument& error) {
    RethrowNamingFlags(error, {{"num_threads", "--threads"},
                               {"all_in_focus_slices", "--all-in-focus-slices"},
                               {"target_margin_m", "--target-margin"}});
  }
  progress.Finish();
  if (!g_quiet) PrintStats(result.simulation);
  const std::vector<std::string> files = WriteDemo(result, c.output_dir);
  Say("wrote %s (%zu views of %s, ground truth in truth/)\n", c.output_dir.c_str(),
      result.simulation.light_field.views.size(), scene.source.c_str());
  if (result.target_blocked_fraction >= 0) {
    std::printf("  the occluders block %.0f %% of the views' rays to the target\n",
                100.0 * result.target_blocked_fraction);
  }
  for (const DemoRender& r : result.renders) {
    std::printf("  %-20s focal plane z = %6.2f m: PSNR %6.2f dB, SSIM %.3f against the ground "
                "truth",
                r.name.c_str(), r.focal_height, r.quality.psnr_db, r.quality.ssim);
    if (r.visibility.has_target) {
      std::printf("; target stands out %3.0f %%, contrast/noise %.2f",
                  100.0 * r.visibility.standout_fraction, r.visibility.contrast_to_noise);
    }
    std::printf("\n");
  }
  Say("demo: %zu files in %s in %.1f s; open %s/index.html\n", files.size(),
      c.output_dir.c_str(), result.seconds_total, c.output_dir.c_str());
  return 0;
}

// "H" (the horizontal plane z = H) or "PX,PY,PZ,NX,NY,NZ".
Plane ParsePlane(const std::string& text, const std::string& option) {
  const std::vector<double> v = ParseNumbers(text, option);
  if (v.size() == 1) return Plane::AtHeight(v[0]);
  if (v.size() != 6) {
    ThrowUsage(option + ": expected a height H or six numbers PX,PY,PZ,NX,NY,NZ (got '" + text +
                 "')");
  }
  return Plane{Vec3d(v[0], v[1], v[2]), Vec3d(v[3], v[4], v[5])};
}

struct StackArgs {
  std::string first_plane = "0";
  std::string last_plane = "10";
};

void AddStackArgs(CLI::App* command, StackArgs& args, FocalStackOptions& options) {
  command->add_option("--first-plane", args.first_plane,
                      "Boundary plane of slice 0: a height H (horizontal plane z = H) or "
                      "PX,PY,PZ,NX,NY,NZ")
      ->capture_default_str();
  command->add_option("--last-plane", args.last_plane,
                      "Boundary plane of the last slice, as --first-plane")
      ->capture_default_str();
  command->add_option("--slices", options.slices, "Number of slices (1..100000)")
      ->capture_default_str();
}

const std::vector<std::pair<std::string, std::string>> kStackFlags{
    {"slices", "--slices"}, {"first_plane", "--first-plane"}, {"last_plane", "--last-plane"}};
const std::vector<std::pair<std::string, std::string>> kMergeFlags{
    {"method", "--method"},
    {"window_radius", "--window-radius"},
    {"smoothing_sigma", "--smoothing-sigma"},
    {"edge_sigma", "--edge-sigma"},
    {"smoothing_iterations", "--smoothing-iterations"},
    {"agreement", "--agreement"},
    {"min_inlier_fraction", "--min-inlier-fraction"},
    {"num_threads", "--threads"}};

using FlagList = std::vector<std::pair<std::string, std::string>>;
FlagList Concat(std::initializer_list<const FlagList*> lists) {
  FlagList all;
  for (const FlagList* list : lists) all.insert(all.end(), list->begin(), list->end());
  return all;
}

struct MergeArgs {
  std::string method = "improved";
};

void AddMergeArgs(CLI::App* command, MergeArgs& args, MergeOptions& options) {
  command->add_option("--method", args.method,
                      "sobel (the paper's), improved (context-aware) or robust (view variance "
                      "and an outlier-rejecting mean; needs the light field)")
      ->capture_default_str();
  command->add_option("--window-radius", options.window_radius,
                      "improved/robust: focus window radius, pixels")
      ->capture_default_str();
  command->add_option("--smoothing-sigma", options.smoothing_sigma,
                      "improved/robust: depth smoothing sigma, pixels (0 = off)")
      ->capture_default_str();
  command->add_option("--edge-sigma", options.edge_sigma,
                      "improved/robust: smoothing range sigma, fraction of the image contrast")
      ->capture_default_str();
  command->add_option("--smoothing-iterations", options.smoothing_iterations,
                      "improved/robust: smoothing passes")
      ->capture_default_str();
  command->add_option("--agreement", options.robust.agreement,
                      "robust: half-width of the band of agreeing samples, fraction of the "
                      "views' range")
      ->capture_default_str();
  command->add_option("--min-inlier-fraction", options.robust.min_inlier_fraction,
                      "robust: fewest agreeing samples (fraction) for the robust mean")
      ->capture_default_str();
}

// Writes image, depth, confidence and slice maps into a new folder (atomically).
void WriteMergeResult(const std::string& output_dir, const MergeResult& result,
                      MergeMethod method) {
  PendingFolder folder(output_dir);
  const fs::path temp = folder.TempPath();
  WriteImageOptions write;
  write.description = std::string("aos all-in-focus image (") + MergeMethodName(method) +
                      ", float32 in the views' units)";
  WriteImage((temp / "all_in_focus.tif").string(), result.image, write);
  write.description = "aos depth map: camera z of the merged surface, metres; 0 = uncovered";
  WriteImage((temp / "depth.tif").string(), result.depth, write);
  write.description = "aos merge confidence in [0, 1]";
  WriteImage((temp / "confidence.tif").string(), result.confidence, write);
  write.description = "aos fractional slice index; -1 = uncovered";
  WriteImage((temp / "slice.tif").string(), result.slice, write);
  // Previews that open correctly in ordinary viewers (the float TIFFs open all white or black).
  Image covered(result.slice.width(), result.slice.height(), 1, PixelType::kU8);
  for (int y = 0; y < covered.height(); ++y) {
    for (int x = 0; x < covered.width(); ++x) {
      *covered.At<uint8_t>(x, y) = result.slice.At<float>(x, y)[0] >= 0.0f ? 1 : 0;
    }
  }
  PreviewRange image_range;
  const Image image_preview = StretchedPreview(result.image, &covered, 1.0, 99.0, &image_range);
  WriteImageOptions preview_write;
  preview_write.description = "aos all-in-focus preview: values " +
                              FormatNumber(image_range.lo) + ".." + FormatNumber(image_range.hi) +
                              " (1st..99th percentile) mapped to 0..255; uncovered pixels black";
  WriteImage((temp / "all_in_focus_preview.png").string(), image_preview, preview_write);
  const PreviewRange depth_range = PercentileRange(result.depth, &covered, 1.0, 99.0);
  preview_write.description = "aos depth preview (turbo colour map): blue = " +
                              FormatNumber(depth_range.lo) + " m, red = " +
                              FormatNumber(depth_range.hi) +
                              " m camera depth; uncovered pixels black";
  WriteImage((temp / "depth_preview.png").string(),
             ColourMappedPreview(result.depth, &covered, depth_range), preview_write);
  preview_write.description = "aos confidence preview: 0..1 mapped to 0..255";
  WriteImage((temp / "confidence_preview.png").string(),
             ColourMappedPreview(result.confidence, nullptr, PreviewRange{0.0, 1.0}),
             preview_write);
  folder.Commit();
  Say("wrote %s: all_in_focus.tif, depth.tif, confidence.tif, slice.tif and *_preview.png "
      "(depth preview %s..%s m) (%dx%d, %s; %lld pixels uncovered)\n",
      output_dir.c_str(), FormatNumber(depth_range.lo).c_str(),
      FormatNumber(depth_range.hi).c_str(), result.image.width(), result.image.height(),
      MergeMethodName(method), static_cast<long long>(result.uncovered_pixels));
}

struct StackCommand {
  IntegralCommand render;
  StackArgs planes;
  FocalStackOptions options;
  std::string output_dir;
};

void AddStack(CLI::App& app, StackCommand& c) {
  CLI::App* command = app.add_subcommand(
      "stack",
      "Render a focal stack: N slices between two boundary planes, written as a folder of "
      "float32 TIFFs with stack.json");
  AddRenderArgs(command, c.render, false);
  AddStackArgs(command, c.planes, c.options);
  command->add_flag("--variance", c.render.options.variance,
                    "Also write the per-pixel variance of the view samples (for --method robust)");
  command->add_option("-o,--output-dir", c.output_dir, "Output folder; must not exist or be empty")
      ->required();
}

int RunStack(StackCommand& c) {
  ProgressBar progress(g_quiet);
  CheckOutputFolder(c.output_dir);  // before any work
  const LoadResult loaded = LoadAndResolveCamera(c.render, progress);
  c.options.render = c.render.options;
  c.options.first_plane = ParsePlane(c.planes.first_plane, "--first-plane");
  c.options.last_plane = ParsePlane(c.planes.last_plane, "--last-plane");
  FocalStack stack;
  try {
    stack = RenderFocalStack(loaded.light_field, c.options, &progress);
  } catch (const std::invalid_argument& error) {
    RethrowNamingFlags(error, Concat({&kStackFlags, &kRenderFlags}));
  }
  progress.Finish();
  WriteFocalStack(c.output_dir, stack);
  Say("wrote %s: %d slices of %dx%d (stack.json, slice_*.tif, count_*.tif%s)\n",
              c.output_dir.c_str(), stack.size(), stack.camera.width, stack.camera.height,
              stack.variances.empty() ? "" : ", variance_*.tif");
  return 0;
}

struct MergeCommand {
  std::string stack_dir;
  std::string light_field_path;
  LoadOptions load;
  MergeArgs args;
  MergeOptions options;
  std::string output_dir;
};

void AddMerge(CLI::App& app, MergeCommand& c) {
  CLI::App* command = app.add_subcommand(
      "merge",
      "Merge a focal stack (from `stack`) into an all-in-focus image, a depth map and a "
      "confidence map");
  command->add_option("stack", c.stack_dir, "Stack folder (with stack.json)")->required();
  AddMergeArgs(command, c.args, c.options);
  command->add_option("--lightfield", c.light_field_path,
                      "The light field the stack was rendered from (needed by --method robust)");
  command->add_option("--frames-fov-deg", c.load.fov_deg,
                      "Horizontal field of view of the frames, degrees (JKU poses.json only)");
  command->add_option("--images-dir", c.load.images_dir,
                      "Folder of the frames (JKU poses.json; default: ../images beside it)");
  command->add_option("--threads", c.options.num_threads, "Worker threads; -1 = all cores")
      ->capture_default_str();
  command->add_option("-o,--output-dir", c.output_dir, "Output folder; must not exist or be empty")
      ->required();
  AddQuiet(command);
}

int RunMerge(MergeCommand& c) {
  ProgressBar progress(g_quiet);
  CheckOutputFolder(c.output_dir);  // before any work
  c.options.method = AsUsage([&] { return ParseMergeMethod(c.args.method, "--method"); });
  const FocalStack stack = ReadFocalStack(c.stack_dir);
  std::optional<LoadResult> loaded;
  if (!c.light_field_path.empty()) {
    c.load.num_threads = c.options.num_threads;
    try {
      loaded = LoadLightField(c.light_field_path, c.load, &progress);
    } catch (const std::invalid_argument& error) {
      RethrowNamingFlags(error, kLoadFlags);
    }
    progress.Finish();
  } else if (c.options.method == MergeMethod::kRobust) {
    ThrowUsage("--method robust: give --lightfield, the light field the stack was rendered "
                 "from (its rays are re-integrated)");
  }
  MergeResult result;
  try {
    result = MergeFocalStack(stack, c.options, loaded ? &loaded->light_field : nullptr, &progress);
  } catch (const std::invalid_argument& error) {
    RethrowNamingFlags(error, kMergeFlags);
  }
  progress.Finish();
  if (!g_quiet) std::fprintf(stderr, "merged %d slices (%s) in %.2f s%s\n", stack.size(),
               MergeMethodName(c.options.method), result.seconds_merge + result.seconds_render,
               c.options.method == MergeMethod::kRobust
                   ? (", " + std::to_string(result.fallback_pixels) +
                      " pixels kept the plain mean").c_str()
                   : "");
  WriteMergeResult(c.output_dir, result, c.options.method);
  return 0;
}

struct AllInFocusCommand {
  IntegralCommand render;
  StackArgs planes;
  MergeArgs args;
  AllInFocusOptions options;
  std::string output_dir;
};

void AddAllInFocus(CLI::App& app, AllInFocusCommand& c) {
  CLI::App* command = app.add_subcommand(
      "allinfocus",
      "One call: render the slices one at a time and merge them (memory does not grow with "
      "--slices) into an all-in-focus image, a depth map and a confidence map");
  AddRenderArgs(command, c.render, false);
  AddStackArgs(command, c.planes, c.options.stack);
  AddMergeArgs(command, c.args, c.options.merge);
  command->add_option("-o,--output-dir", c.output_dir, "Output folder; must not exist or be empty")
      ->required();
}

int RunAllInFocus(AllInFocusCommand& c) {
  ProgressBar progress(g_quiet);
  CheckOutputFolder(c.output_dir);  // before any work
  const LoadResult loaded = LoadAndResolveCamera(c.render, progress);
  c.options.stack.render = c.render.options;
  c.options.stack.first_plane = ParsePlane(c.planes.first_plane, "--first-plane");
  c.options.stack.last_plane = ParsePlane(c.planes.last_plane, "--last-plane");
  c.options.merge.method = AsUsage([&] { return ParseMergeMethod(c.args.method, "--method"); });
  c.options.merge.num_threads = c.render.options.num_threads;
  MergeResult result;
  try {
    result = RenderAllInFocus(loaded.light_field, c.options, &progress);
  } catch (const std::invalid_argument& error) {
    RethrowNamingFlags(error, Concat({&kMergeFlags, &kStackFlags, &kRenderFlags}));
  }
  progress.Finish();
  if (!g_quiet) std::fprintf(stderr, "%d slices rendered and merged (%s): render %.2f s, merge %.2f s\n",
               c.options.stack.slices, MergeMethodName(c.options.merge.method),
               result.seconds_render, result.seconds_merge);
  WriteMergeResult(c.output_dir, result, c.options.merge.method);
  return 0;
}

struct ResolutionCommand {
  int width = 0;
  int height = 0;
  double fov_deg = 0.0;
  std::string focal;      // FX,FY
  std::string principal;  // CX,CY
  std::string model = "pinhole";
  std::string distortion;
  double xi = 0.0;
  double skew = 0.0;
  ResolutionOptions options;
  bool json = false;
};

void AddResolution(CLI::App& app, ResolutionCommand& c) {
  CLI::App* command = app.add_subcommand(
      "resolution",
      "Spatial sampling resolution of a nadir camera over a focal plane (the AOS paper's Eq. 2 "
      "and Appendix A back-projection) and the effective resolution under a pose error");
  command->add_option("--width", c.width, "Image width, pixels")->required();
  command->add_option("--height", c.height, "Image height, pixels")->required();
  auto* fov = command->add_option("--lens-fov-deg,--fov-deg", c.fov_deg,
                                  "Horizontal field of view of the lens, degrees (square pixels, "
                                  "centred; --fov-deg is its old name)");
  auto* focal = command->add_option("--focal", c.focal, "Focal lengths FX,FY in pixels");
  fov->excludes(focal);
  command->add_option("--principal", c.principal,
                      "Principal point CX,CY (pixel centres at +0.5; default: image centre)");
  command->add_option("--model", c.model, "pinhole, radtan, fisheye or omnidir")
      ->capture_default_str();
  command->add_option("--distortion", c.distortion,
                      "Up to 5 coefficients: radtan k1,k2,p1,p2,k3; fisheye k1,k2,k3,k4; "
                      "omnidir k1,k2,p1,p2");
  command->add_option("--xi", c.xi, "omnidir: xi")->capture_default_str();
  command->add_option("--skew", c.skew, "omnidir: skew")->capture_default_str();
  command->add_option("--distance", c.options.distance_m,
                      "Distance to the focal plane (altitude above it), metres")
      ->capture_default_str();
  auto* error_px = command->add_option("--pose-error-px", c.options.pose_error_px,
                                       "Pose error, pixels");
  auto* error_m = command->add_option("--pose-error-m", c.options.pose_error_m,
                                      "Pose error at the focal plane, metres");
  error_px->excludes(error_m);
  command->add_option("--max-off-axis-deg", c.options.max_off_axis_deg,
                      "Back-projected figure over pixels within this angle of the axis, degrees")
      ->capture_default_str();
  command->add_flag("--json", c.json, "Print one JSON object");
  AddQuiet(command);
}

int RunResolution(const ResolutionCommand& c) {
  const LensModel model = AsUsage([&] { return ParseLensModel(c.model, "--model"); });
  std::array<double, 5> distortion{0, 0, 0, 0, 0};
  if (!c.distortion.empty()) {
    const std::vector<double> d = ParseNumbers(c.distortion, "--distortion");
    if (d.size() > 5) ThrowUsage("--distortion: at most 5 coefficients");
    std::copy(d.begin(), d.end(), distortion.begin());
  }
  LensCamera camera;
  if (!c.focal.empty()) {
    const std::vector<double> f = ParseNumbers(c.focal, "--focal", 2);
    camera.model = model;
    camera.width = c.width;
    camera.height = c.height;
    camera.fx = f[0];
    camera.fy = f[1];
    camera.cx = 0.5 * c.width;
    camera.cy = 0.5 * c.height;
    camera.distortion = distortion;
  } else if (c.fov_deg > 0.0) {
    // The field of view through the lens's own radial map (a fisheye's 180 degrees is fine).
    try {
      camera = LensFromFov(model, c.width, c.height, c.fov_deg, distortion, c.xi, "camera");
    } catch (const std::invalid_argument& error) {
      ThrowUsage(std::string(error.what()) + " [option --lens-fov-deg/--model/--distortion]");
    }
  } else {
    ThrowUsage("give --lens-fov-deg or --focal");
  }
  if (!c.principal.empty()) {
    const std::vector<double> p = ParseNumbers(c.principal, "--principal", 2);
    camera.cx = p[0];
    camera.cy = p[1];
  }
  camera.xi = c.xi;
  camera.skew = c.skew;
  ResolutionResult r;
  try {
    r = SamplingResolution(camera, c.options);
  } catch (const std::invalid_argument& error) {
    RethrowNamingFlags(error, {{"distance_m", "--distance"},
                               {"max_off_axis_deg", "--max-off-axis-deg"},
                               {"pose_error_px", "--pose-error-px"},
                               {"pose_error_m", "--pose-error-m"}});
  }
  if (c.json) {
    std::printf("{\"eq2_samples_per_m2\": %s, \"eq2_sample_size_m\": %s, \"samples_per_m2\": %s, "
                "\"sample_size_m\": %s, \"pixels_on_plane\": %lld, \"pixels_off_axis\": %lld, "
                "\"footprint_m2\": %s, "
                "\"pose_error_m\": %s, \"effective_sample_size_m\": %s, "
                "\"effective_samples_per_m2\": %s}\n",
                FormatNumber(r.eq2_samples_per_m2).c_str(), FormatNumber(r.eq2_sample_size_m).c_str(),
                FormatNumber(r.samples_per_m2).c_str(), FormatNumber(r.sample_size_m).c_str(),
                static_cast<long long>(r.pixels_on_plane), static_cast<long long>(r.pixels_off_axis),
                FormatNumber(r.footprint_m2).c_str(),
                FormatNumber(r.pose_error_m).c_str(), FormatNumber(r.effective_sample_size_m).c_str(),
                FormatNumber(r.effective_samples_per_m2).c_str());
    return 0;
  }
  std::printf("Eq. 2 (at nadir):        %.1f samples/m^2, sample size %.2f cm\n",
              r.eq2_samples_per_m2, 100.0 * r.eq2_sample_size_m);
  std::printf("back-projected (App. A): %.1f samples/m^2, sample size %.2f cm (%lld pixels within "
              "%s degrees of the axis over %.1f m^2",
              r.samples_per_m2, 100.0 * r.sample_size_m, static_cast<long long>(r.pixels_on_plane),
              FormatNumber(c.options.max_off_axis_deg).c_str(), r.footprint_m2);
  if (r.pixels_off_axis > 0) {
    std::printf("; %lld pixels further off the axis left out", static_cast<long long>(r.pixels_off_axis));
  }
  std::printf(")\n");
  std::printf("pose error %.2f cm: effective sample size p' = p + 2e = %.2f cm, %.1f samples/m^2\n",
              100.0 * r.pose_error_m, 100.0 * r.effective_sample_size_m, r.effective_samples_per_m2);
  return 0;
}

struct RectifyCommand {
  std::string camera_path;
  std::string light_field_path;
  std::vector<std::string> frames;
  RectifyOptions options;
  std::string output_dir;
};

void AddRectify(CLI::App& app, RectifyCommand& c) {
  CLI::App* command = app.add_subcommand(
      "rectify",
      "Resample raw frames taken through a lens model (a camera file) into perspective frames "
      "with a chosen field of view, size and orientation, in the input's bit depth");
  auto* frames = command->add_option("frames", c.frames, "Raw frames (with --camera)");
  auto* camera = command->add_option("--camera", c.camera_path,
                                     "Camera file (aos-camera JSON) of the lens");
  auto* light_field = command->add_option(
      "--lightfield", c.light_field_path,
      "Instead of frames + --camera: an aos light field whose views have lens cameras; writes "
      "DIR/lightfield.json pointing at the rectified frames, with pinhole cameras");
  light_field->excludes(frames)->excludes(camera);
  command->add_option("--rectified-fov-deg,--fov-deg", c.options.fov_deg,
                      "Horizontal field of view of the rectified frames, degrees (--fov-deg is "
                      "its old name)")
      ->capture_default_str();
  command->add_option("--width", c.options.width, "Output width, pixels (0 = the raw width)")
      ->capture_default_str();
  command->add_option("--height", c.options.height, "Output height, pixels (0 = the raw height)")
      ->capture_default_str();
  command->add_option("--yaw-deg", c.options.yaw_deg, "Turn about the lens's y axis, degrees")
      ->capture_default_str();
  command->add_option("--pitch-deg", c.options.pitch_deg, "Turn about the lens's x axis, degrees")
      ->capture_default_str();
  command->add_option("--roll-deg", c.options.roll_deg, "Turn about the optical axis, degrees")
      ->capture_default_str();
  command->add_option("-o,--output-dir", c.output_dir,
                      "Output folder (must not exist or be empty): the frames under their own "
                      "names, and camera.json (the rectified pinhole camera)")
      ->required();
  AddQuiet(command);
}

const std::vector<std::pair<std::string, std::string>> kRectifyFlags{
    {"fov_deg", "--rectified-fov-deg"},
    {"width/height", "--width/--height"},
    {"yaw_deg/pitch_deg/roll_deg", "--yaw-deg/--pitch-deg/--roll-deg"}};

// rectify --lightfield: every view with a lens model is rectified (one set of maps per distinct
// lens) and re-posed (cam_from_world of the rectified camera = R^T cam_from_world of the lens);
// pinhole views are kept as they are.
int RunRectifyLightField(const RectifyCommand& c, ProgressBar& progress) {
  PendingFolder folder(c.output_dir);
  LoadResult loaded = LoadLightField(c.light_field_path, LoadOptions{}, &progress);
  progress.Finish();
  RectifyLightFieldResult result;
  try {
    result = RectifyLightField(loaded.light_field, c.options, &progress);
  } catch (const std::invalid_argument& error) {
    RethrowNamingFlags(error, kRectifyFlags);
  }
  const LightField& light_field = result.light_field;
  const int rectified = result.rectified_views;
  bool float_views = false;
  for (const View& view : light_field.views) {
    float_views = float_views || view.image.type() == PixelType::kF32;
  }
  progress.Finish();
  WriteLightFieldOptions write;
  write.images_subdir = "views";
  write.image_extension = float_views ? ".tif" : ".png";
  WriteLightField((fs::path(folder.TempPath()) / "lightfield.json").string(), light_field, write);
  folder.Commit();
  Say("wrote %s: lightfield.json with %d rectified views (%s degrees) of %zu\n",
              c.output_dir.c_str(), rectified, FormatNumber(c.options.fov_deg).c_str(),
              light_field.views.size());
  return 0;
}

int RunRectify(const RectifyCommand& c) {
  ProgressBar progress(g_quiet);
  if (!c.light_field_path.empty()) return RunRectifyLightField(c, progress);
  if (c.frames.empty() || c.camera_path.empty()) {
    ThrowUsage("give raw frames and --camera, or --lightfield");
  }
  PendingFolder folder(c.output_dir);
  const LensCamera lens = ReadCameraFile(c.camera_path);
  Rectifier rectifier;
  try {
    rectifier = MakeRectifier(lens, c.options);
  } catch (const std::invalid_argument& error) {
    // A lens that cannot cover the view comes from the camera file: name it too (its values
    // may be what is wrong). Other errors name their flag.
    const std::string message = error.what();
    if (message.rfind("fov_deg: the lens does not cover", 0) == 0) {
      throw UsageError(message + " (the lens of " + c.camera_path +
                       ") [option --rectified-fov-deg]");
    }
    RethrowNamingFlags(error, kRectifyFlags);
  }
  std::set<std::string> names;
  for (const std::string& frame : c.frames) {
    const std::string name = fs::path(frame).filename().string();
    if (!names.insert(name).second) {
      ThrowInvalid(frame + ": another frame has the same name " + name +
                   " (outputs keep the frames' names)");
    }
  }
  ProgressStart(&progress, "rectify", static_cast<int64_t>(c.frames.size()));
  for (const std::string& frame : c.frames) {
    if (ProgressCancelled(&progress)) throw Cancelled();
    const Image raw = ReadImage(frame);
    if (raw.width() != lens.width || raw.height() != lens.height) {
      ThrowInvalid(frame + ": is " + std::to_string(raw.width()) + "x" +
                   std::to_string(raw.height()) + " but the camera (" + c.camera_path + ") is " +
                   std::to_string(lens.width) + "x" + std::to_string(lens.height));
    }
    const Image rectified = Rectify(rectifier, raw);
    WriteImageOptions write;
    write.description = "aos rectified frame (" + std::string(LensModelName(lens.model)) +
                        " -> pinhole, " + FormatNumber(c.options.fov_deg) + " degrees)";
    WriteImage((fs::path(folder.TempPath()) / fs::path(frame).filename()).string(), rectified,
               write);
    ProgressAdvance(&progress, 1);
  }
  progress.Finish();
  WriteCameraFile((fs::path(folder.TempPath()) / "camera.json").string(),
                  LensCamera::FromPinhole(rectifier.camera));
  folder.Commit();
  Say("wrote %s: %zu rectified frames (%dx%d, %s degrees) and camera.json\n",
              c.output_dir.c_str(), c.frames.size(), rectifier.camera.width,
              rectifier.camera.height, FormatNumber(c.options.fov_deg).c_str());
  return 0;
}

struct CalibrateCommand {
  std::vector<std::string> frames;
  std::string pattern = "9x6";
  std::string model = "radtan";
  CalibrateOptions options;
  std::string output;
};

void AddCalibrate(CLI::App& app, CalibrateCommand& c) {
  CLI::App* command = app.add_subcommand(
      "calibrate",
      "Calibrate a lens from checkerboard frames (OpenCV): write a camera file with the RMS "
      "reprojection error and the frames used; frames without the board are listed, not fatal");
  command->add_option("frames", c.frames, "Checkerboard frames")->required();
  command->add_option("--pattern", c.pattern, "Inner corners COLUMNSxROWS")->capture_default_str();
  command->add_option("--square-size", c.options.square_size_m, "Square side, metres")
      ->capture_default_str();
  command->add_option("--model", c.model, "pinhole, radtan, fisheye or omnidir")
      ->capture_default_str();
  command->add_option("-o,--output", c.output, "Camera file to write (JSON)")->required();
  AddQuiet(command);
  AddForce(command);
}

int RunCalibrate(CalibrateCommand& c) {
  ProgressBar progress(g_quiet);
  CheckOutputPath(c.output, c.frames, "output");
  RefuseExisting(c.output, "output");
  c.options.model = AsUsage([&] { return ParseLensModel(c.model, "--model"); });
  const size_t x = c.pattern.find('x');
  if (x == std::string::npos) ThrowUsage("--pattern: expected COLUMNSxROWS, e.g. 9x6");
  const auto count = [&](const std::string& text) {
    const double value = AsUsage([&] { return ParseNumberText(text, "--pattern"); });
    if (value != std::floor(value) || value < 2 || value > 1000) {
      ThrowUsage("--pattern: expected COLUMNSxROWS of whole numbers 2..1000, e.g. 9x6 (got '" +
                 c.pattern + "')");
    }
    return static_cast<int>(value);
  };
  c.options.pattern_columns = count(c.pattern.substr(0, x));
  c.options.pattern_rows = count(c.pattern.substr(x + 1));
  std::vector<Image> frames;
  for (const std::string& frame : c.frames) frames.push_back(ReadImage(frame));
  CalibrationResult result;
  try {
    result = Calibrate(frames, c.frames, c.options, &progress);
  } catch (const std::invalid_argument& error) {
    RethrowNamingFlags(error, {{"pattern", "--pattern"}, {"square_size_m", "--square-size"}});
  }
  progress.Finish();
  for (const std::string& name : result.frames_rejected) {
    std::fprintf(stderr, "warning: %s: board not found; frame not used\n", name.c_str());
  }
  WriteCameraFile(c.output, result.camera, CalibrationRecordJson(result, &c.options));
  Say("wrote %s: %s lens, RMS reprojection error %.3f px over %zu frames (%zu without the "
              "board)\n",
              c.output.c_str(), LensModelName(result.camera.model), result.rms_px,
              result.frames_used.size(), result.frames_rejected.size());
  return 0;
}

struct PosesCommand {
  std::string frames_dir;
  std::string output;
  PosesOptions options;
};

void AddPoses(CLI::App& app, PosesCommand& c) {
  CLI::App* command = app.add_subcommand(
      "poses",
      "Estimate the frames' poses with COLMAP (CPU, headless) and write a light field; "
      "optionally geo-referenced by known positions");
  command->add_option("frames", c.frames_dir, "Folder of frames (never modified)")->required();
  command->add_option("-o,--output", c.output, "Light-field file to write (JSON)")->required();
  command->add_option("--workspace", c.options.workspace,
                      "Keep COLMAP's workspace in this new folder (default: a temporary one)");
  command->add_option("--matcher", c.options.matcher, "sequential, spatial or exhaustive")
      ->capture_default_str();
  command->add_option("--overlap", c.options.sequential_overlap,
                      "Sequential matching: successors each frame is matched with")
      ->capture_default_str();
  command->add_option("--camera", c.options.camera_file,
                      "Known camera (aos-camera file from `calibrate`); default: self-calibration");
  command->add_option("--camera-model", c.options.camera_model,
                      "COLMAP model to self-calibrate")
      ->capture_default_str();
  command->add_option("--frames-fov-deg,--fov-deg", c.options.fov_deg,
                      "The frames' horizontal field of view: self-calibration's start and the "
                      "prior its result is checked against (0 = none; --fov-deg is its old "
                      "name)")
      ->capture_default_str();
  command->add_option("--max-focal-deviation", c.options.max_focal_deviation,
                      "Refuse a self-calibrated focal length further than this fraction from "
                      "the --frames-fov-deg prior's")
      ->capture_default_str();
  command->add_flag("--allow-implausible", c.options.allow_implausible,
                    "Keep implausible self-calibrated intrinsics (with a warning)");
  command->add_option("--positions", c.options.positions_file,
                      "CSV of camera positions, columns by header name: name,x,y,z (metres, e.g. "
                      "UTM) or name,lat,lon,alt (degrees, projected with PROJ): geo-reference, "
                      "and priors for spatial matching");
  command->add_option("--positions-crs", c.options.positions_crs,
                      "CRS of the --positions coordinates (e.g. EPSG:4326, EPSG:25833)");
  command->add_flag("--positions-from-exif", c.options.exif_positions,
                    "Positions from the frames' EXIF GPS tags (projected to UTM) instead");
  command->add_option("--max-image-size", c.options.max_image_size,
                      "Features on frames downscaled to this longest side")
      ->capture_default_str();
  command->add_option("--max-features", c.options.max_num_features, "Features per frame")
      ->capture_default_str();
  command->add_option("--min-registered", c.options.min_registered_fraction,
                      "Fail below this fraction of frames registered")
      ->capture_default_str();
  command->add_option("--colmap", c.options.colmap, "COLMAP executable")->capture_default_str();
  command->add_option("--threads", c.options.num_threads, "COLMAP's threads; -1 = all cores")
      ->capture_default_str();
  AddQuiet(command);
  AddForce(command);
}

// Warnings, then the light field and what the user needs to judge the poses.
void ReportPoses(const PosesResult& result, const std::string& output) {
  for (const std::string& warning : result.warnings) {
    std::fprintf(stderr, "warning: %s\n", warning.c_str());
  }
  Say("wrote %s: %zu of %zu frames registered, %zu points, mean reprojection error "
              "%.3f px\n",
              output.c_str(), result.registered.size(), result.frames.size(), result.points,
              result.mean_reprojection_error_px);
  const char* unit = result.georeferenced ? " m" : " (model units: not geo-referenced)";
  if (result.georeferenced) {
    Say("geo-referenced by %d positions (%s): RMS %.3f m; origin %.3f %.3f %.3f\n",
                result.georeference_frames, result.world_frame.c_str(), result.georeference_rms_m,
                result.light_field.origin.x, result.light_field.origin.y,
                result.light_field.origin.z);
  }
  Say("pose error e = %.4g%s at the median depth %.4g%s\n", result.pose_error, unit,
              result.median_depth, unit);
  if (result.georeferenced && !result.light_field.views.empty() && result.median_depth > 0.0) {
    ResolutionOptions resolution;
    resolution.distance_m = result.median_depth;
    resolution.pose_error_m = result.pose_error;
    const ResolutionResult r = SamplingResolution(result.light_field.views[0].lens, resolution);
    Say("sampling at that depth: p = %.2f cm, p' = p + 2e = %.2f cm (%.1f samples/m^2)\n",
                100.0 * r.sample_size_m, 100.0 * r.effective_sample_size_m,
                r.effective_samples_per_m2);
  }
  for (const auto& stage : result.stages) {
    Say("  %-9s %7.1f s\n", stage.name.c_str(), stage.seconds);
  }
  if (!result.workspace.empty()) Say("COLMAP workspace kept in %s\n", result.workspace.c_str());
}

const std::vector<std::pair<std::string, std::string>> kPosesFlags = {
    {"matcher", "--matcher"},
    {"sequential_overlap", "--overlap"},
    {"camera_model", "--camera-model"},
    {"fov_deg", "--frames-fov-deg"},
    {"max_image_size", "--max-image-size"},
    {"max_num_features", "--max-features"},
    {"min_registered_fraction", "--min-registered"},
    {"num_threads", "--threads"},
    {"colmap", "--colmap"},
    {"positions_file/exif_positions", "--positions/--positions-from-exif"},
    {"positions_crs", "--positions-crs"},
    {"max_focal_deviation", "--max-focal-deviation"}};

int RunPoses(PosesCommand& c) {
  ProgressBar progress(g_quiet);
  // The frames folder (every file in it), the camera and the positions are inputs.
  CheckOutputPath(c.output, {c.frames_dir, c.options.camera_file, c.options.positions_file},
                  "output");
  RefuseExisting(c.output, "output");
  PosesResult result;
  try {
    result = EstimatePoses(c.frames_dir, c.options, &progress);
  } catch (const std::invalid_argument& error) {
    RethrowNamingFlags(error, kPosesFlags);
  }
  progress.Finish();
  WriteLightField(c.output, result.light_field);
  ReportPoses(result, c.output);
  return 0;
}

struct ImportColmapCommand {
  std::string model_dir;
  std::string frames_dir;
  std::string output;
  PosesOptions options;
};

void AddImportColmap(CLI::App& app, ImportColmapCommand& c) {
  CLI::App* command = app.add_subcommand(
      "import-colmap",
      "Import a COLMAP sparse model (text or binary) as a light field; optionally "
      "geo-referenced by known positions");
  command->add_option("model", c.model_dir, "COLMAP model folder (e.g. sparse/0)")->required();
  command->add_option("--images-dir,--images", c.frames_dir,
                      "The frames folder COLMAP was given (--images is its old name)")
      ->required();
  command->add_option("-o,--output", c.output, "Light-field file to write (JSON)")->required();
  command->add_option("--positions", c.options.positions_file,
                      "CSV of camera positions, columns by header name: name,x,y,z (metres) or "
                      "name,lat,lon,alt (degrees, projected with PROJ): geo-reference");
  command->add_option("--positions-crs", c.options.positions_crs,
                      "CRS of the --positions coordinates (e.g. EPSG:4326, EPSG:25833)");
  command->add_flag("--positions-from-exif", c.options.exif_positions,
                    "Positions from the frames' EXIF GPS tags (projected to UTM) instead");
  command->add_option("--min-registered", c.options.min_registered_fraction,
                      "Fail below this fraction of frames registered")
      ->capture_default_str();
  AddQuiet(command);
  AddForce(command);
}

int RunImportColmap(ImportColmapCommand& c) {
  // The model folder (cameras, images, points3D), the frames folder and the positions are inputs.
  const std::vector<std::string> inputs{c.model_dir, c.frames_dir, c.options.positions_file};
  CheckOutputPath(c.output, inputs, "output");
  RefuseExisting(c.output, "output");
  PosesResult result;
  try {
    result = ImportColmapPoses(c.model_dir, c.frames_dir, c.options);
  } catch (const std::invalid_argument& error) {
    RethrowNamingFlags(error, kPosesFlags);
  }
  CheckOutputPath(c.output, inputs, "output");  // again: the model may have changed meanwhile
  WriteLightField(c.output, result.light_field);
  ReportPoses(result, c.output);
  return 0;
}

struct MetricsCommand {
  std::string test_path;
  std::string reference_path;
  std::string mask_path;
  QualityOptions options;
  bool json = false;
};

void AddMetrics(CLI::App& app, MetricsCommand& c) {
  CLI::App* command = app.add_subcommand(
      "metrics", "Compare an image with a reference: MSE, PSNR, SSIM and colour (quaternion) "
                 "SSIM (definitions in docs/metrics.md)");
  command->add_option("test", c.test_path, "Image to assess")->required();
  command->add_option("reference", c.reference_path, "Reference image (ground truth)")->required();
  command->add_option("--mask", c.mask_path,
                      "Only pixels where this image (e.g. a count map) is non-zero");
  command->add_option("--data-range", c.options.data_range,
                      "Peak value range L; 0 = from the reference's type (8-bit 255, 16-bit "
                      "65535, float 1)")
      ->capture_default_str();
  command->add_option("--gaussian-sigma", c.options.gaussian_sigma, "SSIM window sigma, pixels")
      ->capture_default_str();
  command->add_option("--ssim-window-radius,--window-radius", c.options.window_radius,
                      "SSIM window radius, pixels (--window-radius is its old name)")
      ->capture_default_str();
  command->add_option("--k1", c.options.k1, "SSIM constant k1")->capture_default_str();
  command->add_option("--k2", c.options.k2, "SSIM constant k2")->capture_default_str();
  command->add_flag("--json", c.json, "Print one JSON object instead of a line of text");
  AddQuiet(command);
}

int RunMetrics(const MetricsCommand& c) {
  const Image test = ReadImage(c.test_path);
  const Image reference = ReadImage(c.reference_path);
  std::optional<Image> mask;
  if (!c.mask_path.empty()) mask = ReadImage(c.mask_path);
  QualityResult r;
  try {
    r = CompareImages(test, reference, mask ? &*mask : nullptr, c.options);
  } catch (const std::invalid_argument& error) {
    // Name the files: "compare: the test image is ..." does not say which ones.
    const std::string message = error.what();
    if (message.rfind("compare: ", 0) == 0) {
      ThrowInvalid(c.test_path + " against " + c.reference_path +
                   (c.mask_path.empty() ? std::string() : " (mask " + c.mask_path + ")") + ": " +
                   message.substr(9));
    }
    RethrowNamingFlags(error, {{"data_range", "--data-range"},
                               {"gaussian_sigma", "--gaussian-sigma"},
                               {"window_radius", "--ssim-window-radius"},
                               {"k1/k2", "--k1/--k2"}});
  }
  auto number = [](double value) {
    return std::isfinite(value) ? FormatNumber(value) : std::string(value > 0 ? "inf" : "nan");
  };
  if (!r.note.empty()) std::fprintf(stderr, "note: %s\n", r.note.c_str());
  if (c.json) {
    std::printf("{\"mse\": %s, \"psnr_db\": %s, \"ssim\": %s, \"color_ssim\": %s, "
                "\"data_range\": %s, \"mse_pixels\": %lld, \"ssim_pixels\": %lld}\n",
                number(r.mse).c_str(),
                std::isfinite(r.psnr_db) ? number(r.psnr_db).c_str() : "null",
                number(r.ssim).c_str(), number(r.color_ssim).c_str(), number(r.data_range).c_str(),
                static_cast<long long>(r.mse_pixels), static_cast<long long>(r.ssim_pixels));
  } else {
    char psnr[32];
    std::snprintf(psnr, sizeof(psnr), "%.2f", r.psnr_db);
    std::printf("PSNR %s dB  SSIM %.4f  colour SSIM %.4f  (MSE %s over %lld pixels, SSIM over "
                "%lld, L = %s)\n",
                std::isfinite(r.psnr_db) ? psnr : "inf", r.ssim, r.color_ssim, number(r.mse).c_str(),
                static_cast<long long>(r.mse_pixels), static_cast<long long>(r.ssim_pixels),
                number(r.data_range).c_str());
  }
  return 0;
}

}  // namespace
}  // namespace aos::cli

int main(int argc, char** argv) {
  using namespace aos::cli;
  CLI::App app{"aos-render: Airborne Optical Sectioning - integral images from drone light fields"};
  app.set_version_flag("--version", std::string("aos-render ") + aos::kVersion);
  app.require_subcommand(1);
  IntegralCommand integral;
  SimulateCommand simulate;
  DemoCommand demo;
  MetricsCommand metrics;
  StackCommand stack;
  MergeCommand merge;
  AllInFocusCommand all_in_focus;
  ResolutionCommand resolution;
  RectifyCommand rectify;
  CalibrateCommand calibrate;
  PosesCommand poses;
  ImportColmapCommand import_colmap;
  AddIntegral(app, integral);
  AddCalibrate(app, calibrate);
  AddPoses(app, poses);
  AddImportColmap(app, import_colmap);
  AddRectify(app, rectify);
  AddResolution(app, resolution);
  AddStack(app, stack);
  AddMerge(app, merge);
  AddAllInFocus(app, all_in_focus);
  AddSimulate(app, simulate);
  AddDemo(app, demo);
  AddMetrics(app, metrics);
  // First of all, so that a signal is never lost, whatever stage the command is in.
  InstallInterruptHandler();
  WarnDeprecatedSpellings(argc, argv);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& error) {
    // --help and --version end here with code 0; every command-line mistake exits with 2.
    const int code = app.exit(error);
    return code == 0 ? 0 : 2;
  }
  try {
    if (app.got_subcommand("integral")) return RunIntegral(integral);
    if (app.got_subcommand("stack")) return RunStack(stack);
    if (app.got_subcommand("resolution")) return RunResolution(resolution);
    if (app.got_subcommand("rectify")) return RunRectify(rectify);
    if (app.got_subcommand("calibrate")) return RunCalibrate(calibrate);
    if (app.got_subcommand("poses")) return RunPoses(poses);
    if (app.got_subcommand("import-colmap")) return RunImportColmap(import_colmap);
    if (app.got_subcommand("merge")) return RunMerge(merge);
    if (app.got_subcommand("allinfocus")) return RunAllInFocus(all_in_focus);
    if (app.got_subcommand("simulate")) return RunSimulate(simulate);
    if (app.got_subcommand("demo")) return RunDemo(demo);
    if (app.got_subcommand("metrics")) return RunMetrics(metrics);
  } catch (const aos::Cancelled&) {
    std::fprintf(stderr, "aos-render: interrupted; no output written\n");
    return 130;
  } catch (const UsageError& error) {
    std::fprintf(stderr, "aos-render: error: %s\n", error.what());
    return 2;
  } catch (const std::exception& error) {
    // One line, naming the user's paths (also for errors that did not come through ThrowInvalid).
    std::fprintf(stderr, "aos-render: error: %s\n",
                 aos::OneLine(aos::UserPaths(error.what())).c_str());
    return Interrupted() ? 130 : 1;
  }
  return 2;
}
