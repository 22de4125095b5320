#pragma once
// A preview of what a flight plan will reveal: the plan flown in the occlusion simulator over a
// scene (docs/scenes.md: a forest of a given density), scored as the demo scores its renders.
// A top layer: it uses the simulator and the demo (demo/demo.h); nothing below includes it.
//
// Contract
// - The scene's sampling is replaced by the plan's shots, moved so that the plan's growth centre
//   lies at the scene's origin: view i is at (x_i - cx, y_i - cy, agl_i), the height above the
//   scene's z = 0 (the plan's heights above its own terrain; the scene's ground is its own).
//   The truth camera looks straight down from (0, 0, mean agl) unless the scene places it.
// - The integral image focused on the ground under the truth camera, over every view, is compared
//   with the occluder-free ground truth (PSNR, SSIM: metrics/quality.h over the covered pixels);
//   visible_fraction = 1 - the mean over the truth pixels seen by a view of the fraction of the
//   views seeing that ground point whose ray is blocked (the share of rays that reach the
//   ground). With targets in the scene the demo's contrast-to-noise figure is reported too.
//
// Throws std::invalid_argument for a plan without shots and what LoadScene / RunDemo throw.
#include <cstdint>
#include <string>

#include "aos/image/image.h"
#include "aos/plan/flight_plan.h"
#include "aos/sim/scene.h"
#include "aos/util/progress.h"

namespace aos {

struct PlanPreviewResult {
  int64_t views = 0;
  double visible_fraction = 0.0;  // [0, 1]; -1 when the scene computes no blocked fraction
  double psnr_db = 0.0;           // integral on the ground vs the occluder-free truth
  double ssim = 0.0;
  double single_view_psnr_db = 0.0;  // one view (aperture 0), for comparison
  bool has_target = false;
  double contrast_to_noise = 0.0;    // the integral's, with targets
  Image integral;                 // float32, views' units, truth camera size
  Image truth;                    // the occluder-free ground (views' type)
  double seconds = 0.0;
};

PlanPreviewResult PreviewFlightPlan(const FlightPlanResult& plan, Scene scene,
                                    int num_threads = -1, ProgressSink* progress = nullptr);

}  // namespace aos
