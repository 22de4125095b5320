// Bindings of plan/flight_plan.h: FlightPlanOptions (the struct `aos-render plan` fills, so names
// and defaults match the CLI), the result, the exports as text and the map as a numpy array.
#include <cmath>
#include <sstream>

#include "aos/plan/flight_plan.h"
#include "aos/plan/preview.h"
#include "bindings.h"

namespace aos::python {

using namespace pybind11::literals;

void BindPlan(py::module_& m) {
  using O = FlightPlanOptions;
  OptionsClass<O>(m, "FlightPlanOptions",
                  "Options of plan_flight (defaults from the C++ struct aos::FlightPlanOptions; "
                  "docs/flight-planning.md).")
      .Table()
      .Finish()
      .def("check", &O::Check, "Raises ValueError naming the field.");

  py::class_<Waypoint>(m, "Waypoint", "One shot of a flight plan (world frame and WGS84).")
      .def_readonly("x", &Waypoint::x)
      .def_readonly("y", &Waypoint::y)
      .def_readonly("z", &Waypoint::z)
      .def_readonly("ground_z", &Waypoint::ground_z)
      .def_readonly("agl_m", &Waypoint::agl_m)
      .def_readonly("latitude_deg", &Waypoint::latitude_deg, "NaN without a CRS.")
      .def_readonly("longitude_deg", &Waypoint::longitude_deg, "NaN without a CRS.")
      .def_readonly("line", &Waypoint::line)
      .def("__repr__", [](const Waypoint& w) {
        return "Waypoint(x=" + FormatNumber(w.x) + ", y=" + FormatNumber(w.y) + ", z=" +
               FormatNumber(w.z) + ", line=" + std::to_string(w.line) + ")";
      });

  using R = FlightPlanResult;
  py::class_<R>(m, "FlightPlanResult", "Result of plan_flight (docs/flight-planning.md).")
      .def_readonly("waypoints", &R::waypoints, "The shots in flight order (a copied list).")
      .def_readonly("crs", &R::crs)
      .def_readonly("outline", &R::outline)
      .def_readonly("growth_center", &R::growth_center)
      .def_readonly("aperture_radius_m", &R::aperture_radius_m)
      .def_readonly("aperture_area_m2", &R::aperture_area_m2)
      .def_readonly("images", &R::images)
      .def_readonly("lines", &R::lines)
      .def_readonly("length_m", &R::length_m)
      .def_readonly("flight_time_s", &R::flight_time_s)
      .def_readonly("frames_per_minute", &R::frames_per_minute)
      .def_readonly("battery_fraction", &R::battery_fraction)
      .def_readonly("min_step_m", &R::min_step_m)
      .def_readonly("max_step_m", &R::max_step_m)
      .def_readonly("eq2_samples_per_m2", &R::eq2_samples_per_m2)
      .def_readonly("eq2_sample_size_m", &R::eq2_sample_size_m)
      .def_readonly("min_agl_m", &R::min_agl_m)
      .def_readonly("max_agl_m", &R::max_agl_m)
      .def_readonly("warnings", &R::warnings)
      .def("__repr__", [](const R& r) {
        std::ostringstream out;
        out << r;
        return out.str();
      });

  // The GIL is released around each and Ctrl-C (or `progress` raising) stops it: aos::Cancelled
  // gives way to the KeyboardInterrupt.
  m.def(
      "_plan_flight",
      [](const O& options, const py::object& progress) {
        const O copy = options;
        return RunWithProgress(progress, [&](ProgressSink* sink) { return PlanFlight(copy, sink); });
      },
      "options"_a, "progress"_a = py::none(), "Use aos.plan_flight.");
  m.def(
      "flight_plan_csv",
      [](const R& result) {
        return RunWithProgress(py::none(), [&](ProgressSink* sink) { return FlightPlanCsv(result, sink); });
      },
      "result"_a,
      "The waypoints as CSV text: index,latitude,longitude,altitude_agl_m,x_m,y_m,z_m,"
      "ground_z_m,line.");
  m.def(
      "flight_plan_geojson",
      [](const R& result) {
        return RunWithProgress(py::none(), [&](ProgressSink* sink) { return FlightPlanGeoJson(result, sink); });
      },
      "result"_a, "The path and waypoints as GeoJSON text (WGS84); ValueError without a CRS.");
  m.def(
      "flight_plan_kml",
      [](const R& result) {
        return RunWithProgress(py::none(), [&](ProgressSink* sink) { return FlightPlanKml(result, sink); });
      },
      "result"_a, "The path and waypoints as KML text (WGS84); ValueError without a CRS.");
  m.def(
      "flight_plan_map",
      [](const O& options, const R& result, int size_px) {
        const Image image = RunWithProgress(py::none(), [&](ProgressSink* sink) {
          return FlightPlanMap(options, result, size_px, sink);
        });
        return ArrayFromImage(image);
      },
      "options"_a, "result"_a, "size_px"_a = 800,
      "A map of the plan (uint8 RGB array, H x W x 3, sharing the image's memory): the DEM's "
      "hillshade or a blank map, outline, path, shots and a scale bar.");

  py::class_<PlanPreviewResult>(m, "PlanPreviewResult",
                                "What a plan reveals in the simulator (plan/preview.h).")
      .def_readonly("views", &PlanPreviewResult::views)
      .def_readonly("visible_fraction", &PlanPreviewResult::visible_fraction,
                    "Share of the views' rays that reach the ground; -1 without a blocked map.")
      .def_readonly("psnr_db", &PlanPreviewResult::psnr_db)
      .def_readonly("ssim", &PlanPreviewResult::ssim)
      .def_readonly("single_view_psnr_db", &PlanPreviewResult::single_view_psnr_db)
      .def_readonly("has_target", &PlanPreviewResult::has_target)
      .def_readonly("contrast_to_noise", &PlanPreviewResult::contrast_to_noise)
      .def_property_readonly(
          "integral", [](const PlanPreviewResult& r) { return ArrayFromImage(r.integral); },
          "float32 integral image on the ground (views' units), sharing memory.")
      .def_property_readonly(
          "truth", [](const PlanPreviewResult& r) { return ArrayFromImage(r.truth); },
          "The occluder-free ground truth (views' type), sharing memory.")
      .def_readonly("seconds", &PlanPreviewResult::seconds)
      .def("__repr__", [](const PlanPreviewResult& r) {
        return "PlanPreviewResult(views=" + std::to_string(r.views) +
               ", visible_fraction=" + FormatNumber(r.visible_fraction) +
               ", psnr_db=" + FormatNumber(r.psnr_db) + ", ssim=" + FormatNumber(r.ssim) + ")";
      });
  m.def(
      "_preview_flight_plan",
      [](const R& plan, const Scene& scene, int num_threads, const py::object& progress) {
        const FlightPlanResult plan_copy = plan;
        const Scene scene_copy = scene;
        return RunWithProgress(progress, [&](ProgressSink* sink) {
          return PreviewFlightPlan(plan_copy, scene_copy, num_threads, sink);
        });
      },
      "plan"_a, "scene"_a, "num_threads"_a = -1, "progress"_a = py::none(),
      "Use aos.preview_flight_plan.");
}

}  // namespace aos::python
