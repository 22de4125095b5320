#pragma once
// Poses from a folder of frames: runs Debian's COLMAP headless on the CPU (feature extraction,
// matching, incremental mapping), imports the largest model it builds (colmap_model.h), and
// optionally geo-references it with known camera positions (similarity.h).
//
// Contract
// - Inputs are never modified: COLMAP only reads the frames. Its workspace (database.db,
//   sparse/N/, colmap_<stage>.log) is options.workspace, which must not exist or be empty and is
//   kept, or a temporary folder that is removed afterwards.
// - COLMAP runs with --SiftExtraction.use_gpu 0 and --SiftMatching.use_gpu 0 (it aborts without a
//   display otherwise), one camera shared by all frames, and:
//   * options.preset "quick" first sets smaller frames, fewer features and fewer pairs
//     (WithPreset; docs/poses.md gives its time and accuracy against "default");
//   * matcher "sequential" (frames in name order, like a flight's video order; each matched with
//     its sequential_overlap successors, and, COLMAP's default quadratic overlap, with the
//     successors 2, 4, 8, ... apart up to that count), "spatial" (each frame with its
//     spatial_neighbors nearest by position: needs positions, which are written into the
//     database as priors), or "exhaustive" (all pairs; small sets);
//   * camera: a known camera (options.camera_file, an aos-camera file from `aos-render calibrate`;
//     its intrinsics are fixed during mapping) or self-calibration of options.camera_model,
//     started from fov_deg when given. Self-calibration is ill-posed for nadir views of nearly
//     flat ground (focal length and altitude trade off; docs/poses.md): give a known camera.
// - Progress: one stage per COLMAP step ("features", "matching", "mapping"), advanced per frame
//   from COLMAP's own log lines, then "import". Cancelling stops COLMAP and throws aos::Cancelled.
// - Frames: every image file (.png .jpg .jpeg .tif .tiff .exr, any case) under frames_dir. Frames
//   whose header cannot be read are skipped with a warning naming them; frames of another size
//   than the first are an error naming them (one camera for all frames).
// - Registration: frames COLMAP leaves out are listed (PosesResult::unregistered) and warned
//   about; fewer than min_registered_fraction of the frames registered is an error.
// - Geo-referencing: with positions (a CSV file of `name,x,y,z` lines, metres in any metric frame,
//   e.g. UTM easting, northing, altitude, or `name,lat,lon,alt` degrees projected with PROJ; see
//   ReadPositionsFile; a header line and '#' comments allowed; or with
//   exif_positions, the frames' EXIF GPS tags projected to UTM in the zone of the first tagged
//   frame, altitude as z; frames without latitude, longitude and altitude are skipped with a
//   warning), the model is mapped by the least-squares similarity from its camera centres to the
//   given positions of the registered frames (at least 3, not collinear). That fixes scale,
//   orientation (up axis) and origin; LightField::origin holds the positions' mean in double
//   precision and the poses are relative to it. Without positions the light field keeps COLMAP's
//   frame: arbitrary scale, orientation and origin.
// - Plausibility: a self-calibrated focal length is checked against the fov_deg prior
//   (max_focal_deviation) and a geo-referenced model's median depth against flight_height_m
//   (max_scale_deviation); beyond either the result is refused unless allow_implausible, which
//   keeps it with an "IMPLAUSIBLE" warning and PosesResult::implausible set.
// - Pose quality: COLMAP's mean reprojection error (pixels), and e in metres at the median depth
//   of the model's points (e_px times depth over focal length; metres only when geo-referenced),
//   which the effective sample size p' = p + 2e of metrics/resolution.h takes.
// - Frames COLMAP cannot read (float TIFF or EXR) are refused before it runs; so are position
//   files naming fewer than 3 frames and a known omnidir camera (COLMAP has no such model).
//
// Throws std::invalid_argument for bad options (naming the field), a missing or empty frames
// folder, COLMAP missing or failing (with the end of its log), or too few frames registered.
#include <cmath>
#include <string>
#include <vector>

#include "aos/geometry/similarity.h"
#include "aos/lightfield/lightfield.h"
#include "aos/sfm/colmap_model.h"
#include "aos/util/progress.h"
#include "aos/util/option_fields.h"
#include "aos/util/parallel.h"

namespace aos {

struct PosesOptions {
  std::string colmap = "colmap";        // the COLMAP executable (on PATH or a path)
  std::string workspace;                // kept COLMAP workspace; empty = temporary, removed
  std::string matcher = "sequential";   // "sequential", "spatial" or "exhaustive"
  int sequential_overlap = 5;           // sequential: successors each frame is matched with, >= 1
  int spatial_neighbors = 50;           // spatial: nearest frames each frame is matched with, >= 1
  // Known camera: an aos-camera file (pinhole, radtan or fisheye; omnidir frames must be
  // rectified first). Empty = self-calibration of camera_model.
  std::string camera_file;
  // COLMAP camera model for self-calibration: SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL,
  // OPENCV, OPENCV_FISHEYE, SIMPLE_RADIAL_FISHEYE or RADIAL_FISHEYE.
  std::string camera_model = "SIMPLE_RADIAL";
  double fov_deg = 0.0;                 // self-calibration's starting horizontal FOV; 0 = COLMAP's
  std::string positions_file;           // CSV of positions (see ReadPositionsFile); empty = none
  std::string positions_crs;            // CRS of positions_file ("EPSG:4326", ...); "" = header
  bool exif_positions = false;          // positions from the frames' EXIF GPS (UTM); not both
  int max_image_size = 1600;            // SIFT on frames downscaled to this longest side, >= 100
  int max_num_features = 2048;          // per frame, >= 100 (matching cost grows with its square)
  // SIFT's first octave: -1 (COLMAP's default) detects on the frame upsampled 2x (finer
  // features, about 4x the extraction time), 0 on the frame itself; -1 or 0.
  int sift_first_octave = -1;
  double min_registered_fraction = 0.5; // (0, 1]
  int num_threads = -1;                 // COLMAP's threads; -1 = all cores
  // Self-calibration is checked against the fov_deg prior: a focal length further than this
  // fraction from the prior's (1 + d or 1 / (1 + d) times it) is implausible, > 0. Nadir views
  // of nearly flat ground leave the focal length ill-determined (a 60-degree, 640-pixel flight
  // came out at 768 px instead of 554 with a healthy-looking 0.045 px reprojection error).
  double max_focal_deviation = 0.1;
  // The cameras' height above the ground as flown, metres, e.g. 35 for a flight 35 m above the
  // ground; 0 = not checked, >= 0. Checks the scene scale of a geo-referenced model (so it needs
  // positions): the views' median depth (for nadir views, their height above the ground) must
  // lie within max_scale_deviation of it. A wrong focal length or wrong positions scale the
  // depths (a 20 m flight self-calibrated to 768 px instead of 554 read 27.7 m).
  double flight_height_m = 0.0;
  // The median depth may be 1 + d or 1 / (1 + d) times flight_height_m at most, > 0.
  double max_scale_deviation = 0.15;
  // Accept implausible intrinsics or scene scale with a warning instead of refusing them.
  bool allow_implausible = false;
  // Speed against accuracy of the COLMAP stages: "default" (the fields as they are) or "quick":
  // each of these fields still at its default takes the quick value (a field set to another
  // value wins): max_image_size 480, max_num_features 512, sift_first_octave 0, sequential_overlap 3,
  // spatial_neighbors 8, and matcher "spatial" when positions are given (positions_file or
  // exif_positions). docs/poses.md measures both presets on the 100-frame flight of
  // tools/bench_poses.py.
  std::string preset = "default";
  void Check() const;
  // The field table (util/option_fields.h): every field once, in declaration order.
  template <class Visit>
  static void Fields(Visit&& field) {
    using O = PosesOptions;
    field(OptionField("colmap", &O::colmap, "", Range::Any(),
                      "The COLMAP executable (on PATH or a path)."));
    field(OptionField("workspace", &O::workspace, "", Range::Any(),
                      "Keep COLMAP's workspace in this new folder; '' = a temporary one, "
                      "removed."));
    field(OptionField("matcher", &O::matcher, "", Range::OneOf("sequential|spatial|exhaustive"),
                      "'sequential', 'spatial' or 'exhaustive'."));
    field(OptionField("sequential_overlap", &O::sequential_overlap, "", Range::Any(),
                      "Sequential matching: successors each frame is matched with."));
    field(OptionField("spatial_neighbors", &O::spatial_neighbors, "", Range::Any(),
                      "Spatial matching: nearest frames (by position) each frame is matched "
                      "with."));
    field(OptionField("camera_file", &O::camera_file, "", Range::Any(),
                      "Known camera (aos-camera file); '' = self-calibration of camera_model."));
    field(OptionField("camera_model", &O::camera_model, "",
                      Range::OneOf("SIMPLE_PINHOLE|PINHOLE|SIMPLE_RADIAL|RADIAL|OPENCV|"
                                   "OPENCV_FISHEYE|SIMPLE_RADIAL_FISHEYE|RADIAL_FISHEYE"),
                      "COLMAP model to self-calibrate."));
    field(OptionField("fov_deg", &O::fov_deg, "deg", Range::Any(),
                      "Self-calibration's starting horizontal FOV, degrees; 0 = COLMAP's "
                      "guess.")
              .Flag("frames-fov-deg"));
    field(OptionField("positions_file", &O::positions_file, "", Range::Any(),
                      "CSV of name,x,y,z positions (metres): geo-reference and spatial "
                      "priors."));
    field(OptionField("positions_crs", &O::positions_crs, "", Range::Any(),
                      "CRS of positions_file as PROJ names it (e.g. EPSG:4326, EPSG:25833); "
                      "empty: from the header (lat/lon columns are WGS84 degrees, x/y/z "
                      "metres in an unstated frame)."));
    field(OptionField("exif_positions", &O::exif_positions, "", Range::Any(),
                      "Positions from the frames' EXIF GPS tags (UTM) instead of a file."));
    field(OptionField("max_image_size", &O::max_image_size, "", Range::Any(),
                      "Features on frames downscaled to this longest side."));
    field(OptionField("max_num_features", &O::max_num_features, "", Range::Any(),
                      "Features per frame."));
    field(OptionField("sift_first_octave", &O::sift_first_octave, "", Range::Any(),
                      "SIFT's first octave: -1 = on the frame upsampled 2x (COLMAP's "
                      "default), 0 = on the frame itself (about 4x faster extraction)."));
    field(OptionField("min_registered_fraction", &O::min_registered_fraction, "", Range::Any(),
                      "Error below this fraction of frames registered."));
    field(OptionField("num_threads", &O::num_threads, "", kThreadCountRange,
                      "COLMAP's threads; -1 = all cores."));
    field(OptionField("max_focal_deviation", &O::max_focal_deviation, "", Range::Any(),
                      "Self-calibration: refuse a focal length further than this fraction "
                      "from the fov_deg prior's, > 0."));
    field(OptionField("flight_height_m", &O::flight_height_m, "m", Range::Any(),
                      "The cameras' height above the ground as flown, metres (e.g. 35 for a "
                      "flight 35 m above the ground): the geo-referenced median depth is "
                      "checked against it; 0 = not checked. Needs positions."));
    field(OptionField("max_scale_deviation", &O::max_scale_deviation, "", Range::Any(),
                      "Refuse a median depth further than this fraction from flight_height_m, "
                      "> 0."));
    field(OptionField("allow_implausible", &O::allow_implausible, "", Range::Any(),
                      "Keep implausible self-calibrated intrinsics or scene scale with a "
                      "warning instead of refusing."));
    field(OptionField("preset", &O::preset, "", Range::OneOf("default|quick"),
                      "'default' or 'quick': quick sets max_image_size 480, max_num_features "
                      "512, sift_first_octave 0, sequential_overlap 3, spatial_neighbors 8 "
                      "and, with positions, matcher 'spatial', each where left at its default "
                      "(docs/poses.md)."));
  }
};

// The options EstimatePoses runs with: `options` with its preset applied (see
// PosesOptions::preset); "default" returns them unchanged. Throws like Check().
PosesOptions WithPreset(const PosesOptions& options);

struct PosesResult {
  LightField light_field;                 // images not loaded; image_path = the frame files
  std::vector<std::string> frames;        // every readable frame, relative to frames_dir
  std::vector<std::string> registered;    // in view order
  std::vector<std::string> unregistered;  // frames COLMAP did not register
  std::vector<std::string> warnings;      // skipped frames, unregistered frames, other models
  // The view order: "time" (every registered frame has an EXIF capture time) or "name"
  // (natural order), as ColmapImport states it.
  std::string order = "name";
  std::string time_source;
  int models = 0;                         // models COLMAP built (the largest is used)
  size_t points = 0;
  // The model's 3-D points in the light field's local frame (after geo-referencing; the model's
  // frame without it): what the ground estimate (sfm/ground.h) is made from.
  std::vector<Vec3d> point_positions;
  size_t observations = 0;
  double mean_reprojection_error_px = 0.0;
  double median_depth = 0.0;              // of the points, along the optical axes (model units)
  double pose_error = 0.0;                // e at that depth, same units
  bool georeferenced = false;
  Sim3d local_from_model;                 // the geo-referencing similarity (identity without)
  double georeference_rms_m = 0.0;        // RMS of centre residuals after it
  int georeference_frames = 0;            // registered frames with a position
  std::string world_frame;                // "UTM 31N (WGS84)", "the frame of gps.csv", or ""
  std::string crs;                        // "EPSG:32631": the light field's crs, or "" (none)
  // Self-calibration's check: the focal length the fov_deg prior gives (0 without a prior or
  // with a known camera), the recovered one's deviation from it (recovered / prior - 1; NaN when
  // unchecked), and whether it exceeded max_focal_deviation (accepted with allow_implausible).
  double focal_prior_px = 0.0;
  double focal_deviation = std::nan("");
  // The scene-scale check: the median depth's deviation from flight_height_m (median_depth /
  // flight_height_m - 1; NaN when unchecked).
  double scale_deviation = std::nan("");
  // The focal length or the scene scale exceeded its limit (kept under allow_implausible, with a
  // warning starting "IMPLAUSIBLE").
  bool implausible = false;
  struct Stage {
    std::string name;
    double seconds = 0.0;
  };
  std::vector<Stage> stages;              // features, matching, mapping, import
  std::string workspace;                  // the kept workspace, or empty
};

PosesResult EstimatePoses(const std::string& frames_dir, const PosesOptions& options,
                          ProgressSink* progress = nullptr);

// An existing COLMAP model (a sparse/N folder, text or binary) imported as EstimatePoses' last
// stage does it: the frames in frames_dir (the images folder COLMAP was given) that the model
// lacks are unregistered, positions (options.positions_file or exif_positions) geo-reference
// it, min_registered_fraction and the scene-scale check (flight_height_m) apply; the COLMAP and
// self-calibration options are not used. `progress` is polled for cancellation (throws
// aos::Cancelled) while the model is read and its frames listed.
PosesResult ImportColmapPoses(const std::string& model_dir, const std::string& frames_dir,
                              const PosesOptions& options, ProgressSink* progress = nullptr);

// Camera positions from a CSV file (see above): name -> position. Throws std::invalid_argument
// naming the file and line for a malformed line, a non-finite value or a repeated name.
struct NamedPosition {
  std::string name;
  Vec3d position{0.0};
};
// Columns are read by the header's names (case-insensitive): name (or image, file, frame) and
// either x, y, z (or easting, northing, altitude/height) in metres, or lat, lon[, alt] in
// degrees; without a header the columns are name, x, y, z. Degrees (lat/lon columns, or a
// geographic `crs`) are projected through PROJ to the UTM zone of their centre (geodesy.h's
// FlightCentre: median latitude and longitude, also across the 180th meridian); `crs`
// ("EPSG:25833", ...; empty = not stated) names the CRS of the coordinates. Metres in an unstated
// frame that evidently are degrees (the whole flight within 0.1 x 0.1 of a longitude/latitude-
// like point) are refused, with a stated projected `crs` too. A geographic `crs` (or lat/lon
// columns) with a value outside [-180, 180] (longitude) or [-90, 90] (latitude), and lat/lon
// columns with a stated projected `crs`, are refused naming the file, line and field. Fields are
// CSV as util/csv.h reads them (RFC 4180 quotes, a UTF-8 byte-order mark skipped).
// world_frame says which frame the positions are in; crs is its EPSG code ("EPSG:326zz" after
// projecting degrees to UTM, the stated CRS's code for metres), "" for an unstated metric frame.
struct PositionsFile {
  std::vector<NamedPosition> positions;
  std::string world_frame;
  std::string crs;
};
PositionsFile ReadPositionsFile(const std::string& path, const std::string& crs = "");

// The positions renamed to the frames they name: a position's name is a frame's path relative
// to the frames folder, or (when unique) its file name. Names matching no frame are reported in
// *warnings; fewer than 3 matches, or two positions for one frame, throw naming `where`.
std::vector<NamedPosition> MatchPositionsToFrames(const std::vector<NamedPosition>& positions,
                                                  const std::vector<std::string>& frames,
                                                  const std::string& where,
                                                  std::vector<std::string>* warnings);

// Positions from the EXIF GPS tags of `frames` (relative to frames_dir), in UTM (zone of the
// first tagged frame; *zone_label gets e.g. "UTM 31N (WGS84)", *crs its EPSG code when given).
// Frames without a full fix are reported in *skipped.
std::vector<NamedPosition> PositionsFromExif(const std::string& frames_dir,
                                             const std::vector<std::string>& frames,
                                             std::vector<std::string>* skipped,
                                             std::string* zone_label, std::string* crs = nullptr);

// Maps a light field of COLMAP's frame onto the positions of its views (views[i] is frame
// names[i]; a position names a frame, or its file name): sets origin to the positions' mean and
// the poses to local = position - origin. Returns the similarity and its residuals. Throws
// std::invalid_argument when fewer than 3 views have a position or they are degenerate.
// Positions nearly on a line (a straight flight: the RMS extent across the line below
// kNearlyCollinearWidth of the extent along it, GPS noise included) do not fix the roll about the
// line: a plain similarity fit then tilts the cameras arbitrarily (43 degrees seen) with a
// small residual. There the roll comes from the cameras' own mean viewing direction, taken as
// straight down in the positions' frame (z up), and a warning says so; cameras looking along the
// line are refused.
constexpr double kNearlyCollinearWidth = 0.05;
struct GeoreferenceResult {
  Sim3d local_from_model;
  double rms_m = 0.0;
  int frames = 0;
  double width = 0.0;                  // the positions' RMS extent across / along their main axis
  bool roll_from_down_prior = false;   // nearly collinear: roll fixed by the viewing direction
  std::string warning;                 // non-empty when roll_from_down_prior
};
GeoreferenceResult Georeference(LightField* light_field, const std::vector<std::string>& names,
                                const std::vector<NamedPosition>& positions,
                                const std::string& where);

}  // namespace aos
