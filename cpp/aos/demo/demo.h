#pragma once
// The demo: what `aos-render demo` and `aos.run_demo` do. It simulates a scene, renders what AOS
// is about from the scene's truth camera, scores each image against the ground truth, measures
// how visible the scene's targets are in each, and writes it all with a self-contained
// index.html that shows the images side by side.
//
// A top layer: it uses the simulator (sim/), the renderers (render/), the metrics (metrics/) and
// image files; nothing below includes it.
//
// Contract
// - Renders, all from the truth camera (truth.cam_from_world, its field of view and size), in the
//   views' units (float32):
//     single_view          aperture radius 0 (one view per pixel: what one photo shows),
//                          focused on the ground under the truth camera;
//     integral_ground      every view, focused on the ground (the AOS integral image);
//     integral_occluders   every view, focused inside the occluders (only with occluders):
//                          the voxel box's centre height, else the trees' mean crown centre
//                          height (mean tree height x (1 - crown_fraction / 2));
//     all_in_focus         (all_in_focus_slices > 0) RenderAllInFocus, method "improved", with
//                          the slices from the ground to the top of the occluders (the voxel
//                          box's top, else the trees' largest height; 10 m above the ground
//                          without occluders).
//   Each is compared with truth.ground by CompareImages over the pixels it covers (count > 0;
//   the all-in-focus image over all pixels).
// - Target visibility (TargetVisibility), for the truth and each render. Target pixels: truth
//   pixels whose ground point (from truth.depth) lies inside a target rectangle; surroundings:
//   ground pixels within target_margin_m of a target's rectangle and in none. Each pixel's colour
//   is projected onto the unit colour direction from the truth's mean surroundings colour to
//   its mean target colour (for one channel: +1 or -1), giving a "target-likeness" t; then
//     contrast_to_noise = (mean t over the target - mean t over the surroundings) /
//                         sqrt((variance over the target + variance over the surroundings) / 2),
//     standout_fraction = the fraction of target pixels whose t exceeds the 99th percentile of
//                         t over the surroundings (pixels more target-like than 99 % of the
//                         ground around them).
//   In a single view under a canopy the target shows only in the gaps between leaves
//   (standout_fraction about the fraction of the target seen, a low contrast-to-noise ratio
//   from the sharp leaves); the integral blurs the leaves into an even veil, so nearly every
//   target pixel stands out again. Pixels a render does not cover (count 0) are left out.
//   Without targets in the truth camera's view (or a truth without contrast between target and
//   surroundings), has_target is false and the figures are 0.
// - WriteDemo writes a new folder atomically (util/file_util.h PendingFolder): the simulation
//   (WriteSimulation's files), the renders as PNG (8-bit for 8-bit views, else 16-bit;
//   <name>.png), truth_ground.png (the truth as PNG, for float views whose truth/ground is a
//   TIFF), demo.json (the figures) and index.html (no external assets, no script: what AOS is,
//   what each image shows, the figures, the commands that reproduce them; relative links to
//   files in the folder only).
//
// Throws std::invalid_argument naming the option or the folder (a folder that exists and is not
// empty is refused before any work by CheckDemoFolder and again by WriteDemo), and what
// Simulate / RenderIntegral / RenderAllInFocus throw; aos::Cancelled when the sink asks to stop.
#include <cstdint>
#include <string>
#include <vector>

#include "aos/image/image.h"
#include "aos/metrics/quality.h"
#include "aos/sim/scene.h"
#include "aos/sim/simulator.h"
#include "aos/util/progress.h"
#include "aos/util/option_fields.h"
#include "aos/util/parallel.h"

namespace aos {

struct DemoOptions {
  // Worker threads of the simulation and the renders; -1 = all cores.
  int num_threads = -1;
  // Slices of the all-in-focus focal stack, from the ground to the top of the occluders,
  // 0..1000; 0 = no all-in-focus image, 1 = a stack of one slice.
  int all_in_focus_slices = 16;
  // Width of the ring of ground around each target whose pixels are the target's surroundings
  // in the visibility figures, metres (> 0).
  double target_margin_m = 1.0;
  void Check() const;
  // The field table (util/option_fields.h): every field once, in declaration order.
  template <class Visit>
  static void Fields(Visit&& field) {
    using O = DemoOptions;
    field(OptionField("num_threads", &O::num_threads, "", kThreadCountRange,
                      "Worker threads of the simulation and the renders; -1 = all cores."));
    field(OptionField("all_in_focus_slices", &O::all_in_focus_slices, "", Range::Any(),
                      "Slices of the all-in-focus stack from the ground to the top of the "
                      "occluders, 0..1000; 0 = no all-in-focus image."));
    field(OptionField("target_margin_m", &O::target_margin_m, "m", Range::Any(),
                      "Ring of ground around each target used as its surroundings in the "
                      "visibility figures, metres (> 0)."));
  }
};

// How clearly the targets show in one image (see the contract above).
struct TargetVisibility {
  bool has_target = false;
  int64_t target_pixels = 0;        // target pixels compared (covered by the image)
  int64_t surrounding_pixels = 0;   // surrounding pixels compared
  double contrast_to_noise = 0.0;   // dimensionless; higher = clearer
  double standout_fraction = 0.0;   // [0, 1]
};

struct DemoRender {
  std::string name;              // file stem: single_view, integral_ground, ...
  std::string title;             // what it is, for people ("Integral image, focused on the ground")
  double focal_height = 0.0;     // focal plane z (the all-in-focus image: the stack's first plane)
  double aperture_radius = 0.0;  // metres; infinity = every view
  Image image;                   // float32 in the views' units, truth camera size and channels
  Image count;                   // uint32 views per pixel (empty for the all-in-focus image)
  QualityResult quality;         // against truth.ground
  TargetVisibility visibility;
  double seconds = 0.0;          // wall time of the render
};

struct DemoResult {
  Scene scene;                   // as simulated
  DemoOptions options;
  SimulationResult simulation;
  Image target_mask;             // uint8, truth camera size: 1 = target, 2 = surroundings, 0 else
  TargetVisibility truth_visibility;  // the ground truth's own (its best case)
  // Mean blocked fraction (truth.blocked_fraction) over the target pixels: the share of the
  // views' rays to the target that the occluders block; -1 without a blocked-fraction map or
  // target.
  double target_blocked_fraction = -1.0;
  // Focal planes used (z, metres): the ground under the truth camera and inside the occluders.
  double ground_height = 0.0;
  double occluder_height = 0.0;
  double top_height = 0.0;       // the all-in-focus stack's last plane
  std::vector<DemoRender> renders;
  double seconds_simulation = 0.0;
  double seconds_total = 0.0;
  // The render named `name`; throws std::invalid_argument if there is none.
  const DemoRender& Render(const std::string& name) const;
};

// Refuses a demo folder that exists and is not empty, or whose parent is missing (call before
// the work; WriteDemo checks again).
void CheckDemoFolder(const std::string& folder);

DemoResult RunDemo(const Scene& scene, const DemoOptions& options = {},
                   ProgressSink* progress = nullptr);

// Writes the demo into `folder` (a new or empty folder; see the contract). Returns the paths of
// the files written, relative to `folder`, sorted.
std::vector<std::string> WriteDemo(const DemoResult& result, const std::string& folder);

// The figures as JSON (what demo.json holds).
std::string DemoSummaryJson(const DemoResult& result);

// The page (what index.html holds).
std::string DemoIndexHtml(const DemoResult& result);

}  // namespace aos
