#pragma once
// OpenDroneMap interop: its image geolocation file (geo.txt), read as telemetry and written from
// a light field, so that an ODM project's camera positions come into aos and aos's poses go out
// to ODM (`odm --geo geo.txt`); and its ground control file (gcp_list.txt), read and written, and
// checked against a light field's poses (CheckGcps: the reprojection error of each sighting).
//
// The format (ODM's documentation, "Image Geolocation Files"):
//   <projection>
//   image_name geo_x geo_y [geo_z] [yaw pitch roll] [horizontal vertical accuracy] [extras]
// - The projection line: an EPSG code ("EPSG:4326"), a PROJ string ("+proj=utm +zone=10 ..."),
//   or "WGS84 UTM <zone>[N|S]" (read as EPSG:326zz / EPSG:327zz).
// - Fields are separated by spaces or tabs; blank lines and lines starting with '#' are skipped.
//   geo_x, geo_y are easting and northing, or longitude and latitude for a geographic CRS;
//   geo_z is the height in metres. Angles are degrees in ODM's normalised convention
//   (opendm/photo.py, which geo.txt angles are read as): yaw clockwise from true north (for a
//   nadir camera: the image's top; 0 north, 90 east), pitch 0 = nadir and 90 = looking at the
//   horizon (DJI's gimbal pitch + 90), roll as DJI's. ODM's documentation allows 0 0 0 for
//   angles "not available": that is a nadir camera with its image top at north here, and a
//   warning says so when every line has it. Accuracies are metres. Extra fields (a label) are
//   kept as text and otherwise ignored.
//
// Reading: ReadOdmGeo gives the entries as they are (in the file's CRS). ImportTelemetry reads a
// telemetry_file whose first line is a projection as geo.txt (sfm/telemetry.h): every entry
// needs geo_z and the three angles (a pose needs them; ODM may leave them out, aos cannot), and
// positions move to WGS84 through PROJ.
//
// Writing: WriteOdmGeo writes one line per view: the view's name (its frame's name), the camera
// centre in the light field's CRS (origin + local), and yaw, pitch, roll in ODM's convention
// above (the heading turned from grid north to true north by the meridian convergence at the
// view; pitch = aos's (DJI's) + 90);
// the light field must be geo-referenced (LightField::crs). Written atomically; refuses an
// existing file unless `overwrite`, and a path that is one of the frames.
//
// Errors (std::invalid_argument) name the file, the line and the field: an unknown projection, a
// line with too few numbers, a non-numeric or non-finite value, a repeated image name; for writing,
// a light field without a CRS or a view without a name.
#include <array>
#include <optional>
#include <string>
#include <vector>

#include "aos/lightfield/lightfield.h"

namespace aos {

struct OdmGeoEntry {
  int line = 0;                   // line number in the file (1-based)
  std::string image;              // image_name as written
  Vec3d position{0.0};            // geo_x, geo_y, geo_z (geo_z 0 when absent)
  bool has_z = false;
  std::optional<std::array<double, 3>> yaw_pitch_roll_deg;  // as written (ODM's convention)
  std::optional<std::array<double, 2>> accuracy_m;  // horizontal, vertical
  std::string extras;             // the rest of the line, as text
};

struct OdmGeoFile {
  std::string projection;  // the first line as written
  std::string crs;         // as PROJ takes it ("EPSG:32616" for "WGS84 UTM 16N")
  std::vector<OdmGeoEntry> entries;
};

// The CRS PROJ takes for an ODM projection line; throws std::invalid_argument naming `where` for
// one PROJ does not know.
std::string OdmProjectionCrs(const std::string& projection, const std::string& where);

// Whether `text` (a file's contents) starts, after blank and '#' lines, with a projection line
// rather than a CSV header: its first word is "EPSG:<digits>", "+proj=..." or "WGS84".
bool LooksLikeOdmGeo(const std::string& text);

OdmGeoFile ReadOdmGeo(const std::string& path);

// Pitch in ODM's convention (0 = nadir) from DJI's / aos's telemetry convention (-90 = nadir), and
// back.
inline double OdmPitchFromGimbal(double gimbal_pitch_deg) { return gimbal_pitch_deg + 90.0; }
inline double GimbalPitchFromOdm(double odm_pitch_deg) { return odm_pitch_deg - 90.0; }

// Yaw, pitch and roll (degrees, aos's telemetry convention: pitch -90 = nadir) of a camera
// rotation cam_from_world in a
// grid whose true north is `grid_bearing_of_north_rad` clockwise from +y: the inverse of
// WorldFromCameraRotation (sfm/telemetry.h). Looking straight down (|pitch| = 90) the roll is 0
// and the image's rotation is in the yaw.
std::array<double, 3> YawPitchRollOfRotation(const Mat3d& cam_from_world_rotation,
                                             double grid_bearing_of_north_rad = 0.0);

void WriteOdmGeo(const std::string& path, const LightField& light_field, bool overwrite = false);

// ODM's ground control point file (gcp_list.txt; ODM's documentation, "Ground Control Points"):
//   <projection>
//   geo_x geo_y geo_z im_x im_y image_name [gcp_name] [extras]
// The projection line as in geo.txt. Each line is one sighting of a ground point in one image:
// its world position (metres, or degrees for a geographic CRS) and its pixel in that image, ODM's
// pixel coordinates (OpenSfM's: the top-left pixel's centre at (0, 0), x right, y down; aos's put
// pixel centres at +0.5, so aos pixel = ODM pixel + 0.5). A point seen in several images has
// several lines with one gcp_name. Blank and '#' lines are skipped; extras are kept as text.
// Errors name the file, the line and the field (a missing or non-numeric field, a negative pixel).
struct OdmGcp {
  int line = 0;          // line number in the file (1-based)
  Vec3d position{0.0};   // geo_x, geo_y, geo_z in the file's CRS
  Vec2d pixel{0.0};      // im_x, im_y in ODM's pixel coordinates (see above)
  std::string image;     // image_name as written
  std::string name;      // gcp_name, or "" when absent
  std::string extras;    // the rest of the line, as text
};

struct OdmGcpFile {
  std::string projection;  // the first line as written
  std::string crs;         // as PROJ takes it
  std::vector<OdmGcp> points;
};

OdmGcpFile ReadOdmGcp(const std::string& path);
// Writes `file` (projection line, then a line per point, numbers to 15 significant digits). Written
// atomically; refuses an existing file unless `overwrite`; throws naming the point for an image
// or GCP name with white space, a non-finite number, or an unknown projection.
void WriteOdmGcp(const std::string& path, const OdmGcpFile& file, bool overwrite = false);

// How well a light field's poses agree with ground control: each sighting's ground point is
// moved into the light field's CRS (PROJ), projected into its view (found by name, as
// FindViewByName matches it) and compared with the marked pixel.
struct GcpResidual {
  int line = 0;
  std::string image;
  std::string name;
  int view = -1;              // the view's index
  Vec2d predicted{0.0};       // the projected ground point, aos pixel coordinates
  Vec2d observed{0.0};        // the marked pixel, aos pixel coordinates (ODM's + 0.5)
  double error_px = 0.0;      // |predicted - observed|
  // Where the marked pixel's ray meets the horizontal plane at the point's height, minus the
  // point: the error on the ground, metres (x, y in the light field's CRS); NaN when the ray
  // does not reach that plane.
  Vec2d ground_error_m{0.0};
  double ground_error_norm_m = 0.0;
};
struct GcpCheckResult {
  std::vector<GcpResidual> residuals;
  double rms_px = 0.0;
  double max_px = 0.0;
  double rms_ground_m = 0.0;  // over the sightings whose ray reaches the plane
  double max_ground_m = 0.0;
};
// Throws std::invalid_argument naming the GCP file's line for an image that is no view, a point
// behind its camera, and for a light field without a CRS.
GcpCheckResult CheckGcps(const LightField& light_field, const OdmGcpFile& gcps,
                         const std::string& where);

}  // namespace aos
