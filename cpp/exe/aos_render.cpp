// aos-render: the command-line front end. Each command fills the core's Options structs (the
// same ones Python fills) through flags bound to their fields (cli.h), runs the algorithm with a
// progress bar, and writes outputs atomically. The table below lists every command once; each
// area's commands live in their own file (commands.h).
// Before a command runs, every output flag is checked against every input flag of the command
// (CheckFileFlags, cli.h): an input is never an output, --force or not.
// Exit codes: 0 success, 1 bad input or failure (one line on stderr), 2 bad command line (an
// unknown flag, or a value out of range: UsageError), 128 + the signal when interrupted (the
// shell's convention): 130 SIGINT (Ctrl-C), 143 SIGTERM, 129 SIGHUP; the work stops at its next
// poll (within about a second) and no output is left behind.
#include <omp.h>

#include <cstdio>
#include <map>
#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "aos/util/error.h"
#include "aos/util/file_util.h"
#include "aos/util/parallel.h"
#include "aos/util/version.h"
#include "commands.h"
#include "progress_bar.h"

namespace aos::cli {
namespace {

// `aos-render flags`: every flag bound to an Options field, as JSON (tools/vocabulary.py);
// `aos-render flags --files`: every flag naming a file or folder, with its role (cli.h).
CommandRunner DefineFlags(CLI::App* command) {
  auto files = std::make_shared<bool>(false);
  command->add_flag("--files", *files,
                    "List the flags that name files or folders instead, with their role (input, "
                    "input-folder, output, output-folder)");
  return [files] {
    nlohmann::ordered_json list = nlohmann::ordered_json::array();
    if (*files) {
      for (const FileFlag& file : AllFileFlags()) {
        list.push_back({{"command", file.command},
                        {"flag", file.flag},
                        {"role", FileRoleName(file.role)}});
      }
      std::fputs((list.dump(1) + "\n").c_str(), stdout);
      return 0;
    }
    for (const FlagBinding& binding : AllBindings()) {
      list.push_back({{"command", binding.command},
                      {"flag", binding.flag},
                      {"field", binding.field},
                      {"default", binding.default_text},
                      {"source", binding.source}});
    }
    std::fputs((list.dump(1) + "\n").c_str(), stdout);
    return 0;
  };
}

// The commands: name, one line of help, the function that defines it.
const CommandEntry kCommands[] = {
    {"integral", "Render an integral image (Eq. 1) of a light field onto a focal plane",
     DefineIntegral},
    {"detect",
     "Find the person: anomaly detection (RX, local RX, or a temperature) on an integral image, "
     "the detections located on the focal surface and in WGS84, written as GeoJSON, KML, CSV "
     "and an overlay",
     DefineDetect},
    {"live",
     "In flight: integrate a sliding window of the newest frames as they arrive in a folder (or "
     "--replay a recorded flight), detect on every update, and keep the places found as "
     "GeoJSON/CSV",
     DefineLive},
    {"stack",
     "Render a focal stack: N slices between two boundary planes, written as a folder of float32 "
     "TIFFs with stack.json",
     DefineStack},
    {"merge",
     "Merge a focal stack (from `stack`) into an all-in-focus image, a depth map and a confidence "
     "map",
     DefineMerge},
    {"allinfocus",
     "One call: render the slices one at a time and merge them (memory does not grow with "
     "--slices) into an all-in-focus image, a depth map and a confidence map",
     DefineAllInFocus},
    {"map",
     "Render an orthographic map (a virtual camera looking straight down) of a light field onto "
     "a horizontal focal plane, written as a Cloud-Optimised GeoTIFF with a count band",
     DefineMap},
    {"view",
     "Interactive viewer in the browser: load the frames once, serve a local page (127.0.0.1, "
     "a per-session token) that re-renders while you drag focus, aperture, views and camera",
     DefineView},
    {"calibrate",
     "Calibrate a lens from checkerboard frames (OpenCV): write a camera file with the RMS "
     "reprojection error and the frames used; frames without the board are listed, not fatal",
     DefineCalibrate},
    {"camera",
     "Write a camera file (aos-camera JSON) for a known lens, without a checkerboard: model, size, "
     "focal lengths, principal point and distortion, validated as readers will",
     DefineCamera},
    {"rectify",
     "Resample raw frames taken through a lens model (a camera file) into perspective frames with "
     "a chosen field of view, size and orientation, in the input's bit depth",
     DefineRectify},
    {"resolution",
     "Spatial sampling resolution of a nadir camera over a focal plane (the AOS paper's Eq. 2 and "
     "Appendix A back-projection) and the effective resolution under a pose error",
     DefineResolution},
    {"poses",
     "Estimate the frames' poses with COLMAP (CPU, headless) and write a light field; optionally "
     "geo-referenced by known positions",
     DefinePoses},
    {"import-colmap",
     "Import a COLMAP sparse model (text or binary) as a light field; optionally geo-referenced "
     "by known positions",
     DefineImportColmap},
    {"ground",
     "Where is the ground: estimate it from reconstructed points (a robust plane and a coarse DEM "
     "GeoTIFF by a lower-envelope fit, usable as --focal-surface), or report the flight's height "
     "above a given terrain",
     DefineGround},
    {"import-telemetry",
     "Pose frames from GPS and gimbal telemetry (a CSV log, OpenDroneMap's geo.txt or the "
     "frames' EXIF/XMP tags), no COLMAP: a geo-referenced light field in the flight's UTM zone",
     DefineImportTelemetry},
    {"import-video",
     "Frames and poses from a drone video with DJI's SRT telemetry: frames every N seconds or "
     "metres, posed as import-telemetry poses them, into a new folder with a light field",
     DefineImportVideo},
    {"export-odm",
     "Write a geo-referenced light field's camera positions and angles as OpenDroneMap's "
     "geo.txt (odm --geo)",
     DefineExportOdm},
    {"check-gcp",
     "Check a geo-referenced light field's poses against ground control (OpenDroneMap's "
     "gcp_list.txt): the reprojection error of each sighting, in pixels and on the ground",
     DefineCheckGcp},
    {"simulate",
     "Simulate a scene (docs/scenes.md): write its views, the light field (recorded poses) and "
     "the ground truth into a new folder",
     DefineSimulate},
    {"demo",
     "Simulate the built-in default scene (a red person-sized target on a forest floor under "
     "procedural trees, RGB), render a single view, integral images and an all-in-focus image "
     "from above, score them against the ground truth, and write it all with an index.html",
     DefineDemo},
    {"metrics",
     "Compare an image with a reference: MSE, PSNR, SSIM and colour (quaternion) SSIM "
     "(definitions in docs/metrics.md)",
     DefineMetrics},
    {"plan",
     "Plan a flight: the waypoints of a synthetic aperture (circle, sector, rectangle, polygon, "
     "line; scan lines, grid or rings, spacing growing outwards), its length, time and Eq. 2 "
     "resolution, exported as CSV, GeoJSON and KML (WGS84) and drawn as a map",
     DefinePlan},
    {"flags", "List every flag bound to an Options field, with its default (JSON)", DefineFlags},
};

}  // namespace
}  // namespace aos::cli

int main(int argc, char** argv) {
  using namespace aos::cli;
  CLI::App app{"aos-render: Airborne Optical Sectioning - integral images from drone light fields"};
  app.set_version_flag("--version", std::string("aos-render ") + aos::kVersion);
  app.require_subcommand(1);
  std::map<CLI::App*, CommandRunner> runners;
  for (const CommandEntry& entry : kCommands) {
    CLI::App* command = app.add_subcommand(entry.name, entry.help);
    runners[command] = entry.define(command);
    Flags common(command);
    common.Quiet();
    common.Json();
    if (Common().num_threads.count(entry.name) == 0) common.Threads();
  }
  // First of all, so that a signal is never lost, whatever stage the command is in.
  InstallInterruptHandler();
  aos::SetCommitCancelled(&Interrupted);
  WarnDeprecatedSpellings(argc, argv);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ConversionError& error) {
    std::fprintf(stderr, "aos-render: error: %s\n", aos::OneLine(error.what()).c_str());
    return 2;
  } catch (const CLI::ValidationError& error) {
    // A flag's value refused while parsing: one line, like every other error.
    std::fprintf(stderr, "aos-render: error: %s\n", aos::OneLine(error.what()).c_str());
    return 2;
  } catch (const CLI::ParseError& error) {
    // --help and --version end here with code 0; every command-line mistake exits with 2.
    const int code = app.exit(error);
    return code == 0 ? 0 : 2;
  }
  try {
    for (const auto& [command, run] : runners) {
      if (!command->parsed()) continue;
      // --threads also caps the process's OpenMP workers (stages without their own count).
      const int threads = *Common().num_threads.at(command->get_name());
      try {
        aos::CheckThreadCount(threads);
      } catch (const std::invalid_argument& error) {
        throw UsageError(std::string(error.what()) + " [option --threads]");
      }
      if (threads >= 1) omp_set_num_threads(threads);
      CheckFileFlags(command->get_name());
      return run();
    }
  } catch (const aos::Cancelled&) {
    std::fprintf(stderr, "aos-render: interrupted; no output written\n");
    return InterruptExitCode();
  } catch (const UsageError& error) {
    std::fprintf(stderr, "aos-render: error: %s\n", error.what());
    return 2;
  } catch (const std::exception& error) {
    // One line, naming the user's paths (also for errors that did not come through ThrowInvalid).
    std::fprintf(stderr, "aos-render: error: %s\n",
                 aos::OneLine(aos::UserPaths(error.what())).c_str());
    return Interrupted() ? InterruptExitCode() : 1;
  }
  return 2;
}
