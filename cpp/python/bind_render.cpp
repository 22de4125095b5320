// Bindings of render/integral.h. The kwargs merge of aos.render_integral lives in
// python/aos/__init__.py.
#include "aos/render/integral.h"
#include "bindings.h"

namespace aos::python {
namespace {

using namespace pybind11::literals;

void BindIntegral(py::module_& m) {
  // Docstrings are the header's field comments.
  OptionsClass<IntegralOptions>(
      m, "IntegralOptions",
      "Options of render_integral. Defaults come from the C++ struct aos::IntegralOptions; "
      "IntegralOptions(**fields) overrides them by name (unknown names raise TypeError).")
      .Field("cam_from_world", &IntegralOptions::cam_from_world,
             "Virtual camera pose, local frame -> camera (OpenCV axes). Ignored when pose_view "
             ">= 0.")
      .Field("pose_view", &IntegralOptions::pose_view,
             "If >= 0, the virtual camera takes the pose of this view (index into the light "
             "field).")
      .Field("fov_deg", &IntegralOptions::fov_deg,
             "Horizontal field of view of the virtual camera, degrees, (0, 180).")
      .Field("width", &IntegralOptions::width, "Output width, pixels (1 .. 65536).")
      .Field("height", &IntegralOptions::height, "Output height, pixels (1 .. 65536).")
      .Field("aperture_radius", &IntegralOptions::aperture_radius,
             "Radius of the virtual aperture on the lens plane, metres; 0 means a pinhole (one "
             "view per pixel), infinity means every view.")
      .Field("focal_plane", &IntegralOptions::focal_plane,
             "The focal plane (local frame): any point on it and its normal.")
      .Field("view_indices", &IntegralOptions::view_indices,
             "Views to integrate (indices into the light field); empty means all views. Reading "
             "returns a new list: assign a list to change it.")
      .Field("min_view_angle_deg", &IntegralOptions::min_view_angle_deg,
             "Minimum angle between a view's ray and the focal plane, degrees, [0, 90); smaller "
             "(grazing) rays are ignored.")
      .Field("num_threads", &IntegralOptions::num_threads, "Worker threads; -1 = all cores.")
      .Finish()
      .def("check", &IntegralOptions::Check, "view_count"_a,
           "Raises ValueError naming the offending field. `view_count` is the number of views in "
           "the light field (for pose_view and view_indices).");

  py::class_<IntegralResult>(m, "IntegralResult", "What render_integral returns.")
      .def_property_readonly(
          "image", [](const IntegralResult& result) { return ArrayFromImage(result.image); },
          "The integral image, float32 (H, W) or (H, W, C) with the views' channels; shares "
          "memory with the result (no copy).")
      .def_property_readonly(
          "count", [](const IntegralResult& result) { return ArrayFromImage(result.count); },
          "uint32 (H, W): views that contributed to each pixel; shares memory with the result.")
      .def_readonly("samples", &IntegralResult::samples, "Sum of count (view samples taken).")
      .def_readonly("views_used", &IntegralResult::views_used,
                    "Selected views that contributed to at least one pixel.")
      .def_readonly("views_selected", &IntegralResult::views_selected, "Views selected.")
      .def_readonly("uncovered_pixels", &IntegralResult::uncovered_pixels,
                    "Pixels with count 0.")
      .def_readonly("cam_from_world", &IntegralResult::cam_from_world,
                    "The virtual camera pose that was used.")
      .def("__repr__", [](const IntegralResult& result) {
        return "IntegralResult(" + std::to_string(result.image.width()) + "x" +
               std::to_string(result.image.height()) + "x" +
               std::to_string(result.image.channels()) +
               ", views_used=" + std::to_string(result.views_used) + "/" +
               std::to_string(result.views_selected) +
               ", samples=" + std::to_string(result.samples) +
               ", uncovered_pixels=" + std::to_string(result.uncovered_pixels) + ")";
      });

  m.def(
      "render_integral",
      [](const LightField& light_field, const IntegralOptions& options,
         const py::object& progress) {
        // Snapshots (cheap: pixel storage is shared), so other Python threads may change the
        // arguments while the GIL is released.
        const LightField light_field_copy = light_field;
        const IntegralOptions options_copy = options;
        return RunWithProgress(progress, [&](ProgressSink* sink) {
          return RenderIntegral(light_field_copy, options_copy, sink);
        });
      },
      "light_field"_a, "options"_a, "progress"_a = py::none(),
      "Integral rendering (Eq. 1 of the AOS paper), GIL released. progress(stage, done, total) "
      "is called from the calling thread, throttled; if it raises, rendering stops and the error "
      "propagates. Ctrl-C raises KeyboardInterrupt. Raises ValueError for bad options. Prefer "
      "aos.render_integral, which also takes the options as keywords.");

  m.def("virtual_camera", &VirtualCamera, "options"_a,
        "The virtual camera's intrinsics for `options` (square pixels, centred principal point).");
}

}  // namespace

void BindRender(py::module_& m) {
  BindIntegral(m);
}

}  // namespace aos::python
