#pragma once
// The commands of aos-render, one Define function each, grouped by area (one file per area):
//   render_commands.cpp   integral, stack, merge, allinfocus, map, detect, view (hands over to
//                         the Python viewer, python/aos/viewer)
//   live_commands.cpp     live (in-flight integration)
//   sim_commands.cpp      simulate, demo
//   lens_commands.cpp     calibrate, camera, rectify, resolution
//   sfm_commands.cpp      poses, import-colmap, ground
//   telemetry_commands.cpp  import-telemetry
//   metrics_commands.cpp  metrics
//   plan_commands.cpp     plan
// The command table (name, help, Define) is in aos_render.cpp. A Define function declares the
// command's flags on `command` and returns the function that runs it after parsing.
#include "cli.h"

namespace aos::cli {

CommandRunner DefineIntegral(CLI::App* command);
CommandRunner DefineStack(CLI::App* command);
CommandRunner DefineMerge(CLI::App* command);
CommandRunner DefineAllInFocus(CLI::App* command);
CommandRunner DefineMap(CLI::App* command);
CommandRunner DefineView(CLI::App* command);
CommandRunner DefineSimulate(CLI::App* command);
CommandRunner DefineDemo(CLI::App* command);
CommandRunner DefineCalibrate(CLI::App* command);
CommandRunner DefineCamera(CLI::App* command);
CommandRunner DefineRectify(CLI::App* command);
CommandRunner DefineResolution(CLI::App* command);
CommandRunner DefinePoses(CLI::App* command);
CommandRunner DefineImportColmap(CLI::App* command);
CommandRunner DefineGround(CLI::App* command);
CommandRunner DefineImportTelemetry(CLI::App* command);
CommandRunner DefineExportOdm(CLI::App* command);
CommandRunner DefineCheckGcp(CLI::App* command);
CommandRunner DefineDetect(CLI::App* command);
CommandRunner DefineLive(CLI::App* command);
CommandRunner DefineImportVideo(CLI::App* command);
CommandRunner DefineMetrics(CLI::App* command);
CommandRunner DefinePlan(CLI::App* command);

}  // namespace aos::cli
