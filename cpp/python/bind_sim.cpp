// Bindings of sim/scene.h and sim/simulator.h. Scenes are built from JSON (a file, a string, or
// a dict through aos.simulate), so the scene schema is defined once, in the C++ parser.
#include "aos/sim/scene.h"
#include "aos/sim/simulator.h"
#include "aos/util/error.h"
#include "bindings.h"

namespace aos::python {
namespace {

using namespace pybind11::literals;

py::dict StatsDict(const SimulationStats& s) {
  py::dict d;
  d["views"] = s.views;
  d["primary_rays"] = s.primary_rays;
  d["shadow_rays"] = s.shadow_rays;
  d["truth_rays"] = s.truth_rays;
  d["blocked_fraction_rays"] = s.blocked_fraction_rays;
  d["sensor_noise_draws"] = s.sensor_noise_draws;
  d["pose_noise_draws"] = s.pose_noise_draws;
  d["lens_rays"] = s.lens_rays;
  d["voxels"] = s.voxels;
  d["trees"] = s.trees;
  d["leaf_quads"] = s.leaf_quads;
  d["trunk_quads"] = s.trunk_quads;
  d["occluder_bvh"] = s.occluder_bvh;
  d["ground_bvh"] = s.ground_bvh;
  d["ground_cells"] = s.ground_cells;
  d["nadir_blocked_fraction"] = s.nadir_blocked_fraction;
  d["occluder_bytes"] = s.occluder_bytes;
  d["seconds_geometry"] = s.seconds_geometry;
  d["seconds_views"] = s.seconds_views;
  d["seconds_truth"] = s.seconds_truth;
  d["seconds_blocked_fraction"] = s.seconds_blocked_fraction;
  return d;
}

}  // namespace

void BindSim(py::module_& m) {
  py::class_<Scene>(m, "Scene",
                    "A parsed, checked scene (docs/scenes.md). Make one with load_scene, "
                    "parse_scene or default_scene; aos.simulate also takes a dict or a path.")
      .def_readonly("source", &Scene::source, "File name or label used in messages.")
      .def_readonly("seed", &Scene::seed, "Seed of every random stage.")
      .def("to_json", &SceneToJson,
           "The scene as JSON with every field written out (parses back to the same scene).")
      .def("view_positions", &ViewPositions, "True camera centres of the views, in view order.")
      .def("has_occluders", &Scene::HasOccluders, "Whether the scene has voxels or trees.")
      .def("__repr__", [](const Scene& scene) {
        return "Scene(source='" + scene.source + "', views=" +
               std::to_string(ViewPositions(scene).size()) + ")";
      });

  m.def("load_scene", &LoadScene, "path"_a,
        "Reads and checks a scene file; raises ValueError naming the file and the key path.");
  m.def("parse_scene", &ParseScene, "json_text"_a, "source"_a = "<json>", "base_dir"_a = ".",
        "Parses scene JSON; relative image paths resolve against base_dir. Raises ValueError "
        "naming `source` and the key path.");
  m.def("default_scene", &DefaultScene, "The built-in default scene of `aos-render demo`.");

  OptionsClass<SimulateOptions>(
      m, "SimulateOptions",
      "Options of simulate. Defaults come from the C++ struct aos::SimulateOptions.")
      .Table()
      .Finish()
      .def("check", &SimulateOptions::Check, "Raises ValueError naming the offending field.");

  py::class_<GroundTruth>(m, "GroundTruth",
                          "Ground truth seen by the truth camera. Arrays share memory with the "
                          "result (no copy).")
      .def_readonly("camera", &GroundTruth::camera, "The truth camera's intrinsics.")
      .def_readonly("cam_from_world", &GroundTruth::cam_from_world, "The truth camera's pose.")
      .def_property_readonly(
          "ground", [](const GroundTruth& t) { return ArrayFromImage(t.ground); },
          "The occluder-free ground, in the views' dtype and channels.")
      .def_property_readonly(
          "depth", [](const GroundTruth& t) { return ArrayFromImage(t.depth); },
          "float32, metres along the optical axis (0 where no ground).")
      .def_property_readonly(
          "height", [](const GroundTruth& t) { return ArrayFromImage(t.height); },
          "float32, ground z in metres (0 where no ground).")
      .def_property_readonly(
          "views_seeing", [](const GroundTruth& t) { return ArrayFromImage(t.views_seeing); },
          "uint32: views that see each ground point.")
      .def_property_readonly(
          "blocked_fraction",
          [](const GroundTruth& t) { return ArrayFromImage(t.blocked_fraction); },
          "float32 in [0, 1]: fraction of the seeing views whose ray is blocked; None when "
          "truth.blocked_fraction is off.")
      .def_property_readonly(
          "image", [](const GroundTruth& t) { return ArrayFromImage(t.ground); },
          "The truth image: the occluder-free ground (same array as `ground`).")
      .def_readonly("ground_height_at_center", &GroundTruth::ground_height_at_center,
                    "Ground z under the truth camera (the focal plane to render).")
      .def("__repr__", [](const GroundTruth& t) {
        return "GroundTruth(" + std::to_string(t.ground.width()) + "x" +
               std::to_string(t.ground.height()) + "x" + std::to_string(t.ground.channels()) +
               ", ground_height_at_center=" + FormatNumber(t.ground_height_at_center) + ")";
      });

  py::class_<SimulationResult>(m, "SimulationResult", "What simulate returns.")
      .def_readonly("light_field", &SimulationResult::light_field,
                    "Views with the recorded (possibly noisy) poses.")
      .def_readonly("true_cam_from_world", &SimulationResult::true_cam_from_world,
                    "True poses, in view order.")
      .def_readonly("truth", &SimulationResult::truth, "The ground truth.")
      .def_property_readonly(
          "image", [](const SimulationResult& r) { return ArrayFromImage(r.truth.ground); },
          "The truth image (truth.ground): the occluder-free ground seen by the truth camera, "
          "what an integral focused on the ground from truth.cam_from_world should approach. "
          "The simulated views themselves are in light_field.")
      .def_property_readonly(
          "stats", [](const SimulationResult& r) { return StatsDict(r.stats); },
          "What each stage did: ray and draw counters, sizes and seconds (a new dict).")
      .def("summary_json", &SimulationSummaryJson, "What truth/truth.json holds.")
      .def("__repr__", [](const SimulationResult& r) {
        return "SimulationResult(views=" + std::to_string(r.light_field.views.size()) +
               ", primary_rays=" + std::to_string(r.stats.primary_rays) + ")";
      });

  m.def(
      "_simulate",
      [](const Scene& scene, const SimulateOptions& options, const py::object& progress) {
        const Scene scene_copy = scene;
        const SimulateOptions options_copy = options;
        return RunWithProgress(progress, [&](ProgressSink* sink) {
          return Simulate(scene_copy, options_copy, sink);
        });
      },
      "scene"_a, "options"_a, "progress"_a = py::none(),
      "Simulates a scene, GIL released. Use aos.simulate.");
  m.def(
      "write_simulation",
      [](const SimulationResult& result, const Scene& scene, const std::string& output_dir) {
        py::gil_scoped_release release;
        WriteSimulation(result, scene, output_dir);
      },
      "result"_a, "scene"_a, "output_dir"_a,
      "Writes a simulation into a new (or empty) folder, atomically (see simulator.h).");
  m.def(
      "ground_heightfield",
      [](const Scene& scene, const std::array<double, 4>& extent) {
        return GroundHeightfield(scene, extent);
      },
      "scene"_a, "extent"_a = std::array<double, 4>{0.0, 0.0, 0.0, 0.0},
      "The scene's ground as a DEM (Heightfield; local frame, no CRS) whose pixel centres are "
      "the vertices of the grid the simulator traces it on: extent [xmin, ymin, xmax, ymax] "
      "(all zero = ground.extent) cut into ceil(extent / ground.cell_size) cells per axis "
      "(see simulator.h). Raises ValueError when both extents are zero.");
}

}  // namespace aos::python
