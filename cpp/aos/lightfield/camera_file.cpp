#include "aos/lightfield/camera_file.h"

#include <nlohmann/json.hpp>

#include "aos/util/error.h"
#include "aos/util/file_util.h"
#include "aos/lightfield/json_codec.h"
#include "aos/util/json_file.h"

namespace aos {
namespace {

using json = nlohmann::json;

LensCamera CameraFromJson(const json& j, const std::string& path) {
  const JsonPath top(path);
  if (!j.is_object() || !j.contains("format") || !j["format"].is_string() ||
      j["format"].get<std::string>() != "aos-camera") {
    ThrowInvalid(Where(path, "format: must be \"aos-camera\""));
  }
  const json& version = RequireMember(j, "version", top);
  if (!version.is_number() || version.get<double>() != 1) (top / "version").Fail("must be 1");
  // The camera's own fields are the codec's; the file adds its header and the free-form record.
  return ReadCameraJson(j, top, {"format", "version", "calibration"});
}

}  // namespace

LensCamera ReadCameraFile(const std::string& path) {
  const json j = ParseJsonFile(path);
  return WithJsonErrorsNamed(path, [&] { return CameraFromJson(j, path); });
}

void WriteCameraFile(const std::string& path, const LensCamera& camera,
                     const std::string& calibration_json) {
  LensCamera checked = camera;
  checked.Finalize(path);
  nlohmann::ordered_json j;
  j["format"] = "aos-camera";
  j["version"] = 1;
  j.update(CameraToJson(camera));
  if (!calibration_json.empty()) j["calibration"] = nlohmann::ordered_json::parse(calibration_json);
  WriteTextFileAtomic(path, j.dump(2) + "\n");
}

}  // namespace aos
