#pragma once
// Poses from telemetry, without structure from motion: each frame placed from its GPS latitude,
// longitude and altitude and oriented from its gimbal's yaw, pitch and roll, as flight logs and
// drones' EXIF/XMP tags give them. Instant, and works where COLMAP fails (thermal frames over
// uniform ground, straight-line flights); as good as the telemetry (GPS metres, compass degrees).
//
// Inputs
// - Frames: every image file under frames_dir (ListFrameFiles: .png .jpg .jpeg .tif .tiff .exr,
//   any case), all of the camera's size. View order is capture order:
//   * by capture time when every frame has one: the log's time column beside its frame column,
//     else the frames' EXIF DateTimeOriginal (+ SubSecTimeOriginal; image_io.h's
//     ReadCaptureTime); ties keep name order;
//   * else by name in natural order (util/file_util.h's NaturalLess: 2.png before 10.png, as
//     frames named by an unpadded counter were taken), with a warning when only some frames
//     carry a time.
//   When name order and time order disagree, a warning says so with an example.
//   TelemetryResult::order says which order was used; the altitude rule and a time-column log
//   (frame i at time_offset_s + i * frame_interval_s) follow it.
// - Telemetry, one of:
//   (a) a CSV file (telemetry_file) with a header line naming its columns (any order, case-
//       insensitive; '#' comment lines and blank lines allowed; extra columns refused; RFC 4180
//       quoted fields and a UTF-8 byte-order mark as util/csv.h reads them):
//         frame (or name, image, file) [time] | time,  lat, lon, alt, yaw, pitch, roll
//       frame: a frame's path relative to frames_dir, or its file name (when unique); every
//       named frame must exist; a time column beside it is each frame's capture time (seconds,
//       any origin; it orders the views). time alone: seconds; frame i (view order) is at
//       time_offset_s + i * frame_interval_s, and its telemetry is interpolated linearly between
//       the two rows around it (yaw and longitude along the shorter arc); times must increase
//       and cover every frame. lat, lon: WGS84 degrees. alt: metres (altitude_reference: as
//       the world's heights, or above the take-off point). Angles in degrees:
//         yaw   = compass heading of the camera's forward direction (for a nadir camera: of the
//                 image's up direction), clockwise from north: true north by default
//                 (yaw_reference: "grid" for the UTM grid's north, "magnetic" with the
//                 declination for a magnetic compass's), 0 north, 90 east;
//         pitch = gimbal pitch: 0 = looking at the horizon, -90 = straight down (nadir);
//         roll  = rotation about the viewing direction, positive = the image's right side down.
//       (DJI's GimbalYawDegree / GimbalPitchDegree / GimbalRollDegree mean exactly these.)
//   (a') OpenDroneMap's geo.txt (sfm/odm.h; a telemetry_file whose first line is a projection):
//       image_name geo_x geo_y geo_z yaw pitch roll per line, in any CRS PROJ knows, read as a
//       log with a frame column (positions moved to WGS84; geo_z and the angles required).
//   (b) the frames' own tags (telemetry_file empty): EXIF GPS (GPSLatitude, GPSLongitude,
//       GPSAltitude, read through OpenImageIO) and the XMP packet DJI drones write
//       (drone-dji:GimbalYawDegree, GimbalPitchDegree, GimbalRollDegree, RelativeAltitude);
//       GPSLatitudeRef/GPSLongitudeRef must be N/S and E/W (image_io.h's ReadGpsTag),
//       read from the raw packet (OpenImageIO decodes only the XMP tags it knows, not DJI's
//       namespace). `altitude` picks GPSAltitude ("gps"), RelativeAltitude ("relative": above
//       the take-off point), or the latter when present ("auto").
// - Camera: a camera file (camera_file, camera_file.h; any lens model) or a pinhole with the
//   horizontal field of view fov_deg, principal point at the image centre.
//
// Plausibility (telemetry that is plausible and wrong is the worst input), each refused with the
// file and line or the frame, the field and the value:
// - positions: the flight's centre is the median latitude and longitude of its rows (frame
//   column: every row; time column: the rows around the frames; tags: every frame), longitudes
//   unwrapped around each other (geodesy.h's FlightCentre); a position farther than
//   max_distance_from_centre_m from it (great circle) is refused with its distance and a likely
//   cause (latitude and longitude swapped, radians, a hemisphere's sign). Half a flight in the
//   other hemisphere puts the centre between the halves and is refused too.
// - altitudes: EXIF GPSAltitude in [-500, 10000] m (above sea level or the ellipsoid), XMP
//   RelativeAltitude (above the take-off point, negative into a valley) and a log's alt (either
//   datum) in [-5000, 10000] m;
// - non-finite numbers anywhere.
//
// Output: a geo-referenced light field (images not loaded; image_path = the frames):
// - crs = the WGS84 / UTM zone of the flight's centre (as above; "EPSG:326zz" north,
//   "EPSG:327zz" south; one zone for the whole flight, also when it spans several zones or
//   crosses the 180th meridian: PROJ takes each longitude relative to the zone's central
//   meridian, so every view lies within the flight's extent); positions projected with PROJ;
// - origin = the mean position rounded to 100 m in easting and northing, z = 0, so local z is
//   the altitude as given;
// - world axes: x easting, y northing, z up. A magnetic heading is first turned to true north by
//   magnetic_declination_deg (true = magnetic + declination, east positive); a true heading is
//   then turned to grid north by the meridian convergence at each frame (GridBearingOfNorth, up
//   to ~3 degrees at a zone's edge), so that a nadir camera with yaw 0 has its image 'up'
//   pointing at true north; a grid heading is used as it is. With yaw 0, pitch -90, roll 0 on a
//   zone's central meridian the pose is NadirCamFromWorld.
// - Altitude outliers (barometer or GPS jumps): in view order (capture order), each altitude is compared with the
//   median of the given altitudes in a window of altitude_window frames centred on it (shifted
//   to stay inside the flight at its ends; the whole flight when shorter); one further than max_altitude_deviation_m from it
//   is replaced by that median and listed in TelemetryResult::altitude_outliers (frame, given
//   altitude, median), never silently. The rule holds while fewer than half of a window's
//   frames are outliers.
//
// Throws std::invalid_argument naming the file, line and field (a missing or repeated column, a
// non-numeric or non-finite value, malformed quoting, an implausible position or altitude, latitude outside [-80, 84] (UTM's range) or longitude outside
// [-180, 180], an angle outside [-360, 360], pitch outside [-180, 180], a repeated or unknown
// frame name, decreasing times, a frame outside the log's times), or the frame and tag for
// EXIF/XMP (a frame without GPS or gimbal tags), or the option. Nothing is written but, with
// radiometric "flir", the temperature frames (a new folder, moved into place once everything else
// succeeded: before ImportTelemetry returns, or by the caller with commit_frames false, after it
// has written its own outputs).
#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "aos/lightfield/lightfield.h"
#include "aos/util/file_util.h"
#include "aos/util/progress.h"
#include "aos/util/option_fields.h"

namespace aos {

struct TelemetryOptions {
  // CSV of frame|time, lat, lon, alt, yaw, pitch, roll (see above); empty = the frames' own
  // EXIF GPS and DJI XMP tags.
  std::string telemetry_file;
  // Known camera (aos-camera file, any lens model); empty = a pinhole from fov_deg.
  std::string camera_file;
  // Horizontal field of view of a pinhole camera, degrees, (0, 180); used (and required) when
  // camera_file is empty; 0 = not given.
  double fov_deg = 0.0;
  // EXIF altitude: "auto" (XMP RelativeAltitude when present, else GPSAltitude), "gps" or
  // "relative". Not used with a telemetry file.
  std::string altitude = "auto";
  // Altitude outliers: running-median window in frames, odd, >= 3; 0 = no outlier rule.
  int altitude_window = 9;
  // An altitude further than this from its running median is an outlier, metres, > 0.
  double max_altitude_deviation_m = 5.0;
  // A position farther than this from the flight's centre (the median latitude and longitude)
  // is refused, metres, > 0 (infinity = no bound). 50 km holds any drone flight; raise it for a
  // longer one.
  double max_distance_from_centre_m = 50000.0;
  // A time column: seconds between consecutive frames (view order), > 0 (required then).
  double frame_interval_s = 0.0;
  // A time column: the log time of the first frame, seconds.
  double time_offset_s = 0.0;
  // The north the yaw is measured from: "true" (geographic), "grid" (the UTM grid's: no
  // meridian convergence applied) or "magnetic" (a compass's; magnetic_declination_deg needed).
  std::string yaw_reference = "true";
  // With yaw_reference "magnetic": the declination, degrees east of true north (west
  // negative), [-90, 90]: true heading = magnetic heading + declination. Unset otherwise.
  std::optional<double> magnetic_declination_deg;
  // What the altitudes are measured from: "absolute" (world heights as given) or "takeoff"
  // (above the take-off point: world height = altitude + the take-off ground's height).
  std::string altitude_reference = "absolute";
  // With "takeoff": the take-off ground's world height, metres; unset = sampled from `dem`.
  std::optional<double> takeoff_height_m;
  // With "takeoff" and no takeoff_height_m: a DEM raster (GeoTIFF; any CRS PROJ relates to
  // WGS84, heights in metres) the take-off height is sampled from under the home point.
  std::string dem;
  // The take-off (home) point, WGS84 degrees; both unset = the first frame's position.
  std::optional<double> home_latitude_deg;
  std::optional<double> home_longitude_deg;
  // The frames are integrated as grey: RGB(A) frames (false-colour thermal) become one-channel
  // luminance whenever the light field is loaded (LightField::grey, "grey" in its file).
  bool grey = false;
  // What the pixel values measure: "none" (plain images), "flir" (FLIR radiometric JPEGs: their
  // raw counts and Planck calibration, read with exiftool, become 16-bit temperature frames in
  // temperature_frames_dir, 0.01 K per unit; image/flir.h) or "linear" (16-bit one-channel counts:
  // kelvin = kelvin_per_count * count + kelvin_offset). The light field records it (radiometry).
  std::string radiometric = "none";
  // With "linear": kelvin per count, > 0 (0.01 for FLIR's TLinear high resolution, 0.04 for its
  // low resolution). 0 = not given.
  double kelvin_per_count = 0.0;
  // With "linear": the temperature of count 0, kelvin.
  double kelvin_offset = 0.0;
  // With "flir": a new folder for the temperature frames (16-bit PNG, named like the frames);
  // the light field's views read them.
  std::string temperature_frames_dir;
  void Check() const;
  // The field table (util/option_fields.h): every field once, in declaration order.
  template <class Visit>
  static void Fields(Visit&& field) {
    using O = TelemetryOptions;
    field(OptionField("telemetry_file", &O::telemetry_file, "", Range::Any(),
                      "CSV log frame|time,lat,lon,alt,yaw,pitch,roll; '' = the frames' EXIF "
                      "GPS and DJI XMP gimbal tags."));
    field(OptionField("camera_file", &O::camera_file, "", Range::Any(),
                      "Known camera (aos-camera file, any lens model); '' = a pinhole from "
                      "fov_deg."));
    field(OptionField("fov_deg", &O::fov_deg, "deg", Range::Any(),
                      "Horizontal field of view of a pinhole camera, degrees, (0, 180); "
                      "without camera_file.")
              .Flag("frames-fov-deg"));
    field(OptionField("altitude", &O::altitude, "", Range::OneOf("auto|gps|relative"),
                      "EXIF/XMP altitude: 'auto' (XMP RelativeAltitude, else GPSAltitude), "
                      "'gps', 'relative'."));
    field(OptionField("altitude_window", &O::altitude_window, "", Range::Any(),
                      "Altitude outliers: running-median window in frames, odd >= 3; 0 = no "
                      "rule."));
    field(OptionField("max_altitude_deviation_m", &O::max_altitude_deviation_m, "m", Range::Any(),
                      "An altitude further than this from its running median is replaced by "
                      "it, metres."));
    field(OptionField("max_distance_from_centre_m", &O::max_distance_from_centre_m, "m", Range::Any(),
                      "A position farther than this from the flight's centre (median lat, "
                      "lon) is refused, metres."));
    field(OptionField("frame_interval_s", &O::frame_interval_s, "s", Range::Any(),
                      "With a time column: seconds between consecutive frames (view order)."));
    field(OptionField("time_offset_s", &O::time_offset_s, "s", Range::Any(),
                      "With a time column: the log time of the first frame, seconds."));
    field(OptionField("yaw_reference", &O::yaw_reference, "", Range::OneOf("true|grid|magnetic"),
                      "The north yaw is measured from: 'true', 'grid' (UTM grid north) or "
                      "'magnetic' (with magnetic_declination_deg)."));
    field(OptionField("magnetic_declination_deg", &O::magnetic_declination_deg, "deg",
                      Range::Any(),
                      "With yaw_reference 'magnetic': declination, degrees east of true north "
                      "(west negative), [-90, 90]."));
    field(OptionField("altitude_reference", &O::altitude_reference, "",
                      Range::OneOf("absolute|takeoff"),
                      "Altitudes are 'absolute' (world heights) or above the 'takeoff' point "
                      "(plus takeoff_height_m or the DEM's height there)."));
    field(OptionField("takeoff_height_m", &O::takeoff_height_m, "m", Range::Any(),
                      "With altitude_reference 'takeoff': the take-off ground's world height, "
                      "metres; unset = sampled from dem."));
    field(OptionField("dem", &O::dem, "", Range::Any(),
                      "DEM raster (GeoTIFF, any CRS) the take-off height is sampled from under "
                      "the home point."));
    field(OptionField("home_latitude_deg", &O::home_latitude_deg, "deg", Range::Any(),
                      "Take-off point latitude, WGS84 degrees; unset = the first frame's."));
    field(OptionField("home_longitude_deg", &O::home_longitude_deg, "deg", Range::Any(),
                      "Take-off point longitude, WGS84 degrees; unset = the first frame's."));
    field(OptionField("grey", &O::grey, "", Range::Any(),
                      "Integrate the frames as grey (false-colour thermal): recorded in the light "
                      "field, applied at every load."));
    field(OptionField("radiometric", &O::radiometric, "", Range::OneOf("none|flir|linear"),
                      "Pixel values: 'none', 'flir' (FLIR radiometric JPEGs -> temperature frames, "
                      "exiftool) or 'linear' (16-bit counts, kelvin_per_count)."));
    field(OptionField("kelvin_per_count", &O::kelvin_per_count, "K", Range::Any(),
                      "With radiometric 'linear': kelvin per count, > 0 (FLIR TLinear: 0.01 or "
                      "0.04)."));
    field(OptionField("kelvin_offset", &O::kelvin_offset, "K", Range::Any(),
                      "With radiometric 'linear': the temperature of count 0, kelvin."));
    field(OptionField("temperature_frames_dir", &O::temperature_frames_dir, "", Range::Any(),
                      "With radiometric 'flir': new folder for the 16-bit temperature frames "
                      "(0.01 K per unit)."));
  }
};

struct AltitudeOutlier {
  std::string frame;
  double altitude_m = 0.0;  // as given
  double median_m = 0.0;    // the running median that replaced it
};

struct TelemetryResult {
  LightField light_field;                  // images not loaded; image_path = the frame files
  std::vector<std::string> frames;         // view order, relative to frames_dir
  std::string source;                      // "csv", "odm" (geo.txt) or "exif"
  std::string order;                       // view order: "time" (capture times) or "name"
  std::string time_source;                 // "csv time column", "EXIF DateTimeOriginal" or ""
  std::string altitude_source;             // "csv alt", "XMP RelativeAltitude", "EXIF GPSAltitude"
  std::vector<AltitudeOutlier> altitude_outliers;
  std::vector<std::string> warnings;       // frames without telemetry (left out), ...
  std::string yaw_reference;               // as TelemetryOptions::yaw_reference
  double declination_deg = 0.0;            // added to every yaw (magnetic), degrees
  double max_convergence_deg = 0.0;        // largest |meridian convergence| applied, degrees
  std::string altitude_reference;          // as TelemetryOptions::altitude_reference
  double takeoff_height_m = 0.0;           // added to every altitude ("takeoff"), metres
  std::string takeoff_height_from;         // "given", or the DEM and the point it was sampled at
  std::string radiometric;                 // as TelemetryOptions::radiometric
  // With radiometric frames: the first frame's median and 1st/99th percentile temperatures,
  // degrees Celsius (NaN otherwise), a check a person can read at a glance.
  double first_frame_median_c = std::nan("");
  double first_frame_low_c = std::nan("");
  double first_frame_high_c = std::nan("");
  // With commit_frames false and radiometric "flir": the temperature frames' folder, not yet in
  // place (Commit() it once the light field is written; dropped, it is removed).
  std::shared_ptr<PendingFolder> pending_temperature_frames;
};

// `progress` gets a "tags" stage (EXIF/XMP source: a unit per frame's tags) and a "headers"
// stage (a unit per frame's header), and is polled for cancellation once per frame in each
// (throws aos::Cancelled).
TelemetryResult ImportTelemetry(const std::string& frames_dir, const TelemetryOptions& options,
                                ProgressSink* progress = nullptr, bool commit_frames = true);

// One frame's telemetry as read (degrees, metres). Exposed for tests.
struct TelemetrySample {
  double latitude_deg = 0.0;
  double longitude_deg = 0.0;
  double altitude_m = 0.0;
  double yaw_deg = 0.0;
  double pitch_deg = 0.0;
  double roll_deg = 0.0;
};

// The camera orientation of the convention above in a local east-north-up frame whose north is
// `grid_bearing_of_north_rad` clockwise from +y: world_from_cam rotation (columns: the camera's
// x right, y down, z forward in the world).
Mat3d WorldFromCameraRotation(double yaw_deg, double pitch_deg, double roll_deg,
                              double grid_bearing_of_north_rad = 0.0);

// The angle a + t (b - a) along the shorter arc, degrees (not wrapped into a range).
double InterpolateAngle(double a, double b, double t);

// The running-median rule above: altitudes replaced in place; returns the indices replaced and
// their medians.
std::vector<std::pair<size_t, double>> ReplaceAltitudeOutliers(std::vector<double>* altitudes,
                                                               int window, double max_deviation_m);

}  // namespace aos
