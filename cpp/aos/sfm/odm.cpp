#include "aos/sfm/odm.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <set>
#include <sstream>

#include "aos/geometry/geodesy.h"
#include "aos/util/csv.h"
#include "aos/util/error.h"
#include "aos/util/file_util.h"
#include "aos/util/math.h"

namespace fs = std::filesystem;

namespace aos {
namespace {

constexpr double kDeg = kPi / 180.0;

std::vector<std::string> Words(const std::string& line) {
  std::vector<std::string> words;
  std::istringstream stream(line);
  for (std::string word; stream >> word;) words.push_back(word);
  return words;
}

std::string Lower(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return text;
}

// The lines of `text` that carry content: (line number, text without a trailing '\r').
std::vector<std::pair<int, std::string>> ContentLines(const std::string& text) {
  std::vector<std::pair<int, std::string>> lines;
  std::istringstream stream(text);
  int number = 0;
  for (std::string line; std::getline(stream, line);) {
    ++number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (number == 1 && line.compare(0, 3, "\xEF\xBB\xBF") == 0) line.erase(0, 3);  // a BOM
    const size_t first = line.find_first_not_of(" \t");
    if (first == std::string::npos || line[first] == '#') continue;
    lines.emplace_back(number, line);
  }
  return lines;
}

// A coordinate to 15 significant digits (1e-8 m at UTM northings; FormatNumber's 10 are 1 mm).
std::string PreciseNumber(double value) {
  char text[64];
  std::snprintf(text, sizeof(text), "%.15g", value);
  return text;
}

bool IsNumber(const std::string& text) {
  char* end = nullptr;
  std::strtod(text.c_str(), &end);
  return !text.empty() && end == text.c_str() + text.size();
}

}  // namespace

std::string OdmProjectionCrs(const std::string& projection, const std::string& where) {
  const std::vector<std::string> words = Words(projection);
  if (words.empty()) ThrowInvalid(where + ": projection: the first line is empty");
  // "WGS84 UTM 16N": ODM's own spelling of a UTM zone.
  if (words.size() == 3 && Lower(words[0]) == "wgs84" && Lower(words[1]) == "utm") {
    const std::string& zone = words[2];
    const char hemisphere = zone.empty() ? '\0' : static_cast<char>(std::toupper(zone.back()));
    const std::string digits = zone.substr(0, zone.size() - 1);
    const int number = digits.empty() || digits.find_first_not_of("0123456789") != std::string::npos
                           ? 0
                           : std::atoi(digits.c_str());
    if ((hemisphere != 'N' && hemisphere != 'S') || number < 1 || number > 60) {
      ThrowInvalid(where + ": projection: \"" + projection +
                   "\" is not WGS84 UTM <zone 1..60><N|S>");
    }
    return UtmEpsg(number, hemisphere == 'N');
  }
  std::string crs = projection;
  crs.erase(0, crs.find_first_not_of(" \t"));
  crs.erase(crs.find_last_not_of(" \t") + 1);
  EpsgOfCrs(crs, where + ": projection");  // refuses one PROJ does not know
  return crs;
}

bool LooksLikeOdmGeo(const std::string& text) {
  const std::vector<std::pair<int, std::string>> lines = ContentLines(text);
  if (lines.empty()) return false;
  const std::vector<std::string> words = Words(lines.front().second);
  if (words.empty()) return false;
  const std::string first = Lower(words[0]);
  return (first.rfind("epsg:", 0) == 0 && first.find(',') == std::string::npos) ||
         first.rfind("+proj=", 0) == 0 || first == "wgs84";
}

OdmGeoFile ReadOdmGeo(const std::string& path) {
  CheckRegularFile(path, "geo file");
  const std::vector<std::pair<int, std::string>> lines = ContentLines(ReadTextFile(path));
  if (lines.empty()) {
    ThrowInvalid(path + ": empty: expected a projection line, then one line per image");
  }
  OdmGeoFile file;
  file.projection = lines.front().second;
  file.crs = OdmProjectionCrs(file.projection,
                              path + ": line " + std::to_string(lines.front().first));
  std::set<std::string> seen;
  for (size_t k = 1; k < lines.size(); ++k) {
    const auto& [number, text] = lines[k];
    const std::string where = path + ": line " + std::to_string(number);
    const std::vector<std::string> words = Words(text);
    // The numbers after the name, up to the first word that is not one (the extras).
    size_t numbers = 0;
    while (1 + numbers < words.size() && numbers < 8 && IsNumber(words[1 + numbers])) ++numbers;
    if (numbers < 2) {
      ThrowInvalid(where + ": expected image_name geo_x geo_y [geo_z] [yaw pitch roll] "
                   "[horizontal vertical accuracy], got \"" + text + "\"");
    }
    OdmGeoEntry entry;
    entry.line = number;
    entry.image = words[0];
    if (!seen.insert(entry.image).second) {
      ThrowInvalid(where + ": image_name: \"" + entry.image + "\" is repeated");
    }
    const char* const names[8] = {"geo_x", "geo_y", "geo_z", "yaw", "pitch", "roll",
                                  "horizontal accuracy", "vertical accuracy"};
    std::vector<double> v;
    for (size_t i = 0; i < numbers; ++i) {
      v.push_back(ParseFiniteNumber(words[1 + i], where, names[i]));
    }
    entry.position = Vec3d(v[0], v[1], numbers >= 3 ? v[2] : 0.0);
    entry.has_z = numbers >= 3;
    if (numbers == 4 || numbers == 5) {
      ThrowInvalid(where + ": camera angles: give yaw, pitch and roll together (got " +
                   std::to_string(numbers - 3) + " of them)");
    }
    if (numbers >= 6) entry.yaw_pitch_roll_deg = std::array<double, 3>{v[3], v[4], v[5]};
    if (numbers == 7) {
      ThrowInvalid(where + ": accuracies: give the horizontal and vertical accuracy together");
    }
    if (numbers == 8) entry.accuracy_m = std::array<double, 2>{v[6], v[7]};
    for (size_t i = 1 + numbers; i < words.size(); ++i) {
      entry.extras += (entry.extras.empty() ? "" : " ") + words[i];
    }
    file.entries.push_back(std::move(entry));
  }
  if (file.entries.empty()) ThrowInvalid(path + ": no image lines after the projection line");
  return file;
}

std::array<double, 3> YawPitchRollOfRotation(const Mat3d& cam_from_world_rotation,
                                             double grid_bearing_of_north_rad) {
  // Rows of cam_from_world: the camera's x (right), y (down) and z (forward) in the world.
  const Vec3d x = Row(cam_from_world_rotation, 0);
  const Vec3d forward = Row(cam_from_world_rotation, 2);
  const double pitch = std::asin(std::clamp(forward.z, -1.0, 1.0));
  double yaw = 0.0, roll = 0.0;
  if (std::hypot(forward.x, forward.y) > 1e-9) {
    yaw = std::atan2(forward.x, forward.y);
    const double sy = std::sin(yaw), cy = std::cos(yaw);
    const double sp = std::sin(pitch), cp = std::cos(pitch);
    const Vec3d right(cy, -sy, 0.0), down(sy * sp, cy * sp, -cp);
    roll = std::atan2(glm::dot(x, down), glm::dot(x, right));
  } else {
    yaw = std::atan2(-x.y, x.x);  // straight down or up: the roll folded into the yaw
  }
  const auto wrap = [](double degrees) {
    double d = std::fmod(degrees, 360.0);
    if (d > 180.0) d -= 360.0;
    if (d <= -180.0) d += 360.0;
    return d;
  };
  return {wrap((yaw - grid_bearing_of_north_rad) / kDeg), pitch / kDeg, wrap(roll / kDeg)};
}

void WriteOdmGeo(const std::string& path, const LightField& light_field, bool overwrite) {
  if (light_field.crs.empty()) {
    ThrowInvalid(path + ": the light field has no CRS (not geo-referenced): ODM's geo.txt "
                 "needs world coordinates");
  }
  if (light_field.views.empty()) ThrowInvalid(path + ": the light field has no views");
  std::vector<std::string> inputs;
  for (const View& view : light_field.views) {
    if (!view.image_path.empty()) inputs.push_back(view.image_path);
  }
  CheckOutputPath(path, inputs, "geo file");
  std::error_code error;
  if (!overwrite && fs::exists(path, error)) {
    ThrowInvalid(path + ": exists (give overwrite / --force to replace it)");
  }
  std::vector<Vec3d> world;
  for (size_t i = 0; i < light_field.views.size(); ++i) {
    const View& view = light_field.views[i];
    const std::string label = path + ": view " + std::to_string(i);
    if (view.name.empty()) ThrowInvalid(label + ": name: empty (ODM names images by their file)");
    if (view.name.find_first_of(" \t\r\n") != std::string::npos) {
      ThrowInvalid(label + " (" + view.name + "): name: contains white space, which geo.txt "
                   "separates fields by");
    }
    world.push_back(view.cam_from_world.Center() + light_field.origin);
  }
  const std::vector<Vec3d> geographic = TransformPoints(world, light_field.crs, "EPSG:4326", path);
  std::string text = light_field.crs + "\n";
  for (size_t i = 0; i < light_field.views.size(); ++i) {
    const View& view = light_field.views[i];
    const double bearing = GridBearingOfNorth(geographic[i].y, geographic[i].x, light_field.crs,
                                              path);
    const std::array<double, 3> ypr = YawPitchRollOfRotation(view.cam_from_world.rotation, bearing);
    text += view.name + " " + PreciseNumber(world[i].x) + " " + PreciseNumber(world[i].y) + " " +
            PreciseNumber(world[i].z) + " " + FormatNumber(ypr[0]) + " " +
            FormatNumber(OdmPitchFromGimbal(ypr[1])) + " " + FormatNumber(ypr[2]) + "\n";
  }
  WriteTextFileAtomic(path, text);
}

}  // namespace aos

namespace aos {

OdmGcpFile ReadOdmGcp(const std::string& path) {
  CheckRegularFile(path, "GCP file");
  const std::vector<std::pair<int, std::string>> lines = ContentLines(ReadTextFile(path));
  if (lines.empty()) {
    ThrowInvalid(path + ": empty: expected a projection line, then one line per ground point "
                 "sighting");
  }
  OdmGcpFile file;
  file.projection = lines.front().second;
  file.crs = OdmProjectionCrs(file.projection,
                              path + ": line " + std::to_string(lines.front().first));
  const char* const names[5] = {"geo_x", "geo_y", "geo_z", "im_x", "im_y"};
  for (size_t k = 1; k < lines.size(); ++k) {
    const auto& [number, text] = lines[k];
    const std::string where = path + ": line " + std::to_string(number);
    const std::vector<std::string> words = Words(text);
    if (words.size() < 6) {
      ThrowInvalid(where + ": expected geo_x geo_y geo_z im_x im_y image_name [gcp_name], got \"" +
                   text + "\"");
    }
    OdmGcp point;
    point.line = number;
    double v[5];
    for (int i = 0; i < 5; ++i) v[i] = ParseFiniteNumber(words[i], where, names[i]);
    point.position = Vec3d(v[0], v[1], v[2]);
    point.pixel = Vec2d(v[3], v[4]);
    if (point.pixel.x < -0.5 || point.pixel.y < -0.5) {
      ThrowInvalid(where + ": im_x, im_y: (" + FormatNumber(v[3]) + ", " + FormatNumber(v[4]) +
                   ") lies left of or above the image");
    }
    point.image = words[5];
    if (words.size() > 6) point.name = words[6];
    for (size_t i = 7; i < words.size(); ++i) {
      point.extras += (point.extras.empty() ? "" : " ") + words[i];
    }
    file.points.push_back(std::move(point));
  }
  if (file.points.empty()) ThrowInvalid(path + ": no ground points after the projection line");
  return file;
}

void WriteOdmGcp(const std::string& path, const OdmGcpFile& file, bool overwrite) {
  OdmProjectionCrs(file.projection, path + ": projection");
  if (file.projection.find_first_of("\r\n") != std::string::npos) {
    ThrowInvalid(path + ": projection: must be one line");
  }
  std::error_code error;
  if (!overwrite && fs::exists(path, error)) {
    ThrowInvalid(path + ": exists (give overwrite / --force to replace it)");
  }
  std::string text = file.projection + "\n";
  for (size_t i = 0; i < file.points.size(); ++i) {
    const OdmGcp& p = file.points[i];
    const std::string label = path + ": point " + std::to_string(i);
    for (const std::string* word : {&p.image, &p.name}) {
      if (word->find_first_of(" \t\r\n") != std::string::npos) {
        ThrowInvalid(label + ": \"" + *word + "\" contains white space, which the file "
                     "separates fields by");
      }
    }
    if (p.image.empty()) ThrowInvalid(label + ": image_name: empty");
    if (p.extras.find_first_of("\r\n") != std::string::npos) {
      ThrowInvalid(label + ": extras: must be one line");
    }
    if (p.name.empty() && !p.extras.empty()) {
      ThrowInvalid(label + ": extras need a gcp_name before them");
    }
    for (double value : {p.position.x, p.position.y, p.position.z, p.pixel.x, p.pixel.y}) {
      if (!std::isfinite(value)) ThrowInvalid(label + ": a number is not finite");
    }
    text += PreciseNumber(p.position.x) + " " + PreciseNumber(p.position.y) + " " +
            PreciseNumber(p.position.z) + " " + PreciseNumber(p.pixel.x) + " " +
            PreciseNumber(p.pixel.y) + " " + p.image;
    if (!p.name.empty()) text += " " + p.name;
    if (!p.extras.empty()) text += " " + p.extras;
    text += "\n";
  }
  WriteTextFileAtomic(path, text);
}

GcpCheckResult CheckGcps(const LightField& light_field, const OdmGcpFile& gcps,
                         const std::string& where) {
  if (light_field.crs.empty()) {
    ThrowInvalid(where + ": the light field has no CRS (not geo-referenced): ground control "
                 "needs world coordinates");
  }
  if (gcps.points.empty()) ThrowInvalid(where + ": no ground points");
  std::vector<Vec3d> positions;
  for (const OdmGcp& p : gcps.points) positions.push_back(p.position);
  const std::vector<Vec3d> world = TransformPoints(positions, gcps.crs, light_field.crs, where);
  GcpCheckResult result;
  double sum_px = 0.0, sum_m = 0.0;
  int ground_count = 0;
  for (size_t i = 0; i < gcps.points.size(); ++i) {
    const OdmGcp& p = gcps.points[i];
    const std::string label = where + ": line " + std::to_string(p.line);
    GcpResidual r;
    r.line = p.line;
    r.image = p.image;
    r.name = p.name;
    r.view = FindViewByName(light_field, p.image, label + ": image_name");
    const View& view = light_field.views[static_cast<size_t>(r.view)];
    const Vec3d local = world[i] - light_field.origin;
    const Vec3d in_cam = view.cam_from_world * local;
    if (!(in_cam.z > 0.0) || !view.camera.Project(in_cam, &r.predicted)) {
      ThrowInvalid(label + ": the ground point " + (p.name.empty() ? "" : p.name + " ") +
                   "is behind view " + std::to_string(r.view) + " (" + view.name +
                   ") or outside its field: check the CRS line and the poses");
    }
    r.observed = p.pixel + Vec2d(0.5, 0.5);
    r.error_px = glm::length(r.predicted - r.observed);
    // The marked pixel's ray to the plane z = the point's height.
    Vec3d ray_cam;
    r.ground_error_m = Vec2d(std::nan(""));
    r.ground_error_norm_m = std::nan("");
    if (view.camera.Unproject(r.observed, &ray_cam)) {
      const Vec3d direction = glm::transpose(view.cam_from_world.rotation) * ray_cam;
      const Vec3d centre = view.cam_from_world.Center();
      if (std::abs(direction.z) > 1e-12) {
        const double t = (local.z - centre.z) / direction.z;
        if (t > 0.0) {
          const Vec3d hit = centre + t * direction;
          r.ground_error_m = Vec2d(hit.x - local.x, hit.y - local.y);
          r.ground_error_norm_m = glm::length(r.ground_error_m);
          sum_m += r.ground_error_norm_m * r.ground_error_norm_m;
          result.max_ground_m = std::max(result.max_ground_m, r.ground_error_norm_m);
          ++ground_count;
        }
      }
    }
    sum_px += r.error_px * r.error_px;
    result.max_px = std::max(result.max_px, r.error_px);
    result.residuals.push_back(std::move(r));
  }
  result.rms_px = std::sqrt(sum_px / static_cast<double>(result.residuals.size()));
  result.rms_ground_m = ground_count > 0 ? std::sqrt(sum_m / ground_count) : std::nan("");
  if (ground_count == 0) result.max_ground_m = std::nan("");
  return result;
}

}  // namespace aos
