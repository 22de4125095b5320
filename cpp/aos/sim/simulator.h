#pragma once
// The occlusion simulator: renders the views of a scene (scene.h) with Embree and writes the
// ground truth a study needs.
//
// Contract
// - Views are nadir-looking cameras (image top towards +y; pinhole or a lens model, scene.h) at
//   ViewPositions(scene). Each pixel averages samples_per_pixel^2 stratified rays; a ray takes
//   the value of the first surface it hits (ground, target, voxel, leaf or trunk), 0 where it
//   hits nothing. Values are linear in [0, 1] and stored in the views' type: 8-bit (x 255), 16-bit (x 65535), rounded and clamped,
//   or float32 unscaled.
// - Only the stages a scene names run (SimulationStats counts what each did):
//   * occluders: geometry and an Embree BVH only when the scene has voxels or trees; ground
//     rays are intersected analytically for a (tilted) plane and through an Embree grid BVH only
//     for a height field (steps);
//   * sun: one shadow ray per shaded sample, only with effects.sun;
//   * sensor noise: one Gaussian draw per stored value (of an imaged pixel), only with
//     effects.sensor_noise;
//   * pose noise: six draws per view, only with effects.pose_noise; the light field then holds
//     the recorded (noisy) poses while the images are rendered from the true ones;
//   * thermal: emission per material replaces albedo (no extra rays);
//   * lens: only for a lens camera (camera.lens other than "pinhole"): each sample's ray is
//     unprojected through the lens model (exact, no resampling; directions computed once for
//     all views); samples outside the lens's valid field (a fisheye's image circle) trace no
//     ray and count as 0 (a pixel with no such sample stays 0, without sensor noise). Views
//     carry the lens (View::lens) for direct sampling.
//   Each random stage has its own stream (random.h), so adding an effect never changes what
//   other stages produce.
// - Ground truth, seen by the truth camera (nadir, at truth.position): the ground alone (no
//   occluders, no noise; sun shading and the ground's own shadows when a sun is given), in the
//   views' type; the ground's depth along the camera axis and its height z (float32, metres, 0
//   where a ray misses the ground); per pixel the number of views that see the ground point
//   (it lies in the view's valid field and inside its image) and the fraction of those whose ray to
//   it is blocked (by occluders or the ground itself).
// - Deterministic: the same scene (and seed) gives the same bytes for any thread count.
//
// Throws std::invalid_argument for a scene that fails Scene::Check() or needs more memory than
// stated limits (height fields up to 4096 x 4096 cells), aos::Cancelled if the progress sink asks
// to stop.
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "aos/geometry/heightfield.h"
#include "aos/geometry/pinhole.h"
#include "aos/image/image.h"
#include "aos/lightfield/lightfield.h"
#include "aos/sim/scene.h"
#include "aos/util/progress.h"
#include "aos/util/option_fields.h"
#include "aos/util/parallel.h"

namespace aos {

struct SimulateOptions {
  int num_threads = -1;  // worker threads; -1 = all cores
  void Check() const;
  // The field table (util/option_fields.h): every field once, in declaration order.
  template <class Visit>
  static void Fields(Visit&& field) {
    using O = SimulateOptions;
    field(OptionField("num_threads", &O::num_threads, "", kThreadCountRange,
                      "Worker threads; -1 = all cores."));
  }
};

// What each stage did. Counters are exact; seconds are wall time of the stage (0 if skipped).
struct SimulationStats {
  int64_t views = 0;
  int64_t primary_rays = 0;            // camera rays of the views
  int64_t shadow_rays = 0;             // sun visibility rays (views and truth)
  int64_t truth_rays = 0;              // camera rays of the truth image
  int64_t blocked_fraction_rays = 0;   // ground-point-to-view rays of the blocked fraction
  int64_t sensor_noise_draws = 0;
  int64_t pose_noise_draws = 0;
  int64_t lens_rays = 0;               // primary rays unprojected through a lens model (0: pinhole)
  int64_t voxels = 0;                  // occupied voxel cells
  int64_t trees = 0;
  int64_t leaf_quads = 0;
  int64_t trunk_quads = 0;
  bool occluder_bvh = false;           // an Embree scene of occluders was built
  bool ground_bvh = false;             // an Embree grid of the ground was built
  int64_t ground_cells = 0;            // height-field cells
  double nadir_blocked_fraction = 0;   // realised fraction of voxel columns that block
  int64_t occluder_bytes = 0;          // occluder geometry kept for tracing (excl. Embree's BVH)
  double seconds_geometry = 0;         // occluder generation + BVH builds
  double seconds_views = 0;
  double seconds_truth = 0;
  double seconds_blocked_fraction = 0;
};

struct GroundTruth {
  PinholeCamera camera;
  Rigid3d cam_from_world;
  Image ground;            // views' type and channels: the occluder-free ground
  Image depth;             // float32, metres along the optical axis (0 = no ground)
  Image height;            // float32, ground z, metres (0 = no ground)
  Image views_seeing;      // uint32: views that see the ground point
  Image blocked_fraction;  // float32 in [0, 1]: blocked / seeing (0 where no view sees)
  bool has_blocked_fraction = false;  // false when truth.blocked_fraction is off
  double ground_height_at_center = 0;  // ground z under the truth camera (focal plane to use)
};

struct SimulationResult {
  LightField light_field;                      // images + recorded poses
  std::vector<Rigid3d> true_cam_from_world;    // true poses, view order
  GroundTruth truth;
  SimulationStats stats;
};

SimulationResult Simulate(const Scene& scene, const SimulateOptions& options = {},
                          ProgressSink* progress = nullptr);

// Writes a simulation into `output_dir`, which must not exist or be empty (nothing is ever
// overwritten). Everything is written into a temporary sibling folder first and renamed into
// place at the end, so a failure leaves no partial output. Files:
//   lightfield.json (recorded poses), lightfield_true.json (true poses), views/NNNN.png|.tif,
//   truth/ground.png|.tif, truth/depth.tif, truth/height.tif, truth/views_seeing.tif,
//   truth/blocked_fraction.tif (if computed), truth/truth.json (truth camera, suggested focal
//   plane, stats), scene.json (the scene as simulated, every field written out).
void WriteSimulation(const SimulationResult& result, const Scene& scene,
                     const std::string& output_dir);

// The scene's ground as a DEM raster (geometry/heightfield.h), in the simulator's world frame
// (the light field's local frame: origin 0, no CRS): the vertices of the grid the simulator traces
// a height-field ground on are the raster's pixel centres (to double rounding of x, y), each holding GroundSpec::HeightAt there
// (float32). `extent` [xmin, ymin, xmax, ymax] (metres; all zero = ground.extent) is cut into
// ceil(extent / ground.cell_size) cells per axis as the simulator cuts ground.extent, so for a
// height-field ground (steps) with that extent HeightfieldToMesh of the result is the simulated
// ground itself, triangle for triangle (both split a cell along the same diagonal: the raster's
// (i, j)-(i + 1, j + 1), Embree's grid quad v1-v3), and a render focused on it (FocalSurface)
// focuses on the ground the views saw. For a plane ground it is that plane over the extent.
// Nothing is written: WriteHeightfield writes it as a GeoTIFF.
// Throws std::invalid_argument "<source>: ..." when both extents are all zero (the simulator then
// uses the views' footprint, not known here), for an empty or non-finite extent, or more than
// 4096 x 4096 cells.
Heightfield GroundHeightfield(const Scene& scene,
                              const std::array<double, 4>& extent = {0.0, 0.0, 0.0, 0.0});

// The stats and the truth camera as a JSON object (what truth/truth.json holds): truth_camera and
// truth_cam_from_world in the shared shapes of lightfield/json_codec.h, truth_fov_deg beside.
std::string SimulationSummaryJson(const SimulationResult& result);

}  // namespace aos
