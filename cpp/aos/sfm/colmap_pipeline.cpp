#include "aos/sfm/colmap_pipeline.h"

#include <sqlite3.h>
#include <stdlib.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <set>
#include <sstream>

#include "aos/geometry/geodesy.h"
#include "aos/image/image_io.h"
#include "aos/lightfield/camera_file.h"
#include "aos/util/csv.h"
#include "aos/util/error.h"
#include "aos/util/file_util.h"
#include "aos/util/math.h"
#include "aos/util/memory.h"
#include "aos/util/parallel.h"
#include "aos/util/process.h"
#include "aos/util/timer.h"

namespace fs = std::filesystem;

namespace aos {
namespace {

std::string Number(double value) {
  std::ostringstream out;
  out.precision(17);
  out << value;
  return out.str();
}

// A temporary workspace removed on destruction, or the user's (kept).
class Workspace {
 public:
  explicit Workspace(const std::string& named) {
    if (!named.empty()) {
      CheckOutputFolder(named);
      fs::create_directories(named);
      path_ = named;
      return;
    }
    path_ = MakePrivateTempFolder("aos-poses-", "workspace");
    temporary_ = true;
  }
  ~Workspace() {
    if (temporary_) {
      std::error_code ignored;
      fs::remove_all(path_, ignored);
    }
  }
  Workspace(const Workspace&) = delete;
  Workspace& operator=(const Workspace&) = delete;
  const fs::path& path() const { return path_; }
  bool temporary() const { return temporary_; }

 private:
  fs::path path_;
  bool temporary_ = false;
};

// Runs one COLMAP command, logging its output to `log` and calling `on_line` per line. A
// non-zero exit is an error quoting the end of the log.
void RunColmap(const std::string& stage, std::vector<std::string> argv, const fs::path& log_path,
               const std::function<void(const std::string&)>& on_line, ProgressSink* progress) {
  std::ofstream log(log_path);
  log << "$";
  for (const std::string& arg : argv) log << " " << arg;
  log << "\n";
  std::deque<std::string> tail;
  const int status = RunProcess(
      argv,
      [&](const std::string& line) {
        log << line << "\n";
        tail.push_back(line);
        if (tail.size() > 12) tail.pop_front();
        if (on_line) on_line(line);
      },
      [&] { return ProgressCancelled(progress); });
  log.flush();
  if (status != 0) {
    std::string end;
    for (const std::string& line : tail) end += "\n  " + line;
    ThrowInvalid("COLMAP " + argv[1] + " (" + stage + ") failed with exit status " +
                 std::to_string(status) + "; the end of its output:" + end);
  }
}

// "[i/N]" after `marker` in a COLMAP log line: i, or -1.
int BracketIndex(const std::string& line, const std::string& marker) {
  const size_t at = line.find(marker);
  if (at == std::string::npos) return -1;
  const size_t open = line.find('[', at);
  if (open == std::string::npos) return -1;
  try {
    return std::stoi(line.substr(open + 1));
  } catch (const std::exception&) {
    return -1;
  }
}

// COLMAP's camera model and parameters for a known aos lens.
std::pair<std::string, std::string> ColmapCameraFor(const LensCamera& lens, const std::string& where) {
  const auto& d = lens.distortion;
  const std::string f = Number(lens.fx) + "," + Number(lens.fy) + "," + Number(lens.cx) + "," +
                        Number(lens.cy);
  const LensModelTraits& traits = TraitsOf(lens.model);
  if (traits.colmap_model[0] == '\0') {
    ThrowInvalid(where + ": model: COLMAP has no " + traits.name + " model; rectify the frames "
                 "first (aos-render rectify) and give the rectified camera");
  }
  // COLMAP's OPENCV and OPENCV_FISHEYE take the model's coefficients in aos's order; a radtan
  // k3 needs FULL_OPENCV (k1 k2 p1 p2 k3 k4 k5 k6).
  std::string parameters = f;
  for (int i = 0; i < traits.distortion_count && i < 4; ++i) {
    parameters += "," + Number(d[static_cast<size_t>(i)]);
  }
  if (lens.model == LensModel::kRadTan && d[4] != 0.0) {
    return {"FULL_OPENCV", parameters + "," + Number(d[4]) + ",0,0,0"};
  }
  return {traits.colmap_model, parameters};
}

// Starting parameters of a self-calibrated COLMAP model from a horizontal FOV.
std::string InitialParams(const std::string& model, int width, int height, double fov_deg) {
  const double half = DegToRad(0.5 * fov_deg);
  const bool fisheye = model.find("FISHEYE") != std::string::npos;
  const double f = 0.5 * width / (fisheye ? half : std::tan(half));
  const std::string fs_ = Number(f), c = Number(0.5 * width) + "," + Number(0.5 * height);
  if (model == "SIMPLE_PINHOLE") return fs_ + "," + c;
  if (model == "PINHOLE") return fs_ + "," + fs_ + "," + c;
  if (model == "SIMPLE_RADIAL" || model == "SIMPLE_RADIAL_FISHEYE") return fs_ + "," + c + ",0";
  if (model == "RADIAL" || model == "RADIAL_FISHEYE") return fs_ + "," + c + ",0,0";
  if (model == "OPENCV") return fs_ + "," + fs_ + "," + c + ",0,0,0,0";
  return fs_ + "," + fs_ + "," + c + ",0,0,0,0";  // OPENCV_FISHEYE
}

// Writes position priors into COLMAP's database (images.prior_tx/ty/tz) for spatial matching.
// Returns the number of frames that got a prior.
int WritePriors(const fs::path& database, const std::vector<NamedPosition>& positions,
                const Vec3d& origin) {
  sqlite3* db = nullptr;
  if (sqlite3_open_v2(database.c_str(), &db, SQLITE_OPEN_READWRITE, nullptr) != SQLITE_OK) {
    const std::string message = db ? sqlite3_errmsg(db) : "out of memory";
    sqlite3_close(db);
    ThrowInvalid(database.string() + ": cannot open COLMAP's database: " + message);
  }
  sqlite3_stmt* statement = nullptr;
  // COLMAP 3.8's schema: priors are columns of the images table (later versions moved them).
  const char* sql = "UPDATE images SET prior_tx = ?1, prior_ty = ?2, prior_tz = ?3 WHERE name = ?4";
  int updated = 0;
  bool ok = sqlite3_prepare_v2(db, sql, -1, &statement, nullptr) == SQLITE_OK &&
            sqlite3_exec(db, "BEGIN", nullptr, nullptr, nullptr) == SQLITE_OK;
  for (size_t i = 0; ok && i < positions.size(); ++i) {
    const Vec3d local = positions[i].position - origin;
    sqlite3_reset(statement);
    sqlite3_bind_double(statement, 1, local.x);
    sqlite3_bind_double(statement, 2, local.y);
    sqlite3_bind_double(statement, 3, local.z);
    sqlite3_bind_text(statement, 4, positions[i].name.c_str(), -1, SQLITE_TRANSIENT);
    ok = sqlite3_step(statement) == SQLITE_DONE;
    if (ok) updated += sqlite3_changes(db);
  }
  ok = ok && sqlite3_exec(db, "COMMIT", nullptr, nullptr, nullptr) == SQLITE_OK;
  const std::string message = sqlite3_errmsg(db);
  sqlite3_finalize(statement);
  sqlite3_close(db);
  if (!ok) ThrowInvalid(database.string() + ": cannot write position priors: " + message);
  return updated;
}

Vec3d Mean(const std::vector<NamedPosition>& positions) {
  Vec3d sum(0.0);
  for (const NamedPosition& p : positions) sum += p.position;
  return positions.empty() ? sum : sum / static_cast<double>(positions.size());
}

std::string ListSome(const std::vector<std::string>& names, size_t most = 8) {
  std::string text;
  for (size_t i = 0; i < names.size() && i < most; ++i) text += (i ? ", " : "") + names[i];
  if (names.size() > most) text += ", ... (" + std::to_string(names.size()) + " in all)";
  return text;
}

// Median depth along the optical axes of the model's points, over (view, point) pairs where the
// point lies in front of the view and inside its frame.
double MedianDepth(const ColmapModel& model, const LightField& light_field) {
  std::vector<double> depths;
  const size_t step = std::max<size_t>(1, model.points.size() / 20000);  // bounded work
  for (size_t p = 0; p < model.points.size(); p += step) {
    for (const View& view : light_field.views) {
      const Vec3d in_cam = view.cam_from_world * model.points[p].position;
      if (!(in_cam.z > 0.0)) continue;
      Vec2d pixel;
      if (!view.camera.Project(in_cam, &pixel)) continue;
      if (pixel.x < 0 || pixel.y < 0 || pixel.x > view.camera.width || pixel.y > view.camera.height) continue;
      depths.push_back(in_cam.z);
    }
  }
  if (depths.empty()) return 0.0;
  std::nth_element(depths.begin(), depths.begin() + depths.size() / 2, depths.end());
  return depths[depths.size() / 2];
}

// Fills `result` from `model` (COLMAP's frame) for the frames result->frames (relative to
// frames_dir): the light field, registered and unregistered frames, geo-referencing by
// `positions` (matched to frame names), and the pose record.
void ImportInto(ColmapModel model, const std::string& frames_dir,
                const std::vector<NamedPosition>& positions, const std::string& positions_where,
                double min_registered_fraction, PosesResult* result,
                ProgressSink* progress = nullptr) {
  ColmapImportOptions import_options;
  import_options.load_images = false;
  ColmapImport imported = ImportColmapModel(model, frames_dir, import_options, progress);
  result->light_field = std::move(imported.light_field);
  result->registered = imported.registered;
  result->order = imported.order;
  result->time_source = imported.time_source;
  for (std::string& warning : imported.warnings) result->warnings.push_back(std::move(warning));
  // Unregistered: the listed frames the model lacks (not every file in the folder: unreadable
  // ones were never given to COLMAP and are reported as skipped).
  const std::set<std::string> registered(result->registered.begin(), result->registered.end());
  for (const std::string& name : result->frames) {
    if (registered.count(name) == 0) result->unregistered.push_back(name);
  }
  if (!result->unregistered.empty()) {
    result->warnings.push_back(std::to_string(result->unregistered.size()) + " of " +
                               std::to_string(result->frames.size()) +
                               " frames were not registered: " + ListSome(result->unregistered));
  }
  const size_t total = std::max<size_t>(1, result->frames.size());
  if (static_cast<double>(result->registered.size()) / total < min_registered_fraction) {
    ThrowInvalid(frames_dir + ": COLMAP registered only " +
                 std::to_string(result->registered.size()) + " of " + std::to_string(total) +
                 " frames (below min_registered_fraction " + FormatNumber(min_registered_fraction) +
                 "); not registered: " + ListSome(result->unregistered));
  }
  result->points = model.points.size();
  result->observations = model.num_observations;
  result->mean_reprojection_error_px = model.mean_reprojection_error_px;
  if (!positions.empty()) {
    const GeoreferenceResult geo =
        Georeference(&result->light_field, result->registered, positions, positions_where);
    result->georeferenced = true;
    result->local_from_model = geo.local_from_model;
    result->georeference_rms_m = geo.rms_m;
    result->georeference_frames = geo.frames;
    if (!geo.warning.empty()) result->warnings.push_back(geo.warning);
    for (ColmapPoint& point : model.points) {
      point.position = geo.local_from_model * point.position;
    }
  }
  result->point_positions.reserve(model.points.size());
  for (const ColmapPoint& point : model.points) result->point_positions.push_back(point.position);
  result->median_depth = MedianDepth(model, result->light_field);
  const double focal =
      result->light_field.views.empty() ? 0.0 : result->light_field.views[0].camera.fx;
  if (focal > 0.0) {
    result->pose_error = result->mean_reprojection_error_px * result->median_depth / focal;
  }
  PoseSource source;
  source.method = "colmap";
  source.mean_reprojection_error_px = result->mean_reprojection_error_px;
  source.median_depth = result->median_depth;
  source.pose_error = result->pose_error;
  source.georeferenced = result->georeferenced;
  source.georeference_rms_m = result->georeference_rms_m;
  // The frame is said once: by its EPSG code when it has one, else described.
  source.world_frame = result->crs.empty() ? result->world_frame : "";
  source.unregistered = result->unregistered;
  result->light_field.pose_source = source;
  result->light_field.crs = result->georeferenced ? result->crs : "";
}

// Whether `ratio` (recovered / expected) lies within 1 / (1 + deviation) .. 1 + deviation: the
// plausibility band of the focal-length and scene-scale checks.
bool WithinRatio(double ratio, double deviation) {
  const double limit = 1.0 + deviation;
  return ratio <= limit && ratio >= 1.0 / limit;
}

// Self-calibrated intrinsics against the fov_deg prior (see PosesOptions::max_focal_deviation):
// implausible ones are refused, or accepted with a loud warning under allow_implausible; without
// a prior the warning says they could not be checked.
void CheckSelfCalibration(const PosesOptions& options, PosesResult* result) {
  if (result->light_field.views.empty()) return;
  const LensCamera& lens = result->light_field.views[0].camera;
  const double focal = std::sqrt(lens.fx * lens.fy);
  const double recovered_fov_deg = RadToDeg(2.0 * std::atan(0.5 * lens.width / lens.fx));
  char text[512];
  if (!(options.fov_deg > 0.0)) {
    std::snprintf(text, sizeof(text),
                  "the self-calibrated focal length (%.1f px, a %.1f-degree field of view) could "
                  "not be checked: give fov_deg (--frames-fov-deg), the frames' known field of view, or "
                  "a camera file; self-calibration from nadir views of flat ground is ill-posed "
                  "(docs/poses.md)",
                  focal, recovered_fov_deg);
    result->warnings.push_back(text);
    return;
  }
  result->focal_prior_px = 0.5 * lens.width / std::tan(0.5 * DegToRad(options.fov_deg));
  result->focal_deviation = focal / result->focal_prior_px - 1.0;
  if (WithinRatio(focal / result->focal_prior_px, options.max_focal_deviation)) return;
  result->implausible = true;
  std::snprintf(text, sizeof(text),
                "IMPLAUSIBLE self-calibration: the focal length came out at %.1f px (a %.1f-degree "
                "field of view) but the %s-degree prior gives %.1f px (%+.0f %%, more than "
                "max_focal_deviation %s); poses, scale and depths built on it are wrong (nadir "
                "views of flat ground leave the focal length ill-determined)",
                focal, recovered_fov_deg, FormatNumber(options.fov_deg).c_str(),
                result->focal_prior_px, 100.0 * result->focal_deviation,
                FormatNumber(options.max_focal_deviation).c_str());
  if (!options.allow_implausible) {
    ThrowInvalid(std::string(text) + "; give a camera file from `calibrate` (camera_file, --camera-file), or "
                 "allow_implausible (--allow-implausible) to keep the result anyway");
  }
  result->warnings.push_back(text);
}

// A geo-referenced model's scene scale against the flight height (see
// PosesOptions::flight_height_m): implausible scale is refused, or accepted with a loud warning
// under allow_implausible. Without a flight height, `warn_unchecked` adds a warning that the
// scale was not checked.
void CheckSceneScale(const PosesOptions& options, bool warn_unchecked, PosesResult* result) {
  if (!result->georeferenced) return;  // Check() refuses flight_height_m without positions
  char text[640];
  if (!(options.flight_height_m > 0.0)) {
    if (warn_unchecked) {
      std::snprintf(text, sizeof(text),
                    "the scene scale (median depth %.1f m) was not checked: give flight_height_m "
                    "(--flight-height-m), the cameras' height above the ground",
                    result->median_depth);
      result->warnings.push_back(text);
    }
    return;
  }
  const double ratio = result->median_depth / options.flight_height_m;
  result->scale_deviation = ratio - 1.0;
  if (WithinRatio(ratio, options.max_scale_deviation)) return;
  result->implausible = true;
  std::snprintf(text, sizeof(text),
                "IMPLAUSIBLE scene scale: the views' median depth came out at %.1f m but the "
                "flight height is %s m (%.2f times it, outside 1/(1 + d)..1 + d for "
                "max_scale_deviation d = %s); check the focal length (a self-calibrated one is "
                "ill-determined over flat ground: give a camera file or the frames' field of "
                "view) and the positions (altitudes, units, frame)",
                result->median_depth, FormatNumber(options.flight_height_m).c_str(),
                ratio, FormatNumber(options.max_scale_deviation).c_str());
  if (!options.allow_implausible) {
    ThrowInvalid(std::string(text) + "; or allow_implausible (--allow-implausible) to keep the "
                 "result anyway");
  }
  result->warnings.push_back(text);
}

}  // namespace

void PosesOptions::Check() const {
  if (colmap.empty()) ThrowInvalid("colmap: must name the COLMAP executable");
  CheckFieldChoices(*this);  // matcher, preset, camera_model: the table's choices
  if (!(max_focal_deviation > 0.0) || !std::isfinite(max_focal_deviation)) {
    ThrowInvalid("max_focal_deviation: must be > 0 (a fraction of the prior's focal length)");
  }
  if (!(flight_height_m >= 0.0) || !std::isfinite(flight_height_m)) {
    ThrowInvalid("flight_height_m: must be >= 0 metres (0 = not checked; got " +
                 FormatNumber(flight_height_m) + ")");
  }
  if (!(max_scale_deviation > 0.0) || !std::isfinite(max_scale_deviation)) {
    ThrowInvalid("max_scale_deviation: must be > 0 (a fraction of flight_height_m; got " +
                 FormatNumber(max_scale_deviation) + ")");
  }
  if (flight_height_m > 0.0 && positions_file.empty() && !exif_positions) {
    ThrowInvalid("flight_height_m: checks a geo-referenced model's scale, which needs positions "
                 "(positions_file or exif_positions); without them the model's units are "
                 "arbitrary");
  }
  if (!positions_crs.empty() && positions_file.empty()) {
    ThrowInvalid("positions_crs: applies to positions_file, which is not given");
  }
  if (!positions_file.empty() && exif_positions) {
    ThrowInvalid("positions_file/exif_positions: give one source of positions, not both");
  }
  if (matcher == "spatial" && positions_file.empty() && !exif_positions) {
    ThrowInvalid("matcher: spatial matching needs positions (positions_file or exif_positions)");
  }
  if (sequential_overlap < 1) ThrowInvalid("sequential_overlap: must be >= 1");
  if (spatial_neighbors < 1) ThrowInvalid("spatial_neighbors: must be >= 1");
  const bool fisheye = camera_model.find("FISHEYE") != std::string::npos;
  if (!(fov_deg == 0.0 || (fov_deg > 0.0 && fov_deg < (fisheye ? 360.0 : 180.0)))) {
    ThrowInvalid("fov_deg: must be 0 (unknown) or in (0, " + std::string(fisheye ? "360" : "180") +
                 ") degrees");
  }
  if (!camera_file.empty() && fov_deg != 0.0) {
    ThrowInvalid("fov_deg: only for self-calibration; a known camera (camera_file) has its own");
  }
  if (max_image_size < 100) ThrowInvalid("max_image_size: must be >= 100");
  if (max_num_features < 100) ThrowInvalid("max_num_features: must be >= 100");
  if (sift_first_octave != -1 && sift_first_octave != 0) {
    ThrowInvalid("sift_first_octave: must be -1 (upsampled frames, COLMAP's default) or 0 (got " +
                 std::to_string(sift_first_octave) + ")");
  }
  if (!(min_registered_fraction > 0.0 && min_registered_fraction <= 1.0)) {
    ThrowInvalid("min_registered_fraction: must be in (0, 1]");
  }
  CheckThreadCount(num_threads);
}

PosesOptions WithPreset(const PosesOptions& options) {
  options.Check();
  PosesOptions effective = options;
  if (options.preset == "default") return effective;
  // "quick": each field still at its default takes the quick value (header). On the 100-frame,
  // 1152 x 864 flight of tools/bench_poses.py: features on 480-pixel frames (a sixth of the
  // pixels), detected without SIFT's 2x upsampled first octave, a quarter of the features
  // (matching a pair costs about a sixteenth), and with positions each
  // frame matched with its 8 nearest (the 3 x 3 block around it on a grid flight) instead of 7
  // sequential successors that miss the neighbouring rows.
  const PosesOptions defaults;
  if (options.max_image_size == defaults.max_image_size) effective.max_image_size = 480;
  if (options.max_num_features == defaults.max_num_features) effective.max_num_features = 512;
  if (options.sift_first_octave == defaults.sift_first_octave) effective.sift_first_octave = 0;
  if (options.sequential_overlap == defaults.sequential_overlap) effective.sequential_overlap = 3;
  if (options.spatial_neighbors == defaults.spatial_neighbors) effective.spatial_neighbors = 8;
  const bool positions = !options.positions_file.empty() || options.exif_positions;
  if (options.matcher == defaults.matcher && positions) effective.matcher = "spatial";
  effective.Check();
  return effective;
}

namespace {

std::string LowerText(std::string text) {
  for (char& c : text) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return text;
}

// Which column holds what, from a header line (names case-insensitive).
struct PositionColumns {
  int name = -1, x = -1, y = -1, z = -1;  // z may be absent for lat/lon (height 0)
  bool degrees = false;                   // lat/lon columns: x = longitude, y = latitude
};

PositionColumns ColumnsFromHeader(const std::vector<std::string>& fields, const std::string& where) {
  PositionColumns columns;
  bool metric = false;
  for (int i = 0; i < static_cast<int>(fields.size()); ++i) {
    const std::string key = LowerText(fields[i]);
    int* slot = nullptr;
    if (key == "name" || key == "image" || key == "file" || key == "frame" || key == "filename") {
      slot = &columns.name;
    } else if (key == "x" || key == "easting" || key == "east") {
      slot = &columns.x;
      metric = true;
    } else if (key == "y" || key == "northing" || key == "north") {
      slot = &columns.y;
      metric = true;
    } else if (key == "lon" || key == "lng" || key == "long" || key == "longitude") {
      slot = &columns.x;
      columns.degrees = true;
    } else if (key == "lat" || key == "latitude") {
      slot = &columns.y;
      columns.degrees = true;
    } else if (key == "z" || key == "alt" || key == "altitude" || key == "height" ||
               key == "elevation" || key == "h") {
      slot = &columns.z;
    } else {
      ThrowInvalid(where + ": column " + std::to_string(i + 1) + " \"" + fields[i] +
                   "\" is not one of name, x, y, z (or easting, northing, altitude) or lat, lon, alt");
    }
    if (*slot >= 0) ThrowInvalid(where + ": column \"" + fields[i] + "\" is given twice");
    *slot = i;
  }
  if (metric && columns.degrees) {
    ThrowInvalid(where + ": the header mixes metric columns (x, y) with degrees (lat, lon)");
  }
  if (columns.name < 0 || columns.x < 0 || columns.y < 0 || (!columns.degrees && columns.z < 0)) {
    ThrowInvalid(where + ": the header needs name, x, y, z (metres) or name, lat, lon[, alt] "
                         "(degrees)");
  }
  return columns;
}

}  // namespace

PositionsFile ReadPositionsFile(const std::string& path, const std::string& crs) {
  CheckRegularFile(path, "positions file");
  std::vector<NamedPosition> positions;
  std::set<std::string> seen;
  std::optional<PositionColumns> columns;
  std::vector<int> lines;  // the line of each position
  bool header = false;
  for (const CsvRecord& record : ParseCsv(ReadTextFile(path), path)) {
    const int number = record.line;
    const std::string where = path + ": line " + std::to_string(number);
    const std::vector<std::string>& fields = record.fields;
    if (!columns) {
      // The first line: a header when its coordinate fields are not numbers.
      bool numbers = fields.size() >= 2;
      for (size_t k = 1; k < fields.size() && numbers; ++k) {
        char* end = nullptr;
        std::strtod(fields[k].c_str(), &end);
        numbers = !fields[k].empty() && end == fields[k].c_str() + fields[k].size();
      }
      if (!numbers) {
        columns = ColumnsFromHeader(fields, where);
        header = true;
        continue;
      }
      columns = PositionColumns{0, 1, 2, 3, false};  // no header: name, x, y, z
    }
    const int needed =
        1 + std::max({columns->name, columns->x, columns->y, columns->z});
    if (static_cast<int>(fields.size()) != needed &&
        !(header && static_cast<int>(fields.size()) >= needed)) {
      ThrowInvalid(where + ": expected " + std::to_string(needed) +
                   " comma-separated fields, got " + std::to_string(fields.size()));
    }
    NamedPosition p;
    p.name = fields[columns->name];
    const int indices[3] = {columns->x, columns->y, columns->z};
    const char* axis_names[3] = {columns->degrees ? "lon" : "x", columns->degrees ? "lat" : "y",
                                 columns->degrees ? "alt" : "z"};
    for (int k = 0; k < 3; ++k) {
      if (indices[k] < 0) continue;  // no altitude column: 0
      const std::string& value_text = fields[indices[k]];
      char* end = nullptr;
      const double value = std::strtod(value_text.c_str(), &end);
      if (value_text.empty() || end != value_text.c_str() + value_text.size()) {
        ThrowInvalid(where + ": " + axis_names[k] + ": \"" + value_text + "\" is not a number");
      }
      if (!std::isfinite(value)) {
        ThrowInvalid(where + ": " + axis_names[k] + ": " + value_text + " is not finite");
      }
      p.position[k] = value;
    }
    if (p.name.empty()) ThrowInvalid(where + ": name: is empty");
    if (!seen.insert(p.name).second) ThrowInvalid(where + ": name: \"" + p.name + "\" is repeated");
    positions.push_back(p);
    lines.push_back(number);
  }
  if (positions.empty()) ThrowInvalid(path + ": no positions (expected lines name, x, y, z)");

  PositionsFile result;
  result.positions = positions;
  const bool geographic = !crs.empty() && IsGeographicCrs(crs, path + ": positions_crs");
  if (columns->degrees && !crs.empty() && !geographic) {
    ThrowInvalid(path + ": the header names lat, lon columns (degrees) but positions_crs " + crs +
                 " is not geographic (degrees): name the columns x, y, z or give a geographic "
                 "CRS (e.g. EPSG:4326)");
  }
  const bool degrees = columns->degrees || geographic;
  const auto where_line = [&](size_t i) {
    return path + ": line " + std::to_string(lines[i]);
  };
  if (degrees) {
    // Degrees in the file's column order (lon, lat) are projected through PROJ to UTM: first
    // each value is checked to be an angle in range, naming its line.
    const char* longitude_name = columns->degrees ? "lon" : "x";
    const char* latitude_name = columns->degrees ? "lat" : "y";
    const std::string as = crs.empty() ? std::string("degrees (lat, lon columns)")
                                       : "degrees, as positions_crs " + crs + " is geographic";
    for (size_t i = 0; i < positions.size(); ++i) {
      const Vec3d& p = positions[i].position;
      if (!(std::abs(p.x) <= 180.0)) {
        ThrowInvalid(where_line(i) + ": " + longitude_name + ": " + FormatNumber(p.x) +
                     " is not a longitude in [-180, 180] " + as);
      }
      if (!(std::abs(p.y) <= 90.0)) {
        ThrowInvalid(where_line(i) + ": " + latitude_name + ": " + FormatNumber(p.y) +
                     " is not a latitude in [-90, 90] " + as);
      }
    }
    std::vector<Vec3d> points;
    for (const NamedPosition& p : positions) points.push_back(p.position);
    const MetricPoints metric = MetricFromCrs(points, crs.empty() ? "EPSG:4326" : crs, path);
    for (size_t i = 0; i < positions.size(); ++i) result.positions[i].position = metric.points[i];
    result.world_frame = metric.frame;
    result.crs = metric.crs;
    return result;
  }
  // Metres. Refuse what are evidently degrees read as metres (a whole flight inside a square of
  // 0.1 x 0.1 "metres" with longitude- and latitude-like values), in a stated metric CRS too.
  double min_x = positions[0].position.x, max_x = min_x;
  double min_y = positions[0].position.y, max_y = min_y;
  for (const NamedPosition& p : positions) {
    min_x = std::min(min_x, p.position.x);
    max_x = std::max(max_x, p.position.x);
    min_y = std::min(min_y, p.position.y);
    max_y = std::max(max_y, p.position.y);
  }
  const bool like_degrees = positions.size() >= 2 && max_x - min_x < 0.1 && max_y - min_y < 0.1 &&
                            (max_x - min_x > 0.0 || max_y - min_y > 0.0) &&
                            std::abs(min_x) <= 180.0 && std::abs(min_y) <= 180.0 &&
                            std::abs(max_x) <= 180.0 && std::abs(max_y) <= 180.0;
  if (like_degrees) {
    ThrowInvalid(where_line(0) + ": x, y look like degrees (all " +
                 std::to_string(positions.size()) + " positions within 0.1 of (" +
                 FormatNumber(min_x) + ", " + FormatNumber(min_y) + "))" +
                 (crs.empty() ? std::string()
                              : " but positions_crs " + crs + " is in metres") +
                 ": name the columns lat, lon, alt in a header line, or give a geographic CRS "
                 "(positions_crs, e.g. EPSG:4326), or give metres");
  }
  if (!crs.empty()) {
    std::vector<Vec3d> points;
    for (const NamedPosition& p : positions) points.push_back(p.position);
    const MetricPoints metric = MetricFromCrs(points, crs, path);  // checks it is metric
    result.world_frame = metric.frame;
    result.crs = metric.crs;
    return result;
  }
  result.world_frame = "the frame of " + path;
  return result;
}

std::vector<NamedPosition> MatchPositionsToFrames(const std::vector<NamedPosition>& positions,
                                                  const std::vector<std::string>& frames,
                                                  const std::string& where,
                                                  std::vector<std::string>* warnings) {
  std::map<std::string, std::string> by_file_name;  // file name -> frame ("" when ambiguous)
  std::set<std::string> exact(frames.begin(), frames.end());
  for (const std::string& frame : frames) {
    const std::string file = fs::path(frame).filename().string();
    auto [it, inserted] = by_file_name.emplace(file, frame);
    if (!inserted) it->second.clear();
  }
  std::vector<NamedPosition> matched;
  std::vector<std::string> unknown;
  std::set<std::string> used;
  for (const NamedPosition& p : positions) {
    std::string frame;
    if (exact.count(p.name) != 0) {
      frame = p.name;
    } else if (auto it = by_file_name.find(fs::path(p.name).filename().string());
               it != by_file_name.end() && !it->second.empty()) {
      frame = it->second;
    }
    if (frame.empty()) {
      unknown.push_back(p.name);
      continue;
    }
    if (!used.insert(frame).second) ThrowInvalid(where + ": two positions name frame " + frame);
    matched.push_back({frame, p.position});
  }
  if (!unknown.empty() && warnings != nullptr) {
    warnings->push_back(where + ": " + std::to_string(unknown.size()) +
                        " position(s) name no frame: " + ListSome(unknown));
  }
  if (matched.size() < 3) {
    ThrowInvalid(where + ": only " + std::to_string(matched.size()) +
                 " positions name a frame; geo-referencing needs at least 3");
  }
  return matched;
}

std::vector<NamedPosition> PositionsFromExif(const std::string& frames_dir,
                                             const std::vector<std::string>& frames,
                                             std::vector<std::string>* skipped,
                                             std::string* zone_label, std::string* crs) {
  std::vector<NamedPosition> positions;
  int zone = 0;
  bool north = true;
  for (const std::string& name : frames) {
    const std::string path = (fs::path(frames_dir) / name).string();
    const std::optional<GpsTag> tag = ReadGpsTag(path);
    if (!tag || !std::isfinite(tag->altitude_m)) {
      skipped->push_back(name);
      continue;
    }
    UtmCoordinate utm = UtmFromWgs84(tag->latitude_deg, tag->longitude_deg, zone,
                                     path + ": GPS");
    if (zone == 0) {
      zone = utm.zone;
      north = utm.north;
      *zone_label = "UTM " + std::to_string(utm.zone) + (utm.north ? "N" : "S") + " (WGS84)";
      if (crs != nullptr) *crs = UtmEpsg(utm.zone, utm.north);
    }
    // One hemisphere's false northing for the whole flight (one that crosses the equator).
    if (utm.north != north) utm.northing += north ? -10000000.0 : 10000000.0;
    positions.push_back({name, Vec3d(utm.easting, utm.northing, tag->altitude_m)});
  }
  return positions;
}

GeoreferenceResult Georeference(LightField* light_field, const std::vector<std::string>& names,
                                const std::vector<NamedPosition>& positions,
                                const std::string& where) {
  if (names.size() != light_field->views.size()) {
    ThrowInvalid(where + ": one name per view is needed");
  }
  std::map<std::string, Vec3d> by_name;
  for (const NamedPosition& p : positions) by_name[p.name] = p.position;
  std::vector<Vec3d> model_centres, known;
  for (size_t i = 0; i < names.size(); ++i) {
    auto it = by_name.find(names[i]);
    if (it == by_name.end()) it = by_name.find(fs::path(names[i]).filename().string());
    if (it == by_name.end()) continue;
    model_centres.push_back(light_field->views[i].cam_from_world.Center() +
                            light_field->origin);
    known.push_back(it->second);
  }
  if (known.size() < 3) {
    ThrowInvalid(where + ": only " + std::to_string(known.size()) +
                 " registered frames have a position; geo-referencing needs at least 3");
  }
  // The origin: the positions' mean, in double; the similarity maps to positions relative to it
  // (keeps UTM-sized coordinates out of the poses).
  Vec3d origin(0.0);
  for (const Vec3d& p : known) origin += p;
  origin /= static_cast<double>(known.size());
  std::vector<Vec3d> local(known.size());
  for (size_t i = 0; i < known.size(); ++i) local[i] = known[i] - origin;
  GeoreferenceResult result;
  const PointSetShape shape = ShapeOf(local);
  result.width = shape.width;
  SimilarityResult fit;
  // Both sets nearly on a line (the model's centres too; if only one is, the data disagree and
  // the plain fit's own checks speak).
  if (shape.width < kNearlyCollinearWidth && shape.rms_extent[0] > 0.0 &&
      ShapeOf(model_centres).width < kNearlyCollinearWidth) {
    // The cameras' mean viewing direction in the model frame (camera z axis in world).
    Vec3d viewing(0.0);
    for (size_t i = 0; i < names.size(); ++i) {
      viewing += Row(light_field->views[i].cam_from_world.rotation, 2);
    }
    fit = EstimateSimilarityOnLine(model_centres, local, viewing, Vec3d(0.0, 0.0, -1.0), where);
    result.roll_from_down_prior = true;
    char text[256];
    std::snprintf(text, sizeof(text),
                  "the positions lie nearly on a line (%.2f m across over %.1f m along, RMS); "
                  "they do not fix the roll about it, so the cameras' mean viewing direction was "
                  "taken as straight down",
                  shape.rms_extent[1], shape.rms_extent[0]);
    result.warning = Where(where, text);
  } else {
    fit = EstimateSimilarity(model_centres, local, where);
  }
  result.local_from_model = fit.dst_from_src;
  result.rms_m = fit.rms_residual;
  result.frames = static_cast<int>(known.size());
  // Views in the model frame (origin added back) -> local frame about the new origin.
  Sim3d shifted = fit.dst_from_src;
  shifted.translation += shifted.scale * (shifted.rotation * light_field->origin);
  for (View& view : light_field->views) {
    view.cam_from_world = TransformCamFromWorld(shifted, view.cam_from_world);
  }
  light_field->origin = origin;
  return result;
}

namespace {

// What every COLMAP stage runs with.
struct ColmapRun {
  std::string colmap;      // the executable
  std::string frames_dir;  // COLMAP's --image_path
  fs::path workspace;      // its workspace folder
  fs::path database;       // workspace/database.db
  fs::path list;           // workspace/frames.txt: the frames to use, one a line
  std::string threads;     // num_threads as COLMAP takes it
  int total = 0;           // frames
  ProgressSink* progress = nullptr;
};

struct FrameSize {
  int width = 0, height = 0;
};

// The frames of frames_dir into result->frames: the readable ones (the others skipped with a
// warning), all of one size and in a type COLMAP reads (else an error naming them).
FrameSize ListFrames(const std::string& frames_dir, PosesResult* result) {
  std::vector<std::string> unreadable;
  FrameSize size;
  std::string first_frame;
  std::vector<std::string> other_size, float_frames;
  for (const std::string& name : ListFrameFiles(frames_dir)) {
    ImageFileInfo info;
    try {
      info = ReadImageInfo((fs::path(frames_dir) / name).string());
    } catch (const std::invalid_argument&) {
      unreadable.push_back(name);
      continue;
    }
    if (first_frame.empty()) {
      first_frame = name;
      size.width = info.width;
      size.height = info.height;
    } else if (info.width != size.width || info.height != size.height) {
      other_size.push_back(name + " (" + std::to_string(info.width) + "x" +
                           std::to_string(info.height) + ")");
    }
    if (info.type != PixelType::kU8 && info.type != PixelType::kU16) float_frames.push_back(name);
    result->frames.push_back(name);
  }
  if (!unreadable.empty()) {
    result->warnings.push_back("skipped " + std::to_string(unreadable.size()) +
                               " unreadable frame(s): " + ListSome(unreadable));
  }
  if (result->frames.empty()) {
    ThrowInvalid(frames_dir + ": no readable frames (.png .jpg .jpeg .tif .tiff .exr)");
  }
  if (!other_size.empty()) {
    ThrowInvalid(frames_dir + ": frames differ in size (one camera for all frames): " +
                 first_frame + " is " + std::to_string(size.width) + "x" +
                 std::to_string(size.height) + " but " + ListSome(other_size));
  }
  if (!float_frames.empty()) {
    // COLMAP 3.8 cannot read them (it logs "Failed to read image file format" and skips them).
    ThrowInvalid(frames_dir + ": COLMAP reads 8- and 16-bit frames only; convert these to "
                              "16-bit first: " + ListSome(float_frames));
  }
  return size;
}

// The positions of result->frames: those of the positions file (read before the frames were
// listed, for its cheap errors) matched to the frames, or the frames' EXIF GPS tags.
std::vector<NamedPosition> FramePositions(const std::string& frames_dir,
                                          const PosesOptions& options, const PositionsFile& file,
                                          PosesResult* result) {
  std::vector<NamedPosition> positions;
  if (!options.positions_file.empty()) {
    result->world_frame = file.world_frame;
    result->crs = file.crs;
    positions = MatchPositionsToFrames(file.positions, result->frames, options.positions_file,
                                       &result->warnings);
  }
  if (options.exif_positions) {
    std::vector<std::string> untagged;
    positions = PositionsFromExif(frames_dir, result->frames, &untagged, &result->world_frame,
                                  &result->crs);
    if (!untagged.empty()) {
      result->warnings.push_back(std::to_string(untagged.size()) +
                                 " frame(s) without an EXIF GPS latitude, longitude and altitude: " +
                                 ListSome(untagged));
    }
    if (positions.size() < 3) {
      ThrowInvalid(frames_dir + ": only " + std::to_string(positions.size()) +
                   " frames carry EXIF GPS positions; geo-referencing needs at least 3");
    }
  }
  return positions;
}

// 1. SIFT features of every listed frame, with the known camera (fixed) or self-calibration's
// model (started from fov_deg when given).
void ExtractFeatures(const ColmapRun& run, const PosesOptions& options,
                     const std::pair<std::string, std::string>* known_colmap_camera,
                     const FrameSize& size, PosesResult* result) {
  const std::string& frames_dir = run.frames_dir;
  const fs::path& database = run.database;
  const std::string& threads = run.threads;
  const int total = run.total;
  ProgressSink* progress = run.progress;
  const Timer timer;
  ProgressStart(progress, "features", total);
  std::vector<std::string> extract = {
      run.colmap, "feature_extractor", "--database_path", database.string(), "--image_path",
      frames_dir, "--image_list_path", run.list.string(), "--ImageReader.single_camera", "1",
      "--SiftExtraction.use_gpu", "0", "--SiftExtraction.num_threads", threads,
      "--SiftExtraction.max_image_size", std::to_string(options.max_image_size),
      "--SiftExtraction.max_num_features", std::to_string(options.max_num_features),
      "--SiftExtraction.first_octave", std::to_string(options.sift_first_octave)};
  if (known_colmap_camera != nullptr) {
    const auto& [model, params] = *known_colmap_camera;
    extract.insert(extract.end(), {"--ImageReader.camera_model", model,
                                   "--ImageReader.camera_params", params});
  } else {
    extract.insert(extract.end(), {"--ImageReader.camera_model", options.camera_model});
    if (options.fov_deg > 0.0) {
      extract.insert(extract.end(), {"--ImageReader.camera_params",
                                     InitialParams(options.camera_model, size.width, size.height,
                                                   options.fov_deg)});
    }
  }
  RunColmap("features", extract, run.workspace / "colmap_features.log",
            [&](const std::string& line) {
              if (BracketIndex(line, "Processed file") > 0) ProgressAdvance(progress, 1);
            },
            progress);
  result->stages.push_back({"features", timer.Seconds()});
}

// 2. Matching (options.matcher), with the positions written into the database as priors.
void MatchFeatures(const ColmapRun& run, const PosesOptions& options,
                   const std::vector<NamedPosition>& positions, PosesResult* result) {
  const fs::path& database = run.database;
  const std::string& threads = run.threads;
  const int total = run.total;
  ProgressSink* progress = run.progress;
  const Timer timer;
  if (!positions.empty()) {
    const int with_prior = WritePriors(database, positions, Mean(positions));
    if (options.matcher == "spatial" && with_prior < total) {
      result->warnings.push_back(std::to_string(total - with_prior) + " of " +
                                 std::to_string(total) + " frames have no position prior; spatial "
                                 "matching cannot match (or register) them");
    }
  }
  std::vector<std::string> match = {run.colmap, options.matcher + "_matcher", "--database_path",
                                    database.string(), "--SiftMatching.use_gpu", "0",
                                    "--SiftMatching.num_threads", threads};
  int64_t match_total = total;
  std::string marker = "Matching image";
  if (options.matcher == "sequential") {
    match.insert(match.end(), {"--SequentialMatching.overlap",
                               std::to_string(options.sequential_overlap)});
  } else if (options.matcher == "spatial") {
    match.insert(match.end(), {"--SpatialMatching.is_gps", "0", "--SpatialMatching.max_num_neighbors",
                               std::to_string(options.spatial_neighbors)});
  } else {
    // Exhaustive matching goes in blocks of 50 frames: "Matching block [i/B, j/B]".
    const int64_t blocks = (total + 49) / 50;
    match_total = blocks * blocks;
    marker = "Matching block";
  }
  ProgressStart(progress, "matching", match_total);
  RunColmap("matching", match, run.workspace / "colmap_matching.log",
            [&](const std::string& line) {
              if (BracketIndex(line, marker) > 0) ProgressAdvance(progress, 1);
            },
            progress);
  result->stages.push_back({"matching", timer.Seconds()});
}

// 3. Incremental mapping into workspace/sparse/N (the known camera's intrinsics fixed).
// Returns the sparse folder.
fs::path MapFrames(const ColmapRun& run, bool known, PosesResult* result) {
  const std::string& frames_dir = run.frames_dir;
  const fs::path& database = run.database;
  const std::string& threads = run.threads;
  const int total = run.total;
  ProgressSink* progress = run.progress;
  const Timer timer;
  const fs::path sparse = run.workspace / "sparse";
  fs::create_directories(sparse);
  std::vector<std::string> map = {run.colmap, "mapper", "--database_path", database.string(),
                                  "--image_path", frames_dir, "--output_path", sparse.string(),
                                  "--Mapper.num_threads", threads};
  if (known) {
    map.insert(map.end(), {"--Mapper.ba_refine_focal_length", "0",
                           "--Mapper.ba_refine_principal_point", "0",
                           "--Mapper.ba_refine_extra_params", "0"});
  }
  ProgressStart(progress, "mapping", total);
  std::set<std::string> mapped;  // COLMAP may retry an image: count each once
  RunColmap("mapping", map, run.workspace / "colmap_mapping.log",
            [&](const std::string& line) {
              if (line.rfind("Registering image #", 0) != 0) return;
              const std::string id = line.substr(19, line.find(' ', 19) - 19);
              if (mapped.insert(id).second) ProgressAdvance(progress, 1);
            },
            progress);
  result->stages.push_back({"mapping", timer.Seconds()});
  return sparse;
}

// The largest of the models COLMAP built in `sparse` (result->models counts them; more than one
// is warned about); none is an error.
ColmapModel ReadLargestModel(const fs::path& sparse, const std::string& frames_dir, int total,
                             PosesResult* result) {
  std::vector<fs::path> models;
  for (const auto& entry : fs::directory_iterator(sparse)) {
    if (entry.is_directory()) models.push_back(entry.path());
  }
  std::sort(models.begin(), models.end());
  result->models = static_cast<int>(models.size());
  if (models.empty()) {
    ThrowInvalid(frames_dir + ": COLMAP registered no frames (no model was built from " +
                 std::to_string(total) + " frames; the frames may not overlap or lack texture)");
  }
  ColmapModel model;
  for (const fs::path& folder : models) {
    ColmapModel candidate = ReadColmapModel(folder.string());
    if (candidate.images.size() > model.images.size()) model = std::move(candidate);
  }
  if (models.size() > 1) {
    result->warnings.push_back("COLMAP built " + std::to_string(models.size()) +
                               " separate models; the largest (" +
                               std::to_string(model.images.size()) +
                               " frames) is used, the others' frames count as unregistered");
  }
  return model;
}

}  // namespace

PosesResult EstimatePoses(const std::string& frames_dir, const PosesOptions& given_options,
                          ProgressSink* progress) {
  const PosesOptions options = WithPreset(given_options);
  if (frames_dir.empty() || !fs::is_directory(frames_dir)) {
    ThrowInvalid(frames_dir + ": not a folder of frames");
  }
  if (!ProgramExists(options.colmap)) {
    ThrowInvalid("colmap: \"" + options.colmap +
                 "\" not found; install COLMAP (Debian: apt-get install colmap) or give its path");
  }
  PosesResult result;
  // Known inputs first (cheap errors before COLMAP runs).
  LensCamera known_camera;
  const bool known = !options.camera_file.empty();
  if (known) known_camera = ReadCameraFile(options.camera_file);
  PositionsFile positions_file;
  if (!options.positions_file.empty()) {
    positions_file = ReadPositionsFile(options.positions_file, options.positions_crs);
  }

  // Frames: readable ones, one size; then their positions (from EXIF too).
  const FrameSize size = ListFrames(frames_dir, &result);
  // COLMAP decodes a whole frame per extraction thread (a bitmap and its grey copy, about 4 bytes
  // a pixel, before it downscales to max_image_size); its child process inherits this one's
  // limits. Refused here, naming the frames, rather than COLMAP failing on an allocation.
  CheckMemoryBudget(SaturatingProduct({static_cast<uint64_t>(ResolveThreadCount(options.num_threads)),
                                       static_cast<uint64_t>(size.width),
                                       static_cast<uint64_t>(size.height), 4}),
                    frames_dir + ": frames of " + std::to_string(size.width) + "x" +
                        std::to_string(size.height),
                    "COLMAP decodes one frame per extraction thread, about 4 bytes a pixel; "
                    "fewer threads need less");
  if (known && (known_camera.width != size.width || known_camera.height != size.height)) {
    ThrowInvalid(options.camera_file + ": the camera is " + std::to_string(known_camera.width) +
                 "x" + std::to_string(known_camera.height) + " but the frames are " +
                 std::to_string(size.width) + "x" + std::to_string(size.height));
  }
  if (result.frames.size() < 2) ThrowInvalid(frames_dir + ": one frame cannot give poses (need >= 2)");
  std::pair<std::string, std::string> known_colmap_camera;
  if (known) known_colmap_camera = ColmapCameraFor(known_camera, options.camera_file);
  const std::vector<NamedPosition> positions =
      FramePositions(frames_dir, options, positions_file, &result);

  Workspace workspace(options.workspace);
  if (!workspace.temporary()) result.workspace = workspace.path().string();
  ColmapRun run;
  run.colmap = options.colmap;
  run.frames_dir = frames_dir;
  run.workspace = workspace.path();
  run.database = workspace.path() / "database.db";
  run.list = workspace.path() / "frames.txt";
  {
    std::ofstream out(run.list);
    for (const std::string& name : result.frames) out << name << "\n";
    if (!out) ThrowInvalid(run.list.string() + ": cannot write the frame list");
  }
  run.threads = std::to_string(options.num_threads);
  run.total = static_cast<int>(result.frames.size());
  run.progress = progress;

  // 1. Features, 2. matching, 3. mapping.
  ExtractFeatures(run, options, known ? &known_colmap_camera : nullptr, size, &result);
  MatchFeatures(run, options, positions, &result);
  const fs::path sparse = MapFrames(run, known, &result);

  // 4. Import the largest model, geo-referenced, and check it.
  const Timer timer;
  ProgressStart(progress, "import", 1);
  ImportInto(ReadLargestModel(sparse, frames_dir, run.total, &result), frames_dir, positions,
             options.exif_positions ? frames_dir + " (EXIF GPS)" : options.positions_file,
             options.min_registered_fraction, &result);
  if (!known) CheckSelfCalibration(options, &result);
  CheckSceneScale(options, /*warn_unchecked=*/!known, &result);
  ProgressAdvance(progress, 1);
  result.stages.push_back({"import", timer.Seconds()});
  return result;
}

PosesResult ImportColmapPoses(const std::string& model_dir, const std::string& frames_dir,
                              const PosesOptions& options, ProgressSink* progress) {
  options.Check();
  const Timer timer;
  ColmapModel model = ReadColmapModel(model_dir, progress);
  PosesResult result;
  result.models = 1;
  result.frames = ListFrameFiles(frames_dir);  // a registered frame missing here is an error
  std::vector<NamedPosition> positions;
  if (!options.positions_file.empty()) {
    PositionsFile file = ReadPositionsFile(options.positions_file, options.positions_crs);
    result.world_frame = file.world_frame;
    result.crs = file.crs;
    positions = MatchPositionsToFrames(file.positions, result.frames, options.positions_file,
                                       &result.warnings);
  }
  if (options.exif_positions) {
    std::vector<std::string> untagged;
    positions = PositionsFromExif(frames_dir, result.frames, &untagged, &result.world_frame,
                                  &result.crs);
    if (positions.size() < 3) {
      ThrowInvalid(frames_dir + ": only " + std::to_string(positions.size()) +
                   " frames carry EXIF GPS positions; geo-referencing needs at least 3");
    }
  }
  ImportInto(std::move(model), frames_dir, positions,
             options.exif_positions ? frames_dir + " (EXIF GPS)" : options.positions_file,
             options.min_registered_fraction, &result, progress);
  CheckSceneScale(options, /*warn_unchecked=*/false, &result);
  result.stages.push_back({"import", timer.Seconds()});
  return result;
}

}  // namespace aos
