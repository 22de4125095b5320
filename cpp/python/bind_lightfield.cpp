// Bindings of lightfield/lightfield.h and lightfield/formats.h.
#include <filesystem>

#include <pybind11/stl/filesystem.h>

#include "aos/geometry/geodesy.h"
#include "aos/lightfield/formats.h"
#include "aos/lightfield/lightfield.h"
#include "aos/util/error.h"
#include "bindings.h"

namespace aos::python {
namespace {

using namespace pybind11::literals;

std::string ImageSummary(const Image& image) {
  if (image.empty()) return "no image";
  return std::to_string(image.width()) + "x" + std::to_string(image.height()) + "x" +
         std::to_string(image.channels()) + " " + PixelTypeName(image.type());
}

bool ViewsEqual(const View& a, const View& b) {
  return a.name == b.name && a.image_path == b.image_path &&
         LensEqual(a.camera, b.camera) &&
         RigidEqual(a.cam_from_world, b.cam_from_world) &&
         ImagesEqual(a.image, b.image);
}

bool PoseSourcesEqual(const PoseSource& a, const PoseSource& b) {
  return a.method == b.method && a.mean_reprojection_error_px == b.mean_reprojection_error_px &&
         a.median_depth == b.median_depth && a.pose_error == b.pose_error &&
         a.georeferenced == b.georeferenced && a.georeference_rms_m == b.georeference_rms_m &&
         a.world_frame == b.world_frame && a.unregistered == b.unregistered;
}

bool LightFieldsEqual(const LightField& a, const LightField& b) {
  if (a.origin != b.origin || a.crs != b.crs || a.masked != b.masked || a.grey != b.grey ||
      a.radiometry != b.radiometry || a.views.size() != b.views.size()) {
    return false;
  }
  if (a.pose_source.has_value() != b.pose_source.has_value()) return false;
  if (a.pose_source && !PoseSourcesEqual(*a.pose_source, *b.pose_source)) return false;
  for (size_t i = 0; i < a.views.size(); ++i) {
    if (!ViewsEqual(a.views[i], b.views[i])) return false;
  }
  return true;
}

// __eq__ of a bound class from a C++ predicate (NotImplemented for another type).
template <typename T, typename Equal>
auto EqualityMethod(Equal equal) {
  return [equal](const T& a, const py::object& other) -> py::object {
    if (!py::isinstance<T>(other)) return py::reinterpret_borrow<py::object>(Py_NotImplemented);
    return py::bool_(equal(a, other.cast<const T&>()));
  };
}

// View `index` of `light_field`, or std::invalid_argument naming the index.
template <typename LightFieldT>
auto& ViewAt(LightFieldT& light_field, int index) {
  if (index < 0 || static_cast<size_t>(index) >= light_field.views.size()) {
    ThrowInvalid("index: " + std::to_string(index) + " is not a view (the light field has " +
                 std::to_string(light_field.views.size()) + ")");
  }
  return light_field.views[static_cast<size_t>(index)];
}

}  // namespace

void BindLightField(py::module_& m) {
  py::class_<View>(m, "View",
                   "One view of a light field: an image with its camera (a LensCamera: pinhole or "
                   "a lens model) and pose. "
                   "Read-only; build views with LightField.add_view.")
      .def_readonly("name", &View::name, "A label for messages (file name for loaded views).")
      .def_readonly("image_path", &View::image_path,
                    "Source file, if the view was loaded from one (else '').")
      .def_readonly("camera", &View::camera,
                    "The view's camera, a LensCamera (model 'pinhole' for pinhole views; its size "
                    "matches the image), the same whether the view was added with add_view or "
                    "loaded from a file. camera.pinhole() gives its PinholeCamera.")
      .def_readonly("cam_from_world", &View::cam_from_world,
                    "Pose: local frame -> camera (OpenCV axes).")
      .def_property_readonly(
          "lens",
          [](const View& view) {
            // Deprecated alias of `camera` (kept for one release, see CHANGELOG.md).
            if (PyErr_WarnEx(PyExc_DeprecationWarning,
                             "View.lens is deprecated: use View.camera (a LensCamera)", 1) != 0) {
              throw py::error_already_set();
            }
            return view.camera;
          },
          "Deprecated alias of `camera` (a copy); emits DeprecationWarning. Removed in the next "
          "release.")
      .def_property_readonly(
          "image", [](const View& view) { return ArrayFromImage(view.image); },
          "The pixels as a new numpy array (a COPY: (H, W) or (H, W, C), native dtype), or None "
          "if the light field was loaded without images.")
      .def("__eq__", EqualityMethod<View>(&ViewsEqual), "other"_a,
           "Exact equality of every field and of the pixels.")
      .def(py::pickle(
          [](const View& view) {
            // The pixels travel as a numpy array (a copy without the border).
            return py::dict("name"_a = view.name, "image_path"_a = view.image_path,
                            "camera"_a = view.camera,
                            "cam_from_world"_a = view.cam_from_world,
                            "image"_a = ArrayFromImage(view.image));
          },
          [](const py::object& state) {
            // Pickles of aos 0.x before the one-camera view also carry "lens" (and "camera" is
            // a PinholeCamera there): the lens is the camera unless it is a pinhole.
            const bool old_state =
                py::isinstance<py::dict>(state) && py::reinterpret_borrow<py::dict>(state).contains("lens");
            const py::dict v =
                old_state ? StateDict(state, "View",
                                      {"name", "image_path", "camera", "lens", "cam_from_world", "image"})
                          : StateDict(state, "View",
                                      {"name", "image_path", "camera", "cam_from_world", "image"});
            View view;
            view.name = v["name"].cast<std::string>();
            view.image_path = v["image_path"].cast<std::string>();
            if (old_state) {
              const LensCamera lens = v["lens"].cast<LensCamera>();
              view.camera = lens.IsPinhole()
                                ? LensCamera::FromPinhole(v["camera"].cast<PinholeCamera>())
                                : lens;
            } else {
              view.camera = v["camera"].cast<LensCamera>();
            }
            view.cam_from_world = v["cam_from_world"].cast<Rigid3d>();
            const std::string where = "View '" + view.name + "'";
            if (!v["image"].is_none()) {
              // What add_view checks (MakeView: camera, pose, size, finite pixels), so a pickle
              // cannot bring in a view that could not have been made.
              return MakeView(view.name, view.camera, view.cam_from_world,
                              ImageFromArray(v["image"], /*border=*/1, "View: image"),
                              view.image_path);
            }
            // A view loaded without images: its camera and pose still as add_view checks them.
            view.camera.Pinhole().Check(where);
            if (auto problem = DescribeInvalidRigid(view.cam_from_world)) {
              ThrowInvalid(Where(where, "cam_from_world: " + *problem));
            }
            return view;
          }))
      .def("__repr__", [](const View& view) {
        const py::object camera = py::cast(view.camera);
        return "View(name='" + view.name + "', " + ImageSummary(view.image) + ", " +
               std::string(py::repr(camera)) + ")";
      });

  py::class_<Radiometry>(m, "Radiometry",
                         "How pixel values measure temperature: kelvin = kelvin_per_unit * value "
                         "+ kelvin_offset (frames and renders alike).")
      .def(py::init([](double kelvin_per_unit, double kelvin_offset) {
             Radiometry radiometry{kelvin_per_unit, kelvin_offset};
             radiometry.Check();
             return radiometry;
           }),
           "kelvin_per_unit"_a = 0.01, "kelvin_offset"_a = 0.0,
           "Raises ValueError for kelvin_per_unit <= 0 or a non-finite value.")
      .def_readonly("kelvin_per_unit", &Radiometry::kelvin_per_unit, "Kelvin per unit of value.")
      .def_readonly("kelvin_offset", &Radiometry::kelvin_offset, "Kelvin at value 0.")
      .def(
          "kelvin",
          [](const Radiometry& r, const py::object& values) {
            return py::module_::import("numpy").attr("asarray")(values, "dtype"_a = "float64") *
                       py::float_(r.kelvin_per_unit) +
                   py::float_(r.kelvin_offset);
          },
          "values"_a, "Temperatures in kelvin of pixel values (a number or an array; float64).")
      .def(
          "celsius",
          [](const Radiometry& r, const py::object& values) {
            return py::module_::import("numpy").attr("asarray")(values, "dtype"_a = "float64") *
                       py::float_(r.kelvin_per_unit) +
                   py::float_(r.kelvin_offset - kZeroCelsiusK);
          },
          "values"_a, "Temperatures in degrees Celsius of pixel values (a number or an array).")
      .def("value_of_celsius", &Radiometry::ValueOfCelsius, "celsius"_a,
           "The pixel value of a temperature in degrees Celsius.")
      .def("__eq__", EqualityMethod<Radiometry>([](const Radiometry& a, const Radiometry& b) {
             return a == b;
           }),
           "other"_a)
      .def(py::pickle(
          [](const Radiometry& r) {
            return py::dict("kelvin_per_unit"_a = r.kelvin_per_unit,
                            "kelvin_offset"_a = r.kelvin_offset);
          },
          [](const py::object& state) {
            const py::dict v = StateDict(state, "Radiometry", {"kelvin_per_unit", "kelvin_offset"});
            Radiometry r{v["kelvin_per_unit"].cast<double>(), v["kelvin_offset"].cast<double>()};
            r.Check();
            return r;
          }))
      .def("__repr__", [](const Radiometry& r) {
        return "Radiometry(kelvin_per_unit=" + FormatNumber(r.kelvin_per_unit) +
               ", kelvin_offset=" + FormatNumber(r.kelvin_offset) + ")";
      });

  py::class_<PoseSource>(m, "PoseSource",
                         "Where a light field's estimated poses came from and how good they are.")
      .def_readonly("method", &PoseSource::method, "e.g. 'colmap'.")
      .def_readonly("mean_reprojection_error_px", &PoseSource::mean_reprojection_error_px,
                    "COLMAP's mean reprojection error, pixels.")
      .def_readonly("median_depth", &PoseSource::median_depth,
                    "Median depth of the reconstructed points (light-field units).")
      .def_readonly("pose_error", &PoseSource::pose_error,
                    "e = error_px * median_depth / fx (light-field units).")
      .def_readonly("georeferenced", &PoseSource::georeferenced,
                    "Whether units are metres (else COLMAP's arbitrary scale).")
      .def_readonly("georeference_rms_m", &PoseSource::georeference_rms_m,
                    "RMS of the camera-centre residuals of the geo-referencing, metres.")
      .def_readonly("world_frame", &PoseSource::world_frame,
                    "What origin and world coordinates are in, e.g. 'UTM 31N (WGS84)'.")
      .def_readonly("unregistered", &PoseSource::unregistered, "Frames that got no pose.")
      .def("__eq__", EqualityMethod<PoseSource>(&PoseSourcesEqual), "other"_a,
           "Exact equality of every field.")
      .def(py::pickle(
          [](const PoseSource& p) {
            return py::dict("method"_a = p.method,
                            "mean_reprojection_error_px"_a = p.mean_reprojection_error_px,
                            "median_depth"_a = p.median_depth, "pose_error"_a = p.pose_error,
                            "georeferenced"_a = p.georeferenced,
                            "georeference_rms_m"_a = p.georeference_rms_m,
                            "world_frame"_a = p.world_frame, "unregistered"_a = p.unregistered);
          },
          [](const py::object& state) {
            const py::dict v = StateDict(
                state, "PoseSource",
                {"method", "mean_reprojection_error_px", "median_depth", "pose_error",
                 "georeferenced", "georeference_rms_m", "world_frame", "unregistered"});
            PoseSource p;
            p.method = v["method"].cast<std::string>();
            p.mean_reprojection_error_px = v["mean_reprojection_error_px"].cast<double>();
            p.median_depth = v["median_depth"].cast<double>();
            p.pose_error = v["pose_error"].cast<double>();
            p.georeferenced = v["georeferenced"].cast<bool>();
            p.georeference_rms_m = v["georeference_rms_m"].cast<double>();
            p.world_frame = v["world_frame"].cast<std::string>();
            p.unregistered = v["unregistered"].cast<std::vector<std::string>>();
            return p;
          }))
      .def("__repr__", [](const PoseSource& p) {
        return "PoseSource(method='" + p.method + "', mean_reprojection_error_px=" +
               FormatNumber(p.mean_reprojection_error_px) +
               ", pose_error=" + FormatNumber(p.pose_error) +
               ", georeferenced=" + (p.georeferenced ? "True" : "False") + ", world_frame='" +
               p.world_frame + "', unregistered=" + std::to_string(p.unregistered.size()) + ")";
      });

  py::class_<LightField>(m, "LightField",
                         "A light field: views (image, pinhole camera, cam_from_world) in a "
                         "local frame whose zero lies at `origin` in world coordinates.")
      .def(py::init<>(), "An empty light field (origin at zero, no views).")
      .def_readonly("pose_source", &LightField::pose_source,
                    "PoseSource of estimated poses (estimate_poses, import_colmap), or None.")
      .def_readwrite("origin", &LightField::origin,
                     "World position of the local frame's zero (float64 copy; e.g. UTM).")
      .def_property(
          "crs", [](const LightField& light_field) { return light_field.crs; },
          [](LightField& light_field, const std::string& crs) {
            CheckLightFieldCrs(crs, "crs");
            light_field.crs = crs;
          },
          "'EPSG:<code>' of the world coordinates (origin + local), or '' = not "
          "geo-referenced. Setting it checks it with PROJ: a projected CRS in metres (ValueError "
          "for an unknown code or a geographic CRS).")
      .def_readonly("masked", &LightField::masked,
                    "True when loaded with a mask (load_lightfield(mask=...) or mask_dir): each "
                    "view's last channel is the mask weight (0 or the full range) and the others "
                    "are premultiplied by it; renders divide by it and return the other channels.")
      .def_readwrite("grey", &LightField::grey,
                     "True when the frames are read as grey (one-channel luminance) whenever the "
                     "light field is loaded from its file (import_telemetry(grey=True)); written "
                     "to the file as \"grey\": true.")
      .def_property(
          "radiometry", [](const LightField& light_field) { return light_field.radiometry; },
          [](LightField& light_field, const std::optional<Radiometry>& radiometry) {
            if (radiometry) radiometry->Check();
            // Temperatures are one channel (and a weight when masked): refused on RGB views.
            LightField checked = EmptyLike(light_field);
            checked.radiometry = radiometry;
            checked.views = light_field.views;  // pixels shared, not copied
            CheckLightField(checked, "radiometry");
            light_field.radiometry = radiometry;
          },
          "Radiometry when the values measure temperature (radiometric thermal frames: kelvin "
          "= kelvin_per_unit * value + kelvin_offset, renders included), else None. Set it for "
          "16-bit counts with a linear calibration.")
      .def_property_readonly(
          "views", [](const LightField& light_field) { return light_field.views; },
          "The views, as a new list of read-only View objects (their pixels are not copied).")
      .def("__len__", [](const LightField& light_field) { return light_field.views.size(); })
      .def("image_bytes", &LightField::ImageBytes,
           "Total bytes of the decoded frames (width * height * channels * value size).")
      .def(
          "add_view",
          [](LightField& light_field, const py::handle& image, const py::object& camera,
             const Rigid3d& cam_from_world, std::string name) {
            Image copy = ImageFromArray(image, /*border=*/1, "add_view: image");
            if (py::isinstance<LensCamera>(camera)) {
              LensCamera lens = camera.cast<LensCamera>();
              lens.Finalize("add_view: camera");
              light_field.views.push_back(
                  MakeView(std::move(name), lens, cam_from_world, std::move(copy)));
              return;
            }
            light_field.views.push_back(MakeView(std::move(name), camera.cast<PinholeCamera>(),
                                                 cam_from_world, std::move(copy)));
          },
          "image"_a, "camera"_a, "cam_from_world"_a, "name"_a = "",
          "Appends a view. `camera` is a PinholeCamera or a LensCamera (raw frames through a lens "
          "model, rendered by direct sampling). `image` (H, W) or (H, W, C) of dtype uint8, uint16 or float32 "
          "(float64 is converted to float32) is COPIED into the light field with a 1-pixel "
          "border; changing the array afterwards does not change the view. Raises ValueError for "
          "another dtype, a bad camera, a camera that disagrees with the image size, or an "
          "invalid cam_from_world (non-finite, not orthonormal, a reflection).")
      .def("__eq__", EqualityMethod<LightField>(&LightFieldsEqual), "other"_a,
           "Exact equality of origin, crs, pose_source, masked, grey, radiometry and every view "
           "(fields and pixels).")
      .def("__copy__", [](const LightField& light_field) { return LightField(light_field); },
           "A copy; the pixels are shared, which cannot be told apart from a deep copy since "
           "views are read-only.")
      .def(
          "__deepcopy__",
          [](const LightField& light_field, const py::dict&) { return LightField(light_field); },
          "memo"_a, "As __copy__ (the read-only pixels are shared).")
      .def(py::pickle(
          [](const LightField& light_field) {
            py::list views;
            for (const View& view : light_field.views) views.append(py::cast(view));
            return py::dict("origin"_a = light_field.origin, "crs"_a = light_field.crs,
                            "views"_a = views, "pose_source"_a = light_field.pose_source,
                            "masked"_a = light_field.masked, "grey"_a = light_field.grey,
                            "radiometry"_a = light_field.radiometry);
          },
          [](const py::object& state) {
            const py::dict v =
                StateDict(state, "LightField", {"origin", "crs", "views", "pose_source", "masked",
                                                "grey", "radiometry"});
            LightField light_field;
            light_field.origin = v["origin"].cast<Vec3d>();
            light_field.crs = v["crs"].cast<std::string>();
            light_field.views = v["views"].cast<std::vector<View>>();
            light_field.pose_source = v["pose_source"].cast<std::optional<PoseSource>>();
            light_field.masked = v["masked"].cast<bool>();
            light_field.grey = v["grey"].cast<bool>();
            light_field.radiometry = v["radiometry"].cast<std::optional<Radiometry>>();
            return light_field;
          }))
      .def("__repr__", [](const LightField& light_field) {
        py::object origin = py::cast(light_field.origin);
        return "LightField(views=" + std::to_string(light_field.views.size()) + ", origin=" +
               std::string(py::str(py::module_::import("numpy").attr("array2string")(
                   origin, "separator"_a = ", "))) +
               (light_field.crs.empty() ? std::string() : ", crs='" + light_field.crs + "'") +
               (light_field.masked ? ", masked=True" : "") + (light_field.grey ? ", grey=True" : "") +
               (light_field.radiometry ? ", radiometry='" + light_field.radiometry->Describe() + "'"
                                       : std::string()) +
               ", image_bytes=" + std::to_string(light_field.ImageBytes()) + ")";
      });

  py::class_<LoadResult>(m, "LoadResult", "What load_lightfield returns.")
      .def_readonly("light_field", &LoadResult::light_field, "The loaded light field.")
      .def_readonly("format", &LoadResult::format, "'aos' or 'jku'.")
      .def_readonly("notes", &LoadResult::notes,
                    "Things the user should know (e.g. substituted frame names).")
      .def(
          "__eq__",
          EqualityMethod<LoadResult>([](const LoadResult& a, const LoadResult& b) {
            return a.format == b.format && a.notes == b.notes &&
                   LightFieldsEqual(a.light_field, b.light_field);
          }),
          "other"_a, "Exact equality of format, notes and light field.")
      .def(py::pickle(
          [](const LoadResult& result) {
            return py::dict("light_field"_a = result.light_field, "format"_a = result.format,
                            "notes"_a = result.notes);
          },
          [](const py::object& state) {
            const py::dict v = StateDict(state, "LoadResult", {"light_field", "format", "notes"});
            LoadResult result;
            result.light_field = v["light_field"].cast<LightField>();
            result.format = v["format"].cast<std::string>();
            result.notes = v["notes"].cast<std::vector<std::string>>();
            return result;
          }))
      .def("__repr__", [](const LoadResult& result) {
        return "LoadResult(format='" + result.format + "', views=" +
               std::to_string(result.light_field.views.size()) +
               ", notes=" + std::to_string(result.notes.size()) + ")";
      });

  m.def(
      "_load_view_images",
      [](LightField& light_field, const std::vector<int>& indices, bool grey,
         const std::filesystem::path& mask, const std::filesystem::path& mask_dir,
         int num_threads) {
        LoadOptions options;
        options.grey = grey;
        options.mask = mask.string();
        options.mask_dir = mask_dir.string();
        options.num_threads = num_threads;
        py::gil_scoped_release release;
        LoadViewImages(light_field, indices, options);
      },
      "light_field"_a, "indices"_a, "grey"_a = false, "mask"_a = "", "mask_dir"_a = "",
      "num_threads"_a = 1,
      "Decodes the frames of views `indices` in place from their image_path, as load_lightfield "
      "does with grey/mask/mask_dir (formats.h LoadViewImages). Used by aos.distributed.");
  m.def(
      "_drop_view_images",
      [](LightField& light_field, const std::vector<int>& indices) {
        DropViewImages(light_field, indices);
      },
      "light_field"_a, "indices"_a,
      "Drops the decoded images of views `indices` in place (poses stay). Used by aos.distributed.");

  m.def(
      "_view_image",
      [](const LightField& light_field, int index) {
        return ArrayFromImage(ViewAt(light_field, index).image);
      },
      "light_field"_a, "index"_a,
      "The decoded image of view `index` as a new numpy array (None if not decoded). Used by "
      "aos.distributed's shared frame store.");
  m.def(
      "_set_view_image",
      [](LightField& light_field, int index, const py::handle& array) {
        View& view = ViewAt(light_field, index);
        const std::string where = "view " + std::to_string(index) + " (" + view.image_path + ")";
        Image image = ImageFromArray(array, /*border=*/1, where + ": image");
        const Image old = std::move(view.image);
        view.image = std::move(image);
        try {
          CheckView(view, where);
        } catch (...) {
          view.image = old;
          throw;
        }
      },
      "light_field"_a, "index"_a, "image"_a,
      "Sets the decoded image of view `index` (a copy of `image`, checked against the view's "
      "camera). Used by aos.distributed's shared frame store.");

  // LoadOptions' field table (bindings.h FieldRow): its fields are load_lightfield's keywords;
  // the viewer spells them as aos-render's flags from it.
  m.attr("_load_field_table") = FieldTable<LoadOptions>();
  const LoadOptions load_defaults;
  m.def(
      "load_lightfield",
      [](const std::filesystem::path& path, double fov_deg, const std::filesystem::path& images_dir,
         bool load_images, bool grey, const std::filesystem::path& mask,
         const std::filesystem::path& mask_dir, int num_threads, const py::object& progress) {
        LoadOptions options;
        options.fov_deg = fov_deg;
        options.images_dir = images_dir.string();
        options.load_images = load_images;
        options.grey = grey;
        options.mask = mask.string();
        options.mask_dir = mask_dir.string();
        options.num_threads = num_threads;
        return RunWithProgress(progress, [&](ProgressSink* sink) {
          return LoadLightField(path.string(), options, sink);
        });
      },
      "path"_a, "fov_deg"_a = load_defaults.fov_deg, "images_dir"_a = load_defaults.images_dir,
      "load_images"_a = load_defaults.load_images, "grey"_a = load_defaults.grey,
      "mask"_a = load_defaults.mask, "mask_dir"_a = load_defaults.mask_dir,
      "num_threads"_a = load_defaults.num_threads,
      "progress"_a = py::none(),
      "Loads a light field (the aos JSON format, or a JKU-ICG/AOS poses.json), detecting the "
      "format from the content. fov_deg: horizontal field of view of the frames, degrees, "
      "required for poses.json (0 = not given). images_dir: folder of the frames of a "
      "poses.json ('' = beside it). load_images: False loads poses and cameras only (the "
      "frames need not exist; a poses.json reads one frame for its size). grey: frames become "
      "one-channel luminance (Rec. 601: 0.299 R + 0.587 G + 0.114 B) at load. mask: one mask "
      "image for every frame (zero = left out of every average, non-zero = valid); mask_dir: "
      "a folder with one mask per frame, named like the frame (any image extension, case "
      "ignored); the frames then carry a premultiplied weight channel (LightField.masked) and "
      "renders return the mean over valid samples. A frame missing "
      "under its exact name is found under the one name differing only in case. "
      "num_threads: -1 = all cores. progress(stage, done, total) is called from the calling "
      "thread, throttled; if it raises, loading stops and the error propagates. Ctrl-C raises "
      "KeyboardInterrupt.");

  m.def(
      "find_view",
      [](const LightField& light_field, const std::string& name) {
        return FindViewByName(light_field, name, "find_view");
      },
      "light_field"_a, "name"_a,
      "The index of the view named `name` (its name, file name or file name without the "
      "extension; exact matches first, then ignoring case), e.g. for pose_view. Raises "
      "ValueError when none or several match, listing close or matching names.");

  const WriteLightFieldOptions write_defaults;
  m.def(
      "write_lightfield",
      [](const std::filesystem::path& path, const LightField& light_field,
         std::string images_subdir, std::string image_extension) {
        WriteLightFieldOptions options;
        options.images_subdir = std::move(images_subdir);
        options.image_extension = std::move(image_extension);
        const LightField snapshot = light_field;  // cheap: pixel storage is shared
        py::gil_scoped_release release;
        WriteLightField(path.string(), snapshot, options);
      },
      "path"_a, "light_field"_a, "images_subdir"_a = write_defaults.images_subdir,
      "image_extension"_a = write_defaults.image_extension,
      "Writes `light_field` in the aos JSON format to `path`; views without a source file are "
      "written into images_subdir (relative to the JSON file's folder) with image_extension. "
      "Atomic per file; refuses to overwrite any view's source image.");
}

}  // namespace aos::python
