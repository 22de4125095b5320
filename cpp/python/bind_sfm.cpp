// Bindings of sfm/colmap_model.h and sfm/colmap_pipeline.h: poses from frames with COLMAP,
// importing COLMAP models, geo-referencing.
#include "aos/sfm/colmap_model.h"
#include "aos/sfm/colmap_pipeline.h"
#include "aos/sfm/ground.h"
#include "aos/sfm/odm.h"
#include "aos/sfm/telemetry.h"
#include "aos/sfm/video.h"
#include "aos/util/error.h"
#include "bindings.h"

namespace aos::python {

using namespace pybind11::literals;

namespace {

// An (N, 3) array as points; ValueError for another shape.
std::vector<Vec3d> PointsFromArray(
    const py::array_t<double, py::array::c_style | py::array::forcecast>& points) {
  if (points.ndim() != 2 || points.shape(1) != 3) {
    throw py::value_error("points: must be an (N, 3) array");
  }
  std::vector<Vec3d> list(static_cast<size_t>(points.shape(0)));
  auto view = points.unchecked<2>();
  for (size_t i = 0; i < list.size(); ++i) {
    const auto k = static_cast<py::ssize_t>(i);
    list[i] = Vec3d(view(k, 0), view(k, 1), view(k, 2));
  }
  return list;
}

}  // namespace

void BindSfm(py::module_& m) {
  OptionsClass<PosesOptions>(
      m, "PosesOptions",
      "Options of estimate_poses (defaults from the C++ struct aos::PosesOptions).")
      .Table()
      .Finish()
      .def("check", &PosesOptions::Check, "Raises ValueError naming the field.");

  py::class_<PosesResult>(m, "PosesResult", "What estimate_poses found.")
      .def_readonly("light_field", &PosesResult::light_field,
                    "Registered frames with their poses (images not loaded).")
      .def_readonly("frames", &PosesResult::frames, "Every readable frame, relative paths.")
      .def_readonly("registered", &PosesResult::registered, "Registered frames, in view order.")
      .def_readonly("unregistered", &PosesResult::unregistered, "Frames COLMAP left out.")
      .def_readonly("warnings", &PosesResult::warnings, "Skipped frames, unregistered ones, ...")
      .def_readonly("order", &PosesResult::order,
                    "View order: 'time' (EXIF capture times) or 'name' (natural name order).")
      .def_readonly("time_source", &PosesResult::time_source,
                    "Where the capture times came from ('' when ordered by name).")
      .def_readonly("models", &PosesResult::models, "Models COLMAP built (the largest is used).")
      .def_readonly("points", &PosesResult::points, "3-D points of the model.")
      .def_property_readonly(
          "point_positions",
          [](const PosesResult& r) {
            py::array_t<double> out({static_cast<py::ssize_t>(r.point_positions.size()), py::ssize_t{3}});
            auto view = out.mutable_unchecked<2>();
            for (size_t i = 0; i < r.point_positions.size(); ++i) {
              for (int k = 0; k < 3; ++k) view(static_cast<py::ssize_t>(i), k) = r.point_positions[i][k];
            }
            return out;
          },
          "The model's 3-D points, (N, 3) float64, in the light field's local frame.")
      .def_readonly("observations", &PosesResult::observations, "Their observations.")
      .def_readonly("mean_reprojection_error_px", &PosesResult::mean_reprojection_error_px,
                    "COLMAP's mean reprojection error, pixels.")
      .def_readonly("median_depth", &PosesResult::median_depth,
                    "Median depth of the points along the optical axes.")
      .def_readonly("pose_error", &PosesResult::pose_error,
                    "e at the median depth (metres when geo-referenced).")
      .def_readonly("georeferenced", &PosesResult::georeferenced, "Whether positions were used.")
      .def_readonly("georeference_rms_m", &PosesResult::georeference_rms_m,
                    "RMS of the centre residuals after geo-referencing, metres.")
      .def_readonly("georeference_frames", &PosesResult::georeference_frames,
                    "Registered frames with a position.")
      .def_readonly("world_frame", &PosesResult::world_frame,
                    "What the light field's world frame is, e.g. 'UTM 31N (WGS84)'.")
      .def_readonly("crs", &PosesResult::crs,
                    "Its EPSG code ('EPSG:32631'), also light_field.crs; '' when it has none.")
      .def_property_readonly(
          "stage_seconds",
          [](const PosesResult& r) {
            py::dict seconds;
            for (const auto& stage : r.stages) seconds[py::str(stage.name)] = stage.seconds;
            return seconds;
          },
          "Wall time per stage: features, matching, mapping, import.")
      .def_readonly("workspace", &PosesResult::workspace, "The kept workspace, or ''.")
      .def_readonly("focal_prior_px", &PosesResult::focal_prior_px,
                    "Self-calibration: the focal length of the fov_deg prior (0 if none).")
      .def_readonly("focal_deviation", &PosesResult::focal_deviation,
                    "Recovered / prior focal length - 1; NaN when unchecked.")
      .def_readonly("scale_deviation", &PosesResult::scale_deviation,
                    "Median depth / flight_height_m - 1; NaN when unchecked.")
      .def_readonly("implausible", &PosesResult::implausible,
                    "The self-calibration exceeded max_focal_deviation or the scene scale "
                    "max_scale_deviation (kept: allow_implausible).")
      .def("__repr__", [](const PosesResult& r) {
        return "PosesResult(registered=" + std::to_string(r.registered.size()) + "/" +
               std::to_string(r.frames.size()) +
               ", mean_reprojection_error_px=" + FormatNumber(r.mean_reprojection_error_px) +
               ", pose_error=" + FormatNumber(r.pose_error) +
               ", georeferenced=" + (r.georeferenced ? "True" : "False") +
               ", implausible=" + (r.implausible ? "True" : "False") +
               ", warnings=" + std::to_string(r.warnings.size()) + ")";
      });

  m.def(
      "_estimate_poses",
      [](const std::string& frames_dir, const PosesOptions& options, const py::object& progress) {
        const PosesOptions options_copy = options;
        return RunWithProgress(progress, [&](ProgressSink* sink) {
          return EstimatePoses(frames_dir, options_copy, sink);
        });
      },
      "frames_dir"_a, "options"_a, "progress"_a = py::none(),
      "Runs COLMAP, GIL released. Prefer aos.estimate_poses.");

  m.def(
      "_import_colmap",
      [](const std::string& model_dir, const std::string& images_dir, const PosesOptions& options,
         const py::object& progress) {
        const PosesOptions options_copy = options;
        return RunWithProgress(progress, [&](ProgressSink* sink) {
          return ImportColmapPoses(model_dir, images_dir, options_copy, sink);
        });
      },
      "model_dir"_a, "images_dir"_a, "options"_a, "progress"_a = py::none(),
      "Imports a COLMAP sparse model, GIL released. Prefer aos.import_colmap.");
  OptionsClass<GroundOptions>(
      m, "GroundOptions",
      "Options of estimate_ground (defaults from the C++ struct aos::GroundOptions).")
      .Table()
      .Finish()
      .def("check", &GroundOptions::Check, "Raises ValueError naming the field.");

  py::class_<GroundResult>(m, "GroundResult", "Where the ground is (sfm/ground.h).")
      .def_readonly("up_sign", &GroundResult::up_sign, "+1: z up; -1: z down.")
      .def_readonly("plane", &GroundResult::plane, "Robust ground plane (local frame), normal up.")
      .def_readonly("plane_rms_m", &GroundResult::plane_rms_m, "RMS residual of its cells, m.")
      .def_readonly("plane_cells", &GroundResult::plane_cells, "Cells the plane kept.")
      .def_readonly("min_x", &GroundResult::min_x, "Local x of the grid's corner.")
      .def_readonly("min_y", &GroundResult::min_y, "Local y of the grid's corner.")
      .def_readonly("cell_size_m", &GroundResult::cell_size_m, "Cell side, metres.")
      .def_readonly("measured_cells", &GroundResult::measured_cells, "Cells with their own value.")
      .def_readonly("points", &GroundResult::points, "Points used.")
      .def_property_readonly(
          "z",
          [](const GroundResult& r) {
            py::array_t<float> out({static_cast<py::ssize_t>(r.height), static_cast<py::ssize_t>(r.width)});
            std::copy(r.z.begin(), r.z.end(), out.mutable_data());
            return out;
          },
          "Local z of the cell centres, (rows along y from min_y, columns along x), float32.")
      .def("z_at", &GroundResult::ZAt, "x"_a, "y"_a, "Local z of the model at local (x, y).")
      .def("heightfield", [](const GroundResult& r, const Vec3d& origin, const std::string& crs) {
             return GroundHeightfield(r, origin, crs);
           }, "origin"_a, "crs"_a = "",
           "The model as a north-up Heightfield in world coordinates (origin + local).")
      .def("__repr__", [](const GroundResult& r) {
        return "GroundResult(" + std::to_string(r.width) + "x" + std::to_string(r.height) +
               " cells of " + FormatNumber(r.cell_size_m) + " m, measured_cells=" +
               std::to_string(r.measured_cells) + ", plane_rms_m=" + FormatNumber(r.plane_rms_m) +
               ", up_sign=" + std::to_string(r.up_sign) + ")";
      });

  m.def(
      "_estimate_ground",
      [](const py::array_t<double, py::array::c_style | py::array::forcecast>& points, int up_sign,
         const GroundOptions& options) {
        const std::vector<Vec3d> list = PointsFromArray(points);
        const GroundOptions options_copy = options;
        return RunWithProgress(py::none(), [&](ProgressSink* sink) {
          return EstimateGround(list, up_sign, options_copy, sink);
        });
      },
      "points"_a, "up_sign"_a, "options"_a,
      "Prefer aos.estimate_ground (Ctrl-C raises KeyboardInterrupt).");
  m.def(
      "_ground_up_sign",
      [](const py::array_t<double, py::array::c_style | py::array::forcecast>& points,
         const LightField& light_field) {
        const std::vector<Vec3d> list = PointsFromArray(points);
        return GroundUpSign(list, light_field);
      },
      "points"_a, "light_field"_a, "+1 if the cameras fly above the points' median z, else -1.");

  m.def(
      "read_positions",
      [](const std::string& path, const std::string& crs) {
        py::dict positions;
        for (const NamedPosition& p : ReadPositionsFile(path, crs).positions) {
          positions[py::str(p.name)] = py::make_tuple(p.position.x, p.position.y, p.position.z);
        }
        return positions;
      },
      "path"_a, "crs"_a = "",
      "A positions CSV as {name: (x, y, z)} in metres: columns by their header names (name, x, "
      "y, z or name, lat, lon, alt; degrees projected to UTM with PROJ); `crs` states the CRS.");

  OptionsClass<TelemetryOptions>(
      m, "TelemetryOptions",
      "Options of import_telemetry (defaults from the C++ struct aos::TelemetryOptions).")
      .Table()
      .Finish()
      .def("check", &TelemetryOptions::Check, "Raises ValueError naming the field.");

  py::class_<AltitudeOutlier>(m, "AltitudeOutlier", "An altitude replaced by its running median.")
      .def_readonly("frame", &AltitudeOutlier::frame)
      .def_readonly("altitude_m", &AltitudeOutlier::altitude_m, "As given, metres.")
      .def_readonly("median_m", &AltitudeOutlier::median_m, "The median that replaced it.")
      .def("__repr__", [](const AltitudeOutlier& o) {
        return "AltitudeOutlier(frame='" + o.frame + "', altitude_m=" +
               FormatNumber(o.altitude_m) + ", median_m=" + FormatNumber(o.median_m) + ")";
      });

  py::class_<TelemetryResult>(m, "TelemetryResult", "What import_telemetry made.")
      .def_readonly("light_field", &TelemetryResult::light_field,
                    "The posed frames (images not loaded), crs = the flight's UTM zone.")
      .def_readonly("frames", &TelemetryResult::frames, "Frames in view order.")
      .def_readonly("source", &TelemetryResult::source, "'csv', 'odm' (geo.txt) or 'exif'.")
      .def_readonly("order", &TelemetryResult::order,
                    "View order: 'time' (capture times) or 'name' (natural name order).")
      .def_readonly("time_source", &TelemetryResult::time_source,
                    "Where the capture times came from ('' when ordered by name).")
      .def_readonly("altitude_source", &TelemetryResult::altitude_source,
                    "Which altitude was read ('csv alt', 'XMP RelativeAltitude', ...).")
      .def_readonly("yaw_reference", &TelemetryResult::yaw_reference,
                    "'true', 'grid' or 'magnetic', as given.")
      .def_readonly("declination_deg", &TelemetryResult::declination_deg,
                    "Added to every yaw (magnetic), degrees.")
      .def_readonly("altitude_reference", &TelemetryResult::altitude_reference,
                    "'absolute' or 'takeoff', as given.")
      .def_readonly("takeoff_height_m", &TelemetryResult::takeoff_height_m,
                    "Added to every altitude ('takeoff'), metres.")
      .def_readonly("takeoff_height_from", &TelemetryResult::takeoff_height_from,
                    "'given', or the DEM and the point it was sampled at.")
      .def_readonly("altitude_outliers", &TelemetryResult::altitude_outliers,
                    "Altitudes replaced by their running median.")
      .def_readonly("warnings", &TelemetryResult::warnings, "Frames left out, ...")
      .def_readonly("max_convergence_deg", &TelemetryResult::max_convergence_deg,
                    "Largest meridian convergence applied to a heading, degrees.")
      .def_readonly("radiometric", &TelemetryResult::radiometric,
                    "'none', 'flir' or 'linear', as given (light_field.radiometry: the map).")
      .def_readonly("first_frame_median_c", &TelemetryResult::first_frame_median_c,
                    "Radiometric frames: the first frame's median temperature, C (else NaN).")
      .def_readonly("first_frame_low_c", &TelemetryResult::first_frame_low_c,
                    "Radiometric frames: its 1st percentile temperature, C (else NaN).")
      .def_readonly("first_frame_high_c", &TelemetryResult::first_frame_high_c,
                    "Radiometric frames: its 99th percentile temperature, C (else NaN).")
      .def("__repr__", [](const TelemetryResult& r) {
        return "TelemetryResult(views=" + std::to_string(r.light_field.views.size()) +
               ", source='" + r.source + "', crs='" + r.light_field.crs +
               "', altitude_outliers=" + std::to_string(r.altitude_outliers.size()) + ")";
      });

  m.def(
      "_import_telemetry",
      [](const std::string& frames_dir, const TelemetryOptions& options,
         const py::object& progress) {
        const TelemetryOptions options_copy = options;
        return RunWithProgress(progress, [&](ProgressSink* sink) {
          return ImportTelemetry(frames_dir, options_copy, sink);
        });
      },
      "frames_dir"_a, "options"_a, "progress"_a = py::none(), "Poses from telemetry, GIL released. Prefer aos.import_telemetry.");

  OptionsClass<VideoFramesOptions>(
      m, "VideoFramesOptions",
      "Options of import_video's frames (defaults from the C++ struct aos::VideoFramesOptions).")
      .Table()
      .Finish()
      .def("check", &VideoFramesOptions::Check, "Raises ValueError naming the field.");
  py::class_<VideoFramesResult>(m, "VideoFramesResult", "The frames import_video took.")
      .def_readonly("frames", &VideoFramesResult::frames, "File names in frames/, time order.")
      .def_readonly("times_s", &VideoFramesResult::times_s, "Their times in the video, seconds.")
      .def_readonly("video_frames", &VideoFramesResult::video_frames, "Frames decoded.")
      .def_readonly("fps", &VideoFramesResult::fps)
      .def_readonly("width", &VideoFramesResult::width)
      .def_readonly("height", &VideoFramesResult::height)
      .def_readonly("srt_samples", &VideoFramesResult::srt_samples, "SRT blocks with a position.")
      .def_readonly("srt_skipped_blocks", &VideoFramesResult::srt_skipped_blocks,
                    "SRT blocks without one (before a GPS fix).")
      .def_readonly("yaw_from", &VideoFramesResult::yaw_from)
      .def_readonly("pitch_from", &VideoFramesResult::pitch_from)
      .def_readonly("altitude_from", &VideoFramesResult::altitude_from)
      .def("__repr__", [](const VideoFramesResult& r) {
        return "VideoFramesResult(frames=" + std::to_string(r.frames.size()) + " of " +
               std::to_string(r.video_frames) + ", yaw_from='" + r.yaw_from + "')";
      });
  py::class_<VideoImportResult>(m, "VideoImportResult", "What import_video wrote.")
      .def_readonly("frames", &VideoImportResult::frames)
      .def_readonly("telemetry", &VideoImportResult::telemetry,
                    "The posing, as import_telemetry reports it (its light_field as written).")
      .def_readonly("light_field_path", &VideoImportResult::light_field_path)
      .def("__repr__", [](const VideoImportResult& r) {
        return "VideoImportResult(views=" + std::to_string(r.telemetry.light_field.views.size()) +
               ", light_field_path='" + r.light_field_path + "')";
      });
  m.def(
      "_import_video",
      [](const std::string& video, const std::string& output_dir,
         const VideoFramesOptions& options, const TelemetryOptions& telemetry,
         const py::object& progress) {
        const VideoFramesOptions options_copy = options;
        const TelemetryOptions telemetry_copy = telemetry;
        return RunWithProgress(progress, [&](ProgressSink* sink) {
          return ImportVideo(video, output_dir, options_copy, telemetry_copy, sink);
        });
      },
      "video"_a, "output_dir"_a, "options"_a, "telemetry"_a, "progress"_a = py::none(),
      "Frames and poses from a drone video and its DJI SRT into a new folder, GIL released. "
      "Prefer aos.import_video.");

  py::class_<OdmGeoEntry>(m, "OdmGeoEntry", "One image line of an OpenDroneMap geo.txt.")
      .def_readonly("line", &OdmGeoEntry::line, "Line number in the file (1-based).")
      .def_readonly("image", &OdmGeoEntry::image)
      .def_readonly("position", &OdmGeoEntry::position, "geo_x, geo_y, geo_z (in the file's CRS).")
      .def_readonly("has_z", &OdmGeoEntry::has_z)
      .def_readonly("yaw_pitch_roll_deg", &OdmGeoEntry::yaw_pitch_roll_deg,
                    "Camera angles, degrees (yaw from true north, pitch -90 = nadir), or None.")
      .def_readonly("accuracy_m", &OdmGeoEntry::accuracy_m,
                    "Horizontal and vertical accuracy, metres, or None.")
      .def_readonly("extras", &OdmGeoEntry::extras, "The rest of the line.")
      .def("__repr__", [](const OdmGeoEntry& e) {
        return "OdmGeoEntry(image='" + e.image + "', line=" + std::to_string(e.line) + ")";
      });
  py::class_<OdmGeoFile>(m, "OdmGeoFile", "An OpenDroneMap image geolocation file (sfm/odm.h).")
      .def_readonly("projection", &OdmGeoFile::projection, "The first line as written.")
      .def_readonly("crs", &OdmGeoFile::crs, "As PROJ takes it ('EPSG:32616' for 'WGS84 UTM 16N').")
      .def_readonly("entries", &OdmGeoFile::entries)
      .def("__repr__", [](const OdmGeoFile& f) {
        return "OdmGeoFile(crs='" + f.crs + "', entries=" + std::to_string(f.entries.size()) + ")";
      });
  m.def("read_odm_geo", &ReadOdmGeo, "path"_a,
        "An OpenDroneMap geo.txt (projection line, then image x y [z] [yaw pitch roll] "
        "[accuracies]). aos.import_telemetry(frames, telemetry_file='geo.txt') poses frames "
        "from one. Raises ValueError naming the file, line and field.");
  m.def(
      "write_odm_geo",
      [](const std::string& path, const LightField& light_field, bool overwrite) {
        WriteOdmGeo(path, light_field, overwrite);
      },
      "path"_a, "light_field"_a, "overwrite"_a = false,
      "Writes a geo-referenced light field's camera centres (its CRS) and angles (yaw from true "
      "north, pitch -90 = nadir) as OpenDroneMap's geo.txt (odm --geo).");

  py::class_<OdmGcp>(m, "OdmGcp", "One sighting of a ground control point (gcp_list.txt line).")
      .def(py::init([](const Vec3d& position, const Vec2d& pixel, std::string image,
                       std::string name, std::string extras) {
             OdmGcp p;
             p.position = position;
             p.pixel = pixel;
             p.image = std::move(image);
             p.name = std::move(name);
             p.extras = std::move(extras);
             return p;
           }),
           "position"_a, "pixel"_a, "image"_a, "name"_a = "", "extras"_a = "",
           "position: geo_x, geo_y, geo_z in the file's CRS; pixel: ODM's im_x, im_y (the "
           "top-left pixel's centre at (0, 0); aos pixel = ODM pixel + 0.5).")
      .def_readonly("line", &OdmGcp::line, "Line number in the file (1-based; 0 when built).")
      .def_readonly("position", &OdmGcp::position, "geo_x, geo_y, geo_z (the file's CRS).")
      .def_readonly("pixel", &OdmGcp::pixel, "im_x, im_y (ODM's pixel coordinates).")
      .def_readonly("image", &OdmGcp::image)
      .def_readonly("name", &OdmGcp::name, "gcp_name, or ''.")
      .def_readonly("extras", &OdmGcp::extras, "The rest of the line.")
      .def("__repr__", [](const OdmGcp& p) {
        return "OdmGcp(name='" + p.name + "', image='" + p.image + "', line=" +
               std::to_string(p.line) + ")";
      });
  py::class_<OdmGcpFile>(m, "OdmGcpFile", "An OpenDroneMap ground control file (sfm/odm.h).")
      .def(py::init([](std::string projection, std::vector<OdmGcp> points) {
             OdmGcpFile f;
             f.crs = OdmProjectionCrs(projection, "projection");
             f.projection = std::move(projection);
             f.points = std::move(points);
             return f;
           }),
           "projection"_a, "points"_a,
           "A projection line ('EPSG:32633', 'WGS84 UTM 33N', a PROJ string) and the sightings.")
      .def_readonly("projection", &OdmGcpFile::projection, "The first line as written.")
      .def_readonly("crs", &OdmGcpFile::crs, "As PROJ takes it.")
      .def_readonly("points", &OdmGcpFile::points)
      .def("__repr__", [](const OdmGcpFile& f) {
        return "OdmGcpFile(crs='" + f.crs + "', points=" + std::to_string(f.points.size()) + ")";
      });
  m.def("read_odm_gcp", &ReadOdmGcp, "path"_a,
        "An OpenDroneMap gcp_list.txt (projection line, then geo_x geo_y geo_z im_x im_y "
        "image_name [gcp_name]). Raises ValueError naming the file, line and field.");
  m.def("write_odm_gcp", &WriteOdmGcp, "path"_a, "gcp_file"_a, "overwrite"_a = false,
        "Writes ground control as OpenDroneMap's gcp_list.txt (odm --gcp), atomically.");
  py::class_<GcpResidual>(m, "GcpResidual", "How one ground control sighting agrees with a pose.")
      .def_readonly("line", &GcpResidual::line)
      .def_readonly("image", &GcpResidual::image)
      .def_readonly("name", &GcpResidual::name)
      .def_readonly("view", &GcpResidual::view, "The view's index.")
      .def_readonly("predicted", &GcpResidual::predicted,
                    "The ground point projected into the view (aos pixel coordinates).")
      .def_readonly("observed", &GcpResidual::observed, "The marked pixel (ODM's + 0.5).")
      .def_readonly("error_px", &GcpResidual::error_px)
      .def_readonly("ground_error_m", &GcpResidual::ground_error_m,
                    "The marked pixel's ray at the point's height minus the point (x, y), m.")
      .def_readonly("ground_error_norm_m", &GcpResidual::ground_error_norm_m)
      .def("__repr__", [](const GcpResidual& r) {
        return "GcpResidual(name='" + r.name + "', image='" + r.image +
               "', error_px=" + FormatNumber(r.error_px) + ")";
      });
  py::class_<GcpCheckResult>(m, "GcpCheckResult", "What check_gcps measured.")
      .def_readonly("residuals", &GcpCheckResult::residuals)
      .def_readonly("rms_px", &GcpCheckResult::rms_px)
      .def_readonly("max_px", &GcpCheckResult::max_px)
      .def_readonly("rms_ground_m", &GcpCheckResult::rms_ground_m)
      .def_readonly("max_ground_m", &GcpCheckResult::max_ground_m)
      .def("__repr__", [](const GcpCheckResult& r) {
        return "GcpCheckResult(sightings=" + std::to_string(r.residuals.size()) +
               ", rms_px=" + FormatNumber(r.rms_px) + ", rms_ground_m=" +
               FormatNumber(r.rms_ground_m) + ")";
      });
  m.def(
      "check_gcps",
      [](const LightField& light_field, const OdmGcpFile& gcps) {
        return CheckGcps(light_field, gcps, "gcps");
      },
      "light_field"_a, "gcps"_a,
      "Each ground control sighting projected into its view (found by name) with the light "
      "field's poses (PROJ moves the points into its CRS): the pixel and ground errors, as "
      "aos-render check-gcp reports them. Raises ValueError for an image that is no view.");
}

}  // namespace aos::python
