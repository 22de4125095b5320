// Detection (detect/anomaly.h, detect/detect.h): DetectOptions, anomaly_scores, detect; and live
// integration with detection (live/live.h): LiveOptions, LiveTrack, LiveIntegrator.
#include "aos/detect/detect.h"
#include "aos/live/live.h"
#include "aos/render/map.h"
#include "bindings.h"

namespace aos::python {
namespace {

using namespace pybind11::literals;

py::object OptionalVec2(const std::optional<Vec2d>& value) {
  if (!value) return py::none();
  return py::make_tuple(value->x, value->y);
}

py::dict DetectionState(const Detection& d) {
  return py::dict("pixel"_a = py::make_tuple(d.pixel.x, d.pixel.y), "area_px"_a = d.area_px,
                  "peak_score"_a = d.peak_score, "mean_score"_a = d.mean_score, "box"_a = d.box,
                  "local"_a = py::make_tuple(d.local.x, d.local.y, d.local.z),
                  "world"_a = py::make_tuple(d.world.x, d.world.y, d.world.z),
                  "lon_lat"_a = OptionalVec2(d.lon_lat), "views"_a = d.views,
                  "peak_celsius"_a = d.peak_celsius, "mean_celsius"_a = d.mean_celsius);
}

Detection DetectionFromState(const py::handle& state) {
  const py::dict v = StateDict(state, "Detection",
                               {"pixel", "area_px", "peak_score", "mean_score", "box", "local",
                                "world", "lon_lat", "views", "peak_celsius", "mean_celsius"});
  Detection d;
  const auto pixel = v["pixel"].cast<std::array<double, 2>>();
  d.pixel = Vec2d(pixel[0], pixel[1]);
  d.area_px = v["area_px"].cast<int>();
  d.peak_score = v["peak_score"].cast<double>();
  d.mean_score = v["mean_score"].cast<double>();
  d.box = v["box"].cast<std::array<int, 4>>();
  const auto local = v["local"].cast<std::array<double, 3>>();
  d.local = Vec3d(local[0], local[1], local[2]);
  const auto world = v["world"].cast<std::array<double, 3>>();
  d.world = Vec3d(world[0], world[1], world[2]);
  if (!v["lon_lat"].is_none()) {
    const auto lon_lat = v["lon_lat"].cast<std::array<double, 2>>();
    d.lon_lat = Vec2d(lon_lat[0], lon_lat[1]);
  }
  d.views = v["views"].cast<std::vector<int>>();
  d.peak_celsius = v["peak_celsius"].cast<double>();
  d.mean_celsius = v["mean_celsius"].cast<double>();
  return d;
}

// An (N, k) float64 array of a per-detection vector.
template <class Get>
py::array_t<double> Column(const std::vector<Detection>& detections, int k, Get&& get) {
  py::array_t<double> out({static_cast<py::ssize_t>(detections.size()), static_cast<py::ssize_t>(k)});
  auto view = out.mutable_unchecked<2>();
  for (size_t i = 0; i < detections.size(); ++i) {
    const std::array<double, 3> values = get(detections[i]);
    for (int j = 0; j < k; ++j) view(static_cast<py::ssize_t>(i), j) = values[static_cast<size_t>(j)];
  }
  return out;
}

}  // namespace

void BindDetect(py::module_& m) {
  OptionsClass<DetectOptions>(m, "DetectOptions",
                              "Options of detect (defaults from the C++ struct "
                              "aos::DetectOptions): the anomaly scores, the threshold, the blobs.")
      .Table()
      .Finish()
      .def("check", &DetectOptions::Check, "Raises ValueError naming the field.");

  py::class_<Detection>(m, "Detection", "One detection: a blob of pixels above the threshold.")
      .def_readonly("sightings", &Detection::sightings,
                    "Live tracks: the updates that saw it (0 for one detection).")
      .def_readonly("first_seen", &Detection::first_seen,
                    "Live tracks: the newest frame at the first sighting ('' otherwise).")
      .def_readonly("last_seen", &Detection::last_seen,
                    "Live tracks: the newest frame at the last sighting ('' otherwise).")
      .def_property_readonly("pixel", [](const Detection& d) { return py::make_tuple(d.pixel.x, d.pixel.y); },
                             "Score-weighted centroid, pixel coordinates (centres at +0.5).")
      .def_readonly("area_px", &Detection::area_px)
      .def_readonly("peak_score", &Detection::peak_score)
      .def_readonly("mean_score", &Detection::mean_score)
      .def_readonly("box", &Detection::box, "x0, y0, x1, y1 (x1, y1 exclusive).")
      .def_property_readonly("local", [](const Detection& d) { return py::make_tuple(d.local.x, d.local.y, d.local.z); },
                             "On the focal surface, local frame (NaN when not located).")
      .def_property_readonly("world", [](const Detection& d) { return py::make_tuple(d.world.x, d.world.y, d.world.z); },
                             "origin + local (the light field's CRS).")
      .def_property_readonly("lon_lat", [](const Detection& d) { return OptionalVec2(d.lon_lat); },
                             "WGS84 (longitude, latitude) degrees, or None without a CRS.")
      .def_readonly("views", &Detection::views, "Indices of the views that saw the point.")
      .def_readonly("peak_celsius", &Detection::peak_celsius,
                    "Peak temperature, C (radiometric light fields; else NaN).")
      .def_readonly("mean_celsius", &Detection::mean_celsius)
      .def(py::pickle([](const Detection& d) { return DetectionState(d); },
                      [](const py::object& state) { return DetectionFromState(state); }))
      .def("__repr__", [](const Detection& d) {
        std::string text = "Detection(pixel=(" + FormatNumber(d.pixel.x) + ", " +
                           FormatNumber(d.pixel.y) + "), area_px=" + std::to_string(d.area_px) +
                           ", peak_score=" + FormatNumber(d.peak_score);
        if (d.lon_lat) {
          text += ", lon_lat=(" + FormatNumber(d.lon_lat->x) + ", " + FormatNumber(d.lon_lat->y) + ")";
        } else if (std::isfinite(d.world.x)) {
          text += ", world=(" + FormatNumber(d.world.x) + ", " + FormatNumber(d.world.y) + ", " +
                  FormatNumber(d.world.z) + ")";
        }
        return text + ", views=" + std::to_string(d.views.size()) + ")";
      });

  py::class_<DetectResult>(m, "DetectResult", "What detect found, and what it was found in.")
      .def_readonly("render", &DetectResult::render, "The integral image the scores are of.")
      .def_readonly("camera", &DetectResult::camera, "Its virtual camera.")
      .def_readonly("ground_sampling_m", &DetectResult::ground_sampling_m,
                    "The render's metres per pixel on the focal surface (median).")
      .def_readonly("windows_px", &DetectResult::windows_px,
                    "rx-local's inner and outer windows as used, pixels.")
      .def_property_readonly(
          "scores", [](const DetectResult& r) { return ArrayFromImage(r.scores.scores); },
          "float32 (H, W): the anomaly scores (squared Mahalanobis distance; degrees C for "
          "'temperature'), 0 where no view sees the pixel.")
      .def_property_readonly("dimensions", [](const DetectResult& r) { return r.scores.dimensions; },
                             "Features per pixel (the chi-square degrees of freedom).")
      .def_readonly("threshold", &DetectResult::threshold)
      .def_readonly("threshold_rule", &DetectResult::threshold_rule)
      .def_readonly("flagged_pixels", &DetectResult::flagged_pixels)
      .def_readonly("detections", &DetectResult::detections, "Highest peak first.")
      .def_readonly("dropped", &DetectResult::dropped, "Blobs beyond max_detections.")
      .def_readonly("crs", &DetectResult::crs)
      .def_readonly("geotransform", &DetectResult::geotransform,
                    "Detection on the map (detect_map): its GDAL geotransform; else None.")
      .def_property_readonly(
          "pixels",
          [](const DetectResult& r) {
            return Column(r.detections, 2, [](const Detection& d) {
              return std::array<double, 3>{d.pixel.x, d.pixel.y, 0.0};
            });
          },
          "float64 (N, 2): the detections' pixel centroids.")
      .def_property_readonly(
          "world",
          [](const DetectResult& r) {
            return Column(r.detections, 3, [](const Detection& d) {
              return std::array<double, 3>{d.world.x, d.world.y, d.world.z};
            });
          },
          "float64 (N, 3): the detections' world points (NaN where not located).")
      .def_property_readonly(
          "lon_lat",
          [](const DetectResult& r) -> py::object {
            if (r.crs.empty()) return py::none();
            return Column(r.detections, 2, [](const Detection& d) {
              return d.lon_lat ? std::array<double, 3>{d.lon_lat->x, d.lon_lat->y, 0.0}
                               : std::array<double, 3>{std::nan(""), std::nan(""), 0.0};
            });
          },
          "float64 (N, 2) WGS84 longitude, latitude; None without a CRS.")
      .def_property_readonly(
          "peak_scores",
          [](const DetectResult& r) {
            py::array_t<double> out(static_cast<py::ssize_t>(r.detections.size()));
            for (size_t i = 0; i < r.detections.size(); ++i) {
              out.mutable_at(static_cast<py::ssize_t>(i)) = r.detections[i].peak_score;
            }
            return out;
          },
          "float64 (N,): the detections' peak scores.")
      .def(
          "write", [](const DetectResult& r, const std::string& path, bool overwrite) {
            WriteDetections(path, r, overwrite);
          },
          "path"_a, "overwrite"_a = false,
          "Writes the detections as GeoJSON (.geojson/.json), KML (.kml) or CSV (.csv).")
      .def(
          "overlay", [](const DetectResult& r) { return ArrayFromImage(DetectionOverlay(r)); },
          "uint8 (H, W, 3): the integral image with the detections boxed in red.")
      .def(py::pickle(
          [](const DetectResult& r) {
            py::list detections;
            for (const Detection& d : r.detections) detections.append(DetectionState(d));
            return py::dict("image"_a = ArrayFromImage(r.render.image),
                            "count"_a = ArrayFromImage(r.render.count),
                            "cam_from_world"_a = r.render.cam_from_world, "camera"_a = r.camera,
                            "scores"_a = ArrayFromImage(r.scores.scores),
                            "dimensions"_a = r.scores.dimensions, "threshold"_a = r.threshold,
                            "threshold_rule"_a = r.threshold_rule,
                            "flagged_pixels"_a = r.flagged_pixels, "detections"_a = detections,
                            "dropped"_a = r.dropped, "crs"_a = r.crs,
                            "radiometry"_a = r.radiometry,
                            "ground_sampling_m"_a = r.ground_sampling_m,
                            "windows_px"_a = r.windows_px, "geotransform"_a = r.geotransform);
          },
          [](const py::object& state) {
            const py::dict v = StateDict(
                state, "DetectResult",
                {"image", "count", "cam_from_world", "camera", "scores", "dimensions", "threshold",
                 "threshold_rule", "flagged_pixels", "detections", "dropped", "crs", "radiometry",
                 "ground_sampling_m", "windows_px", "geotransform"});
            DetectResult r;
            r.render.image = ImageFromArray(v["image"], 0, "image");
            r.render.count = ImageFromArray(v["count"], 0, "count");
            r.render.cam_from_world = v["cam_from_world"].cast<Rigid3d>();
            r.camera = v["camera"].cast<PinholeCamera>();
            r.scores.scores = ImageFromArray(v["scores"], 0, "scores");
            r.scores.dimensions = v["dimensions"].cast<int>();
            r.threshold = v["threshold"].cast<double>();
            r.threshold_rule = v["threshold_rule"].cast<std::string>();
            r.flagged_pixels = v["flagged_pixels"].cast<int64_t>();
            for (const py::handle& d : v["detections"]) r.detections.push_back(DetectionFromState(d));
            r.dropped = v["dropped"].cast<int>();
            r.crs = v["crs"].cast<std::string>();
            r.radiometry = v["radiometry"].cast<std::optional<Radiometry>>();
            r.ground_sampling_m = v["ground_sampling_m"].cast<double>();
            r.windows_px = v["windows_px"].cast<std::array<int, 2>>();
            r.geotransform = v["geotransform"].cast<std::optional<std::array<double, 6>>>();
            return r;
          }))
      .def("__len__", [](const DetectResult& r) { return r.detections.size(); })
      .def("__repr__", [](const DetectResult& r) {
        return "DetectResult(detections=" + std::to_string(r.detections.size()) + ", " +
               r.threshold_rule + ": threshold " + FormatNumber(r.threshold) + ", " +
               std::to_string(r.scores.scores.width()) + "x" +
               std::to_string(r.scores.scores.height()) +
               (r.crs.empty() ? std::string() : ", crs='" + r.crs + "'") + ")";
      });

  m.def(
      "_detect",
      [](const LightField& light_field, const IntegralOptions& options,
         const DetectOptions& detect, const py::object& progress) {
        const LightField light_field_copy = light_field;
        IntegralOptions options_copy = options;
        const DetectOptions detect_copy = detect;
        return RunWithProgress(progress, [&](ProgressSink* sink) {
          options_copy.focal_surface = InCrs(options_copy.focal_surface, light_field_copy.crs);
          DetectResult result = Detect(light_field_copy, options_copy, detect_copy, sink);
          CheckSurfaceCovers(options_copy.focal_surface, light_field_copy,
                             "the virtual camera's view", result.render.uncovered_pixels,
                             static_cast<int64_t>(result.render.image.width()) *
                                 result.render.image.height());
          return result;
        });
      },
      "light_field"_a, "options"_a, "detect"_a, "progress"_a = py::none(),
      "Detection on the integral image, GIL released. Prefer aos.detect.");
  m.def(
      "_detect_map",
      [](const LightField& light_field, const MapOptions& options, const DetectOptions& detect,
         const py::object& progress) {
        const LightField light_field_copy = light_field;
        MapOptions options_copy = options;
        const DetectOptions detect_copy = detect;
        return RunWithProgress(progress, [&](ProgressSink* sink) {
          options_copy.focal_surface = InCrs(options_copy.focal_surface, light_field_copy.crs);
          return DetectOnMap(light_field_copy, options_copy, detect_copy, sink);
        });
      },
      "light_field"_a, "options"_a, "detect"_a, "progress"_a = py::none(),
      "Detection on the orthographic map, GIL released. Prefer aos.detect_map.");
  m.def(
      "_detect_on_rendered_map",
      [](const LightField& light_field, const MapOptions& options, const DetectOptions& detect,
         const py::handle& image, const py::handle& count, int views_used, int views_selected,
         const py::handle& anomaly_scores) {
        MapResult map;
        map.image = ImageFromArray(image, 0, "image");
        map.count = ImageFromArray(count, 0, "count");
        map.summary.views_used = views_used;
        map.summary.views_selected = views_selected;
        std::optional<Image> scores;
        if (!anomaly_scores.is_none()) scores = ImageFromArray(anomaly_scores, 0, "anomaly_scores");
        MapOptions options_copy = options;
        options_copy.focal_surface = InCrs(options_copy.focal_surface, light_field.crs);
        py::gil_scoped_release release;
        return DetectOnRenderedMap(light_field, options_copy, detect, std::move(map),
                                   std::move(scores));
      },
      "light_field"_a, "options"_a, "detect"_a, "image"_a, "count"_a, "views_used"_a = 0,
      "views_selected"_a = 0, "anomaly_scores"_a = py::none(),
      "Detection on a map rendered elsewhere (a Dask cluster's; aos.distributed): image "
      "float32 (H, W[, C]) and count uint32 (H, W) of the options' grid; for anomaly imaging "
      "also anomaly_scores, float32 (H, W): the frames' scores integrated on that grid "
      "(_quantised_frame_scores, times _frame_score_step). GIL released.");
  m.def(
      "_quantised_frame_scores",
      [](const py::handle& frame, const DetectOptions& detect) {
        const Image image = ImageFromArray(frame, 0, "frame");
        Image scores;
        {
          py::gil_scoped_release release;
          scores = QuantisedFrameScores(image, detect);
        }
        return ArrayFromImage(scores);
      },
      "frame"_a, "detect"_a,
      "Anomaly imaging's scores of one frame (anomaly.h QuantisedFrameScores: global RX, uint16 "
      "steps of _frame_score_step). Used by aos.distributed's workers.");
  m.attr("_frame_score_step") = kFrameScoreStep;
  m.def(
      "anomaly_scores",
      [](const py::handle& image, const py::handle& count, const DetectOptions& options,
         const std::optional<Radiometry>& radiometry) {
        const Image pixels = ImageFromArray(image, 0, "image");
        const Image counts = count.is_none() ? Image() : ImageFromArray(count, 0, "count");
        AnomalyScores scores;
        {
          py::gil_scoped_release release;
          scores = ComputeAnomalyScores(pixels, counts, options, radiometry);
        }
        return ArrayFromImage(scores.scores);
      },
      "image"_a, "count"_a = py::none(), "options"_a = DetectOptions(), "radiometry"_a = py::none(),
      "The anomaly scores of an image (float32 (H, W) or (H, W, C)): squared Mahalanobis "
      "distances ('rx', 'rx-local') or degrees C ('temperature', with a radiometry). `count` "
      "(uint32 (H, W)) marks the pixels with a view; None = all.");

  OptionsClass<LiveOptions>(m, "LiveOptions",
                            "Options of live integration (defaults from the C++ struct "
                            "aos::LiveOptions): the window, the virtual camera, the tracks.")
      .Table()
      .Finish()
      .def("check", &LiveOptions::Check, "Raises ValueError naming the field.");

  py::class_<LiveTrack>(m, "LiveTrack", "One place found during a live run: its strongest sighting.")
      .def_readonly("detection", &LiveTrack::detection, "The strongest sighting (a Detection).")
      .def_readonly("sightings", &LiveTrack::sightings, "Updates that detected it.")
      .def_readonly("first_update", &LiveTrack::first_update)
      .def_readonly("last_update", &LiveTrack::last_update)
      .def_readonly("first_frame", &LiveTrack::first_frame,
                    "The newest frame's name at the first sighting.")
      .def_readonly("last_frame", &LiveTrack::last_frame)
      .def("__repr__", [](const LiveTrack& t) {
        return "LiveTrack(world=(" + FormatNumber(t.detection.world.x) + ", " +
               FormatNumber(t.detection.world.y) + ", " + FormatNumber(t.detection.world.z) +
               "), peak_score=" + FormatNumber(t.detection.peak_score) +
               ", sightings=" + std::to_string(t.sightings) + ")";
      });

  py::class_<LiveIntegrator>(
      m, "LiveIntegrator",
      "Live, in-flight integration (docs/live.md): a sliding window of the newest views, "
      "re-rendered and searched after each add; equal to the batch render of the window.")
      .def(py::init([](const LightField& base, const IntegralOptions& options,
                       const DetectOptions& detect, const LiveOptions& live,
                       const std::optional<MapOptions>& map_options) {
             if (map_options) {  // follow 'map': the orthographic map of a fixed area
               MapOptions map = *map_options;
               map.focal_surface = InCrs(map.focal_surface, base.crs);
               return std::make_unique<LiveIntegrator>(base, map, detect, live);
             }
             IntegralOptions render = options;
             render.focal_surface = InCrs(render.focal_surface, base.crs);
             return std::make_unique<LiveIntegrator>(base, render, detect, live);
           }),
           "base"_a = LightField(), "options"_a = IntegralOptions(),
           "detect_options"_a = DetectOptions(), "live_options"_a = LiveOptions(),
           "map_options"_a = py::none(),
           "`base` gives what every view shares (crs, origin, radiometry; its views are ignored). "
           "`options`: the virtual camera and focus of each update's render; with `map_options` "
           "(follow 'map') instead every update is the window's orthographic map over its extent "
           "(set). Raises ValueError naming the field.")
      .def(
          "add",
          [](LiveIntegrator& self, const py::handle& image, const py::object& camera,
             const Rigid3d& cam_from_world, std::string name, bool update, double time_s) {
            Image copy = ImageFromArray(image, /*border=*/1, "add: image");
            View view;
            if (py::isinstance<LensCamera>(camera)) {
              LensCamera lens = camera.cast<LensCamera>();
              lens.Finalize("add: camera");
              view = MakeView(std::move(name), lens, cam_from_world, std::move(copy));
            } else {
              view = MakeView(std::move(name), camera.cast<PinholeCamera>(), cam_from_world,
                              std::move(copy));
            }
            py::gil_scoped_release release;
            return self.Add(std::move(view), update, nullptr, time_s);
          },
          "image"_a, "camera"_a, "cam_from_world"_a, "name"_a, "update"_a = true,
          "time_s"_a = std::nan(""),
          "Adds a frame (COPIED, as LightField.add_view) with its camera and pose; drops the "
          "oldest beyond window_frames (their names are returned); with `update`, renders and "
          "detects. `time_s`: the frame's time in seconds (capture or arrival), for window_s.")
      .def(
          "add_view",
          [](LiveIntegrator& self, const View& view, bool update, double time_s) {
            py::gil_scoped_release release;
            return self.Add(view, update, nullptr, time_s);
          },
          "view"_a, "update"_a = true, "time_s"_a = std::nan(""),
          "Adds a light field's view (e.g. a replay); `time_s` as in add.")
      .def(
          "remove",
          [](LiveIntegrator& self, const std::string& name, bool update) {
            py::gil_scoped_release release;
            return self.Remove(name, update);
          },
          "name"_a, "update"_a = true, "Takes the named view out; False when it is not there.")
      .def(
          "update",
          [](LiveIntegrator& self) {
            py::gil_scoped_release release;
            self.Update();
          },
          "Renders the window and detects.")
      // The getters wait for a running update (the integrator's lock) with the GIL released.
      .def_property_readonly(
          "image",
          [](const LiveIntegrator& self) {
            DetectResult result;
            {
              py::gil_scoped_release release;
              result = self.result();
            }
            return ArrayFromImage(result.render.image).attr("copy")();
          },
          "The newest update's integral image (a copy), None before the first.")
      .def_property_readonly(
          "count",
          [](const LiveIntegrator& self) {
            DetectResult result;
            {
              py::gil_scoped_release release;
              result = self.result();
            }
            return ArrayFromImage(result.render.count).attr("copy")();
          },
          "Views per pixel of the newest update (a copy).")
      .def_property_readonly(
          "detections",
          [](const LiveIntegrator& self) {
            py::gil_scoped_release release;
            return self.result().detections;
          },
          "The newest update's detections.")
      .def_property_readonly(
          "result",
          [](const LiveIntegrator& self) {
            py::gil_scoped_release release;
            return self.result();
          },
          "The newest update's DetectResult (a copy).")
      .def_property_readonly(
          "tracks",
          [](const LiveIntegrator& self) {
            py::gil_scoped_release release;
            return self.tracks();
          },
          "The places found so far, most sighted first.")
      .def_property_readonly(
          "window",
          [](const LiveIntegrator& self) {
            py::gil_scoped_release release;
            return self.window();
          },
          "The window as a light field (a copy; pixels shared).")
      .def_property_readonly("updates", [](const LiveIntegrator& self) {
        py::gil_scoped_release release;
        return self.updates();
      })
      .def_property_readonly(
          "path",
          [](const LiveIntegrator& self) {
            std::vector<Vec3d> path;
            {
              py::gil_scoped_release release;
              path = self.path();
            }
            std::vector<std::array<double, 3>> out;
            for (const Vec3d& c : path) out.push_back({c.x, c.y, c.z});
            return out;
          },
          "Every added view's centre (local frame), oldest first (thinned beyond 10,000).")
      .def("state_json", &LiveIntegrator::StateJson, py::call_guard<py::gil_scoped_release>(),
           "The newest update as JSON: what the live page shows (docs/live.md).")
      .def("render_options", &LiveIntegrator::RenderOptions,
           py::call_guard<py::gil_scoped_release>(),
           "The options the newest update rendered with (pose_view resolved).")
      .def("tracks_result", &LiveIntegrator::TracksResult,
           py::call_guard<py::gil_scoped_release>(),
           "The tracks as a DetectResult (write() it as GeoJSON/KML/CSV).")
      .def("__repr__", [](const LiveIntegrator& self) {
        return "LiveIntegrator(window=" + std::to_string(self.window().views.size()) + "/" +
               std::to_string(self.live_options().window_frames) + ", updates=" +
               std::to_string(self.updates()) + ", tracks=" + std::to_string(self.tracks().size()) +
               ")";
      });
}

}  // namespace aos::python
