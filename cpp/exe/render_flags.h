#pragma once
// Flags and hand-overs the rendering commands share (render_commands.cpp defines them;
// live_commands.cpp uses them too): the light field to load and the virtual camera, the focal
// surface, detection and viewer flags, and the Python interpreter the viewer runs in.
#include <string>
#include <vector>

#include "aos/detect/detect.h"
#include "aos/lightfield/lightfield.h"
#include "aos/render/integral.h"
#include "aos/viewer/viewer_options.h"
#include "cli.h"

namespace aos::cli {

// The light field to load and the virtual camera: shared by integral, stack and allinfocus.
struct RenderArgs {
  std::string light_field_path;
  LoadOptions load;
  std::string look_at;
  std::string cam_from_world;
  std::string views;
  std::string focal_surface;  // --focal-surface FILE (mesh or DEM raster)
  std::string pose_view;  // an index or a view's name, resolved once the light field is loaded
};

// --frames-fov-deg, --images-dir, --grey, --mask, --mask-dir (LoadOptions).
void AddLoadFlags(const Flags& flags, LoadOptions& load);
// --focal-height H: the horizontal plane z = H as the focal surface.
CLI::Option* AddFocalHeightFlag(Flags& flags, FocalSurface& focal_surface, const char* help);
// The detector's flags (DetectOptions), under the same names everywhere.
void AddDetectFlags(Flags& flags, DetectOptions& detect);
// --host, --port, --max-pages, --no-browser, --open-browser (ViewerOptions); returns
// --open-browser.
CLI::Option* AddViewerFlags(Flags& flags, ViewerOptions& viewer, bool& no_browser);
// --focal-surface FILE|PLANE and --surface-offset.
CLI::Option* AddSurfaceFlags(Flags& render, RenderArgs& args, IntegralOptions& options);
// Reads the focal surface file `path` (none when empty) into `surface`, with a note.
void ReadFocalSurface(const std::string& path, FocalSurface* surface);

// The Python interpreters tried for the viewer, in order (AOS_PYTHON first).
std::vector<std::string> PythonCandidates();
// The first candidate that imports aos.MODULE; throws naming `command` and the candidates.
std::string FindPython(const std::string& command, const std::string& module);
// `python -c` code that runs aos.MODULE's main(argv) and answers a Ctrl-C while the package
// loads like any interrupt (one line, exit 130).
std::string PythonLauncher(const std::string& command, const std::string& module);

}  // namespace aos::cli
