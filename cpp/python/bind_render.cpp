// Bindings of render/integral.h. The kwargs merge of aos.render_integral lives in
// python/aos/__init__.py.
#include <array>

#include "aos/render/focal_stack.h"
#include "aos/render/focal_surface.h"
#include "aos/viewer/viewer_options.h"
#include "aos/render/integral.h"
#include "aos/render/integral_kernels.h"
#include "aos/render/map.h"
#include "aos/render/merge.h"
#include "aos/render/rectify.h"
#include "aos/render/surface_integral.h"
#include "aos/util/error.h"
#include "aos/util/file_util.h"
#include "bindings.h"

namespace aos::python {

FocalSurface SurfaceFromPython(const py::object& value) {
  if (py::isinstance<FocalSurface>(value)) return value.cast<FocalSurface>();
  if (py::isinstance<Mesh>(value)) return FocalSurface::FromMesh(value.cast<Mesh>());
  if (py::isinstance<Heightfield>(value)) return FocalSurface::FromHeightfield(value.cast<Heightfield>());
  // A path, as the CLI's --focal-surface FILE: a mesh (OBJ, PLY) or a DEM raster.
  if (py::isinstance<py::str>(value) || py::hasattr(value, "__fspath__")) {
    return FocalSurface::Read(py::str(py::module_::import("os").attr("fspath")(value)));
  }
  if (!value.is_none() && !PyBool_Check(value.ptr())) {
    try {
      return FocalSurface::FromPlane(value.cast<Plane>());
    } catch (const py::cast_error&) {
    }
    if (PyNumber_Check(value.ptr()) && !py::isinstance<py::array>(value)) {
      try {  // a numpy scalar (np.float32(21.0)): the height of a horizontal plane
        return FocalSurface::FromPlane(Plane::AtHeight(value.cast<double>()));
      } catch (const py::cast_error&) {
      }
    }
  }
  throw py::type_error("focal_surface: expected a FocalSurface, Mesh, Heightfield, Plane, a number "
                       "(the height of a horizontal plane) or a file path (a mesh or DEM), got " +
                       std::string(py::str(py::type::of(value).attr("__name__"))));
}

namespace {

using namespace pybind11::literals;

// A plane surface's Plane, None for other kinds (the deprecated focal_plane's value).
py::object PlaneOfSurface(const py::object& surface) {
  const FocalSurface& s = surface.cast<const FocalSurface&>();
  if (s.kind() != FocalSurfaceKind::kPlane) return py::none();
  return py::cast(s.plane());
}

void BindFocalSurface(py::module_& m) {
  py::class_<FocalSurface>(m, "FocalSurface",
                           "Where the virtual camera focuses (render/focal_surface.h): a plane "
                           "(local frame), a mesh or a DEM height field (world coordinates), or a "
                           "depth map of a virtual camera. Shared and immutable; its Embree BVH is "
                           "built once on first use. Up = +z or -z, whichever points from the "
                           "surface towards the views' mean centre; an offset moves it along up.")
      .def(py::init([](const py::object& value) { return SurfaceFromPython(value); }), "surface"_a,
           "From a Mesh, a Heightfield, a Plane or a number (horizontal plane).")
      .def("in_crs", &InCrs, "crs"_a,
           "The surface in another CRS ('EPSG:32633'): a DEM whose raster CRS differs is "
           "transformed through PROJ (a mesh); anything else comes back as it is.")
      .def_static("read", &FocalSurface::Read, "path"_a,
                  "A mesh (OBJ/PLY) or else any GDAL raster (a DEM). Raises ValueError naming the file.")
      .def_static("from_depth_map",
                  [](const py::object& depth, const PinholeCamera& camera, const Rigid3d& cam_from_world) {
                    return FocalSurface::FromDepthMap(ImageFromArray(depth, 0, "depth"), camera, cam_from_world);
                  },
                  "depth"_a, "camera"_a, "cam_from_world"_a,
                  "A depth map (float32 (H, W), camera z in metres, copied) of the virtual camera "
                  "`camera` at `cam_from_world` (local frame).")
      .def_property_readonly("kind", [](const FocalSurface& s) { return FocalSurfaceKindName(s.kind()); },
                             "'plane', 'mesh', 'heightfield' or 'depth_map'.")
      .def_property_readonly("source", &FocalSurface::source, "The file it was read from, or ''.")
      .def_property_readonly(
          "plane", [](const py::object& self) { return PlaneOfSurface(self); },
          "The plane (local frame) of a plane surface; None for other kinds.")
      .def_property_readonly("file", &FocalSurface::file,
                             "The file read() read it from, when it is that file's surface as "
                             "it is (not moved between CRSs); else ''. What to_json carries.")
      .def("describe", &FocalSurface::Describe, "One line: kind, source, size.")
      .def(
          "depth_for",
          [](const FocalSurface& surface, const LightField& light_field, const PinholeCamera& camera,
             const Rigid3d& cam_from_world, double offset, const std::vector<int>& view_indices) {
            const SurfacePlacement placement =
                ResolveSurfacePlacement(surface, light_field, view_indices, offset);
            Image depth;
            {
              py::gil_scoped_release release;
              depth = surface.DepthFor(camera, cam_from_world, placement);
            }
            return ArrayFromImage(depth);
          },
          "light_field"_a, "camera"_a, "cam_from_world"_a, "offset"_a = 0.0,
          "view_indices"_a = std::vector<int>{},
          "float32 (H, W): camera z where each pixel's ray first meets the surface (placed for "
          "`light_field`: its origin, up from its views), 0 where it misses.")
      .def(
          "heights_at",
          [](const FocalSurface& surface, const LightField& light_field, const py::object& xy_object,
             double offset) {
            const auto xy = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(xy_object);
            if (!xy || xy.ndim() != 2 || xy.shape(1) != 2) throw py::value_error("xy: must be an (N, 2) array");
            std::vector<Vec2d> points;
            for (py::ssize_t i = 0; i < xy.shape(0); ++i) points.emplace_back(xy.at(i, 0), xy.at(i, 1));
            const SurfacePlacement placement = ResolveSurfacePlacement(surface, light_field, {}, offset);
            const std::vector<double> z = surface.HeightsAt(points, placement);
            return py::array_t<double>(static_cast<py::ssize_t>(z.size()), z.data());
          },
          "light_field"_a, "xy"_a, "offset"_a = 0.0,
          "World z of the (offset) surface under world (x, y) points (N, 2), met by vertical rays "
          "from the up side; NaN where they miss.")
      .def(py::pickle(
          [](const FocalSurface& surface) {
            py::dict state;
            state["kind"] = FocalSurfaceKindName(surface.kind());
            state["source"] = surface.source();
            state["file"] = surface.file();
            switch (surface.kind()) {
              case FocalSurfaceKind::kPlane: state["data"] = py::cast(surface.plane()); break;
              case FocalSurfaceKind::kMesh: state["data"] = py::cast(surface.mesh()); break;
              case FocalSurfaceKind::kHeightfield: state["data"] = py::cast(surface.heightfield()); break;
              case FocalSurfaceKind::kDepthMap:
                state["data"] = py::make_tuple(ArrayFromImage(surface.depth()).attr("copy")(),
                                               surface.depth_camera(), surface.depth_cam_from_world());
                break;
            }
            return state;
          },
          [](const py::object& state) {
            // Pickles before the file travelled have no "file": a surface not read from one.
            const bool has_file =
                py::isinstance<py::dict>(state) && py::reinterpret_borrow<py::dict>(state).contains("file");
            const py::dict values =
                has_file ? StateDict(state, "FocalSurface", {"kind", "source", "file", "data"})
                         : StateDict(state, "FocalSurface", {"kind", "source", "data"});
            const std::string kind = values["kind"].cast<std::string>();
            const std::string source = values["source"].cast<std::string>();
            const std::string file = has_file ? values["file"].cast<std::string>() : "";
            const auto read_from = [&](FocalSurface surface) {
              return file.empty() ? surface : FocalSurface::AsReadFrom(std::move(surface), file);
            };
            if (kind == "plane") return FocalSurface::FromPlane(values["data"].cast<Plane>());
            if (kind == "mesh") return read_from(FocalSurface::FromMesh(values["data"].cast<Mesh>(), source));
            if (kind == "heightfield") {
              return read_from(FocalSurface::FromHeightfield(values["data"].cast<Heightfield>(), source));
            }
            if (kind == "depth_map") {
              const py::tuple data = values["data"];
              return FocalSurface::FromDepthMap(ImageFromArray(data[0], 0, "depth"), data[1].cast<PinholeCamera>(),
                                                data[2].cast<Rigid3d>());
            }
            throw py::value_error("FocalSurface: unknown kind '" + kind + "'");
          }))
      .def("__eq__",
           [](const FocalSurface& a, const py::object& other) -> py::object {
             if (!py::isinstance<FocalSurface>(other)) return py::reinterpret_borrow<py::object>(Py_NotImplemented);
             return py::bool_(a.SameAs(other.cast<const FocalSurface&>()));
           },
           "other"_a, "Same kind and exactly equal data (a pickled copy equals its original).")
      .def("__hash__", [](const FocalSurface& s) { return std::hash<std::string>()(s.Describe()); })
      .def("__repr__", [](const FocalSurface& s) { return "FocalSurface(" + s.Describe() + ")"; });
  py::implicitly_convertible<Mesh, FocalSurface>();
  py::implicitly_convertible<Heightfield, FocalSurface>();
}

void BindIntegral(py::module_& m) {
  BindFocalSurface(m);
  OptionsClass<ApertureOptions>(
      m, "ApertureOptions",
      "The synthetic aperture every render integrates (render/aperture.h): the base of "
      "IntegralOptions and MapOptions, whose fields these are. Defaults from the C++ struct "
      "aos::ApertureOptions.")
      .Table()
      .Finish();
  // Docstrings are the header's field comments.
  OptionsClass<IntegralOptions, ApertureOptions>(
      m, "IntegralOptions",
      "Options of render_integral. Defaults come from the C++ struct aos::IntegralOptions; "
      "IntegralOptions(**fields) overrides them by name (unknown names raise TypeError).")
      .Table()
      .Deprecated("focal_plane", "focal_surface", PlaneOfSurface)
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
      .def_property_readonly(
          "variance", [](const IntegralResult& result) { return ArrayFromImage(result.variance); },
          "float32 (H, W): population variance of the view samples, mean over channels (0 where "
          "count < 2), when options.variance; else None. Shares memory with the result.")
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
        IntegralOptions options_copy = options;
        return RunWithProgress(progress, [&](ProgressSink* sink) {
          // As the CLI: a DEM in another CRS is moved into the light field's, and a render that
          // covers no pixel is an error naming the likely cause.
          options_copy.focal_surface = InCrs(options_copy.focal_surface, light_field_copy.crs);
          IntegralResult result = RenderIntegral(light_field_copy, options_copy, sink);
          CheckSurfaceCovers(options_copy.focal_surface, light_field_copy,
                             "the virtual camera's view", result.uncovered_pixels,
                             static_cast<int64_t>(result.image.width()) * result.image.height());
          return result;
        });
      },
      "light_field"_a, "options"_a, "progress"_a = py::none(),
      "Integral rendering (Eq. 1 of the AOS paper), GIL released. progress(stage, done, total) "
      "is called from the calling thread, throttled; if it raises, rendering stops and the error "
      "propagates. Ctrl-C raises KeyboardInterrupt. A focal surface read from a DEM in another "
      "CRS than the light field's is moved into it through PROJ. Raises ValueError for bad "
      "options, and when no pixel is covered (naming the likely cause: a surface above the "
      "cameras, its extent, its CRS). Prefer aos.render_integral, which also takes the options "
      "as keywords.");

  // Private, for benchmarks: the baselines they time in the same run (integral_kernels.h).
  m.def(
      "_set_simd_kernels",
      [](bool enabled, bool variance, bool row_loads) {
        internal::SetSimdEnabled(enabled);
        internal::SetSimdVarianceEnabled(variance);
        internal::SetSimdRowLoadsEnabled(row_loads);
      },
      "enabled"_a = true, "variance"_a = true, "row_loads"_a = true,
      "Benchmarks only, not thread-safe: turn the renderer's SIMD kernels off (enabled=False), "
      "only its SIMD variance kernel (variance=False), or the 8-bit kernel's row loads "
      "(row_loads=False: gathers, as before), to time the baselines.");
  m.def("virtual_camera", &VirtualCamera, "light_field"_a, "options"_a,
        "The virtual camera's intrinsics for `options` (square pixels, centred principal point): "
        "fov_deg, width and height where given (non-zero), else view pose_view's, else 50 "
        "degrees and 512 x 512.");
}

// The slices' images stacked into one new array (N, H, W) or (N, H, W, C) of their dtype (a
// copy: the slices are separate images in C++). An empty list gives (0, height, width) of
// `type`.
py::array StackArrays(const std::vector<Image>& images, int width, int height, PixelType type) {
  const Image* first = images.empty() ? nullptr : &images.front();
  const PixelType dtype_type = first ? first->type() : type;
  const py::dtype dtype = py::dtype::from_args(py::str(PixelTypeName(dtype_type)));
  std::vector<py::ssize_t> shape{static_cast<py::ssize_t>(images.size()),
                                 first ? first->height() : height, first ? first->width() : width};
  const int channels = first ? first->channels() : 1;
  if (channels > 1) shape.push_back(channels);
  py::array array(dtype, shape);
  const size_t plane_bytes = static_cast<size_t>(shape[1]) * shape[2] * channels *
                             PixelTypeSize(dtype_type);
  auto* out = static_cast<unsigned char*>(array.mutable_data());
  for (size_t i = 0; i < images.size(); ++i) {
    const Image& image = images[i];
    if (image.width() != shape[2] || image.height() != shape[1] ||
        image.channels() != channels || image.type() != dtype_type) {
      throw py::value_error("FocalStack: slice " + std::to_string(i) +
                            " differs in size, channels or type from slice 0");
    }
    image.CopyTo(out + i * plane_bytes, static_cast<ptrdiff_t>(image.width()) * channels);
  }
  return array;
}

std::string SizeText(const Image& image) {
  if (image.empty()) return "empty";
  return std::to_string(image.width()) + "x" + std::to_string(image.height()) + "x" +
         std::to_string(image.channels());
}

void BindSurfaceIntegral(py::module_& m) {
  OptionsClass<SurfaceIntegralOptions>(
      m, "SurfaceIntegralOptions",
      "Options of render_integral_on_depth (the mean on a depth surface). Defaults from the C++ "
      "struct aos::SurfaceIntegralOptions.")
      .Table()
      .Finish()
      .def("check", &SurfaceIntegralOptions::Check, "Raises ValueError naming the field.");

  py::class_<SurfaceIntegralResult>(m, "SurfaceIntegralResult",
                                    "What render_integral_on_depth returns.")
      .def_readonly("integral", &SurfaceIntegralResult::integral,
                    "image, count and statistics, as render_integral's result.")
      .def_property_readonly(
          "inliers",
          [](const SurfaceIntegralResult& result) { return ArrayFromImage(result.inliers); },
          "uint32 (H, W): samples averaged per pixel (robust only, else None); shares memory.")
      .def_property_readonly(
          "image",
          [](const SurfaceIntegralResult& result) { return ArrayFromImage(result.integral.image); },
          "The integral image on the surface (integral.image): float32 (H, W) or (H, W, C); "
          "shares memory with the result.")
      .def_property_readonly(
          "count",
          [](const SurfaceIntegralResult& result) { return ArrayFromImage(result.integral.count); },
          "uint32 (H, W): views that contributed to each pixel (integral.count); shared.")
      .def_readonly("fallback_pixels", &SurfaceIntegralResult::fallback_pixels,
                    "Robust: pixels that kept the plain mean (too few rays agreed).")
      .def("__repr__", [](const SurfaceIntegralResult& result) {
        return "SurfaceIntegralResult(" + SizeText(result.integral.image) +
               ", views_used=" + std::to_string(result.integral.views_used) + "/" +
               std::to_string(result.integral.views_selected) +
               ", uncovered_pixels=" + std::to_string(result.integral.uncovered_pixels) +
               ", robust=" + (result.inliers.empty() ? "False" : "True") +
               ", fallback_pixels=" + std::to_string(result.fallback_pixels) + ")";
      });

  m.def(
      "_render_integral_on_depth",
      [](const LightField& light_field, const IntegralOptions& options, const py::handle& depth,
         const SurfaceIntegralOptions& surface, const py::object& progress) {
        const LightField light_field_copy = light_field;
        const IntegralOptions options_copy = options;
        const Image depth_image = ImageFromArray(depth, 0, "depth");
        return RunWithProgress(progress, [&](ProgressSink* sink) {
          return RenderIntegralOnDepth(light_field_copy, options_copy, depth_image, surface, sink);
        });
      },
      "light_field"_a, "options"_a, "depth"_a, "surface"_a, "progress"_a = py::none(),
      "Integral on a per-pixel depth surface (camera z, metres; float32 (H, W), copied). GIL "
      "released. Prefer aos.render_integral_on_depth.");
}

// A map's image or count, or ValueError when render_map streamed the map to its file only.
const Image& KeptMapArray(const MapResult& map, const Image& array, const char* name) {
  if (map.image.empty()) {
    throw py::value_error(std::string("MapResult.") + name +
                          ": the map was streamed to its file and not kept in memory; pass "
                          "arrays=True to render_map to keep it (memory grows with the map)");
  }
  return array;
}

void BindMap(py::module_& m) {
  OptionsClass<MapOptions, ApertureOptions>(
      m, "MapOptions",
      "Options of render_map (an orthographic map looking straight down). Defaults from the C++ "
      "struct aos::MapOptions.")
      .Table()
      .Deprecated("focal_height", "focal_surface",
                  [](const py::object& surface) -> py::object {
                    const py::object plane = PlaneOfSurface(surface);
                    if (plane.is_none()) return plane;
                    return py::float_(plane.cast<Plane>().point.z);
                  })
      .Finish()
      .def("check", &MapOptions::Check, "view_count"_a, "Raises ValueError naming the field.");

  OptionsClass<DistributedOptions>(
      m, "DistributedOptions",
      "How aos.distributed.render_map (and aos-render map --workers/--scheduler) spreads a "
      "map's tiles over Dask. Defaults from the C++ struct aos::DistributedOptions.")
      .Table()
      .Finish()
      .def("check", &DistributedOptions::Check, "Raises ValueError naming the field.");

  OptionsClass<ViewerOptions>(
      m, "ViewerOptions",
      "The browser viewer's own settings (aos.view, aos-render view): where it listens, how "
      "many pages it serves, whether it opens a browser. Defaults from the C++ struct "
      "aos::ViewerOptions.")
      .Table()
      .Finish()
      .def("check", &ViewerOptions::Check, "Raises ValueError naming the field.");

  OptionsClass<ViewParams>(
      m, "ViewParams",
      "What one page request of the viewer may set (aos.viewer's session validates a page's "
      "values by this table): focus, aperture, views, the virtual camera, the display mapping. "
      "Defaults from the C++ struct aos::ViewParams.")
      .Table()
      .Finish()
      .def("check", &ViewParams::Check, "view_count"_a,
           "Raises ValueError naming the field; pose_view and the view range must lie within "
           "view_count views.");

  py::class_<MapResult>(m, "MapResult", "What render_map returns: the map and its grid.")
      .def_property_readonly(
          "image", [](const MapResult& map) { return ArrayFromImage(KeptMapArray(map, map.image, "image")); },
          "float32 (H, W) or (H, W, C): mean of the view samples, 0 where count is 0; row 0 is "
          "the largest y (north-up); shares memory with the result. ValueError when the map was "
          "only streamed to its file (render_map(path=...) without arrays=True).")
      .def_property_readonly(
          "count", [](const MapResult& map) { return ArrayFromImage(KeptMapArray(map, map.count, "count")); },
          "uint32 (H, W): view samples per pixel (0 = no view sees it); shared. ValueError when "
          "the map was only streamed to its file.")
      .def_property_readonly("has_arrays", [](const MapResult& map) { return !map.image.empty(); },
                             "Whether image and count are held in memory.")
      .def_property_readonly(
          "geotransform",
          [](const MapResult& map) {
            const std::array<double, 6> t = map.summary.grid.GeoTransform();
            return py::make_tuple(t[0], t[1], t[2], t[3], t[4], t[5]);
          },
          "GDAL's (x_min, pixel_size, 0, y_max, 0, -pixel_size), world coordinates: pixel "
          "(col, row) has its centre at x_min + (col + 0.5) p, y_max - (row + 0.5) p.")
      .def_readonly("crs", &MapResult::crs, "The light field's CRS ('' = none).")
      .def_property_readonly("width", [](const MapResult& map) { return map.summary.grid.width; })
      .def_property_readonly("height", [](const MapResult& map) { return map.summary.grid.height; })
      .def_property_readonly("pixel_size",
                             [](const MapResult& map) { return map.summary.grid.pixel_size; },
                             "Metres.")
      .def_property_readonly("up_z", [](const MapResult& map) { return map.summary.grid.up_z; },
                             "+1: up is +z; -1: up is -z (z-down frames).")
      .def_property_readonly("samples",
                             [](const MapResult& map) { return map.summary.samples; })
      .def_property_readonly("uncovered_pixels",
                             [](const MapResult& map) { return map.summary.uncovered_pixels; },
                             "Pixels with count 0.")
      .def_property_readonly("views_selected",
                             [](const MapResult& map) { return map.summary.views_selected; })
      .def_property_readonly("views_used", [](const MapResult& map) { return map.summary.views_used; },
                             "Selected views that contributed to at least one pixel.")
      .def_property_readonly("tiles", [](const MapResult& map) { return map.summary.tiles; })
      .def("__repr__", [](const MapResult& map) {
        const MapGrid& grid = map.summary.grid;
        return "MapResult(" + std::to_string(grid.width) + "x" + std::to_string(grid.height) +
               ", pixel_size=" + FormatNumber(grid.pixel_size) + ", crs='" + map.crs +
               "', uncovered_pixels=" + std::to_string(map.summary.uncovered_pixels) + ")";
      });

  m.def(
      "_render_map",
      [](const LightField& light_field, const MapOptions& options, const std::string& path,
         bool force, bool arrays, const py::object& progress) {
        const LightField light_field_copy = light_field;
        MapOptions options_copy = options;
        return RunWithProgress(progress, [&](ProgressSink* sink) {
          // A DEM in another CRS moved into the light field's, as the CLI does.
          options_copy.focal_surface = InCrs(options_copy.focal_surface, light_field_copy.crs);
          MapWriteOptions write;
          write.force = force;
          if (!path.empty()) {
            // Refuse a bad output (never over a frame) and CRS before rendering.
            std::vector<std::string> inputs;
            for (const View& view : light_field_copy.views) {
              if (!view.image_path.empty()) inputs.push_back(view.image_path);
            }
            CheckOutputPath(path, inputs, "path");
            CheckMapOutputPath(path, write);
            CheckMapCrs(light_field_copy.crs, path);
          }
          if (!path.empty() && !arrays) {
            // Streamed tile by tile into the file (memory independent of the map's size, as the
            // CLI); only the summary is kept.
            MapResult map;
            map.crs = light_field_copy.crs;
            map.summary = WriteMapGeoTiff(light_field_copy, options_copy, path, write, sink);
            return map;
          }
          MapResult map = RenderMap(light_field_copy, options_copy, sink);
          if (!path.empty()) WriteMapGeoTiff(map, path, write);
          return map;
        });
      },
      "light_field"_a, "options"_a, "path"_a, "force"_a, "arrays"_a, "progress"_a = py::none(),
      "An orthographic map: with `path` written as a Cloud-Optimised GeoTIFF, streamed tile by "
      "tile unless `arrays` (then also kept in memory); without `path` in memory (`arrays` must "
      "then be true). GIL released. Prefer aos.render_map.");
}

// The pieces of a map rendered window by window in other processes (aos.distributed): each
// call resolves the grid again from the poses (ResolveMapGrid reads poses and cameras only).
void BindMapWindows(py::module_& m) {
  m.def(
      "_map_grid",
      [](const LightField& light_field, const MapOptions& options) {
        MapGrid grid;
        {
          py::gil_scoped_release release;
          grid = ResolveMapGrid(light_field, options);
        }
        const std::array<double, 6> t = grid.GeoTransform();
        py::dict out;
        out["width"] = grid.width;
        out["height"] = grid.height;
        out["pixel_size"] = grid.pixel_size;
        out["up_z"] = grid.up_z;
        out["geotransform"] = py::make_tuple(t[0], t[1], t[2], t[3], t[4], t[5]);
        return out;
      },
      "light_field"_a, "options"_a,
      "The map's grid (ResolveMapGrid): width, height, pixel_size, up_z, geotransform.");
  m.def(
      "_map_window_views",
      [](const LightField& light_field, const MapOptions& options, int x0, int y0, int w, int h) {
        py::gil_scoped_release release;
        const MapGrid grid = ResolveMapGrid(light_field, options);
        return MapWindowViews(light_field, grid, options, x0, y0, w, h);
      },
      "light_field"_a, "options"_a, "x0"_a, "y0"_a, "w"_a, "h"_a,
      "The views that may contribute to map pixels [x0, x0 + w) x [y0, y0 + h) (map.h "
      "MapWindowViews; poses only).");
  m.def(
      "_map_windows_views",
      [](const LightField& light_field, const MapOptions& options,
         const std::vector<std::array<int, 4>>& windows) {
        py::gil_scoped_release release;
        std::vector<MapWindow> list;
        list.reserve(windows.size());
        for (const auto& [x0, y0, w, h] : windows) list.push_back(MapWindow{x0, y0, w, h});
        return MapWindowsViews(light_field, ResolveMapGrid(light_field, options), options, list);
      },
      "light_field"_a, "options"_a, "windows"_a,
      "_map_window_views for each (x0, y0, w, h) of `windows`, the grid resolved once.");
  m.def(
      "_render_map_window",
      [](const LightField& light_field, const MapOptions& options, int x0, int y0, int w, int h,
         const std::vector<int>& views) {
        SurfaceIntegralResult result;
        {
          py::gil_scoped_release release;
          const MapGrid grid = ResolveMapGrid(light_field, options);
          result = RenderMapWindow(light_field, grid, options, x0, y0, w, h, views);
        }
        py::dict out;
        out["image"] = ArrayFromImage(result.integral.image);
        out["count"] = ArrayFromImage(result.integral.count);
        out["used_view_indices"] = result.used_view_indices;
        out["samples"] = result.integral.samples;
        out["uncovered_pixels"] = result.integral.uncovered_pixels;
        return out;
      },
      "light_field"_a, "options"_a, "x0"_a, "y0"_a, "w"_a, "h"_a, "views"_a,
      "Map pixels [x0, x0 + w) x [y0, y0 + h) from views `views` only (map.h RenderMapWindow): "
      "a dict with image (float32 (h, w, C) or (h, w)), count (uint32), used_view_indices, "
      "samples, uncovered_pixels. GIL released.");
  m.def(
      "_check_map_covered",
      [](const LightField& light_field, const MapOptions& options, int64_t uncovered_pixels) {
        py::gil_scoped_release release;
        CheckMapCovered(light_field, ResolveMapGrid(light_field, options), uncovered_pixels);
      },
      "light_field"_a, "options"_a, "uncovered_pixels"_a,
      "Refuses a map on a focal surface with no pixel covered (map.h CheckMapCovered).");
  py::class_<MapGeoTiffWriter>(m, "_MapGeoTiffWriter",
                               "Writes a map window by window (map.h MapGeoTiffWriter).")
      .def(py::init([](const LightField& light_field, const MapOptions& options, int channels,
                       const std::string& path, bool force) {
             MapWriteOptions write;
             write.force = force;
             py::gil_scoped_release release;
             const MapGrid grid = ResolveMapGrid(light_field, options);
             CheckMapCrs(light_field.crs, path);
             return std::make_unique<MapGeoTiffWriter>(grid, channels, light_field.crs, path, write);
           }),
           "light_field"_a, "options"_a, "channels"_a, "path"_a, "force"_a = false)
      .def(
          "write",
          [](MapGeoTiffWriter& writer, int x0, int y0, const py::array& image,
             const py::array& count) {
            const Image image_in = ImageFromArray(image, 0, "image");
            const Image count_in = ImageFromArray(count, 0, "count");
            py::gil_scoped_release release;
            writer.Write(x0, y0, image_in, count_in);
          },
          "x0"_a, "y0"_a, "image"_a, "count"_a)
      .def(
          "commit",
          [](MapGeoTiffWriter& writer, const py::object& progress) {
            RunWithProgress(progress, [&](ProgressSink* sink) {
              writer.Commit(sink);
              return 0;
            });
          },
          "progress"_a = py::none());
}

void BindFocalStack(py::module_& m) {
  OptionsClass<FocalStackOptions>(
      m, "FocalStackOptions",
      "Options of render_focal_stack. Defaults from the C++ struct aos::FocalStackOptions.")
      .Table()
      .Finish()
      .def("check", &FocalStackOptions::Check, "view_count"_a,
           "Raises ValueError naming the offending field.");

  py::class_<FocalStack>(m, "FocalStack",
                         "A focal stack: one integral image per slice plane, in memory.")
      .def_readonly("camera", &FocalStack::camera, "The virtual camera.")
      .def_readonly("cam_from_world", &FocalStack::cam_from_world, "Its pose (local frame).")
      .def_readonly("render", &FocalStack::render,
                    "How the slices were rendered (pose resolved, pose_view -1).")
      .def_property_readonly(
          "planes", [](const FocalStack& stack) { return stack.focus.planes; },
          "The slice planes (a copy); empty for a terrain-following stack.")
      .def_property_readonly(
          "offsets", [](const FocalStack& stack) { return stack.focus.offsets; },
          "Terrain-following stacks: each slice's offset along up, metres (else empty).")
      .def_property_readonly(
          "surface",
          [](const FocalStack& stack) -> py::object {
            if (!stack.focus.surface) return py::none();
            return py::cast(*stack.focus.surface);
          },
          "Terrain-following stacks: the FocalSurface the slices follow (else None).")
      .def_property_readonly(
          "up", [](const FocalStack& stack) { return stack.focus.placement.up; },
          "Terrain-following stacks: the up axis the offsets are measured along.")
      .def_property_readonly(
          "images",
          [](const FocalStack& stack) {
            return StackArrays(stack.images, stack.camera.width, stack.camera.height,
                               PixelType::kF32);
          },
          "float32 (N, H, W) or (N, H, W, C): the slices' integral images, slice index first. A "
          "new array (a COPY) on every access: keep it in a variable rather than reading "
          "stack.images[i] in a loop.")
      .def_property_readonly(
          "counts",
          [](const FocalStack& stack) {
            return StackArrays(stack.counts, stack.camera.width, stack.camera.height,
                               PixelType::kU32);
          },
          "uint32 (N, H, W): views per pixel of each slice; a new array (a COPY) per access.")
      .def_property_readonly(
          "variances",
          [](const FocalStack& stack) -> py::object {
            if (stack.variances.empty()) return py::none();
            return StackArrays(stack.variances, stack.camera.width, stack.camera.height,
                               PixelType::kF32);
          },
          "float32 (N, H, W): variance of the view samples per slice, or None unless rendered "
          "with variance; a new array (a COPY) per access.")
      .def("__len__", &FocalStack::size)
      .def("__repr__", [](const FocalStack& stack) {
        return "FocalStack(" + std::to_string(stack.size()) + " slices of " +
               std::to_string(stack.camera.width) + "x" + std::to_string(stack.camera.height) +
               (stack.variances.empty() ? "" : ", with variance") + ")";
      });

  m.def(
      "_render_focal_stack",
      [](const LightField& light_field, const FocalStackOptions& options,
         const py::object& progress) {
        const LightField light_field_copy = light_field;
        const FocalStackOptions options_copy = options;
        return RunWithProgress(progress, [&](ProgressSink* sink) {
          return RenderFocalStack(light_field_copy, options_copy, sink);
        });
      },
      "light_field"_a, "options"_a, "progress"_a = py::none(),
      "Renders every slice, GIL released. Prefer aos.render_focal_stack.");
  m.def("stack_planes", &StackPlanes, "first"_a, "last"_a, "slices"_a, "center"_a,
        "The slice planes between two boundary planes, interpolated about the camera centre.");
  m.def("interpolate_plane", &InterpolatePlane, "first"_a, "last"_a, "s"_a, "center"_a,
        "The plane of parameter s in [0, 1] between two boundary planes.");
  m.def(
      "plane_depth",
      [](const PinholeCamera& camera, const Rigid3d& cam_from_world, const Plane& plane) {
        return ArrayFromImage(PlaneDepth(camera, cam_from_world, plane));
      },
      "camera"_a, "cam_from_world"_a, "plane"_a,
      "float32 (H, W): camera depth at which each pixel's ray meets the plane (0 if never in "
      "front).");
  m.def(
      "write_focal_stack",
      [](const std::string& folder, const FocalStack& stack) {
        py::gil_scoped_release release;
        WriteFocalStack(folder, stack);
      },
      "folder"_a, "stack"_a,
      "Writes the stack into a new (or empty) folder: stack.json + slice/count/variance TIFFs.");
  m.def(
      "read_focal_stack",
      [](const std::string& folder) {
        py::gil_scoped_release release;
        return ReadFocalStack(folder);
      },
      "folder"_a, "Reads a stack folder written by write_focal_stack (or aos-render stack).");
}

void BindMerge(py::module_& m) {
  BindEnum<MergeMethod>(m, "MergeMethod", "All-in-focus merge method (docs: merge.h).");

  OptionsClass<MergeOptions>(
      m, "MergeOptions",
      "Options of merge_focal_stack and all_in_focus. Defaults from the C++ struct "
      "aos::MergeOptions. aos.merge_focal_stack also accepts method as a string.")
      .Table()
      .Finish()
      .def("check", &MergeOptions::Check, "Raises ValueError naming the field.");

  py::class_<MergeResult>(m, "MergeResult", "An all-in-focus image with its depth and confidence.")
      .def_property_readonly(
          "image", [](const MergeResult& r) { return ArrayFromImage(r.image); },
          "float32 (H, W) or (H, W, C): the all-in-focus image; shares memory.")
      .def_property_readonly(
          "depth", [](const MergeResult& r) { return ArrayFromImage(r.depth); },
          "float32 (H, W): camera depth of the merged surface, metres; 0 where uncovered.")
      .def_property_readonly(
          "confidence", [](const MergeResult& r) { return ArrayFromImage(r.confidence); },
          "float32 (H, W) in [0, 1].")
      .def_property_readonly(
          "slice", [](const MergeResult& r) { return ArrayFromImage(r.slice); },
          "float32 (H, W): fractional slice index; -1 where uncovered.")
      .def_readonly("uncovered_pixels", &MergeResult::uncovered_pixels,
                    "Pixels no slice covers.")
      .def_readonly("fallback_pixels", &MergeResult::fallback_pixels,
                    "robust: pixels that kept the plain mean.")
      .def_readonly("seconds_merge", &MergeResult::seconds_merge,
                    "Time of focus measures, refinement, smoothing and image assembly, s.")
      .def_readonly("seconds_render", &MergeResult::seconds_render,
                    "Time of rendering (slices, re-integration), s.")
      .def_readonly("rendered_fraction", &MergeResult::rendered_fraction,
                    "all_in_focus: full-resolution slice pixels rendered, fraction of the full "
                    "stack's (1 without coarse_to_fine).")
      .def("__repr__", [](const MergeResult& r) {
        return "MergeResult(" + SizeText(r.image) +
               ", uncovered_pixels=" + std::to_string(r.uncovered_pixels) +
               ", fallback_pixels=" + std::to_string(r.fallback_pixels) +
               ", seconds_render=" + FormatNumber(r.seconds_render) +
               ", seconds_merge=" + FormatNumber(r.seconds_merge) + ")";
      });

  OptionsClass<AllInFocusOptions>(m, "AllInFocusOptions", "Options of all_in_focus.")
      .Table()
      .Finish()
      .def("check", &AllInFocusOptions::Check, "view_count"_a, "Raises ValueError naming the field.");

  m.def(
      "_merge_focal_stack",
      [](const FocalStack& stack, const MergeOptions& options, const LightField* light_field,
         const py::object& progress) {
        const MergeOptions options_copy = options;
        return RunWithProgress(progress, [&](ProgressSink* sink) {
          return MergeFocalStack(stack, options_copy, light_field, sink);
        });
      },
      "stack"_a, "options"_a, "light_field"_a = py::none(), "progress"_a = py::none(),
      "Merges a stack, GIL released (do not change the stack meanwhile). Prefer "
      "aos.merge_focal_stack.");
  m.def(
      "_all_in_focus",
      [](const LightField& light_field, const AllInFocusOptions& options,
         const py::object& progress) {
        const LightField light_field_copy = light_field;
        const AllInFocusOptions options_copy = options;
        return RunWithProgress(progress, [&](ProgressSink* sink) {
          return RenderAllInFocus(light_field_copy, options_copy, sink);
        });
      },
      "light_field"_a, "options"_a, "progress"_a = py::none(),
      "The streaming pipeline, GIL released. Prefer aos.all_in_focus.");
}

}  // namespace

void BindRectify(py::module_& m) {
  OptionsClass<RectifyOptions>(
      m, "RectifyOptions",
      "Options of make_rectifier (defaults from the C++ struct aos::RectifyOptions).")
      .Table()
      .Finish()
      .def("check", &RectifyOptions::Check, "Raises ValueError naming the field.");

  py::class_<Rectifier>(m, "Rectifier",
                        "Resampling maps from a lens to a perspective camera (make_rectifier).")
      .def_readonly("camera", &Rectifier::camera, "The rectified pinhole camera.")
      .def(
          "rectify",
          [](const Rectifier& rectifier, const py::handle& raw) {
            const Image image = ImageFromArray(raw, 0, "rectify: image");
            Image out;
            {
              py::gil_scoped_release release;
              out = Rectify(rectifier, image);
            }
            return ArrayFromImage(out);
          },
          "image"_a,
          "The rectified frame (a new array, the input's dtype and channels; the input is "
          "copied).")
      .def("__repr__", [](const Rectifier& rectifier) {
        return "Rectifier(camera=" + std::string(py::repr(py::cast(rectifier.camera))) + ")";
      });

  m.def(
      "make_rectifier",
      [](const LensCamera& lens, const RectifyOptions& options) {
        const LensCamera lens_copy = lens;  // the GIL is released while the maps are built
        const RectifyOptions options_copy = options;
        return RunWithProgress(py::none(), [&](ProgressSink* sink) {
          return MakeRectifier(lens_copy, options_copy, sink);
        });
      },
      "lens"_a, "options"_a,
      "Resampling maps for a lens and options; raises ValueError if the lens does not cover "
      "the requested view (Ctrl-C raises KeyboardInterrupt).");

  py::class_<RectifyLightFieldResult>(m, "RectifyLightFieldResult",
                                      "What rectify_light_field returns.")
      .def_readonly("light_field", &RectifyLightFieldResult::light_field,
                    "The light field with every view pinhole (a copy).")
      .def_readonly("rectified_views", &RectifyLightFieldResult::rectified_views,
                    "Views that went through a lens model (the rest were pinhole already).")
      .def("__repr__", [](const RectifyLightFieldResult& r) {
        return "RectifyLightFieldResult(views=" + std::to_string(r.light_field.views.size()) +
               ", rectified_views=" + std::to_string(r.rectified_views) + ")";
      });
  m.def(
      "_rectify_light_field",
      [](const LightField& light_field, const RectifyOptions& options,
         const py::object& progress) {
        const LightField light_field_copy = light_field;
        const RectifyOptions options_copy = options;
        return RunWithProgress(progress, [&](ProgressSink* sink) {
          return RectifyLightField(light_field_copy, options_copy, sink);
        });
      },
      "light_field"_a, "options"_a, "progress"_a = py::none(),
      "Rectifies every lens view, GIL released. Prefer aos.rectify_light_field.");
}

void BindRender(py::module_& m) {
  BindIntegral(m);
  BindRectify(m);
  BindSurfaceIntegral(m);
  BindMap(m);
  BindMapWindows(m);
  BindFocalStack(m);
  BindMerge(m);
}

}  // namespace aos::python
