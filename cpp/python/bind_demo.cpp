// Bindings of demo/demo.h: aos.run_demo / aos.write_demo (wrappers in python/aos/__init__.py).
#include "aos/demo/demo.h"
#include "bindings.h"

namespace aos::python {

using namespace pybind11::literals;

void BindDemo(py::module_& m) {
  OptionsClass<DemoOptions>(m, "DemoOptions",
                            "Options of run_demo. Defaults come from the C++ struct "
                            "aos::DemoOptions.")
      .Table()
      .Finish()
      .def("check", &DemoOptions::Check, "Raises ValueError naming the offending field.");

  py::class_<TargetVisibility>(m, "TargetVisibility",
                               "How clearly the targets show in one image (demo.h).")
      .def_readonly("has_target", &TargetVisibility::has_target,
                    "Whether a target with contrast to its surroundings is in view.")
      .def_readonly("target_pixels", &TargetVisibility::target_pixels, "Target pixels compared.")
      .def_readonly("surrounding_pixels", &TargetVisibility::surrounding_pixels,
                    "Surrounding pixels compared.")
      .def_readonly("contrast_to_noise", &TargetVisibility::contrast_to_noise,
                    "(mean over target - mean over surroundings) / pooled standard deviation of "
                    "the pixels' target-likeness.")
      .def_readonly("standout_fraction", &TargetVisibility::standout_fraction,
                    "Share of target pixels more target-like than 99 % of the surroundings.")
      .def("__repr__", [](const TargetVisibility& v) {
        return "TargetVisibility(standout_fraction=" + FormatNumber(v.standout_fraction) +
               ", contrast_to_noise=" + FormatNumber(v.contrast_to_noise) + ")";
      });

  py::class_<DemoRender>(m, "DemoRender", "One image of the demo, from the truth camera.")
      .def_readonly("name", &DemoRender::name, "File stem: single_view, integral_ground, ...")
      .def_readonly("title", &DemoRender::title, "What the image shows.")
      .def_readonly("focal_height", &DemoRender::focal_height, "Focal plane z, metres.")
      .def_readonly("aperture_radius", &DemoRender::aperture_radius,
                    "Metres; inf = every view.")
      .def_property_readonly(
          "image", [](const DemoRender& r) { return ArrayFromImage(r.image); },
          "float32 in the views' units (shares memory with the result).")
      .def_property_readonly(
          "count",
          [](const DemoRender& r) -> py::object {
            if (r.count.empty()) return py::none();
            return ArrayFromImage(r.count);
          },
          "uint32 views per pixel; None for the all-in-focus image.")
      .def_readonly("quality", &DemoRender::quality, "Against the ground truth.")
      .def_readonly("visibility", &DemoRender::visibility, "The target's visibility.")
      .def_readonly("seconds", &DemoRender::seconds, "Wall time of the render.")
      .def("__repr__", [](const DemoRender& r) { return "DemoRender(name='" + r.name + "')"; });

  py::class_<DemoResult>(m, "DemoResult", "What run_demo returns.")
      .def_readonly("scene", &DemoResult::scene, "The scene as simulated.")
      .def_readonly("options", &DemoResult::options, "The options used.")
      .def_readonly("simulation", &DemoResult::simulation, "The simulation.")
      .def_property_readonly(
          "target_mask", [](const DemoResult& r) { return ArrayFromImage(r.target_mask); },
          "uint8, truth camera size: 1 = target, 2 = surroundings, 0 = neither.")
      .def_readonly("truth_visibility", &DemoResult::truth_visibility,
                    "The target's visibility in the ground truth.")
      .def_readonly("target_blocked_fraction", &DemoResult::target_blocked_fraction,
                    "Share of the views' rays to the target that occluders block; -1 if unknown.")
      .def_readonly("ground_height", &DemoResult::ground_height, "Ground focal plane z, metres.")
      .def_readonly("occluder_height", &DemoResult::occluder_height,
                    "Focal plane z inside the occluders, metres.")
      .def_readonly("top_height", &DemoResult::top_height,
                    "Last plane of the all-in-focus stack, metres.")
      .def_readonly("renders", &DemoResult::renders, "The images, in order.")
      .def_readonly("seconds_simulation", &DemoResult::seconds_simulation, "Wall time.")
      .def_readonly("seconds_total", &DemoResult::seconds_total, "Wall time.")
      .def("render", &DemoResult::Render, "name"_a, py::return_value_policy::reference_internal,
           "The render of that name; ValueError if there is none.")
      .def("summary_json", &DemoSummaryJson, "What demo.json holds.")
      .def("index_html", &DemoIndexHtml, "What index.html holds.")
      .def("__repr__", [](const DemoResult& r) {
        return "DemoResult(views=" + std::to_string(r.simulation.light_field.views.size()) +
               ", renders=" + std::to_string(r.renders.size()) + ")";
      });

  m.def("_check_demo_folder", &CheckDemoFolder, "folder"_a,
        "Raises ValueError unless `folder` is missing or empty and its parent exists.");
  m.def(
      "_run_demo",
      [](const Scene& scene, const DemoOptions& options, const py::object& progress) {
        const Scene scene_copy = scene;
        const DemoOptions options_copy = options;
        return RunWithProgress(progress, [&](ProgressSink* sink) {
          return RunDemo(scene_copy, options_copy, sink);
        });
      },
      "scene"_a, "options"_a, "progress"_a = py::none(), "Runs the demo. Use aos.run_demo.");
  m.def(
      "write_demo",
      [](const DemoResult& result, const std::string& folder) {
        py::gil_scoped_release release;
        return WriteDemo(result, folder);
      },
      "result"_a, "folder"_a,
      "Writes the demo (simulation, PNGs, demo.json, index.html) into a new or empty folder, "
      "atomically; returns the files written, relative to the folder, sorted.");
}

}  // namespace aos::python
