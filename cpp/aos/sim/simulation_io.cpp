// Writing a simulation to a folder (declared in simulator.h).
#include <filesystem>
#include <system_error>

#include <nlohmann/json.hpp>

#include "aos/image/image_io.h"
#include "aos/lightfield/formats.h"
#include "aos/lightfield/json_codec.h"
#include "aos/sim/simulator.h"
#include "aos/util/error.h"
#include "aos/util/file_util.h"

namespace fs = std::filesystem;

namespace aos {

using ojson = nlohmann::ordered_json;

std::string SimulationSummaryJson(const SimulationResult& result) {
  const SimulationStats& s = result.stats;
  const GroundTruth& t = result.truth;
  ojson j;
  // The camera and pose in the shapes every aos format shares (json_codec.h): the camera reads
  // back as a light field's or a camera file's; its field of view is given beside it.
  j["truth_camera"] = CameraToJson(LensCamera::FromPinhole(t.camera));
  j["truth_fov_deg"] = t.camera.FovXDeg();
  j["truth_cam_from_world"] = PoseToJson(t.cam_from_world);
  const Vec3d centre = t.cam_from_world.Center();
  j["truth_position"] = {centre.x, centre.y, centre.z};
  j["focal_plane_height"] = t.ground_height_at_center;
  j["stats"] = {{"views", s.views},
                {"primary_rays", s.primary_rays},
                {"shadow_rays", s.shadow_rays},
                {"truth_rays", s.truth_rays},
                {"blocked_fraction_rays", s.blocked_fraction_rays},
                {"sensor_noise_draws", s.sensor_noise_draws},
                {"pose_noise_draws", s.pose_noise_draws},
                {"lens_rays", s.lens_rays},
                {"voxels", s.voxels},
                {"trees", s.trees},
                {"leaf_quads", s.leaf_quads},
                {"trunk_quads", s.trunk_quads},
                {"occluder_bvh", s.occluder_bvh},
                {"ground_bvh", s.ground_bvh},
                {"ground_cells", s.ground_cells},
                {"nadir_blocked_fraction", s.nadir_blocked_fraction},
                {"occluder_bytes", s.occluder_bytes},
                {"seconds_geometry", s.seconds_geometry},
                {"seconds_views", s.seconds_views},
                {"seconds_truth", s.seconds_truth},
                {"seconds_blocked_fraction", s.seconds_blocked_fraction}};
  return j.dump(2) + "\n";
}

void WriteSimulation(const SimulationResult& result, const Scene& scene,
                     const std::string& output_dir) {
  PendingFolder folder(output_dir);
  const fs::path temp = folder.TempPath();
  const bool float_views = scene.camera.bit_depth == 32;
  const std::string extension = float_views ? ".tif" : ".png";

  // Views and the light field with recorded poses.
  WriteLightFieldOptions lf_options;
  lf_options.images_subdir = "views";
  lf_options.image_extension = extension;
  WriteLightField((temp / "lightfield.json").string(), result.light_field, lf_options);
  // The same images with the true poses.
  LightField true_field = result.light_field;
  for (size_t i = 0; i < true_field.views.size(); ++i) {
    char name[32];
    std::snprintf(name, sizeof(name), "%04zu", i);
    true_field.views[i].image_path = (temp / "views" / (std::string(name) + extension)).string();
    true_field.views[i].cam_from_world = result.true_cam_from_world[i];
  }
  WriteLightField((temp / "lightfield_true.json").string(), true_field, lf_options);

  // Ground truth.
  std::error_code error;
  const fs::path truth = temp / "truth";
  fs::create_directory(truth, error);
  if (error) ThrowInvalid(truth.string() + ": cannot create the folder (" + error.message() + ")");
  const GroundTruth& t = result.truth;
  WriteImage((truth / ("ground" + extension)).string(), t.ground);
  WriteImage((truth / "depth.tif").string(), t.depth);
  WriteImage((truth / "height.tif").string(), t.height);
  WriteImage((truth / "views_seeing.tif").string(), t.views_seeing);
  if (t.has_blocked_fraction) WriteImage((truth / "blocked_fraction.tif").string(), t.blocked_fraction);
  WriteTextFileAtomic((truth / "truth.json").string(), SimulationSummaryJson(result));
  WriteTextFileAtomic((temp / "scene.json").string(), SceneToJson(scene));

  folder.Commit();
}

}  // namespace aos
