// Lens commands: calibrate, camera, rectify, resolution.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <set>

#include "aos/calib/calibrate.h"
#include "aos/image/image_io.h"
#include "aos/lightfield/camera_file.h"
#include "aos/lightfield/formats.h"
#include "aos/metrics/resolution.h"
#include "aos/render/rectify.h"
#include "aos/util/file_util.h"
#include "aos/util/memory.h"
#include "aos/util/parallel.h"
#include "commands.h"
#include "progress_bar.h"

namespace fs = std::filesystem;

namespace aos::cli {
namespace {


// ---- calibrate ----

struct CalibrateCommand {
  std::vector<std::string> frames;
  CalibrateOptions options;
  std::string output;
};

// "9x6" -> (9, 6), whole numbers 2..1000.
std::pair<int, int> ParsePattern(const std::string& pattern) {
  const size_t x = pattern.find('x');
  if (x == std::string::npos) ThrowUsage("--pattern: expected COLUMNSxROWS, e.g. 9x6");
  const auto count = [&](const std::string& text) {
    const double value = AsUsage([&] { return ParseNumberText(text, "--pattern"); });
    if (value != std::floor(value) || value < 2 || value > 1000) {
      ThrowUsage("--pattern: expected COLUMNSxROWS of whole numbers 2..1000, e.g. 9x6 (got '" +
                 pattern + "')");
    }
    return static_cast<int>(value);
  };
  return {count(pattern.substr(0, x)), count(pattern.substr(x + 1))};
}

int RunCalibrate(CalibrateCommand& c, const Flags& flags) {
  ProgressBar progress(Common().quiet);
  CheckOutputPath(c.output, c.frames, "output");
  RefuseExisting(c.output, "output");
  flags.NamingFlags([&] { c.options.Check(); });  // before the frames are read
  std::vector<Image> frames;
  for (const std::string& frame : c.frames) frames.push_back(ReadImage(frame));
  const CalibrationResult result =
      flags.NamingFlags([&] { return Calibrate(frames, c.frames, c.options, &progress); });
  progress.Finish();
  for (const std::string& name : result.frames_rejected) {
    Warn(name + ": board not found; frame not used");
  }
  WriteCameraFile(c.output, result.camera, CalibrationRecordJson(result, &c.options));
  Report report("calibrate");
  report.Set("output", c.output);
  report.Set("model", LensModelName(result.camera.model));
  report.Set("rms_px", result.rms_px);
  report.Set("frames_used", result.frames_used);
  report.Set("frames_rejected", result.frames_rejected);
  report.Line("wrote %s: %s lens, RMS reprojection error %.3f px over %zu frames (%zu without "
              "the board)",
              c.output.c_str(), LensModelName(result.camera.model), result.rms_px,
              result.frames_used.size(), result.frames_rejected.size());
  report.Print();
  return 0;
}

}  // namespace

CommandRunner DefineCalibrate(CLI::App* command) {
  auto c = std::make_shared<CalibrateCommand>();
  Flags flags(command);
  command->add_option("frames", c->frames, "Checkerboard frames")->required();
  CalibrateOptions& options = c->options;
  const std::string pattern = std::to_string(options.pattern_columns) + "x" +
                              std::to_string(options.pattern_rows);
  CLI::Option* columns = flags.Field(options, "pattern_columns");
  CLI::Option* rows = flags.Field(options, "pattern_rows");
  flags.Shorthand("pattern_columns", "--pattern");
  flags.Shorthand("pattern_rows", "--pattern");
  command
      ->add_option_function<std::string>(
          "--pattern",
          [c](const std::string& text) {
            try {
              std::tie(c->options.pattern_columns, c->options.pattern_rows) = ParsePattern(text);
            } catch (const std::invalid_argument& error) {
              throw CLI::ValidationError(OneLine(error.what()));
            }
          },
          "Inner corners COLUMNSxROWS: sets --pattern-columns and --pattern-rows")
      ->default_str(pattern)
      ->excludes(columns)
      ->excludes(rows);
  flags.Field(options, "square_size_m");
  flags.Field(options, "model");
  command->add_option("-o,--output", c->output, "Camera file to write (JSON)")->required();
  flags.Input("frames");
  flags.Output("--output");
  flags.Threads();
  flags.Force();
  // Every other field of the tables (tools/vocabulary.py NOT_ON_THE_CLI: why not those).
  flags.Remaining(c->options);
  return [c, flags] { return RunCalibrate(*c, flags); };
}

// ---- camera ----

namespace {

// Distortion coefficients by name, and where each model keeps them (lens.h).
struct DistortionFlag {
  const char* name;  // "k1" -> --k1
  double value = 0.0;
  bool given = false;
};

struct CameraCommand {
  LensCamera camera;
  std::array<DistortionFlag, 6> distortion{{{"k1"}, {"k2"}, {"p1"}, {"p2"}, {"k3"}, {"k4"}}};
  bool cx_given = false, cy_given = false, fy_given = false;
  std::string output;
};

int RunCamera(CameraCommand& c, const Flags& flags) {
  LensCamera& camera = c.camera;
  if (!c.fy_given) camera.fy = camera.fx;  // square pixels
  if (!c.cx_given) camera.cx = 0.5 * camera.width;
  if (!c.cy_given) camera.cy = 0.5 * camera.height;
  for (const DistortionFlag& flag : c.distortion) {
    if (!flag.given) continue;
    const int index = DistortionIndex(camera.model, flag.name);
    if (index < 0) {
      std::string known;
      for (const DistortionFlag& other : c.distortion) {
        if (DistortionIndex(camera.model, other.name) >= 0) {
          known += (known.empty() ? "--" : ", --") + std::string(other.name);
        }
      }
      ThrowUsage(std::string("--") + flag.name + ": the " + LensModelName(camera.model) +
                 " model has " + (known.empty() ? std::string("no distortion") : known));
    }
    camera.distortion[static_cast<size_t>(index)] = flag.value;
  }
  // --distortion: only the model's own coefficients may be non-zero (a reader refuses others).
  const LensModelTraits& traits = TraitsOf(camera.model);
  for (int i = traits.distortion_count; i < 5; ++i) {
    if (camera.distortion[static_cast<size_t>(i)] != 0.0) {
      ThrowUsage("--distortion: the " + std::string(traits.name) + " model has " +
                 (traits.distortion_count == 0
                      ? std::string("no distortion")
                      : std::to_string(traits.distortion_count) + " coefficients") +
                 " (coefficient " + std::to_string(i + 1) + " is " +
                 FormatNumber(camera.distortion[static_cast<size_t>(i)]) + ")");
    }
  }
  // Validate as every reader of the file will (LensCamera::Finalize): errors name the flag.
  try {
    LensCamera checked = camera;
    checked.Finalize("camera");
  } catch (const std::invalid_argument& error) {
    std::string message = error.what();
    if (message.rfind("camera: ", 0) == 0) message = message.substr(8);
    flags.RethrowNamingFlags(std::invalid_argument(message));
  }
  RefuseExisting(c.output, "output");
  WriteCameraFile(c.output, camera);
  Report report("camera");
  report.Set("output", c.output);
  report.Set("model", LensModelName(camera.model));
  report.Set("width", camera.width);
  report.Set("height", camera.height);
  report.Set("fx", camera.fx);
  report.Set("fy", camera.fy);
  report.Set("cx", camera.cx);
  report.Set("cy", camera.cy);
  report.Set("distortion", std::vector<double>(camera.distortion.begin(), camera.distortion.end()));
  report.Line("wrote %s: %s camera %dx%d, fx %s, fy %s, cx %s, cy %s", c.output.c_str(),
              LensModelName(camera.model), camera.width, camera.height,
              FormatNumber(camera.fx).c_str(), FormatNumber(camera.fy).c_str(),
              FormatNumber(camera.cx).c_str(), FormatNumber(camera.cy).c_str());
  report.Print();
  return 0;
}

}  // namespace

CommandRunner DefineCamera(CLI::App* command) {
  auto c = std::make_shared<CameraCommand>();
  Flags flags(command);
  LensCamera& camera = c->camera;
  flags.Field(camera, "model");
  flags.Field(camera, "width")->required();
  flags.Field(camera, "height")->required();
  flags.Field(camera, "fx")->required();
  // Not given, they follow from the others (RunCamera): --help prints no default for them.
  flags.NoDefault(flags.Field(camera, "fy"))->each([c](const std::string&) { c->fy_given = true; });
  flags.NoDefault(flags.Field(camera, "cx"))->each([c](const std::string&) { c->cx_given = true; });
  flags.NoDefault(flags.Field(camera, "cy"))->each([c](const std::string&) { c->cy_given = true; });
  CLI::Option* all = flags.Field(
      camera, "distortion",
      [&camera](const std::string& text) {
        const std::vector<double> v = ParseNumbers(text, "--distortion");
        if (v.size() > 5) ThrowUsage("--distortion: at most 5 coefficients (got " + text + ")");
        camera.distortion = {0, 0, 0, 0, 0};
        std::copy(v.begin(), v.end(), camera.distortion.begin());
      },
      " On the command line up to 5 numbers K1,K2,...");
  for (DistortionFlag& flag : c->distortion) {
    DistortionFlag* target = &flag;
    flags.Shorthand("distortion", std::string("--") + flag.name);
    command
        ->add_option_function<double>(
            std::string("--") + flag.name,
            [target](double value) {
              target->value = value;
              target->given = true;
            },
            std::string("Distortion coefficient ") + flag.name +
                " (radtan k1 k2 p1 p2 k3; fisheye k1..k4; omnidir k1 k2 p1 p2; default 0): sets "
                "its place in --distortion")
        ->excludes(all);
  }
  flags.Field(camera, "xi");
  flags.Field(camera, "skew");
  command->add_option("-o,--output", c->output, "Camera file to write (aos-camera JSON)")
      ->required();
  flags.Output("--output");
  flags.Force();
  return [c, flags] { return RunCamera(*c, flags); };
}

// ---- rectify ----

namespace {

struct RectifyCommand {
  std::string camera_path;
  std::string light_field_path;
  std::vector<std::string> frames;
  RectifyOptions options;
  LoadOptions load;  // --lightfield: --grey
  std::string output_dir;
};

// The library says "fill" (RectifyOptions::fill); the command line's spelling is --fill.
std::string WithFillFlag(std::string message) {
  const std::string library = "or fill to make";
  if (const size_t at = message.find(library); at != std::string::npos) {
    message.replace(at, library.size(), "or --fill to make");
  }
  return message;
}

// rectify --lightfield: every view with a lens model is rectified (one set of maps per distinct
// lens) and re-posed; pinhole views are kept as they are.
int RunRectifyLightField(const RectifyCommand& c, const Flags& flags, ProgressBar& progress) {
  PendingFolder folder(c.output_dir);
  // The flags before any frame is decoded.
  try {
    c.options.Check();
  } catch (const std::invalid_argument& error) {
    flags.RethrowNamingFlags(std::invalid_argument(WithFillFlag(error.what())));
  }
  LoadResult loaded = LoadLightField(c.light_field_path, c.load, &progress);
  progress.Finish();
  for (const std::string& note : loaded.notes) Note(note);
  RectifyLightFieldResult result;
  try {
    result = RectifyLightField(loaded.light_field, c.options, &progress);
  } catch (const std::invalid_argument& error) {
    const std::string message = error.what();
    if (message.rfind("rectify: ", 0) == 0) {  // the memory needed: name the light field
      ThrowInvalid(c.light_field_path + ": " + message.substr(9));
    }
    flags.RethrowNamingFlags(std::invalid_argument(WithFillFlag(message)));
  }
  if (c.options.fill) {
    Warn("--fill: pixels outside the lens's coverage are black in the rectified views, and a "
         "render integrates them as black samples");
  }
  const LightField& light_field = result.light_field;
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
  Report report("rectify");
  report.Set("output_dir", c.output_dir);
  report.Set("rectified_views", result.rectified_views);
  report.Set("views", light_field.views.size());
  report.Line("wrote %s: lightfield.json with %d rectified views (%s degrees) of %zu",
              c.output_dir.c_str(), result.rectified_views,
              FormatNumber(c.options.fov_deg).c_str(), light_field.views.size());
  report.Print();
  return 0;
}

int RunRectify(const RectifyCommand& c, const Flags& flags) {
  ProgressBar progress(Common().quiet);
  if (!c.light_field_path.empty()) return RunRectifyLightField(c, flags, progress);
  if (c.frames.empty() || c.camera_path.empty()) {
    ThrowUsage("give raw frames and --camera, or --lightfield");
  }
  PendingFolder folder(c.output_dir);
  const LensCamera lens = ReadCameraFile(c.camera_path);
  {
    // Memory from the headers, before any map or frame is allocated: the maps, and for each
    // frame in flight its decoded raw pixels, the rectified frame and the file buffer of it.
    int width = 0, height = 0;
    RectifiedSize(lens, c.options, &width, &height);
    uint64_t per_frame = 0;
    std::string largest;
    for (const std::string& frame : c.frames) {
      const ImageFileInfo info = ReadImageInfo(frame);
      const uint64_t sample = static_cast<uint64_t>(info.channels) * PixelTypeSize(info.type);
      const uint64_t bytes =
          SaturatingProduct({static_cast<uint64_t>(info.width), static_cast<uint64_t>(info.height),
                             sample}) +
          SaturatingProduct({2, static_cast<uint64_t>(std::max(width, 0)),
                             static_cast<uint64_t>(std::max(height, 0)), sample});
      if (bytes > per_frame) {
        per_frame = bytes;
        largest = frame;
      }
    }
    const uint64_t in_flight =
        std::min<uint64_t>(c.frames.size(), static_cast<uint64_t>(ResolveThreadCount(-1)));
    const uint64_t frames_bytes = SaturatingProduct({in_flight, per_frame});
    const uint64_t maps = RectifierBytes(lens, c.options);
    CheckMemoryBudget(maps + frames_bytes < maps ? UINT64_MAX : maps + frames_bytes,
                      largest + ": rectifying " + std::to_string(c.frames.size()) +
                          " frame(s) to " + std::to_string(width) + "x" + std::to_string(height) +
                          " pixels (" + c.camera_path + ")",
                      "the resampling maps, and for each of " + std::to_string(in_flight) +
                          " frame(s) in flight the raw frame, the rectified frame and its file "
                          "buffer");
  }
  Rectifier rectifier;
  try {
    rectifier = MakeRectifier(lens, c.options, &progress);
  } catch (const std::invalid_argument& error) {
    // A lens that cannot cover the view comes from the camera file: name it too (its values
    // may be what is wrong). Other errors name their flag.
    const std::string message = error.what();
    if (message.rfind("fov_deg: the lens does not cover", 0) == 0) {
      throw UsageError(WithFillFlag(message) + " (the lens of " + c.camera_path +
                       ") [option --rectified-fov-deg]");
    }
    flags.RethrowNamingFlags(error);
  }
  std::set<std::string> names;
  for (const std::string& frame : c.frames) {
    const std::string name = fs::path(frame).filename().string();
    if (!names.insert(name).second) {
      ThrowInvalid(frame + ": another frame has the same name " + name +
                   " (outputs keep the frames' names)");
    }
  }
  // Frames in parallel (read, resample, write each): writing dominates (PNG compression), and
  // the frames are independent. The first failing frame (in input order) is the error reported.
  WriteImageOptions write;
  write.description = "aos rectified frame (" + std::string(LensModelName(lens.model)) +
                      " -> pinhole, " + FormatNumber(c.options.fov_deg) + " degrees" +
                      (rectifier.uncovered > 0 ? ", black outside the lens's coverage" : "") + ")";
  ProgressStart(&progress, "rectify", static_cast<int64_t>(c.frames.size()));
  ParallelFor(static_cast<int64_t>(c.frames.size()), -1, &progress, [&](int64_t i) {
    const std::string& frame = c.frames[static_cast<size_t>(i)];
    const Image raw = ReadImage(frame);
    if (raw.width() != lens.width || raw.height() != lens.height) {
      ThrowInvalid(frame + ": is " + std::to_string(raw.width()) + "x" +
                   std::to_string(raw.height()) + " but the camera (" + c.camera_path + ") is " +
                   std::to_string(lens.width) + "x" + std::to_string(lens.height));
    }
    WriteImage((fs::path(folder.TempPath()) / fs::path(frame).filename()).string(),
               Rectify(rectifier, raw), write);
  });
  progress.Finish();
  WriteCameraFile((fs::path(folder.TempPath()) / "camera.json").string(),
                  LensCamera::FromPinhole(rectifier.camera));
  folder.Commit();
  Report report("rectify");
  report.Set("output_dir", c.output_dir);
  report.Set("frames", c.frames.size());
  report.Set("width", rectifier.camera.width);
  report.Set("height", rectifier.camera.height);
  report.Set("filled_pixels", static_cast<long long>(rectifier.uncovered));
  report.Line("wrote %s: %zu rectified frames (%dx%d, %s degrees%s) and camera.json",
              c.output_dir.c_str(), c.frames.size(), rectifier.camera.width,
              rectifier.camera.height, FormatNumber(c.options.fov_deg).c_str(),
              rectifier.uncovered > 0
                  ? (", " + std::to_string(rectifier.uncovered) + " pixels black (--fill)").c_str()
                  : "");
  report.Print();
  return 0;
}

}  // namespace

CommandRunner DefineRectify(CLI::App* command) {
  auto c = std::make_shared<RectifyCommand>();
  Flags flags(command);
  auto* frames = command->add_option("frames", c->frames, "Raw frames (with --camera)");
  auto* camera = command->add_option("--camera", c->camera_path,
                                     "Camera file (aos-camera JSON) of the lens");
  auto* light_field = command->add_option(
      "--lightfield", c->light_field_path,
      "Instead of frames + --camera: an aos light field whose views have lens cameras; writes "
      "DIR/lightfield.json pointing at the rectified frames, with pinhole cameras");
  light_field->excludes(frames)->excludes(camera);
  RectifyOptions& options = c->options;
  flags.Field(options, "fov_deg");
  flags.Field(options, "width");
  flags.Field(options, "height");
  flags.Field(options, "yaw_deg");
  flags.Field(options, "pitch_deg");
  flags.Field(options, "roll_deg");
  flags.Field(options, "fill");
  Flags loader = flags.At("load.");
  AddGreyFlag(loader, c->load)->needs(light_field);
  command->add_option("-o,--output-dir", c->output_dir,
                      "Output folder (must not exist or be empty): the frames under their own "
                      "names, and camera.json (the rectified pinhole camera)")
      ->required();
  flags.Input("frames");
  flags.Input("--camera");
  flags.Input("--lightfield");
  flags.OutputFolder("--output-dir");
  flags.Threads();
  // Every other field of the tables (tools/vocabulary.py NOT_ON_THE_CLI: why not those).
  flags.Remaining(c->options);
  return [c, flags] { return RunRectify(*c, flags); };
}

// ---- resolution ----

namespace {

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
};

LensCamera CameraOf(const ResolutionCommand& c) {
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
  return camera;
}

int RunResolution(const ResolutionCommand& c, const Flags& flags) {
  const LensCamera camera = CameraOf(c);
  const ResolutionResult r =
      flags.NamingFlags([&] { return SamplingResolution(camera, c.options); });
  Report report("resolution");
  report.Set("eq2_samples_per_m2", r.eq2_samples_per_m2);
  report.Set("eq2_sample_size_m", r.eq2_sample_size_m);
  report.Set("samples_per_m2", r.samples_per_m2);
  report.Set("sample_size_m", r.sample_size_m);
  report.Set("pixels_on_plane", static_cast<long long>(r.pixels_on_plane));
  report.Set("pixels_off_axis", static_cast<long long>(r.pixels_off_axis));
  report.Set("footprint_m2", r.footprint_m2);
  report.Set("pose_error_m", r.pose_error_m);
  report.Set("effective_sample_size_m", r.effective_sample_size_m);
  report.Set("effective_samples_per_m2", r.effective_samples_per_m2);
  report.Result("Eq. 2 (at nadir):        %.1f samples/m^2, sample size %.2f cm",
                r.eq2_samples_per_m2, 100.0 * r.eq2_sample_size_m);
  std::string off_axis;
  if (r.pixels_off_axis > 0) {
    off_axis = "; " + std::to_string(r.pixels_off_axis) + " pixels further off the axis left out";
  }
  report.Result("back-projected (App. A): %.1f samples/m^2, sample size %.2f cm (%lld pixels "
                "within %s degrees of the axis over %.1f m^2%s)",
                r.samples_per_m2, 100.0 * r.sample_size_m,
                static_cast<long long>(r.pixels_on_plane),
                FormatNumber(c.options.max_off_axis_deg).c_str(), r.footprint_m2,
                off_axis.c_str());
  report.Result("pose error %.2f cm: effective sample size p' = p + 2e = %.2f cm, %.1f "
                "samples/m^2",
                100.0 * r.pose_error_m, 100.0 * r.effective_sample_size_m,
                r.effective_samples_per_m2);
  report.Print();
  return 0;
}

}  // namespace

CommandRunner DefineResolution(CLI::App* command) {
  auto c = std::make_shared<ResolutionCommand>();
  Flags flags(command);
  command->add_option("--width", c->width, "Image width, pixels")->required();
  command->add_option("--height", c->height, "Image height, pixels")->required();
  auto* fov = command->add_option("--lens-fov-deg,--fov-deg", c->fov_deg,
                                  "Horizontal field of view of the lens, degrees (square pixels, "
                                  "centred; --fov-deg is its old name)");
  auto* focal = command->add_option("--focal", c->focal, "Focal lengths FX,FY in pixels");
  fov->excludes(focal);
  command->add_option("--principal", c->principal,
                      "Principal point CX,CY (pixel centres at +0.5; default: image centre)");
  command->add_option("--model", c->model, "pinhole, radtan, fisheye or omnidir")
      ->capture_default_str();
  command->add_option("--distortion", c->distortion,
                      "Up to 5 coefficients: radtan k1,k2,p1,p2,k3; fisheye k1,k2,k3,k4; "
                      "omnidir k1,k2,p1,p2");
  command->add_option("--xi", c->xi, "omnidir: xi")->capture_default_str();
  command->add_option("--skew", c->skew, "omnidir: skew")->capture_default_str();
  ResolutionOptions& options = c->options;
  flags.Field(options, "distance_m");
  auto* error_px = flags.Field(options, "pose_error_px");
  auto* error_m = flags.Field(options, "pose_error_m");
  error_px->excludes(error_m);
  flags.Field(options, "max_off_axis_deg");
  flags.Threads();
  // Every other field of the tables (tools/vocabulary.py NOT_ON_THE_CLI: why not those).
  flags.Remaining(c->options);
  return [c, flags] { return RunResolution(*c, flags); };
}

}  // namespace aos::cli
