#include "aos/sfm/telemetry.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <sstream>

#include "aos/geometry/geodesy.h"
#include "aos/geometry/heightfield.h"
#include "aos/geometry/pinhole.h"
#include "aos/image/flir.h"
#include "aos/image/image_io.h"
#include "aos/lightfield/camera_file.h"
#include "aos/sfm/colmap_model.h"
#include "aos/sfm/odm.h"
#include "aos/util/csv.h"
#include "aos/util/error.h"
#include "aos/util/file_util.h"
#include "aos/util/math.h"

namespace fs = std::filesystem;

namespace aos {
namespace {

constexpr double kDeg = kPi / 180.0;

std::string Lower(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return text;
}

std::string Trim(const std::string& text) {
  const size_t a = text.find_first_not_of(" \t"), b = text.find_last_not_of(" \t");
  return a == std::string::npos ? "" : text.substr(a, b - a + 1);
}

// Range checks shared by the CSV and the tags: `where` names the line or the frame.
void CheckSample(const TelemetrySample& s, const std::string& where,
                 const char* const names[6]) {
  const auto check = [&](double value, double low, double high, const char* name,
                         const char* what) {
    if (value < low || value > high) {
      ThrowInvalid(where + ": " + name + ": " + FormatNumber(value) + " is outside " + what);
    }
  };
  check(s.latitude_deg, -90.0, 90.0, names[0], "[-90, 90] degrees");
  check(s.latitude_deg, -80.0, 84.0, names[0], "UTM's range [-80, 84] degrees");
  check(s.longitude_deg, -180.0, 180.0, names[1], "[-180, 180] degrees");
  check(s.yaw_deg, -360.0, 360.0, names[3], "[-360, 360] degrees");
  check(s.pitch_deg, -180.0, 180.0, names[4], "[-180, 180] degrees");
  check(s.roll_deg, -180.0, 180.0, names[5], "[-180, 180] degrees");
}

// Plausible altitudes, metres (see the header): GPSAltitude is above sea level or the
// ellipsoid; RelativeAltitude is above the take-off point (negative down into a valley); a log's
// alt may be either.
constexpr double kMaxAltitudeM = 10000.0;
constexpr double kMinAbsoluteAltitudeM = -500.0;
constexpr double kMinRelativeAltitudeM = -5000.0;
constexpr double kMinLoggedAltitudeM = kMinRelativeAltitudeM;

void CheckAltitude(double value, double low, const std::string& where, const std::string& name) {
  if (!(value >= low && value <= kMaxAltitudeM)) {
    ThrowInvalid(where + ": " + name + ": " + FormatNumber(value) +
                 " is outside the plausible altitudes [" + FormatNumber(low) + ", " +
                 FormatNumber(kMaxAltitudeM) + "] metres");
  }
}

const char* const kCsvNames[6] = {"lat", "lon", "alt", "yaw", "pitch", "roll"};
const char* const kTagNames[6] = {"GPS:Latitude",
                                  "GPS:Longitude",
                                  "altitude",
                                  "drone-dji:GimbalYawDegree",
                                  "drone-dji:GimbalPitchDegree",
                                  "drone-dji:GimbalRollDegree"};

struct CsvRow {
  int line = 0;
  std::string frame;  // frame column
  double time = 0.0;  // time column
  TelemetrySample sample;
};

struct CsvLog {
  bool by_time = false;    // a time column without a frame column: frames placed by time
  bool frame_time = false;  // a time column beside the frame column: each frame's capture time
  std::vector<CsvRow> rows;
};

CsvLog ReadTelemetryCsv(const std::string& path) {
  CheckRegularFile(path, "telemetry file");
  const std::vector<CsvRecord> records = ParseCsv(ReadTextFile(path), path);
  // Column index per field: key, lat, lon, alt, yaw, pitch, roll.
  std::map<std::string, std::string> aliases = {
      {"frame", "frame"},      {"name", "frame"},      {"image", "frame"},
      {"file", "frame"},       {"time", "time"},       {"lat", "lat"},
      {"latitude", "lat"},     {"lon", "lon"},         {"lng", "lon"},
      {"longitude", "lon"},    {"alt", "alt"},         {"altitude", "alt"},
      {"yaw", "yaw"},          {"heading", "yaw"},     {"pitch", "pitch"},
      {"roll", "roll"}};
  std::map<std::string, int> column;
  CsvLog log;
  std::set<std::string> seen;
  bool header = false;
  size_t columns = 0;
  for (const CsvRecord& record : records) {
    const std::string where = path + ": line " + std::to_string(record.line);
    const std::vector<std::string>& fields = record.fields;
    if (!header) {
      header = true;
      columns = fields.size();
      for (size_t i = 0; i < fields.size(); ++i) {
        const auto alias = aliases.find(Lower(fields[i]));
        if (alias == aliases.end()) {
          ThrowInvalid(where + ": column " + std::to_string(i + 1) + " \"" + fields[i] +
                       "\" is not one of frame (name, image, file), time, lat, lon, alt, yaw, "
                       "pitch, roll");
        }
        if (!column.emplace(alias->second, static_cast<int>(i)).second) {
          ThrowInvalid(where + ": column \"" + alias->second + "\" is given twice");
        }
      }
      const bool frame = column.count("frame") != 0, time = column.count("time") != 0;
      if (!frame && !time) {
        ThrowInvalid(where + ": the header needs a frame column (frame names) or a time column "
                             "(seconds), and has neither");
      }
      log.by_time = time && !frame;
      log.frame_time = time && frame;
      for (const char* name : kCsvNames) {
        if (column.count(name) == 0) {
          ThrowInvalid(where + ": the header has no " + name + " column (needed: " +
                       (time ? "time" : "frame") + ", lat, lon, alt, yaw, pitch, roll)");
        }
      }
      continue;
    }
    if (fields.size() != columns) {
      ThrowInvalid(where + ": expected " + std::to_string(columns) +
                   " comma-separated fields (as the header), got " +
                   std::to_string(fields.size()));
    }
    CsvRow row;
    row.line = record.line;
    if (log.by_time || log.frame_time) {
      row.time = ParseFiniteNumber(fields[column["time"]], where, "time");
    }
    if (!log.by_time) {
      row.frame = fields[column["frame"]];
      if (row.frame.empty()) ThrowInvalid(where + ": frame: is empty");
      if (!seen.insert(row.frame).second) {
        ThrowInvalid(where + ": frame: \"" + row.frame + "\" is repeated");
      }
    }
    double* values[6] = {&row.sample.latitude_deg, &row.sample.longitude_deg,
                         &row.sample.altitude_m,   &row.sample.yaw_deg,
                         &row.sample.pitch_deg,    &row.sample.roll_deg};
    for (int k = 0; k < 6; ++k) {
      *values[k] = ParseFiniteNumber(fields[column[kCsvNames[k]]], where, kCsvNames[k]);
    }
    CheckSample(row.sample, where, kCsvNames);
    CheckAltitude(row.sample.altitude_m, kMinLoggedAltitudeM, where, "alt");
    if (log.by_time && !log.rows.empty() && !(row.time > log.rows.back().time)) {
      ThrowInvalid(where + ": time: " + FormatNumber(row.time) +
                   " does not increase (the line before has " +
                   FormatNumber(log.rows.back().time) + ")");
    }
    log.rows.push_back(row);
  }
  if (!header) ThrowInvalid(path + ": no header line (frame|time, lat, lon, alt, yaw, pitch, roll)");
  if (log.rows.empty()) ThrowInvalid(path + ": no telemetry rows after the header");
  return log;
}

const char* const kOdmNames[6] = {"geo_y (latitude)", "geo_x (longitude)", "geo_z",
                                  "yaw", "pitch", "roll"};

// OpenDroneMap's geo.txt (sfm/odm.h) as a log with a frame column: positions moved from its
// projection to WGS84 through PROJ, pitch from ODM's convention (0 = nadir) to the gimbal's;
// every line needs geo_z and the camera angles. A warning when every line's angles are 0 0 0.
CsvLog ReadOdmGeoLog(const std::string& path, std::vector<std::string>* warnings) {
  const OdmGeoFile geo = ReadOdmGeo(path);
  std::vector<Vec3d> points;
  for (const OdmGeoEntry& entry : geo.entries) points.push_back(entry.position);
  const std::vector<Vec3d> wgs84 =
      TransformPoints(points, geo.crs, "EPSG:4326", path + ": projection " + geo.projection);
  CsvLog log;
  for (size_t i = 0; i < geo.entries.size(); ++i) {
    const OdmGeoEntry& entry = geo.entries[i];
    const std::string where = path + ": line " + std::to_string(entry.line);
    if (!entry.has_z) {
      ThrowInvalid(where + ": geo_z: missing (image " + entry.image + "): aos needs each "
                   "camera's height (ODM can do without it, from structure from motion)");
    }
    if (!entry.yaw_pitch_roll_deg) {
      ThrowInvalid(where + ": yaw pitch roll: missing (image " + entry.image + "): aos poses "
                   "each frame from its camera angles (ODM can do without them); give them, or "
                   "estimate the poses with aos-render poses");
    }
    CsvRow row;
    row.line = entry.line;
    row.frame = entry.image;
    row.sample.latitude_deg = wgs84[i].y;
    row.sample.longitude_deg = wgs84[i].x;
    row.sample.altitude_m = entry.position.z;
    row.sample.yaw_deg = (*entry.yaw_pitch_roll_deg)[0];
    row.sample.pitch_deg = GimbalPitchFromOdm((*entry.yaw_pitch_roll_deg)[1]);
    row.sample.roll_deg = (*entry.yaw_pitch_roll_deg)[2];
    CheckSample(row.sample, where, kOdmNames);
    CheckAltitude(row.sample.altitude_m, kMinLoggedAltitudeM, where, "geo_z");
    log.rows.push_back(row);
  }
  const bool all_zero = std::all_of(geo.entries.begin(), geo.entries.end(), [](const auto& e) {
    return (*e.yaw_pitch_roll_deg)[0] == 0.0 && (*e.yaw_pitch_roll_deg)[1] == 0.0 &&
           (*e.yaw_pitch_roll_deg)[2] == 0.0;
  });
  if (all_zero) {
    warnings->push_back(path + ": every camera's yaw, pitch and roll are 0 (ODM's placeholder "
                        "for angles not available): read as nadir cameras with the image top "
                        "at true north; check that the frames were taken so");
  }
  return log;
}

// Refuses a position farther than max_distance_m from the flight's centre (FlightCentre: the
// median latitude and longitude of all `samples`), naming the first such (`wheres[i]`, `fields`),
// its distance and a likely cause.
void CheckNearCentre(const std::vector<TelemetrySample>& samples,
                     const std::vector<std::string>& wheres, const std::string& fields,
                     double max_distance_m, const std::string& source) {
  std::vector<GeographicPosition> positions;
  for (const TelemetrySample& s : samples) positions.push_back({s.latitude_deg, s.longitude_deg});
  const GeographicPosition centre = FlightCentre(positions, source);
  const auto distance = [&](double latitude, double longitude) {
    return GreatCircleDistance({latitude, longitude}, centre);
  };
  size_t first = positions.size(), count = 0;
  for (size_t i = 0; i < positions.size(); ++i) {
    if (distance(positions[i].latitude_deg, positions[i].longitude_deg) > max_distance_m) {
      if (count++ == 0) first = i;
    }
  }
  if (count == 0) return;
  const double latitude = positions[first].latitude_deg;
  const double longitude = positions[first].longitude_deg;
  const auto near = [&](double lat, double lon) {
    return std::abs(lat) <= 90.0 && distance(lat, lon) <= max_distance_m;
  };
  std::string hint;
  if (near(longitude, latitude)) {
    hint = "; latitude and longitude swapped?";
  } else if (near(latitude / kDeg, longitude / kDeg)) {
    hint = "; in radians, not degrees?";
  } else if (near(-latitude, longitude)) {
    hint = "; the latitude's sign (hemisphere) wrong?";
  } else if (near(latitude, -longitude)) {
    hint = "; the longitude's sign wrong?";
  }
  char text[256];
  std::snprintf(text, sizeof(text), "%.1f km from the flight's centre (%.6f, %.6f", 
                distance(latitude, longitude) / 1000.0, centre.latitude_deg,
                centre.longitude_deg);
  ThrowInvalid(wheres[first] + ": " + fields + ": (" + FormatNumber(latitude) + ", " +
               FormatNumber(longitude) + ") is " + text + ": the median of " +
               std::to_string(positions.size()) + " positions), farther than "
               "max_distance_from_centre_m = " + FormatNumber(max_distance_m) + " m" + hint +
               (count > 1 ? " (" + std::to_string(count - 1) + " more position(s) as far)" : ""));
}


// XMP: the raw packet of a file (plain text by the XMP specification, wherever the container
// keeps it). JPEGs keep it in an APP1 segment near the start: the first MiB is searched first,
// then the rest of the file (TIFFs may keep it anywhere), up to 256 MiB.
std::string ReadXmpPacket(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) ThrowInvalid(path + ": cannot open the frame");
  std::error_code error;
  const uintmax_t file_size = fs::file_size(path, error);
  const size_t whole = error ? size_t{256} << 20
                             : static_cast<size_t>(std::min<uintmax_t>(file_size, 256u << 20));
  std::string data;
  for (size_t limit : {std::min(whole, size_t{1} << 20), whole}) {
    const size_t had = data.size();
    if (limit <= had) break;
    data.resize(limit);
    in.read(&data[had], static_cast<std::streamsize>(limit - had));
    data.resize(had + static_cast<size_t>(in.gcount()));
    const size_t begin = data.find("<x:xmpmeta");
    if (begin != std::string::npos) {
      size_t end = data.find("</x:xmpmeta>", begin);
      if (end == std::string::npos && in) {  // the packet runs past the first MiB
        continue;
      }
      return data.substr(begin, end == std::string::npos ? std::string::npos : end + 12 - begin);
    }
    if (!in) break;  // the whole file was read
  }
  return "";
}

// An XMP property's text, as an attribute (name="value") or an element (<name>value</name>).
std::optional<std::string> XmpProperty(const std::string& packet, const std::string& name) {
  for (size_t at = packet.find(name); at != std::string::npos; at = packet.find(name, at + 1)) {
    const size_t after = at + name.size();
    if (at > 0 && packet[at - 1] == '<' && after < packet.size() && packet[after] == '>') {
      const size_t close = packet.find('<', after + 1);
      if (close == std::string::npos) return std::nullopt;
      return Trim(packet.substr(after + 1, close - after - 1));
    }
    size_t p = after;
    while (p < packet.size() && std::isspace(static_cast<unsigned char>(packet[p]))) ++p;
    if (p < packet.size() && packet[p] == '=') {
      ++p;
      while (p < packet.size() && std::isspace(static_cast<unsigned char>(packet[p]))) ++p;
      if (p >= packet.size() || (packet[p] != '"' && packet[p] != '\'')) continue;
      const char quote = packet[p];
      const size_t close = packet.find(quote, p + 1);
      if (close == std::string::npos) return std::nullopt;
      return Trim(packet.substr(p + 1, close - p - 1));
    }
  }
  return std::nullopt;
}

TelemetrySample SampleFromTags(const std::string& path, const std::string& altitude_mode,
                               bool* relative_altitude) {
  const std::optional<GpsTag> gps = ReadGpsTag(path);
  if (!gps) ThrowInvalid(path + ": no EXIF GPSLatitude/GPSLongitude tags");
  const std::string packet = ReadXmpPacket(path);
  const auto xmp = [&](const char* name, bool required) -> std::optional<double> {
    const std::optional<std::string> text = XmpProperty(packet, name);
    if (!text) {
      if (required) {
        ThrowInvalid(path + ": no XMP " + name +
                     (packet.empty() ? " (the frame has no XMP packet)" : ""));
      }
      return std::nullopt;
    }
    std::string value = *text;
    if (!value.empty() && value[0] == '+') value.erase(0, 1);  // DJI writes "+12.30"
    return ParseFiniteNumber(value, path, std::string("XMP ") + name);
  };
  TelemetrySample s;
  s.latitude_deg = gps->latitude_deg;
  s.longitude_deg = gps->longitude_deg;
  s.yaw_deg = *xmp("drone-dji:GimbalYawDegree", true);
  s.pitch_deg = *xmp("drone-dji:GimbalPitchDegree", true);
  s.roll_deg = *xmp("drone-dji:GimbalRollDegree", true);
  const std::optional<double> relative =
      xmp("drone-dji:RelativeAltitude", altitude_mode == "relative");
  *relative_altitude = altitude_mode == "relative" || (altitude_mode == "auto" && relative);
  if (*relative_altitude) {
    s.altitude_m = *relative;
    CheckAltitude(s.altitude_m, kMinRelativeAltitudeM, path, "XMP drone-dji:RelativeAltitude");
  } else {
    if (!std::isfinite(gps->altitude_m)) {
      ThrowInvalid(path + ": no EXIF GPSAltitude" +
                   (altitude_mode == "auto" ? " (and no XMP drone-dji:RelativeAltitude)" : ""));
    }
    s.altitude_m = gps->altitude_m;
    CheckAltitude(s.altitude_m, kMinAbsoluteAltitudeM, path, "GPS:Altitude");
  }
  CheckSample(s, path, kTagNames);
  return s;
}

// The view order of `frames` (given in natural name order): by capture time (stable: ties keep
// name order) when every frame has one, else by name. Sets result->order and time_source, and
// warns when only some frames have a time, or when the two orders disagree (with an example).
std::vector<size_t> CaptureOrder(const std::vector<std::string>& frames,
                                 const std::vector<std::optional<double>>& times,
                                 const std::string& time_source, TelemetryResult* result) {
  FrameOrder order = CaptureTimeOrder(frames, times, time_source);
  result->order = order.by;
  result->time_source = order.time_source;
  for (std::string& warning : order.warnings) result->warnings.push_back(std::move(warning));
  return order.order;
}

template <class T>
std::vector<T> Permuted(const std::vector<T>& values, const std::vector<size_t>& order) {
  std::vector<T> out;
  out.reserve(order.size());
  for (size_t i : order) out.push_back(values[i]);
  return out;
}

// The height of the DEM raster `path` under (latitude, longitude), bilinear between the four
// pixel centres around it (nearest at the raster's rim); `from` describes where it came from.
double SampleTakeoffHeight(const std::string& path, double latitude, double longitude,
                           const std::string& point, std::string* from) {
  const Heightfield dem = ReadHeightfield(path);
  if (dem.crs_wkt.empty()) {
    ThrowInvalid(path + ": dem: the raster has no CRS, so the take-off point (WGS84) cannot be "
                 "placed on it; give takeoff_height_m instead");
  }
  const Vec3d at = TransformPoints({Vec3d(longitude, latitude, 0.0)}, "EPSG:4326", dem.crs_wkt,
                                   path + ": dem")[0];
  const std::array<double, 6>& gt = dem.geotransform;
  const double u = (at.x - gt[0]) / gt[1] - 0.5, v = (at.y - gt[3]) / gt[5] - 0.5;
  const std::string place = point + " (" + FormatNumber(latitude) + ", " +
                            FormatNumber(longitude) + ")";
  if (!(u >= -0.5 && u <= dem.width - 0.5 && v >= -0.5 && v <= dem.height - 0.5)) {
    ThrowInvalid(path + ": dem: " + place + " lies outside the raster (x " +
                 FormatNumber(gt[0]) + " .. " + FormatNumber(gt[0] + dem.width * gt[1]) +
                 ", y " + FormatNumber(gt[3] + dem.height * gt[5]) + " .. " +
                 FormatNumber(gt[3]) + " in its CRS; the point is at " + FormatNumber(at.x) +
                 ", " + FormatNumber(at.y) + ")");
  }
  const double uc = std::clamp(u, 0.0, dem.width - 1.0), vc = std::clamp(v, 0.0, dem.height - 1.0);
  const int i0 = std::min(static_cast<int>(uc), dem.width - 1);
  const int j0 = std::min(static_cast<int>(vc), dem.height - 1);
  const int i1 = std::min(i0 + 1, dem.width - 1), j1 = std::min(j0 + 1, dem.height - 1);
  const double fu = uc - i0, fv = vc - j0;
  // Terms of weight 0 left out: a nodata neighbour the point does not reach is no hole.
  double height = 0.0;
  const auto add = [&](double weight, int i, int j) {
    if (weight > 0.0) height += weight * dem.At(i, j);
  };
  add((1 - fu) * (1 - fv), i0, j0);
  add(fu * (1 - fv), i1, j0);
  add((1 - fu) * fv, i0, j1);
  add(fu * fv, i1, j1);
  if (!std::isfinite(height)) {
    ThrowInvalid(path + ": dem: the raster has no height (nodata) at " + place +
                 "; give takeoff_height_m instead");
  }
  *from = path + " at " + place;
  return height;
}

}  // namespace

void TelemetryOptions::Check() const {
  CheckFieldChoices(*this);  // altitude: the table's choices (telemetry.h)
  if (camera_file.empty() && !(fov_deg > 0.0 && fov_deg < 180.0)) {
    ThrowInvalid("fov_deg: a camera is needed: give camera_file, or fov_deg in (0, 180) (got " +
                 FormatNumber(fov_deg) + ")");
  }
  if (!camera_file.empty() && fov_deg != 0.0) {
    ThrowInvalid("fov_deg: give camera_file or fov_deg, not both (the camera file has its "
                 "intrinsics)");
  }
  if (altitude != "auto" && !telemetry_file.empty()) {
    ThrowInvalid("altitude: picks an EXIF/XMP altitude; a telemetry file has its alt column");
  }
  if (altitude_window != 0 && (altitude_window < 3 || altitude_window % 2 == 0)) {
    ThrowInvalid("altitude_window: must be odd and >= 3, or 0 = no outlier rule (got " +
                 std::to_string(altitude_window) + ")");
  }
  if (!(max_altitude_deviation_m > 0.0) || !std::isfinite(max_altitude_deviation_m)) {
    ThrowInvalid("max_altitude_deviation_m: must be > 0 metres (got " +
                 FormatNumber(max_altitude_deviation_m) + ")");
  }
  if (!(max_distance_from_centre_m > 0.0)) {
    ThrowInvalid("max_distance_from_centre_m: must be > 0 metres (got " +
                 FormatNumber(max_distance_from_centre_m) + ")");
  }
  if (!(frame_interval_s >= 0.0) || !std::isfinite(frame_interval_s)) {
    ThrowInvalid("frame_interval_s: must be >= 0 seconds (0 = no time column)");
  }
  if (!std::isfinite(time_offset_s)) ThrowInvalid("time_offset_s: must be finite");
  const auto finite = [](const std::optional<double>& value, const char* name) {
    if (value && !std::isfinite(*value)) {
      ThrowInvalid(std::string(name) + ": must be finite (got " + FormatNumber(*value) + ")");
    }
  };
  finite(magnetic_declination_deg, "magnetic_declination_deg");
  finite(takeoff_height_m, "takeoff_height_m");
  finite(home_latitude_deg, "home_latitude_deg");
  finite(home_longitude_deg, "home_longitude_deg");
  if (yaw_reference == "magnetic") {
    if (!magnetic_declination_deg) {
      ThrowInvalid("magnetic_declination_deg: yaw_reference 'magnetic' needs the magnetic "
                   "declination at the site (degrees east of true north, west negative)");
    }
    if (std::abs(*magnetic_declination_deg) > 90.0) {
      ThrowInvalid("magnetic_declination_deg: must be within [-90, 90] degrees (got " +
                   FormatNumber(*magnetic_declination_deg) + ")");
    }
  } else if (magnetic_declination_deg) {
    ThrowInvalid("magnetic_declination_deg: applies to yaw_reference 'magnetic' only (it is '" +
                 yaw_reference + "')");
  }
  if (altitude_reference == "takeoff") {
    if (takeoff_height_m.has_value() == !dem.empty()) {
      ThrowInvalid(std::string("takeoff_height_m: altitude_reference 'takeoff' needs the take-off "
                               "ground's height: give takeoff_height_m or dem (to sample it), ") +
                   (dem.empty() ? "one of them" : "not both"));
    }
  } else if (takeoff_height_m || !dem.empty()) {
    ThrowInvalid(std::string(takeoff_height_m ? "takeoff_height_m" : "dem") +
                 ": applies to altitude_reference 'takeoff' only (it is '" + altitude_reference +
                 "')");
  }
  if (home_latitude_deg.has_value() != home_longitude_deg.has_value()) {
    ThrowInvalid(std::string(home_latitude_deg ? "home_longitude_deg" : "home_latitude_deg") +
                 ": give the home point's latitude and longitude together");
  }
  if (home_latitude_deg && dem.empty()) {
    ThrowInvalid("home_latitude_deg: the home point places the take-off height on dem; give dem");
  }
  if (home_latitude_deg && std::abs(*home_latitude_deg) > 90.0) {
    ThrowInvalid("home_latitude_deg: must be within [-90, 90] degrees (got " +
                 FormatNumber(*home_latitude_deg) + ")");
  }
  if (home_longitude_deg && std::abs(*home_longitude_deg) > 180.0) {
    ThrowInvalid("home_longitude_deg: must be within [-180, 180] degrees (got " +
                 FormatNumber(*home_longitude_deg) + ")");
  }
  if (radiometric == "linear") {
    if (!(kelvin_per_count > 0.0) || !std::isfinite(kelvin_per_count)) {
      ThrowInvalid("kelvin_per_count: radiometric 'linear' needs the kelvin per count, > 0 (got " +
                   FormatNumber(kelvin_per_count) + "; FLIR TLinear: 0.01 or 0.04)");
    }
    if (!std::isfinite(kelvin_offset)) ThrowInvalid("kelvin_offset: must be finite");
  } else if (kelvin_per_count != 0.0 || kelvin_offset != 0.0) {
    ThrowInvalid(std::string(kelvin_per_count != 0.0 ? "kelvin_per_count" : "kelvin_offset") +
                 ": applies to radiometric 'linear' only (it is '" + radiometric + "')");
  }
  if (radiometric == "flir") {
    if (temperature_frames_dir.empty()) {
      ThrowInvalid("temperature_frames_dir: radiometric 'flir' writes 16-bit temperature frames: "
                   "give a new folder for them");
    }
  } else if (!temperature_frames_dir.empty()) {
    ThrowInvalid("temperature_frames_dir: applies to radiometric 'flir' only (it is '" +
                 radiometric + "')");
  }
  if (grey && radiometric != "none") {
    ThrowInvalid("grey: radiometric frames have one channel of temperatures already");
  }
}

Mat3d WorldFromCameraRotation(double yaw_deg, double pitch_deg, double roll_deg,
                              double grid_bearing_of_north_rad) {
  const double yaw = yaw_deg * kDeg + grid_bearing_of_north_rad;  // clockwise from grid +y
  const double pitch = pitch_deg * kDeg, roll = roll_deg * kDeg;
  const double sy = std::sin(yaw), cy = std::cos(yaw);
  const double sp = std::sin(pitch), cp = std::cos(pitch);
  const double sr = std::sin(roll), cr = std::cos(roll);
  // Without roll: forward at the heading, tilted up by the pitch; right horizontal; down the
  // image's down direction. Roll turns right and down about forward (right side down > 0).
  const Vec3d forward(sy * cp, cy * cp, sp);
  const Vec3d right(cy, -sy, 0.0);
  const Vec3d down(sy * sp, cy * sp, -cp);
  const Vec3d x = cr * right + sr * down;
  const Vec3d y = -sr * right + cr * down;
  Mat3d world_from_cam;
  world_from_cam[0] = x;  // GLM: columns
  world_from_cam[1] = y;
  world_from_cam[2] = forward;
  return world_from_cam;
}

std::vector<std::pair<size_t, double>> ReplaceAltitudeOutliers(std::vector<double>* altitudes,
                                                               int window, double max_deviation_m) {
  std::vector<std::pair<size_t, double>> replaced;
  if (window <= 0 || altitudes->empty()) return replaced;
  const std::vector<double> given = *altitudes;  // medians of the given values, not the fixed
  const int64_t n = static_cast<int64_t>(given.size());
  const int64_t half = window / 2;
  for (int64_t i = 0; i < n; ++i) {
    // The window centred on i, shifted (not shrunk) at the ends while the flight is long enough.
    int64_t begin = i - half, end = i + half + 1;
    if (begin < 0) {
      end = std::min(n, end - begin);
      begin = 0;
    }
    if (end > n) {
      begin = std::max<int64_t>(0, begin - (end - n));
      end = n;
    }
    std::vector<double> values(given.begin() + begin, given.begin() + end);
    std::sort(values.begin(), values.end());
    const size_t m = values.size();
    const double median = m % 2 == 1 ? values[m / 2] : 0.5 * (values[m / 2 - 1] + values[m / 2]);
    if (std::abs(given[i] - median) > max_deviation_m) {
      (*altitudes)[i] = median;
      replaced.push_back({static_cast<size_t>(i), median});
    }
  }
  return replaced;
}

// The 1st, 50th and 99th percentile temperatures of a radiometric frame, degrees Celsius.
void FrameTemperatures(const Image& image, const Radiometry& radiometry, TelemetryResult* result) {
  std::vector<double> values;
  values.reserve(static_cast<size_t>(image.width()) * image.height());
  for (int y = 0; y < image.height(); ++y) {
    for (int x = 0; x < image.width(); ++x) values.push_back(image.Value(x, y));
  }
  const auto percentile = [&](double p) {
    const size_t k = static_cast<size_t>(p * static_cast<double>(values.size() - 1));
    std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
    return radiometry.Celsius(values[k]);
  };
  result->first_frame_low_c = percentile(0.01);
  result->first_frame_median_c = percentile(0.5);
  result->first_frame_high_c = percentile(0.99);
}

// FLIR radiometric frames -> 16-bit temperature frames (0.01 K per unit) in `folder`, named by
// the frames' stems; `paths` become the written files.
void ConvertFlirFrames(std::vector<std::string>* paths, const std::string& folder,
                       const std::string& final_folder, const Radiometry& radiometry,
                       TelemetryResult* result, ProgressSink* progress) {
  std::set<std::string> names;
  std::vector<std::string> written;
  ProgressStart(progress, "flir", static_cast<int64_t>(paths->size()));
  constexpr size_t kBatch = 16;
  for (size_t start = 0; start < paths->size(); start += kBatch) {
    const size_t end = std::min(paths->size(), start + kBatch);
    const std::vector<std::string> batch(paths->begin() + static_cast<std::ptrdiff_t>(start),
                                         paths->begin() + static_cast<std::ptrdiff_t>(end));
    for (const FlirFrame& frame : ReadFlirFrames(batch)) {
      if (ProgressCancelled(progress)) throw Cancelled();
      for (const std::string& warning : frame.warnings) result->warnings.push_back(warning);
      const std::string name = fs::path(frame.path).stem().string() + ".png";
      if (!names.insert(name).second) {
        ThrowInvalid(frame.path + ": two frames share the name " + name +
                     " in temperature_frames_dir " + final_folder);
      }
      const Image temperatures = FlirTemperatureImage(frame, radiometry);
      if (written.empty()) FrameTemperatures(temperatures, radiometry, result);
      WriteImageOptions write;
      write.description = "aos temperature frame: " + radiometry.Describe() + " (from " +
                          fs::path(frame.path).filename().string() + ")";
      WriteImage((fs::path(folder) / name).string(), temperatures, write);
      written.push_back((fs::path(final_folder) / name).string());
      ProgressAdvance(progress, 1);
    }
  }
  *paths = written;
}

TelemetryResult ImportTelemetry(const std::string& frames_dir, const TelemetryOptions& options,
                                ProgressSink* progress, bool commit_frames) {
  options.Check();
  auto poll = [progress] {
    if (ProgressCancelled(progress)) throw Cancelled();
  };
  TelemetryResult result;
  if (options.radiometric == "flir") CheckOutputFolder(options.temperature_frames_dir);
  const bool odm = !options.telemetry_file.empty() &&
                   LooksLikeOdmGeo(ReadTextFile(options.telemetry_file));
  result.source = options.telemetry_file.empty() ? "exif" : odm ? "odm" : "csv";
  result.yaw_reference = options.yaw_reference;
  result.altitude_reference = options.altitude_reference;
  result.altitude_source = result.source == "csv" ? "csv alt" : odm ? "geo.txt geo_z" : "";
  // Natural name order (2.png before 10.png); capture order below where the frames have times.
  std::vector<std::string> all_frames = ListFrameFiles(frames_dir);
  if (all_frames.empty()) ThrowInvalid(frames_dir + ": no frames (png, jpg, tif, exr) found");
  const std::string kExifTime = "EXIF DateTimeOriginal";
  // The frames' EXIF capture times (headers only).
  const auto exif_times = [&](const std::vector<std::string>& names) {
    std::vector<std::optional<double>> times;
    ProgressStart(progress, "times", static_cast<int64_t>(names.size()));
    for (const std::string& frame : names) {
      poll();
      ProgressAdvance(progress, 1);
      times.push_back(ReadCaptureTime((fs::path(frames_dir) / frame).string()));
    }
    return times;
  };

  // Telemetry per frame, in natural name order (a time-column log: in view order).
  std::vector<std::string> frames;
  std::vector<TelemetrySample> samples;
  std::vector<std::optional<double>> times;  // capture times, when known
  std::string time_source;
  bool ordered = false;  // frames and samples are in view order already
  if (!options.telemetry_file.empty()) {
    const std::string& path = options.telemetry_file;
    const CsvLog log = odm ? ReadOdmGeoLog(path, &result.warnings) : ReadTelemetryCsv(path);
    if (log.by_time) {
      if (options.frame_interval_s <= 0.0) {
        ThrowInvalid(path + ": a time column needs frame_interval_s (seconds between frames)");
      }
      // Frame i (view order: capture time where the frames carry it, else natural name order)
      // is at time_offset_s + i * frame_interval_s.
      all_frames = Permuted(all_frames, CaptureOrder(all_frames, exif_times(all_frames),
                                                     kExifTime, &result));
      ordered = true;
      // Each frame's time and the row before it; the rows used must be plausible.
      std::vector<double> times;
      std::vector<size_t> before;
      std::set<size_t> used;
      for (size_t i = 0; i < all_frames.size(); ++i) {
        const double t = options.time_offset_s + static_cast<double>(i) * options.frame_interval_s;
        if (t < log.rows.front().time || t > log.rows.back().time) {
          ThrowInvalid(path + ": frame " + all_frames[i] + " at time " + FormatNumber(t) +
                       " s lies outside the log's times [" + FormatNumber(log.rows.front().time) +
                       ", " + FormatNumber(log.rows.back().time) +
                       "] (frame_interval_s, time_offset_s)");
        }
        size_t k = before.empty() ? 0 : before.back();
        while (k + 1 < log.rows.size() && log.rows[k + 1].time < t) ++k;
        times.push_back(t);
        before.push_back(k);
        used.insert(k);
        used.insert(std::min(k + 1, log.rows.size() - 1));
      }
      std::vector<TelemetrySample> used_samples;
      std::vector<std::string> wheres;
      for (size_t k : used) {
        used_samples.push_back(log.rows[k].sample);
        wheres.push_back(path + ": line " + std::to_string(log.rows[k].line));
      }
      CheckNearCentre(used_samples, wheres, "lat, lon", options.max_distance_from_centre_m, path);
      for (size_t i = 0; i < all_frames.size(); ++i) {
        const double t = times[i];
        const size_t k = before[i];
        const CsvRow& a = log.rows[k];
        const CsvRow& b = log.rows[std::min(k + 1, log.rows.size() - 1)];
        const double f = b.time > a.time ? (t - a.time) / (b.time - a.time) : 0.0;
        const auto lerp = [f](double u, double v) { return u + f * (v - u); };
        TelemetrySample s;
        s.latitude_deg = lerp(a.sample.latitude_deg, b.sample.latitude_deg);
        // Along the shorter arc, also across the 180th meridian; back into (-180, 180].
        s.longitude_deg = UnwrapLongitude(
            InterpolateAngle(a.sample.longitude_deg, b.sample.longitude_deg, f), 0.0);
        s.altitude_m = lerp(a.sample.altitude_m, b.sample.altitude_m);
        s.yaw_deg = InterpolateAngle(a.sample.yaw_deg, b.sample.yaw_deg, f);
        s.pitch_deg = lerp(a.sample.pitch_deg, b.sample.pitch_deg);
        s.roll_deg = InterpolateAngle(a.sample.roll_deg, b.sample.roll_deg, f);
        frames.push_back(all_frames[i]);
        samples.push_back(s);
      }
    } else {
      // Names: a frame's relative path, or its file name when unique.
      std::map<std::string, std::string> by_file_name;  // "" when ambiguous
      const std::set<std::string> exact(all_frames.begin(), all_frames.end());
      for (const std::string& frame : all_frames) {
        auto [it, inserted] = by_file_name.emplace(fs::path(frame).filename().string(), frame);
        if (!inserted) it->second.clear();
      }
      std::vector<TelemetrySample> row_samples;
      std::vector<std::string> wheres;
      for (const CsvRow& row : log.rows) {
        row_samples.push_back(row.sample);
        wheres.push_back(path + ": line " + std::to_string(row.line) + " (frame " + row.frame +
                         ")");
      }
      CheckNearCentre(row_samples, wheres, "lat, lon", options.max_distance_from_centre_m, path);
      std::map<std::string, const CsvRow*> by_frame;
      for (const CsvRow& row : log.rows) {
        std::string frame;
        if (exact.count(row.frame) != 0) {
          frame = row.frame;
        } else if (auto it = by_file_name.find(row.frame);
                   it != by_file_name.end() && !it->second.empty()) {
          frame = it->second;
        }
        if (frame.empty()) {
          ThrowInvalid(path + ": line " + std::to_string(row.line) + ": frame: \"" + row.frame +
                       "\" names no frame in " + frames_dir);
        }
        if (!by_frame.emplace(frame, &row).second) {
          ThrowInvalid(path + ": line " + std::to_string(row.line) + ": frame: \"" + row.frame +
                       "\" names frame " + frame + " a second time");
        }
      }
      std::vector<std::string> missing;
      for (const std::string& frame : all_frames) {
        const auto it = by_frame.find(frame);
        if (it == by_frame.end()) {
          missing.push_back(frame);
          continue;
        }
        frames.push_back(frame);
        samples.push_back(it->second->sample);
        if (log.frame_time) times.push_back(it->second->time);
      }
      if (log.frame_time) {
        time_source = "the time column of " + path;
      } else {
        times = exif_times(frames);
        time_source = kExifTime;
      }
      if (!missing.empty()) {
        std::string list;
        for (size_t i = 0; i < missing.size() && i < 5; ++i) list += (i ? ", " : "") + missing[i];
        if (missing.size() > 5) list += ", ...";
        result.warnings.push_back(std::to_string(missing.size()) + " frame(s) have no row in " +
                                  path + " and are left out: " + list);
      }
    }
  } else {
    std::vector<std::string> paths;
    ProgressStart(progress, "tags", static_cast<int64_t>(all_frames.size()));
    size_t relative = 0;
    for (const std::string& frame : all_frames) {
      poll();
      ProgressAdvance(progress, 1);
      frames.push_back(frame);
      paths.push_back((fs::path(frames_dir) / frame).string());
      bool is_relative = false;
      samples.push_back(SampleFromTags(paths.back(), options.altitude, &is_relative));
      relative += is_relative ? 1 : 0;
      times.push_back(ReadCaptureTime(paths.back()));
    }
    time_source = kExifTime;
    CheckNearCentre(samples, paths, std::string(kTagNames[0]) + ", " + kTagNames[1],
                    options.max_distance_from_centre_m, frames_dir);
    result.altitude_source = relative == frames.size() ? "XMP RelativeAltitude"
                             : relative == 0           ? "EXIF GPSAltitude"
                                                       : "XMP RelativeAltitude, else EXIF "
                                                         "GPSAltitude";
    if (relative > 0 && relative < frames.size()) {
      result.warnings.push_back(std::to_string(relative) + " of " +
                                std::to_string(frames.size()) +
                                " frames have XMP RelativeAltitude (above the take-off point), "
                                "the others only EXIF GPSAltitude (above sea level): their "
                                "heights differ by the take-off point's; give altitude 'gps' "
                                "or 'relative'");
    }
    if (relative > 0 && options.altitude_reference == "absolute") {
      result.warnings.push_back(
          "altitudes are XMP RelativeAltitude (above the take-off point) but "
          "altitude_reference is 'absolute': world z is the height above the take-off point, "
          "not the DEM's; give altitude_reference 'takeoff' with takeoff_height_m or dem to "
          "focus on a DEM");
    }
  }
  if (!ordered) {
    const std::vector<size_t> order = CaptureOrder(frames, times, time_source, &result);
    frames = Permuted(frames, order);
    samples = Permuted(samples, order);
  }

  // The files the views read: the frames, or their temperatures (FLIR radiometric frames,
  // written to a pending folder that is moved into place once everything else succeeded).
  std::vector<std::string> read_paths;  // where the files are now
  for (const std::string& frame : frames) read_paths.push_back((fs::path(frames_dir) / frame).string());
  std::vector<std::string> view_paths = read_paths;  // where the views will find them
  std::shared_ptr<PendingFolder> temperature_frames;
  result.radiometric = options.radiometric;
  if (options.radiometric == "flir") {
    temperature_frames = std::make_shared<PendingFolder>(options.temperature_frames_dir);
    result.light_field.radiometry = Radiometry{0.01, 0.0};
    view_paths = read_paths;
    ConvertFlirFrames(&view_paths, temperature_frames->TempPath(), options.temperature_frames_dir,
                      *result.light_field.radiometry, &result, progress);
    for (size_t i = 0; i < view_paths.size(); ++i) {
      read_paths[i] = (fs::path(temperature_frames->TempPath()) /
                       fs::path(view_paths[i]).filename()).string();
    }
  } else if (options.radiometric == "linear") {
    result.light_field.radiometry = Radiometry{options.kelvin_per_count, options.kelvin_offset};
  }

  // The camera, and every frame's size against it (headers only).
  LensCamera camera;
  const std::string first_path = read_paths.front();
  if (!options.camera_file.empty()) {
    camera = ReadCameraFile(options.camera_file);
    camera.Finalize(options.camera_file);
  } else {
    const ImageFileInfo info = ReadImageInfo(first_path);
    camera = LensCamera::FromPinhole(PinholeCamera::FromFov(info.width, info.height,
                                                            options.fov_deg));
  }
  ProgressStart(progress, "headers", static_cast<int64_t>(frames.size()));
  for (const std::string& path : read_paths) {
    poll();
    ProgressAdvance(progress, 1);
    const ImageFileInfo info = ReadImageInfo(path);
    if (options.radiometric == "linear" && (info.channels != 1 || info.type != PixelType::kU16)) {
      ThrowInvalid(path + ": radiometric 'linear' reads 16-bit one-channel counts, but the frame "
                   "has " + std::to_string(info.channels) + " channel" +
                   (info.channels == 1 ? "" : "s") + " of " + PixelTypeName(info.type));
    }
    if (info.width != camera.width || info.height != camera.height) {
      ThrowInvalid(path + ": the frame is " + std::to_string(info.width) + "x" +
                   std::to_string(info.height) + " but the camera is " +
                   std::to_string(camera.width) + "x" + std::to_string(camera.height) +
                   (options.camera_file.empty() ? " (from the first frame)"
                                                : " (" + options.camera_file + ")"));
    }
  }

  if (options.radiometric == "linear") {
    // A calibration that makes the scene implausibly hot or cold is a wrong calibration.
    FrameTemperatures(ReadImage(read_paths.front()), *result.light_field.radiometry, &result);
    if (!(result.first_frame_median_c > -100.0 && result.first_frame_median_c < 200.0)) {
      ThrowInvalid(read_paths.front() + ": kelvin_per_count, kelvin_offset: the frame's median "
                   "temperature would be " + FormatNumber(result.first_frame_median_c) +
                   " C (" + result.light_field.radiometry->Describe() +
                   "); -100..200 C expected: check the calibration");
    }
  }

  // Altitude outliers, in view order (capture order).
  std::vector<double> altitudes;
  for (const TelemetrySample& s : samples) altitudes.push_back(s.altitude_m);
  for (const auto& [index, median] : ReplaceAltitudeOutliers(
           &altitudes, options.altitude_window, options.max_altitude_deviation_m)) {
    result.altitude_outliers.push_back({frames[index], samples[index].altitude_m, median});
  }
  // Altitudes above the take-off point: plus its ground's height.
  if (options.altitude_reference == "takeoff") {
    if (options.takeoff_height_m) {
      result.takeoff_height_m = *options.takeoff_height_m;
      result.takeoff_height_from = "given";
    } else {
      const bool home = options.home_latitude_deg.has_value();
      result.takeoff_height_m = SampleTakeoffHeight(
          options.dem, home ? *options.home_latitude_deg : samples.front().latitude_deg,
          home ? *options.home_longitude_deg : samples.front().longitude_deg,
          home ? std::string("the home point") : "the first frame " + frames.front(),
          &result.takeoff_height_from);
      if (!home && std::abs(altitudes.front()) > 5.0) {
        result.warnings.push_back(
            "the take-off height was sampled under the first frame " + frames.front() + ", " +
            FormatNumber(altitudes.front()) + " m above the take-off point: unless the drone "
            "climbed straight up there, give the home point (home_latitude_deg, "
            "home_longitude_deg) or takeoff_height_m");
      }
    }
    for (double& altitude : altitudes) altitude += result.takeoff_height_m;
  }

  // One UTM zone for the flight: its centre's (the median latitude and longitude, longitudes
  // unwrapped around each other, so a flight across the 180th meridian is centred there), through
  // PROJ, which takes every longitude relative to that zone's central meridian; the meridian
  // convergence from each position and one 1e-5 degrees north of it.
  std::vector<GeographicPosition> positions;
  for (const TelemetrySample& s : samples) positions.push_back({s.latitude_deg, s.longitude_deg});
  const GeographicPosition centre = FlightCentre(positions, "telemetry");
  const UtmCoordinate zone =
      UtmFromWgs84(centre.latitude_deg, centre.longitude_deg, 0, "telemetry: the flight's centre");
  const std::string crs = UtmEpsg(zone.zone, zone.north);
  std::vector<Vec3d> geographic;
  for (size_t i = 0; i < samples.size(); ++i) {
    geographic.push_back(Vec3d(samples[i].longitude_deg, samples[i].latitude_deg, altitudes[i]));
  }
  for (const TelemetrySample& s : samples) {
    geographic.push_back(Vec3d(s.longitude_deg, s.latitude_deg + 1e-5, 0.0));
  }
  const std::string where = options.telemetry_file.empty() ? frames_dir : options.telemetry_file;
  const std::vector<Vec3d> grid = TransformPoints(geographic, "EPSG:4326", crs, where);
  const size_t n = samples.size();
  Vec3d mean(0.0);
  for (size_t i = 0; i < n; ++i) mean += grid[i];
  mean /= static_cast<double>(n);
  LightField& light_field = result.light_field;
  light_field.crs = crs;
  light_field.origin = Vec3d(std::round(mean.x / 100.0) * 100.0, std::round(mean.y / 100.0) * 100.0,
                             0.0);
  // Yaw: magnetic -> true by the declination; true -> grid by the meridian convergence.
  result.declination_deg = options.magnetic_declination_deg.value_or(0.0);
  const bool grid_yaw = options.yaw_reference == "grid";
  for (size_t i = 0; i < n; ++i) {
    const Vec3d north = grid[n + i] - grid[i];
    const double bearing_of_north = grid_yaw ? 0.0 : std::atan2(north.x, north.y);
    result.max_convergence_deg =
        std::max(result.max_convergence_deg, std::abs(bearing_of_north) / kDeg);
    const Mat3d world_from_cam =
        WorldFromCameraRotation(samples[i].yaw_deg + result.declination_deg, samples[i].pitch_deg,
                                samples[i].roll_deg, bearing_of_north);
    View view;
    view.name = frames[i];
    view.image_path = view_paths[i];
    view.camera = camera;
    view.cam_from_world.rotation = glm::transpose(world_from_cam);
    const Vec3d centre = grid[i] - light_field.origin;
    view.cam_from_world.translation = -(view.cam_from_world.rotation * centre);
    light_field.views.push_back(std::move(view));
  }
  PoseSource source;
  source.method = "telemetry";
  source.georeferenced = true;
  light_field.pose_source = source;
  light_field.grey = options.grey;
  result.frames = frames;
  if (temperature_frames) {
    if (commit_frames) {
      temperature_frames->Commit();
    } else {
      result.pending_temperature_frames = temperature_frames;
    }
  }
  return result;
}

double InterpolateAngle(double a, double b, double t) {
  double d = std::fmod(b - a, 360.0);
  if (d > 180.0) d -= 360.0;
  if (d < -180.0) d += 360.0;
  return a + t * d;
}

}  // namespace aos
