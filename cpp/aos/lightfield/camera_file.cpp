#include "aos/lightfield/camera_file.h"

#include <cmath>
#include <set>

#include <nlohmann/json.hpp>

#include "aos/util/error.h"
#include "aos/util/file_util.h"
#include "aos/util/json_file.h"

namespace aos {
namespace {

using json = nlohmann::json;

double Number(const json& j, const std::string& key, const std::string& file, bool required,
              double fallback = 0.0) {
  if (!j.contains(key)) {
    if (required) ThrowInvalid(Where(file, key + ": missing"));
    return fallback;
  }
  if (!j[key].is_number() || !std::isfinite(j[key].get<double>())) {
    ThrowInvalid(Where(file, key + ": must be a finite number"));
  }
  return j[key].get<double>();
}

LensCamera CameraFromJson(const json& j, const std::string& path);

}  // namespace

LensCamera ReadCameraFile(const std::string& path) {
  const json j = ParseJsonFile(path);
  return WithJsonErrorsNamed(path, [&] { return CameraFromJson(j, path); });
}

namespace {

LensCamera CameraFromJson(const json& j, const std::string& path) {
  if (!j.is_object() || !j.contains("format") || !j["format"].is_string() ||
      j["format"].get<std::string>() != "aos-camera") {
    ThrowInvalid(Where(path, "format: must be \"aos-camera\""));
  }
  static const std::set<std::string> kKeys{"format", "version", "model", "width", "height", "fx",
                                           "fy", "cx", "cy", "distortion", "xi", "skew",
                                           "calibration"};
  for (const auto& item : j.items()) {
    if (!kKeys.count(item.key())) ThrowInvalid(Where(path, item.key() + ": unknown key"));
  }
  if (Number(j, "version", path, true) != 1) ThrowInvalid(Where(path, "version: must be 1"));
  LensCamera camera;
  if (!j.contains("model") || !j["model"].is_string()) {
    ThrowInvalid(Where(path, "model: must be a string"));
  }
  camera.model = ParseLensModel(j["model"].get<std::string>(), path + ": model");
  const double width = Number(j, "width", path, true), height = Number(j, "height", path, true);
  if (width != std::floor(width) || height != std::floor(height) || width < 1 || height < 1 ||
      width > 65536 || height > 65536) {
    ThrowInvalid(Where(path, "width/height: must be integers 1..65536"));
  }
  camera.width = static_cast<int>(width);
  camera.height = static_cast<int>(height);
  camera.fx = Number(j, "fx", path, true);
  camera.fy = Number(j, "fy", path, true);
  camera.cx = Number(j, "cx", path, true);
  camera.cy = Number(j, "cy", path, true);
  camera.xi = Number(j, "xi", path, false);
  camera.skew = Number(j, "skew", path, false);
  if (j.contains("distortion")) {
    const json& d = j["distortion"];
    if (!d.is_array() || d.size() > 5) {
      ThrowInvalid(Where(path, "distortion: must be an array of at most 5 numbers"));
    }
    for (size_t i = 0; i < d.size(); ++i) {
      if (!d[i].is_number() || !std::isfinite(d[i].get<double>())) {
        ThrowInvalid(Where(path, "distortion[" + std::to_string(i) + "]: must be a finite number"));
      }
      camera.distortion[i] = d[i].get<double>();
    }
  }
  camera.Finalize(path);
  return camera;
}

}  // namespace

void WriteCameraFile(const std::string& path, const LensCamera& camera,
                     const std::string& calibration_json) {
  LensCamera checked = camera;
  checked.Finalize(path);
  nlohmann::ordered_json j;
  j["format"] = "aos-camera";
  j["version"] = 1;
  j["model"] = LensModelName(camera.model);
  j["width"] = camera.width;
  j["height"] = camera.height;
  j["fx"] = camera.fx;
  j["fy"] = camera.fy;
  j["cx"] = camera.cx;
  j["cy"] = camera.cy;
  j["distortion"] = camera.distortion;
  j["xi"] = camera.xi;
  j["skew"] = camera.skew;
  if (!calibration_json.empty()) j["calibration"] = nlohmann::ordered_json::parse(calibration_json);
  WriteTextFileAtomic(path, j.dump(2) + "\n");
}

}  // namespace aos
