// Rendering commands: integral, stack, merge, allinfocus, map, detect, and view (the browser viewer).
#include <algorithm>
#include <map>
#include <set>
#include <thread>
#include <array>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <functional>
#include <limits>
#include <memory>
#include <optional>

#include <fcntl.h>
#include <sys/wait.h>
#include <csignal>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>

#include <nlohmann/json.hpp>

#include "aos/detect/detect.h"
#include "aos/image/image_io.h"
#include "aos/image/preview.h"
#include "aos/lightfield/formats.h"
#include "aos/lightfield/options_json.h"
#include "aos/render/focal_surface_json.h"
#include "aos/viewer/viewer_options.h"
#include "aos/render/focal_stack.h"
#include "aos/render/integral.h"
#include "aos/render/map.h"
#include "aos/render/merge.h"
#include "aos/sfm/ground.h"
#include "aos/util/file_util.h"
#include "commands.h"
#include "progress_bar.h"
#include "render_flags.h"
#include "render_output.h"

namespace fs = std::filesystem;

namespace aos::cli {

// What --view-indices takes on the command line.
constexpr const char* kViewListHelp =
    " On the command line indices and half-open ranges, e.g. 0:100,150 (default: all).";

void AddLoadFlags(const Flags& flags, LoadOptions& load) {
  Flags loader = flags.At("load.");
  loader.Field(load, "fov_deg");
  loader.Field(load, "images_dir");
  AddGreyFlag(loader, load);
  auto* mask = loader.Field(load, "mask");
  auto* mask_dir = loader.Field(load, "mask_dir");
  mask->excludes(mask_dir);
  flags.InputFolder("--images-dir");
  flags.Input("--mask");
  flags.InputFolder("--mask-dir");
}

namespace {

// `render` binds the IntegralOptions fields (nested for stack and allinfocus).
void AddRenderFlags(Flags& render, RenderArgs& args, IntegralOptions& options) {
  render.command()
      ->add_option("lightfield", args.light_field_path,
                   "Light-field file: aos JSON, or a JKU-ICG/AOS poses.json")
      ->required();
  render.Input("lightfield");
  AddLoadFlags(render, args.load);
  // No default printed: none means --look-at/--cam-from-world (the viewer: the middle view).
  auto* pose_view = render.NoDefault(render.Field(
      options, "pose_view", [&args](const std::string& text) { args.pose_view = text; },
      " On the command line also the view named NAME (its frame name, with or without the "
      "extension; case is ignored if nothing matches exactly)."));
  auto* pose = render.Field(
      options, "cam_from_world", [&args](const std::string& text) { args.cam_from_world = text; },
      " On the command line 12 numbers: the 3x4 matrix [R|t] row by row.");
  render.Shorthand("cam_from_world", "--look-at");
  auto* look_at = render.command()->add_option(
      "--look-at", args.look_at,
      "Virtual camera at EX,EY,EZ looking at TX,TY,TZ (optional up UX,UY,UZ; default 0,0,1, or "
      "0,1,0 looking straight down or up): sets --cam-from-world");
  pose_view->excludes(look_at)->excludes(pose);
  look_at->excludes(pose);
  render.Field(options, "fov_deg");
  render.Field(options, "width");
  render.Field(options, "height");
  render.Field(options, "aperture_radius");
  render.Field(options, "view_indices", [&args](const std::string& text) { args.views = text; },
               kViewListHelp);
  render.Field(options, "min_view_angle_deg");
  render.Field(options, "lens_tolerance_px");
  render.Threads(options);
}

// --focal-surface's text: a height H or PX,PY,PZ,NX,NY,NZ is that plane (at once); anything else
// is a mesh or DEM file, kept in `path` and read by ReadFocalSurface before the frames.
// A stack (`planes` false) takes a terrain file only: its planes are --first-plane/--last-plane.
std::function<void(const std::string&)> TakeFocalSurface(FocalSurface* surface, std::string* path,
                                                         bool planes = true) {
  return [surface, path, planes](const std::string& text) {
    std::vector<double> numbers;
    try {
      numbers = ParseNumbers(text, "--focal-surface");
    } catch (const std::invalid_argument&) {
    }
    if ((numbers.size() == 1 || numbers.size() == 6) && !planes) {
      ThrowUsage("--focal-surface: a stack follows a terrain file (a mesh or a DEM); its planes "
                 "are --first-plane/--last-plane (a file named like a number: ./" + text + ")");
    }
    if (numbers.size() == 1 || numbers.size() == 6) {
      *surface = FocalSurface::FromPlane(ParsePlane(text, "--focal-surface"));
      path->clear();
    } else {
      *path = text;
    }
  };
}

constexpr const char* kFocalSurfaceHelp =
    " On the command line a height H (the horizontal plane z = H), a plane PX,PY,PZ,NX,NY,NZ, or "
    "a file: an OBJ or PLY mesh or a DEM raster GDAL reads (GeoTIFF...), in world coordinates "
    "(light field origin + local; a file named like a number: ./12.5).";

}  // namespace

// --focal-height H: focal_surface as the horizontal plane z = H.
CLI::Option* AddFocalHeightFlag(Flags& flags, FocalSurface& focal_surface, const char* help) {
  return flags.Shorthand(
      "focal_surface", "--focal-height", focal_surface,
      [](const std::string& text) {
        return FocalSurface::FromPlane(Plane::AtHeight(ParseNumberText(text, "--focal-height")));
      },
      help);
}

// The detector's flags (DetectOptions under "detect.", detect and live): the scores and the
// threshold first in --help, then --force, then the rest of the table.
void AddDetectFlags(Flags& flags, DetectOptions& detect) {
  Flags scoring = flags.At("detect.");
  for (const char* name : {"detector", "channels", "one_sided", "quantile", "false_alarm_rate",
                           "min_score", "robust_sigmas", "min_temperature_c"}) {
    scoring.Field(detect, name);
  }
  flags.Force();
  scoring.Remaining(detect);
}

// The viewer server's flags (ViewerOptions under "viewer.", view and live --view): host, port,
// max_pages, open_browser and --no-browser; returns open_browser's option.
CLI::Option* AddViewerFlags(Flags& flags, ViewerOptions& viewer, bool& no_browser) {
  Flags served = flags.At("viewer.");
  served.Field(viewer, "host");
  served.Field(viewer, "port");
  served.Field(viewer, "max_pages");
  CLI::Option* open_browser = served.Field(viewer, "open_browser");
  served.Shorthand("open_browser", "--no-browser");
  CLI::Option* none = flags.command()->add_flag(
      "--no-browser", no_browser, "Do not open a browser: sets --open-browser false");
  none->excludes(open_browser);
  return open_browser;
}

namespace {

// --focal-surface (IntegralOptions::focal_surface), with a command's `note` on it.
CLI::Option* AddFocalSurfaceFlag(Flags& render, RenderArgs& args, IntegralOptions& options,
                                 const char* note, bool planes = true) {
  render.Field(options, "focal_surface",
               TakeFocalSurface(&options.focal_surface, &args.focal_surface, planes),
               std::string(kFocalSurfaceHelp) + " " + note);
  return render.Input("--focal-surface");
}

}  // namespace

// --focal-surface and --surface-offset (IntegralOptions::focal_surface, surface_offset).
CLI::Option* AddSurfaceFlags(Flags& render, RenderArgs& args, IntegralOptions& options) {
  CLI::Option* surface = AddFocalSurfaceFlag(
      render, args, options, "Pixels whose rays miss a terrain are uncovered.");
  render.Field(options, "surface_offset");
  return surface;
}

// --focal-surface FILE: the mesh or DEM read into `surface` (left as it is when no file is
// given), before the frames so that a bad file fails first; described on stderr.
void ReadFocalSurface(const std::string& path, FocalSurface* surface) {
  if (path.empty()) return;
  *surface = FocalSurface::Read(path);
  if (!Common().quiet && !Common().json) {
    std::fprintf(stderr, "focal surface: %s\n", surface->Describe().c_str());
  }
}

namespace {

// --pose-view: a view's index or its name (FindViewByName). Digits are both an index and a
// possible name (frames are often called 0042.png): the one that exists is taken; if the index
// and a view so named are different views, it is refused as ambiguous.
int ResolvePoseView(const std::string& text, const LightField& light_field) {
  const auto all_digits = [](auto begin, auto end) {
    return begin != end &&
           std::all_of(begin, end, [](unsigned char c) { return std::isdigit(c) != 0; });
  };
  if (text.size() > 1 && text[0] == '-' && all_digits(text.begin() + 1, text.end())) {
    ThrowUsage("--pose-view: a view index is >= 0 (got " + text + ")");
  }
  if (!all_digits(text.begin(), text.end())) {
    return AsUsage([&] { return FindViewByName(light_field, text, "--pose-view"); });
  }
  const int view_count = static_cast<int>(light_field.views.size());
  const int index = text.size() > 9 ? -1 : std::stoi(text);
  const bool index_valid = index >= 0 && index < view_count;
  int named = -1;
  std::string name_error;
  try {
    named = FindViewByName(light_field, text, "--pose-view");
  } catch (const std::invalid_argument& error) {
    name_error = error.what();
  }
  if (named < 0) {
    if (index_valid) return index;
    ThrowUsage("--pose-view: no view " + text + " (the light field has " +
               std::to_string(view_count) + " views), and " +
               name_error.substr(std::string("--pose-view: ").size()));
  }
  if (!index_valid || named == index) return named;
  ThrowUsage("--pose-view: " + text + " is ambiguous: view " + std::to_string(index) +
             " by index, or " +
             ViewNameAndFile(light_field.views[static_cast<size_t>(named)], named) +
             " by name; give that name with its extension");
}

// The light field's poses and cameras without its frames (LoadOptions::load_images false):
// what flags naming views are checked against before the frames are decoded.
LightField PosesOnly(const std::string& light_field_path, LoadOptions load, const Flags& flags) {
  load.load_images = false;
  return flags.At("load.").NamingFlags(
      [&] { return LoadLightField(light_field_path, load, nullptr); }).light_field;
}


// Loads the light field and fills `options`' virtual camera (pose, views) from the command
// line; the focal plane is left to the caller. Everything that needs no light field is checked
// first, so that a bad flag is refused before a frame is decoded (F0's 382 frames take about
// 0.5-1 s to decode; a bad --aperture-radius used to be refused only after that): the focal
// surface file, the virtual camera given by numbers, the loader's options, and `check` (the
// command's Options::Check on one placeholder view; the views and the pose view are checked
// again against the loaded light field).
LoadResult LoadAndResolveCamera(RenderArgs& args, IntegralOptions& options, const Flags& flags,
                                ProgressBar& progress, const std::function<void(int)>& check) {
  args.load.num_threads = options.num_threads;
  ReadFocalSurface(args.focal_surface, &options.focal_surface);
  if (!args.look_at.empty()) {
    const std::vector<double> v = ParseNumbers(args.look_at, "--look-at");
    if (v.size() != 6 && v.size() != 9) ThrowUsage("--look-at: expected 6 or 9 numbers");
    const Vec3d eye(v[0], v[1], v[2]), target(v[3], v[4], v[5]);
    options.cam_from_world = AsUsage([&] {
      return v.size() == 9 ? LookAt(eye, target, Vec3d(v[6], v[7], v[8])) : LookAt(eye, target);
    });
  } else if (!args.cam_from_world.empty()) {
    const std::vector<double> v = ParseNumbers(args.cam_from_world, "--cam-from-world", 12);
    std::array<double, 12> m{};
    std::copy(v.begin(), v.end(), m.begin());
    options.cam_from_world = Rigid3d::FromMatrix3x4(m);
  } else if (args.pose_view.empty() && options.pose_view < 0) {
    ThrowUsage("no virtual camera pose: give --pose-view, --look-at or --cam-from-world");
  }
  flags.At("load.").NamingFlags([&] { args.load.Check(); });
  flags.NamingFlags([&] { check(1); });
  if (!args.views.empty() || !args.pose_view.empty()) {
    // The flags that name views, against the poses alone (no frame decoded yet).
    const LightField poses = PosesOnly(args.light_field_path, args.load, flags);
    if (!args.pose_view.empty()) ResolvePoseView(args.pose_view, poses);
    if (!args.views.empty()) ParseViewList(args.views, static_cast<int>(poses.views.size()));
  }
  LoadResult loaded = flags.At("load.").NamingFlags(
      [&] { return LoadLightField(args.light_field_path, args.load, &progress); });
  progress.Finish();
  for (const std::string& note : loaded.notes) Note(note);
  // The surface in the light field's CRS (a DEM in another CRS transformed through PROJ).
  options.focal_surface = InCrs(options.focal_surface, loaded.light_field.crs);
  if (!args.pose_view.empty()) options.pose_view = ResolvePoseView(args.pose_view, loaded.light_field);
  if (!args.views.empty()) {
    options.view_indices =
        ParseViewList(args.views, static_cast<int>(loaded.light_field.views.size()));
  }
  return loaded;
}

std::vector<std::string> InputsOf(const std::string& light_field_path,
                                  const LightField& light_field) {
  std::vector<std::string> inputs{light_field_path};
  for (const View& view : light_field.views) inputs.push_back(view.image_path);
  return inputs;
}

// ---- integral ----

struct IntegralCommand {
  RenderArgs args;
  IntegralOptions options;
  double focal_distance = 0.0;
  bool horizontal = false;
  RenderOutput out;
};

// The focus flags of integral and detect: --focal-surface FILE, --focal-height, --focal-plane,
// --focal-distance [--horizontal], one of them.
void AddFocusFlags(Flags& flags, RenderArgs& args, IntegralOptions& options,
                   double* focal_distance, bool* horizontal_plane) {
  CLI::App* command = flags.command();
  // Errors about focal_surface name all its flags (the first description of a field wins).
  CLI::Option* surface = AddSurfaceFlags(flags, args, options);
  CLI::Option* height = AddFocalHeightFlag(flags, options.focal_surface,
                                           "Horizontal focal plane z = H (local frame, metres)");
  auto* plane = flags.Shorthand(
      "focal_surface", "--focal-plane", options.focal_surface,
      [](const std::string& text) {
        const std::vector<double> v = ParseNumbers(text, "--focal-plane", 6);
        return FocalSurface::FromPlane(Plane{Vec3d(v[0], v[1], v[2]), Vec3d(v[3], v[4], v[5])});
      },
      "Focal plane through PX,PY,PZ with normal NX,NY,NZ");
  flags.Shorthand("focal_surface", "--focal-distance");
  auto* distance = command->add_option(
      "--focal-distance", *focal_distance,
      "Focal plane D metres in front of the virtual camera, perpendicular to its axis (e.g. 35 "
      "for 'focus 35 m below the drone')");
  auto* horizontal = command->add_flag("--horizontal", *horizontal_plane,
                                       "With --focal-distance: the horizontal plane through that "
                                       "point instead");
  height->excludes(plane)->excludes(distance)->excludes(surface);
  plane->excludes(distance)->excludes(surface);
  distance->excludes(surface);
  horizontal->needs(distance);
}

// --focal-distance D [--horizontal] as the focal surface, once the light field is loaded.
void ApplyFocalDistance(const LightField& light_field, double focal_distance, bool horizontal,
                        IntegralOptions& options, const Flags& flags) {
  if (focal_distance == 0.0) return;
  const Rigid3d cam_from_world =
      flags.NamingFlags([&] { return VirtualCamFromWorld(light_field, options); });
  options.focal_surface = AsUsage([&] {
    return FocalSurface::FromPlane(Plane::InFrontOf(cam_from_world, focal_distance, horizontal));
  });
}

int RunIntegral(IntegralCommand& c, const Flags& flags) {
  ProgressBar progress(Common().quiet);
  // Refuse bad outputs (an input, a missing folder, a format that cannot hold the samples)
  // before spending time on loading; the frames are checked again once known.
  CheckRenderOutput(c.out, {c.args.light_field_path});
  const LoadResult loaded = LoadAndResolveCamera(c.args, c.options, flags, progress,
                                                 [&](int views) { c.options.Check(views); });
  const LightField& light_field = loaded.light_field;
  ApplyFocalDistance(light_field, c.focal_distance, c.horizontal, c.options, flags);
  std::vector<std::string> inputs = InputsOf(c.args.light_field_path, light_field);
  if (!c.args.focal_surface.empty()) inputs.push_back(c.args.focal_surface);
  CheckRenderOutput(c.out, inputs);
  const IntegralResult result =
      flags.NamingFlags([&] { return RenderIntegral(light_field, c.options, &progress); });
  progress.Finish();
  const long long pixels = static_cast<long long>(result.image.width()) * result.image.height();
  // Nothing written: an all-empty image is no render (the map refuses the same).
  CheckSurfaceCovers(c.options.focal_surface, light_field, "the virtual camera's view",
                     result.uncovered_pixels, pixels);
  if (!c.args.focal_surface.empty() && result.uncovered_pixels > 0) {
    Warn(c.args.focal_surface + ": " +
         FormatNumber(100.0 * static_cast<double>(result.uncovered_pixels) / pixels) +
         "% of the pixels are uncovered (count 0): their rays miss the surface (beyond its "
         "extent, nodata holes) or no view sees them");
  }
  if (!Common().quiet && !Common().json) {
    std::fprintf(stderr,
                 "integrated %d of %d selected views: %lld samples, %lld of %lld pixels "
                 "uncovered\n",
                 result.views_used, result.views_selected, static_cast<long long>(result.samples),
                 static_cast<long long>(result.uncovered_pixels),
                 static_cast<long long>(result.image.width()) * result.image.height());
  }
  Report report("integral");
  report.Set("views_used", result.views_used);
  report.Set("views_selected", result.views_selected);
  report.Set("samples", static_cast<long long>(result.samples));
  report.Set("uncovered_pixels", static_cast<long long>(result.uncovered_pixels));
  WriteRenderOutput(result, c.out, light_field.views.front().image.type(), inputs, report,
                    light_field.radiometry);
  report.Print();
  return 0;
}

}  // namespace

CommandRunner DefineIntegral(CLI::App* command) {
  auto c = std::make_shared<IntegralCommand>();
  Flags flags(command);
  AddRenderFlags(flags, c->args, c->options);
  AddFocusFlags(flags, c->args, c->options, &c->focal_distance, &c->horizontal);
  AddRenderOutputFlags(flags, c->out);
  flags.Force();
  // Every other field of the tables (tools/vocabulary.py NOT_ON_THE_CLI: why not those).
  flags.Remaining(c->options, {"variance"});
  return [c, flags] { return RunIntegral(*c, flags); };
}

// ---- detect ----

namespace {

struct DetectCommand {
  RenderArgs args;
  IntegralOptions options;
  double focal_distance = 0.0;
  bool horizontal = false;
  DetectOptions detect;
  std::string geojson, kml, csv, overlay, scores;
};

int RunDetect(DetectCommand& c, const Flags& flags) {
  const std::vector<std::pair<std::string, const char*>> outputs{
      {c.geojson, "geojson"}, {c.kml, "kml"}, {c.csv, "csv"}, {c.overlay, "overlay"},
      {c.scores, "scores"}};
  if (c.geojson.empty() && c.kml.empty() && c.csv.empty() && c.overlay.empty() &&
      c.scores.empty()) {
    ThrowUsage("--geojson, --kml, --csv, --overlay, --scores: give at least one output");
  }
  flags.NamingFlags([&] { c.detect.Check(); });
  const auto check_outputs = [&](const std::vector<std::string>& inputs) {
    for (const auto& [path, what] : outputs) {
      if (path.empty()) continue;
      CheckOutputPath(path, inputs, what);
      RefuseExisting(path, what);
    }
    if (!c.overlay.empty()) {
      ResolveSampleType(c.overlay, Image(1, 1, 3, PixelType::kU8), WriteImageOptions{});
    }
    if (!c.scores.empty()) {
      WriteImageOptions write;
      write.sample_type = SampleType::kF32;
      ResolveSampleType(c.scores, Image(1, 1, 1, PixelType::kF32), write);
    }
  };
  check_outputs({c.args.light_field_path});
  for (const std::string* path : {&c.geojson, &c.kml, &c.csv}) {
    if (!path->empty()) CheckDetectionsPath(*path, "EPSG:4326");  // the format; KML's CRS below
  }
  ProgressBar progress(Common().quiet);
  const LoadResult loaded = LoadAndResolveCamera(c.args, c.options, flags, progress,
                                                 [&](int views) { c.options.Check(views); });
  const LightField& light_field = loaded.light_field;
  if (!c.kml.empty() && light_field.crs.empty()) {
    ThrowInvalid(c.kml + ": kml: KML is in WGS84 longitude and latitude, but " +
                 c.args.light_field_path + " has no CRS (not geo-referenced); write --geojson "
                 "or --csv");
  }
  ApplyFocalDistance(light_field, c.focal_distance, c.horizontal, c.options, flags);
  std::vector<std::string> inputs = InputsOf(c.args.light_field_path, light_field);
  if (!c.args.focal_surface.empty()) inputs.push_back(c.args.focal_surface);
  check_outputs(inputs);
  const DetectResult result = flags.NamingFlags(
      [&] { return Detect(light_field, c.options, c.detect, &progress); });
  progress.Finish();
  const long long pixels =
      static_cast<long long>(result.render.image.width()) * result.render.image.height();
  CheckSurfaceCovers(c.options.focal_surface, light_field, "the virtual camera's view",
                     result.render.uncovered_pixels, pixels);

  // Every output to a temporary file first, moved into place together.
  std::vector<std::unique_ptr<PendingFile>> pending;
  for (const std::string* path : {&c.geojson, &c.kml, &c.csv}) {
    if (path->empty()) continue;
    pending.push_back(std::make_unique<PendingFile>(*path));
    WriteDetections(pending.back()->TempPath(), result, /*overwrite=*/true);
  }
  if (!c.overlay.empty()) {
    pending.push_back(std::make_unique<PendingFile>(c.overlay));
    WriteImageOptions write;
    write.description = "aos detections: the integral image (1st..99th percentile) with each "
                        "detection boxed in red";
    WriteImage(pending.back()->TempPath(), DetectionOverlay(result), write);
  }
  if (!c.scores.empty()) {
    pending.push_back(std::make_unique<PendingFile>(c.scores));
    WriteImageOptions write;
    write.sample_type = SampleType::kF32;
    write.description = "aos anomaly scores (" + c.detect.detector + "): " +
                        (c.detect.detector == "temperature" ? std::string("degrees C")
                                                            : std::string("squared Mahalanobis "
                                                                          "distance")) +
                        "; threshold " + FormatNumber(result.threshold);
    WriteImage(pending.back()->TempPath(), result.scores.scores, write);
  }
  std::vector<PendingFile*> files;
  for (auto& file : pending) files.push_back(file.get());
  CommitTogether(files);

  Report report("detect");
  report.Set("detections", result.detections.size());
  report.Set("dropped", result.dropped);
  report.Set("threshold", result.threshold);
  report.Set("threshold_rule", result.threshold_rule);
  report.Set("flagged_pixels", static_cast<long long>(result.flagged_pixels));
  report.Set("dimensions", result.scores.dimensions);
  report.Set("crs", result.crs);
  report.Set("ground_sampling_m", result.ground_sampling_m);
  if (c.detect.detector == "rx-local") {
    report.Set("windows_px", std::vector<double>{static_cast<double>(result.windows_px[0]),
                                                 static_cast<double>(result.windows_px[1])});
  }
  for (const auto& [path, what] : outputs) {
    if (!path.empty()) report.Set(what, path);
  }
  report.Line("%zu detections (%s: threshold %s, %lld pixels above it; %d more beyond "
              "--max-detections dropped)",
              result.detections.size(), result.threshold_rule.c_str(),
              FormatNumber(result.threshold).c_str(),
              static_cast<long long>(result.flagged_pixels), result.dropped);
  for (size_t i = 0; i < result.detections.size(); ++i) {
    const Detection& d = result.detections[i];
    std::string where = std::isfinite(d.world.x)
                            ? "world " + FormatNumber(d.world.x) + " " + FormatNumber(d.world.y) +
                                  " " + FormatNumber(d.world.z)
                            : std::string("not on the focal surface");
    if (d.lon_lat) {
      where += " (lon " + FormatNumber(d.lon_lat->x) + ", lat " + FormatNumber(d.lon_lat->y) + ")";
    }
    report.Line("%zu: pixel (%.1f, %.1f), %d px, peak %s, %s, seen by %zu views%s", i + 1,
                d.pixel.x, d.pixel.y, d.area_px, FormatNumber(d.peak_score).c_str(),
                where.c_str(), d.views.size(),
                std::isfinite(d.peak_celsius)
                    ? (", peak " + FormatNumber(d.peak_celsius) + " C").c_str()
                    : "");
  }
  report.Print();
  return 0;
}

}  // namespace

CommandRunner DefineDetect(CLI::App* command) {
  auto c = std::make_shared<DetectCommand>();
  Flags flags(command);
  AddRenderFlags(flags, c->args, c->options);
  AddFocusFlags(flags, c->args, c->options, &c->focal_distance, &c->horizontal);
  command->add_option("--geojson", c->geojson,
                      "Detections as GeoJSON (RFC 7946: WGS84 points; null geometries without a "
                      "CRS)");
  command->add_option("--kml", c->kml, "Detections as KML placemarks (needs a CRS)");
  command->add_option("--csv", c->csv, "Detections as CSV (pixel, world, lon/lat, views, ...)");
  command->add_option("--overlay", c->overlay,
                      "The integral image with the detections boxed in red (8-bit PNG/JPEG/TIFF)");
  command->add_option("--scores", c->scores, "The anomaly scores (float32 TIFF/EXR)");
  for (const char* output : {"--geojson", "--kml", "--csv", "--overlay", "--scores"}) {
    flags.Output(output);
  }
  AddDetectFlags(flags, c->detect);
  flags.Remaining(c->options, {"variance"});
  return [c, flags] { return RunDetect(*c, flags); };
}

// ---- stack ----

namespace {

// --ground FILE and the offset flags, checked once the command line is parsed.
struct StackFlags {
  std::string ground;  // --ground FILE: points or a mesh to estimate the ground plane from
  CLI::Option* surface = nullptr;
  CLI::Option* ground_flag = nullptr;
  CLI::Option* ground_plane = nullptr;
  CLI::Option* offsets[2] = {nullptr, nullptr};

  void Check() const {
    for (const CLI::Option* offset : offsets) {
      if (offset->count() > 0 && surface->count() == 0 && ground_flag->count() == 0 &&
          ground_plane->count() == 0) {
        ThrowUsage(offset->get_name() + ": needs --focal-surface (a terrain-following stack), "
                   "--ground or --ground-plane (planes around the ground)");
      }
    }
  }
};

// --ground FILE: the robust ground plane of the points (or mesh vertices) in FILE, world
// coordinates (EstimateGround, as `aos-render ground`), into options.ground_plane.
// The points are read before the light field is loaded (a bad file fails before the frames are
// decoded) and given here.
void ResolveGround(const std::string& path, std::vector<Vec3d> points,
                   const LightField& light_field, FocalStackOptions& options) {
  if (path.empty()) return;
  for (Vec3d& point : points) point = WorldToLocal(point, light_field.origin);
  GroundResult ground;
  try {
    ground = EstimateGround(points, GroundUpSign(points, light_field));
  } catch (const std::invalid_argument& error) {
    ThrowInvalid("--ground: " + path + ": " + error.what());
  }
  options.ground_plane = ground.plane;
  if (!Common().quiet && !Common().json) {
    const Vec3d p = light_field.origin + ground.plane.point;
    std::fprintf(stderr,
                 "ground: plane through %.3f %.3f %.3f (world), normal %.4f %.4f %.4f, RMS %.3f m "
                 "over %d cells of %zu points; slices %s .. %s m along up from it\n",
                 p.x, p.y, p.z, ground.plane.normal.x, ground.plane.normal.y,
                 ground.plane.normal.z, ground.plane_rms_m, ground.plane_cells, ground.points,
                 FormatNumber(options.first_offset).c_str(),
                 FormatNumber(options.last_offset).c_str());
  }
}

// The slices: planes, or (with --focal-surface) a terrain-following stack's offsets, or (with
// --ground) planes parallel to an estimated ground.
StackFlags AddStackFlags(Flags& stack, Flags& render, RenderArgs& args,
                         FocalStackOptions& options, std::string& ground) {
  CLI::Option* first = stack.Field(options, "first_plane");
  CLI::Option* last = stack.Field(options, "last_plane");
  CLI::Option* surface = AddFocalSurfaceFlag(
      render, args, options.render,
      "A stack given a terrain follows it: every slice lies on the terrain moved along up by "
      "--first-offset .. --last-offset, instead of --first-plane/--last-plane.",
      /*planes=*/false);
  CLI::Option* ground_plane = stack.Field(options, "ground_plane");
  stack.Shorthand("ground_plane", "--ground");
  CLI::Option* ground_flag = stack.command()->add_option(
      "--ground", ground,
      "Planes parallel to the ground estimated from this file, from --first-offset to "
      "--last-offset along up: reconstructed points (poses --points-output) or a mesh, PLY/OBJ in "
      "world coordinates (the robust plane of `aos-render ground`); for a DEM use "
      "--focal-surface; sets --ground-plane");
  ground_flag->excludes(ground_plane);
  ground_plane->excludes(first)->excludes(last);
  CLI::Option* first_offset = stack.Field(options, "first_offset");
  CLI::Option* last_offset = stack.Field(options, "last_offset");
  surface->excludes(first)->excludes(last)->excludes(ground_flag)->excludes(ground_plane);
  ground_flag->excludes(first)->excludes(last);
  stack.Input("--ground");
  stack.Field(options, "slices");
  StackFlags flags;
  flags.surface = surface;
  flags.ground_flag = ground_flag;
  flags.ground_plane = ground_plane;
  flags.offsets[0] = first_offset;
  flags.offsets[1] = last_offset;
  return flags;
}

void AddMergeFlags(Flags& merge, MergeOptions& options) {
  merge.Field(options, "method");
  merge.Field(options, "window_radius");
  merge.Field(options, "smoothing_sigma");
  merge.Field(options, "edge_sigma");
  merge.Field(options, "smoothing_iterations");
  Flags robust = merge.Nested("robust.");
  robust.Field(options.robust, "agreement");
  robust.Field(options.robust, "min_inlier_fraction");
}

// Writes image, depth, confidence and slice maps and their previews into a new folder
// (atomically).
void WriteMergeResult(const std::string& output_dir, const MergeResult& result,
                      MergeMethod method, Report& report) {
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
  report.Set("output_dir", output_dir);
  report.Set("files", std::vector<std::string>{"all_in_focus.tif", "depth.tif", "confidence.tif",
                                               "slice.tif", "all_in_focus_preview.png",
                                               "depth_preview.png", "confidence_preview.png"});
  report.Set("width", result.image.width());
  report.Set("height", result.image.height());
  report.Set("method", MergeMethodName(method));
  report.Set("uncovered_pixels", static_cast<long long>(result.uncovered_pixels));
  report.Set("depth_preview_range_m", std::vector<double>{depth_range.lo, depth_range.hi});
  report.Set("seconds_render", result.seconds_render);
  report.Set("seconds_merge", result.seconds_merge);
  report.Line("wrote %s: all_in_focus.tif, depth.tif, confidence.tif, slice.tif and *_preview.png "
              "(depth preview %s..%s m) (%dx%d, %s; %lld pixels uncovered)",
              output_dir.c_str(), FormatNumber(depth_range.lo).c_str(),
              FormatNumber(depth_range.hi).c_str(), result.image.width(), result.image.height(),
              MergeMethodName(method), static_cast<long long>(result.uncovered_pixels));
}

// stack and allinfocus: the light field, the slices' flags and the output folder, and the
// options (FocalStackOptions, or AllInFocusOptions holding one).
template <class Options>
struct SlicesCommand {
  RenderArgs args;
  Options options;
  std::string ground;
  StackFlags stack_flags;
  std::string output_dir;
};
using StackCommand = SlicesCommand<FocalStackOptions>;

FocalStackOptions& StackPart(FocalStackOptions& options) { return options; }
FocalStackOptions& StackPart(AllInFocusOptions& options) { return options.stack; }

// What stack and allinfocus do before rendering: the slices' flags checked, the output folder
// refused when in use (before any work), the --ground points read (a bad file fails before the
// frames are decoded), the light field loaded with the camera resolved, the ground estimated.
template <class Options>
LoadResult LoadSlices(SlicesCommand<Options>& c, const Flags& flags, ProgressBar& progress) {
  c.stack_flags.Check();
  CheckOutputFolder(c.output_dir);
  std::vector<Vec3d> ground_points;
  if (!c.ground.empty()) ground_points = ReadPoints(c.ground);
  FocalStackOptions& stack = StackPart(c.options);
  LoadResult loaded = LoadAndResolveCamera(c.args, stack.render, flags, progress,
                                           [&](int views) { c.options.Check(views); });
  ResolveGround(c.ground, std::move(ground_points), loaded.light_field, stack);
  return loaded;
}

int RunStack(StackCommand& c, const Flags& flags) {
  ProgressBar progress(Common().quiet);
  const LoadResult loaded = LoadSlices(c, flags, progress);
  const FocalStack stack =
      flags.NamingFlags([&] { return RenderFocalStack(loaded.light_field, c.options, &progress); });
  progress.Finish();
  WriteFocalStack(c.output_dir, stack);
  Report report("stack");
  report.Set("output_dir", c.output_dir);
  report.Set("slices", stack.size());
  report.Set("width", stack.camera.width);
  report.Set("height", stack.camera.height);
  report.Set("variance", !stack.variances.empty());
  report.Line("wrote %s: %d slices of %dx%d (stack.json, slice_*.tif, count_*.tif%s)",
              c.output_dir.c_str(), stack.size(), stack.camera.width, stack.camera.height,
              stack.variances.empty() ? "" : ", variance_*.tif");
  report.Print();
  return 0;
}

}  // namespace

CommandRunner DefineStack(CLI::App* command) {
  auto c = std::make_shared<StackCommand>();
  Flags flags(command);
  Flags render = flags.Nested("render.");
  AddRenderFlags(render, c->args, c->options.render);
  render.Field(c->options.render, "variance");
  c->stack_flags = AddStackFlags(flags, render, c->args, c->options, c->ground);
  command->add_option("-o,--output-dir", c->output_dir, "Output folder; must not exist or be empty")
      ->required();
  flags.OutputFolder("--output-dir");
  // Every other field of the tables (tools/vocabulary.py NOT_ON_THE_CLI: why not those).
  render.Remaining(c->options.render, {"surface_offset"});
  flags.Remaining(c->options);
  return [c, flags] { return RunStack(*c, flags); };
}

// ---- merge ----

namespace {

struct MergeCommand {
  std::string stack_dir;
  std::string light_field_path;
  LoadOptions load;
  MergeOptions options;
  std::string output_dir;
};

int RunMerge(MergeCommand& c, const Flags& flags) {
  ProgressBar progress(Common().quiet);
  CheckOutputFolder(c.output_dir);  // before any work
  // The flags before the stack's slices or the light field's frames are read.
  c.load.num_threads = c.options.num_threads;
  flags.NamingFlags([&] { c.options.Check(); });
  flags.At("load.").NamingFlags([&] { c.load.Check(); });
  if (c.light_field_path.empty() && c.options.method == MergeMethod::kRobust) {
    ThrowUsage("--method robust: give --lightfield, the light field the stack was rendered "
               "from (its rays are re-integrated)");
  }
  const FocalStack stack = ReadFocalStack(c.stack_dir);
  std::optional<LoadResult> loaded;
  if (!c.light_field_path.empty()) {
    loaded = flags.At("load.").NamingFlags(
        [&] { return LoadLightField(c.light_field_path, c.load, &progress); });
    progress.Finish();
  } else if (c.options.method == MergeMethod::kRobust) {
    ThrowUsage("--method robust: give --lightfield, the light field the stack was rendered "
               "from (its rays are re-integrated)");
  }
  const MergeResult result = flags.NamingFlags([&] {
    return MergeFocalStack(stack, c.options, loaded ? &loaded->light_field : nullptr, &progress);
  });
  progress.Finish();
  if (!Common().quiet && !Common().json) {
    std::fprintf(stderr, "merged %d slices (%s) in %.2f s%s\n", stack.size(),
                 MergeMethodName(c.options.method), result.seconds_merge + result.seconds_render,
                 c.options.method == MergeMethod::kRobust
                     ? (", " + std::to_string(result.fallback_pixels) +
                        " pixels kept the plain mean").c_str()
                     : "");
  }
  Report report("merge");
  report.Set("slices", stack.size());
  if (c.options.method == MergeMethod::kRobust) {
    report.Set("fallback_pixels", static_cast<long long>(result.fallback_pixels));
  }
  WriteMergeResult(c.output_dir, result, c.options.method, report);
  report.Print();
  return 0;
}

}  // namespace

CommandRunner DefineMerge(CLI::App* command) {
  auto c = std::make_shared<MergeCommand>();
  Flags flags(command);
  command->add_option("stack", c->stack_dir, "Stack folder (with stack.json)")->required();
  AddMergeFlags(flags, c->options);
  command->add_option("--lightfield", c->light_field_path,
                      "The light field the stack was rendered from (needed by --method robust)");
  AddLoadFlags(flags, c->load);
  flags.Threads(c->options);
  command->add_option("-o,--output-dir", c->output_dir, "Output folder; must not exist or be empty")
      ->required();
  flags.InputFolder("stack");
  flags.Input("--lightfield");
  flags.OutputFolder("--output-dir");
  // Every other field of the tables (tools/vocabulary.py NOT_ON_THE_CLI: why not those).
  flags.Remaining(c->options);
  flags.Nested("robust.").Remaining(c->options.robust, {"robust"});
  return [c, flags] { return RunMerge(*c, flags); };
}

// ---- allinfocus ----

namespace {

using AllInFocusCommand = SlicesCommand<AllInFocusOptions>;

int RunAllInFocus(AllInFocusCommand& c, const Flags& flags) {
  ProgressBar progress(Common().quiet);
  const LoadResult loaded = LoadSlices(c, flags, progress);
  // --threads sets every stage's thread count.
  c.options.merge.num_threads = c.options.stack.render.num_threads;
  const MergeResult result =
      flags.NamingFlags([&] { return RenderAllInFocus(loaded.light_field, c.options, &progress); });
  progress.Finish();
  if (!Common().quiet && !Common().json) {
    std::fprintf(stderr, "%d slices rendered and merged (%s): render %.2f s, merge %.2f s\n",
                 c.options.stack.slices, MergeMethodName(c.options.merge.method),
                 result.seconds_render, result.seconds_merge);
  }
  Report report("allinfocus");
  report.Set("slices", c.options.stack.slices);
  WriteMergeResult(c.output_dir, result, c.options.merge.method, report);
  report.Print();
  return 0;
}

}  // namespace

CommandRunner DefineAllInFocus(CLI::App* command) {
  auto c = std::make_shared<AllInFocusCommand>();
  Flags flags(command);
  Flags render = flags.Nested("stack.render.");
  AddRenderFlags(render, c->args, c->options.stack.render);
  flags.AlsoSets("merge.num_threads", "--threads");
  Flags stack = flags.Nested("stack.");
  c->stack_flags = AddStackFlags(stack, render, c->args, c->options.stack, c->ground);
  Flags merge = flags.Nested("merge.");
  AddMergeFlags(merge, c->options.merge);
  flags.Field(c->options, "coarse_to_fine");
  command->add_option("-o,--output-dir", c->output_dir, "Output folder; must not exist or be empty")
      ->required();
  flags.OutputFolder("--output-dir");
  // Every other field of the tables (tools/vocabulary.py NOT_ON_THE_CLI: why not those).
  render.Remaining(c->options.stack.render, {"surface_offset", "variance"});
  stack.Remaining(c->options.stack);
  merge.Remaining(c->options.merge);
  merge.Nested("robust.").Remaining(c->options.merge.robust, {"robust"});
  flags.Remaining(c->options);
  return [c, flags] { return RunAllInFocus(*c, flags); };
}

// ---- map ----

namespace {

struct MapCommand {
  std::string light_field_path;
  LoadOptions load;
  MapOptions options;
  std::string focal_surface;  // --focal-surface FILE (mesh or DEM raster)
  std::string views;
  std::string output;
  DistributedOptions distributed;  // --workers, --scheduler, --cache-mb, --share-mb, --dashboard
  std::string detect;              // --detect FILE: detections on the map (GeoJSON, KML, CSV)
  DetectOptions detect_options;
};

int RunMapDistributed(MapCommand& c);

std::string UpText(const MapGrid& grid) { return grid.up_z > 0 ? "+z" : "-z"; }

int RunMap(MapCommand& c, const Flags& flags) {
  ProgressBar progress(Common().quiet);
  MapWriteOptions write;
  write.force = Common().force;
  // Refuse a bad output before loading: one of the inputs, not a .tif name, an existing file
  // without --force, a missing or read-only folder.
  CheckOutputPath(c.output, {c.light_field_path}, "output");
  try {
    CheckMapOutputExtension(c.output);
  } catch (const std::invalid_argument& error) {
    // Over a frame is the graver mistake (a frame.png given as -o): say that first, from the
    // poses alone (no frame decoded).
    const LightField poses = PosesOnly(c.light_field_path, c.load, flags);
    CheckOutputPath(c.output, InputsOf(c.light_field_path, poses), "output");
    throw UsageError(std::string(error.what()) + " [option --output]");
  }
  RefuseExisting(c.output, "output");
  CheckMapOutputPath(c.output, write);
  // The cluster options are checked whether or not there is a cluster; those that only a
  // cluster reads are named when given without one.
  flags.At("distributed.").NamingFlags([&] { c.distributed.Check(); });
  const DistributedOptions& d = c.distributed;
  c.load.num_threads = c.options.num_threads;
  flags.At("load.").NamingFlags([&] { c.load.Check(); });  // also before a cluster's hand-off
  if (!c.detect.empty()) {
    CheckOutputPath(c.detect, {c.light_field_path}, "detect");
    RefuseExisting(c.detect, "detect");
    CheckDetectionsPath(c.detect, "EPSG:4326");  // the format; KML's CRS once loaded
    flags.NamingFlags([&] { c.detect_options.Check(); });
  }
  if (d.workers != 0 || !d.scheduler.empty() || d.dashboard) return RunMapDistributed(c);
  for (const char* flag : {"--cache-mb", "--share-mb"}) {
    if (flags.command()->count(flag) > 0) {
      Warn(std::string(flag) + " is ignored without --workers or --scheduler (it budgets the "
           "frames of a Dask worker; this process holds every frame)");
    }
  }
  c.load.num_threads = c.options.num_threads;
  // The surface and the flags first: a bad mesh, DEM or flag fails before the frames are loaded
  // (the views are checked again against the light field).
  ReadFocalSurface(c.focal_surface, &c.options.focal_surface);
  flags.At("load.").NamingFlags([&] { c.load.Check(); });
  flags.NamingFlags([&] { c.options.Check(1); });
  if (!c.views.empty()) {  // against the poses alone, before any frame is decoded
    ParseViewList(c.views,
                  static_cast<int>(PosesOnly(c.light_field_path, c.load, flags).views.size()));
  }
  const LoadResult loaded = flags.At("load.").NamingFlags(
      [&] { return LoadLightField(c.light_field_path, c.load, &progress); });
  progress.Finish();
  for (const std::string& note : loaded.notes) Note(note);
  const LightField& light_field = loaded.light_field;
  c.options.focal_surface = InCrs(c.options.focal_surface, light_field.crs);
  if (!c.views.empty()) {
    c.options.view_indices =
        ParseViewList(c.views, static_cast<int>(light_field.views.size()));
  }
  // Never over an input: the light field or any frame (links resolved).
  CheckOutputPath(c.output, InputsOf(c.light_field_path, light_field), "output");
  const MapGrid grid = flags.NamingFlags([&] { return ResolveMapGrid(light_field, c.options); });
  CheckMapCrs(light_field.crs, c.light_field_path);
  if (light_field.crs.empty()) {
    Warn(c.light_field_path + ": the light field has no CRS, so the map has none: GIS tools "
         "will place it in the frame's own coordinates (origin + local), not on the Earth");
  }
  if (!Common().quiet && !Common().json) {
    const std::string focus =
        grid.surface ? "focal surface offset " + FormatNumber(grid.placement.offset) + " m"
                     : "focal plane z = " + FormatNumber(grid.focal_height) + " (local)";
    std::fprintf(stderr, "map: %d x %d pixels of %s m, up %s, %s\n", grid.width, grid.height,
                 FormatNumber(grid.pixel_size).c_str(), UpText(grid).c_str(), focus.c_str());
  }
  // Detections first (in memory, written beside their final path), then the map, then the
  // detections into place: an error leaves neither new.
  std::optional<DetectResult> found;
  std::optional<PendingFile> detections;
  if (!c.detect.empty()) {
    CheckOutputPath(c.detect, InputsOf(c.light_field_path, light_field), "detect");
    CheckDetectionsPath(c.detect, light_field.crs);
    found = flags.NamingFlags(
        [&] { return DetectOnMap(light_field, c.options, c.detect_options, &progress); });
    detections.emplace(c.detect);
    WriteDetections(detections->TempPath(), *found, /*overwrite=*/true);
  }
  const MapSummary summary = flags.NamingFlags(
      [&] { return WriteMapGeoTiff(light_field, c.options, c.output, write, &progress); });
  progress.Finish();
  if (detections) detections->Commit();
  const int64_t pixels = static_cast<int64_t>(grid.width) * grid.height;
  Report report("map");
  report.Set("output", c.output);
  report.Set("width", grid.width);
  report.Set("height", grid.height);
  report.Set("pixel_size", grid.pixel_size);
  const std::array<double, 6> transform = grid.GeoTransform();
  report.Set("geotransform", std::vector<double>(transform.begin(), transform.end()));
  report.Set("crs", light_field.crs);
  report.Set("up", UpText(grid));
  report.Set("views_used", summary.views_used);
  report.Set("views_selected", summary.views_selected);
  report.Set("samples", static_cast<long long>(summary.samples));
  report.Set("uncovered_pixels", static_cast<long long>(summary.uncovered_pixels));
  report.Set("tiles", summary.tiles);
  report.Line("wrote %s: %d x %d pixels of %s m, x %s .. %s, y %s .. %s%s%s", c.output.c_str(),
              grid.width, grid.height, FormatNumber(grid.pixel_size).c_str(),
              FormatNumber(grid.x_min).c_str(),
              FormatNumber(grid.x_min + grid.width * grid.pixel_size).c_str(),
              FormatNumber(grid.y_max - grid.height * grid.pixel_size).c_str(),
              FormatNumber(grid.y_max).c_str(), light_field.crs.empty() ? "" : ", ",
              light_field.crs.c_str());
  report.Line("integrated %d of %d selected views: %lld samples, %lld of %lld pixels seen by no "
              "view (nodata, count 0)",
              summary.views_used, summary.views_selected, static_cast<long long>(summary.samples),
              static_cast<long long>(summary.uncovered_pixels), static_cast<long long>(pixels));
  if (found) {
    report.Set("detect", c.detect);
    report.Set("detections", found->detections.size());
    report.Set("threshold_rule", found->threshold_rule);
    report.Line("wrote %s: %zu detections on the map (%s: threshold %s)", c.detect.c_str(),
                found->detections.size(), found->threshold_rule.c_str(),
                FormatNumber(found->threshold).c_str());
    for (size_t i = 0; i < found->detections.size(); ++i) {
      const Detection& d = found->detections[i];
      report.Line("%zu: map pixel (%.1f, %.1f), %d px, peak %s, world %s %s %s, seen by %zu "
                  "views",
                  i + 1, d.pixel.x, d.pixel.y, d.area_px, FormatNumber(d.peak_score).c_str(),
                  FormatNumber(d.world.x).c_str(), FormatNumber(d.world.y).c_str(),
                  FormatNumber(d.world.z).c_str(), d.views.size());
    }
  }
  report.Print();
  return 0;
}

}  // namespace

CommandRunner DefineMap(CLI::App* command) {
  auto c = std::make_shared<MapCommand>();
  Flags flags(command);
  command
      ->add_option("lightfield", c->light_field_path,
                   "Light-field file: aos JSON, or a JKU-ICG/AOS poses.json")
      ->required();
  AddLoadFlags(flags, c->load);
  MapOptions& options = c->options;
  flags.Field(options, "pixel_size");
  flags.Field(options, "width");
  flags.Field(options, "extent")->expected(4);
  CLI::Option* surface = flags.Field(
      options, "focal_surface", TakeFocalSurface(&options.focal_surface, &c->focal_surface),
      std::string(kFocalSurfaceHelp) + " Pixels whose vertical line misses a terrain are nodata.");
  CLI::Option* height = AddFocalHeightFlag(
      flags, options.focal_surface, "Horizontal focal plane z = H (local frame, metres)");
  surface->excludes(height);
  flags.Field(options, "surface_offset");
  flags.Field(options, "aperture_radius");
  flags.Field(options, "view_indices", [c](const std::string& text) { c->views = text; },
               kViewListHelp);
  flags.Field(options, "min_view_angle_deg");
  flags.Field(options, "lens_tolerance_px");
  flags.Field(options, "tile_size");
  flags.Threads(options);
  command->add_option("-o,--output", c->output, "GeoTIFF to write (Cloud-Optimised)")->required();
  Flags run = flags.At("distributed.");
  run.Field(c->distributed, "workers");
  run.Field(c->distributed, "scheduler");
  run.Field(c->distributed, "cache_mb");
  run.Field(c->distributed, "share_mb");
  run.Field(c->distributed, "dashboard");
  flags.Force();
  flags.Input("lightfield");
  flags.Input("--focal-surface");
  flags.Output("--output");
  // Every other field of the tables (tools/vocabulary.py NOT_ON_THE_CLI: why not those).
  command->add_option("--detect", c->detect,
                      "Also find anomalies on the map (detect's options) and write them here: "
                      "GeoJSON, KML or CSV by the extension");
  flags.Output("--detect");
  flags.Remaining(c->options);
  flags.At("distributed.").Remaining(c->distributed);
  flags.At("detect.").Remaining(c->detect_options);
  return [c, flags] { return RunMap(*c, flags); };
}

// ---- view ----
//
// `aos-render view` checks its command line here (the same flags as integral, bound to the same
// IntegralOptions fields, plus --host/--port/--no-browser), then hands over to the Python viewer
// (python/aos/viewer: an aiohttp server) by exec'ing PYTHON on aos.viewer's main with
// `--spec JSON`, the flags' values as one JSON object. The interpreter is the first of: $AOS_PYTHON; python3 beside
// this executable's real path (pip installs aos-render into the interpreter's scripts folder);
// the interpreter the build was configured with (AOS_PYTHON_EXECUTABLE); python3 on PATH; the
// first one that finds the aos package is used.

namespace {

struct ViewCommand {
  RenderArgs args;
  IntegralOptions options;
  ViewerOptions viewer;  // the server's own settings (viewer/viewer_options.h)
  bool no_browser = false;
  bool browser = false;
};

// Whether `python` runs and finds the aos package with `module` (a sub-package folder holding
// __main__.py), without importing aos (which would load the core): tens of milliseconds.
bool PythonFindsAos(const std::string& python, const std::string& module) {
  if (python.empty()) return false;
  const pid_t pid = fork();
  if (pid < 0) return false;
  if (pid == 0) {
    const int null = open("/dev/null", O_WRONLY);
    if (null >= 0) {
      dup2(null, 1);
      dup2(null, 2);
    }
    const std::string check =
        "import importlib.util, os, sys; s = importlib.util.find_spec('aos'); "
        "sys.exit(0 if s and any(os.path.isfile(os.path.join(p, '" + module + "', '__main__.py')) "
        "for p in s.submodule_search_locations or []) else 1)";
    execlp(python.c_str(), python.c_str(), "-c", check.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  int status = 0;
  if (waitpid(pid, &status, 0) < 0) return false;
  return WIFEXITED(status) && WEXITSTATUS(status) == 0;
}

}  // namespace

std::vector<std::string> PythonCandidates() {
  std::vector<std::string> candidates;
  if (const char* chosen = std::getenv("AOS_PYTHON"); chosen != nullptr && *chosen != '\0') {
    candidates.emplace_back(chosen);
    return candidates;  // an explicit choice is the only one tried
  }
  std::error_code error;
  const fs::path self = fs::canonical("/proc/self/exe", error);
  if (!error) {
    for (const char* name : {"python3", "python"}) {
      const fs::path beside = self.parent_path() / name;
      if (fs::exists(beside, error)) candidates.push_back(beside.string());
    }
  }
#ifdef AOS_PYTHON_EXECUTABLE
  candidates.emplace_back(AOS_PYTHON_EXECUTABLE);
#endif
  candidates.emplace_back("python3");
  return candidates;
}

// The first interpreter (PythonCandidates) that finds the aos package with `module`.
std::string FindPython(const std::string& command, const std::string& module) {
  std::string python;
  const std::vector<std::string> candidates = PythonCandidates();
  for (const std::string& candidate : candidates) {
    if (PythonFindsAos(candidate, module)) {
      python = candidate;
      break;
    }
  }
  if (python.empty()) {
    std::string tried;
    for (const std::string& candidate : candidates) tried += (tried.empty() ? "" : ", ") + candidate;
    ThrowInvalid(command + ": no Python interpreter with the aos package found (tried " + tried +
                 "); set AOS_PYTHON to the python3 that aos was installed into");
  }
  return python;
}

// `python -c` code that runs aos.MODULE's main(argv) and answers a Ctrl-C that lands while the
// package loads (before main() can catch it: `python -m` imports the package first) like any
// interrupt: one line, exit 130, no traceback.
std::string PythonLauncher(const std::string& command, const std::string& module) {
  return "import sys\n"
         "try:\n"
         "    from aos." + module + ".__main__ import main\n"
         "except KeyboardInterrupt:\n"
         "    sys.stderr.write('aos-render " + command + ": interrupted\\n')\n"
         "    sys.exit(130)\n"
         "sys.exit(main(sys.argv[1:]))\n";
}

// Replaces this process by PYTHON running aos.<module>'s main with `--spec TEXT` (through
// PythonLauncher; the interpreter from FindPython); throws if none finds the package.
[[noreturn]] void ExecPythonModule(const std::string& command, const std::string& module,
                                   const std::string& text) {
  const std::string python = FindPython(command, module);
  std::fflush(stdout);
  std::fflush(stderr);
  // A signal that came while this process checked the command line ends it here: after exec
  // the handler is gone and the flag with it.
  if (Interrupted()) throw Cancelled();
  const std::string launcher = PythonLauncher(command, module);
  execlp(python.c_str(), python.c_str(), "-c", launcher.c_str(), "--spec", text.c_str(),
         static_cast<char*>(nullptr));
  ThrowInvalid(command + ": cannot run " + python + ": " + std::strerror(errno));
}

namespace {

int RunView(ViewCommand& c, const Flags& flags) {
  if (!fs::exists(c.args.light_field_path)) {
    ThrowInvalid(c.args.light_field_path + ": no such light-field file");
  }
  if (!c.args.focal_surface.empty() && !fs::exists(c.args.focal_surface)) {
    throw UsageError("--focal-surface: " + c.args.focal_surface + ": no such file");
  }
  nlohmann::ordered_json spec;
  spec["light_field"] = c.args.light_field_path;
  spec["load"] = OptionsToJson(c.args.load);
  spec["pose_view"] = c.args.pose_view;
  if (!c.args.pose_view.empty() && c.args.pose_view[0] == '-') {
    ThrowUsage("--pose-view: a view index is >= 0 (got " + c.args.pose_view + ")");
  }
  std::optional<Rigid3d> cam_from_world;
  if (!c.args.look_at.empty()) {
    const std::vector<double> v = ParseNumbers(c.args.look_at, "--look-at");
    if (v.size() != 6 && v.size() != 9) ThrowUsage("--look-at: expected 6 or 9 numbers");
    const Vec3d eye(v[0], v[1], v[2]), target(v[3], v[4], v[5]);
    cam_from_world = AsUsage([&] {
      return v.size() == 9 ? LookAt(eye, target, Vec3d(v[6], v[7], v[8])) : LookAt(eye, target);
    });
  } else if (!c.args.cam_from_world.empty()) {
    const std::vector<double> v = ParseNumbers(c.args.cam_from_world, "--cam-from-world", 12);
    std::array<double, 12> m{};
    std::copy(v.begin(), v.end(), m.begin());
    cam_from_world = Rigid3d::FromMatrix3x4(m);
  }
  if (cam_from_world) {
    const std::array<double, 12> m = cam_from_world->ToMatrix3x4();
    spec["cam_from_world"] = std::vector<double>(m.begin(), m.end());
  } else {
    spec["cam_from_world"] = nullptr;
  }
  // The virtual camera's and the focus's ranges, as integral checks them (view counts aside).
  const IntegralOptions& o = c.options;
  if (!(o.fov_deg >= 0.0 && o.fov_deg < 180.0)) {
    ThrowUsage("--fov-deg: must be 0 (the pose view's) or in (0, 180), got " +
               FormatNumber(o.fov_deg));
  }
  for (const auto& [flag, size] : {std::pair{"--width", o.width}, {"--height", o.height}}) {
    if (size != 0 && (size < 8 || size > 2048)) {
      ThrowUsage(std::string(flag) + ": must be 0 (the pose view's) or 8..2048 pixels in the "
                 "viewer, got " + std::to_string(size));
    }
  }
  if (!(o.min_view_angle_deg >= 0.0 && o.min_view_angle_deg < 90.0)) {
    ThrowUsage("--min-view-angle-deg: must be in [0, 90), got " +
               FormatNumber(o.min_view_angle_deg));
  }
  if (o.focal_surface.kind() != FocalSurfaceKind::kPlane ||
      o.focal_surface.plane().normal != Vec3d(0.0, 0.0, 1.0)) {
    ThrowUsage("focal_surface: the viewer starts on a horizontal plane (--focal-height H, "
               "--focal-surface H or a terrain file) [option --focal-surface/--focal-height]");
  }
  // The rest as integral checks it (one placeholder view; the viewer checks the views), before
  // the viewer loads the frames.
  flags.NamingFlags([&] { o.Check(1); });
  flags.At("load.").NamingFlags([&] { c.args.load.Check(); });
  // The options travel whole, in their JSON form (lightfield/options_json.h); the view list
  // and a pose view given by name are resolved once the light field is loaded.
  spec["options"] = OptionsToJson(o);
  spec["views"] = c.args.views;
  spec["focal_surface"] = c.args.focal_surface;
  if (c.no_browser) {
    c.viewer.open_browser = false;
  } else if (c.browser) {
    c.viewer.open_browser = true;
  }
  flags.At("viewer.").NamingFlags([&] { c.viewer.Check(); });
  spec["viewer"] = OptionsToJson(c.viewer);
  spec["quiet"] = Common().quiet;
  spec["json"] = Common().json;
  const std::string text = spec.dump();

  ExecPythonModule("view", "viewer", text);
}

// `aos-render map --workers N / --scheduler ADDRESS`: the command line is checked here (the
// output before anything else, in RunMap), then handed over to aos.distributed's main with
// `--spec JSON` (python/aos/distributed), which renders the tiles as Dask tasks.
int RunMapDistributed(MapCommand& c) {  // RunMap checked c.distributed
  if (!fs::exists(c.light_field_path)) ThrowInvalid(c.light_field_path + ": no such light-field file");
  if (!c.focal_surface.empty() && !fs::exists(c.focal_surface)) {
    throw UsageError("--focal-surface: " + c.focal_surface + ": no such file");
  }
  ReadFocalSurface(c.focal_surface, &c.options.focal_surface);  // a bad file fails here
  c.options.Check(std::numeric_limits<int>::max());  // the view count is known after loading
  nlohmann::ordered_json spec;
  spec["light_field"] = c.light_field_path;
  // The options travel whole, in their JSON form (lightfield/options_json.h); the view list
  // is resolved once the light field is loaded; a surface travels as its file (read there,
  // and moved into the light field's CRS as here).
  spec["load"] = OptionsToJson(c.load);
  spec["options"] = OptionsToJson(c.options);
  spec["distributed"] = OptionsToJson(c.distributed);
  spec["views"] = c.views;
  spec["output"] = c.output;
  // --detect: the map stays in the client's memory too and is scored there (DetectOnRenderedMap).
  spec["detect"] = c.detect;
  spec["detect_options"] = OptionsToJson(c.detect_options);
  spec["force"] = Common().force;
  spec["quiet"] = Common().quiet;
  spec["json"] = Common().json;
  ExecPythonModule("map", "distributed", spec.dump());
}

}  // namespace

CommandRunner DefineView(CLI::App* command) {
  auto c = std::make_shared<ViewCommand>();
  Flags flags(command);
  AddRenderFlags(flags, c->args, c->options);
  CLI::Option* surface = AddSurfaceFlags(flags, c->args, c->options);
  AddFocalHeightFlag(flags, c->options.focal_surface,
                     "Starting focus: the horizontal focal plane z = H (local frame, metres); the "
                     "page moves it");
  (void)surface;
  CLI::Option* open_browser = AddViewerFlags(flags, c->viewer, c->no_browser);
  Flags viewer = flags.At("viewer.");
  viewer.Shorthand("open_browser", "--browser");
  CLI::Option* browser = command->add_flag(
      "--browser", c->browser,
      "Open a browser even without a desktop session: sets --open-browser true");
  browser->excludes(command->get_option("--no-browser"))->excludes(open_browser);
  // Every other field of the tables (tools/vocabulary.py NOT_ON_THE_CLI: why not those).
  flags.Remaining(c->options, {"variance"});
  viewer.Remaining(c->viewer);
  return [c, flags] { return RunView(*c, flags); };
}

}  // namespace aos::cli
