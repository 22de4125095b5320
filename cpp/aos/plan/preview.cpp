// The simulated preview of a flight plan (preview.h).
#include "aos/plan/preview.h"

#include <chrono>
#include <cmath>

#include "aos/demo/demo.h"
#include "aos/util/error.h"

namespace aos {

PlanPreviewResult PreviewFlightPlan(const FlightPlanResult& plan, Scene scene, int num_threads,
                                    ProgressSink* progress) {
  if (plan.waypoints.empty()) ThrowInvalid("preview: the plan has no shots");
  const auto start = std::chrono::steady_clock::now();
  scene.sampling.positions.clear();
  double mean_agl = 0.0;
  for (const Waypoint& w : plan.waypoints) {
    scene.sampling.positions.push_back(
        {w.x - plan.growth_center[0], w.y - plan.growth_center[1], w.agl_m});
    mean_agl += w.agl_m / static_cast<double>(plan.waypoints.size());
  }
  if (std::isnan(scene.truth.position[0])) scene.truth.position = {0.0, 0.0, mean_agl};
  DemoOptions options;
  options.num_threads = num_threads;
  options.all_in_focus_slices = 0;
  const DemoResult demo = RunDemo(scene, options, progress);
  const DemoRender& integral = demo.Render("integral_ground");
  PlanPreviewResult result;
  result.views = static_cast<int64_t>(plan.waypoints.size());
  result.psnr_db = integral.quality.psnr_db;
  result.ssim = integral.quality.ssim;
  result.single_view_psnr_db = demo.Render("single_view").quality.psnr_db;
  result.has_target = integral.visibility.has_target;
  result.contrast_to_noise = integral.visibility.contrast_to_noise;
  result.integral = integral.image;
  result.truth = demo.simulation.truth.ground;
  const GroundTruth& truth = demo.simulation.truth;
  if (truth.has_blocked_fraction) {
    double blocked = 0.0;
    int64_t seen = 0;
    for (int y = 0; y < truth.blocked_fraction.height(); ++y) {
      for (int x = 0; x < truth.blocked_fraction.width(); ++x) {
        if (*truth.views_seeing.At<uint32_t>(x, y) == 0) continue;
        blocked += *truth.blocked_fraction.At<float>(x, y);
        ++seen;
      }
    }
    result.visible_fraction = seen > 0 ? 1.0 - blocked / static_cast<double>(seen) : 0.0;
  } else {
    result.visible_fraction = -1.0;
  }
  result.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace aos
