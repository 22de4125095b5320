#include "aos/lightfield/json_codec.h"

#include <cmath>

#include "aos/util/error.h"

namespace aos {

using nlohmann::json;
using nlohmann::ordered_json;

JsonPath JsonPath::operator/(const std::string& key) const {
  std::string escaped;
  for (char c : key) {
    if (c == '~') {
      escaped += "~0";
    } else if (c == '/') {
      escaped += "~1";
    } else {
      escaped += c;
    }
  }
  return JsonPath(file_, pointer_ + "/" + escaped).Noted(note_);
}

JsonPath JsonPath::operator/(size_t index) const {
  return JsonPath(file_, pointer_ + "/" + std::to_string(index)).Noted(note_);
}

std::string JsonPath::Text() const {
  const std::string place = pointer_.empty() ? file_ : file_ + ": " + pointer_;
  return note_.empty() ? place : place + " (" + note_ + ")";
}

void JsonPath::Fail(const std::string& reason) const { ThrowInvalid(Text() + ": " + reason); }

std::string DescribeJson(const json& value) {
  if (value.is_string()) return "\"" + value.get<std::string>() + "\"";
  std::string text = value.dump();
  if (text.size() > 60) text = text.substr(0, 57) + "...";
  return text;
}

void RequireKnownKeys(const json& value, std::initializer_list<const char*> known,
                      const JsonPath& at, std::initializer_list<const char*> more) {
  if (!value.is_object()) at.Fail("expected an object, got " + DescribeJson(value));
  for (const auto& item : value.items()) {
    bool found = false;
    for (const char* key : known) found = found || item.key() == key;
    for (const char* key : more) found = found || item.key() == key;
    if (!found) {
      std::string list;
      for (const char* key : known) list += (list.empty() ? "" : ", ") + std::string(key);
      for (const char* key : more) list += (list.empty() ? "" : ", ") + std::string(key);
      (at / item.key()).Fail("unknown key (known: " + list + ")");
    }
  }
}

const json& RequireMember(const json& value, const char* key, const JsonPath& at) {
  if (!value.is_object()) at.Fail("expected an object, got " + DescribeJson(value));
  auto it = value.find(key);
  if (it == value.end()) (at / key).Fail("missing");
  return *it;
}

double ReadJsonNumber(const json& value, const JsonPath& at) {
  if (!value.is_number()) at.Fail("expected a number, got " + DescribeJson(value));
  const double number = value.get<double>();
  if (!std::isfinite(number)) at.Fail("is not a finite number");
  return number;
}

int ReadJsonInt(const json& value, const JsonPath& at, int lo, int hi) {
  if (!value.is_number()) at.Fail("expected a whole number, got " + DescribeJson(value));
  const double number = value.get<double>();
  if (!(number >= lo && number <= hi) || number != std::floor(number)) {
    at.Fail("expected a whole number in " + std::to_string(lo) + ".." + std::to_string(hi) +
            ", got " + DescribeJson(value));
  }
  return static_cast<int>(number);
}

std::string ReadJsonString(const json& value, const JsonPath& at) {
  if (!value.is_string()) at.Fail("expected a string, got " + DescribeJson(value));
  std::string text = value.get<std::string>();
  if (text.empty()) at.Fail("is empty");
  return text;
}

Vec3d ReadVec3Json(const json& value, const JsonPath& at) {
  if (!value.is_array() || value.size() != 3) {
    at.Fail("expected 3 numbers, got " + DescribeJson(value));
  }
  Vec3d v;
  for (size_t i = 0; i < 3; ++i) v[static_cast<int>(i)] = ReadJsonNumber(value[i], at / i);
  return v;
}

ordered_json Vec3ToJson(const Vec3d& value) { return ordered_json::array({value.x, value.y, value.z}); }

Rigid3d ReadPoseJson(const json& value, const JsonPath& at) {
  RequireKnownKeys(value, {"rotation", "translation"}, at);
  const JsonPath rotation_at = at / "rotation";
  const json& rotation = RequireMember(value, "rotation", at);
  if (!rotation.is_array() || rotation.size() != 3) {
    rotation_at.Fail("expected 3 rows of 3 numbers, got " + DescribeJson(rotation));
  }
  std::array<double, 12> rows{};
  for (size_t r = 0; r < 3; ++r) {
    const Vec3d row = ReadVec3Json(rotation[r], rotation_at / r);
    for (int c = 0; c < 3; ++c) rows[4 * r + c] = row[c];
  }
  const Vec3d translation = ReadVec3Json(RequireMember(value, "translation", at), at / "translation");
  for (int r = 0; r < 3; ++r) rows[4 * r + 3] = translation[r];
  const Rigid3d pose = Rigid3d::FromMatrix3x4(rows);
  if (auto problem = DescribeInvalidRigid(pose)) at.Fail(*problem);
  return pose;
}

ordered_json PoseToJson(const Rigid3d& cam_from_world) {
  ordered_json rotation = ordered_json::array();
  for (int r = 0; r < 3; ++r) rotation.push_back(Vec3ToJson(Row(cam_from_world.rotation, r)));
  return {{"rotation", rotation}, {"translation", Vec3ToJson(cam_from_world.translation)}};
}

Plane ReadPlaneJson(const json& value, const JsonPath& at) {
  RequireKnownKeys(value, {"point", "normal"}, at);
  Plane plane{ReadVec3Json(RequireMember(value, "point", at), at / "point"),
              ReadVec3Json(RequireMember(value, "normal", at), at / "normal")};
  if (!(glm::length(plane.normal) > 0.0)) (at / "normal").Fail("must not be zero");
  return plane;
}

ordered_json PlaneToJson(const Plane& plane) {
  return {{"point", Vec3ToJson(plane.point)}, {"normal", Vec3ToJson(plane.normal)}};
}

LensCamera ReadCameraJson(const json& value, const JsonPath& at,
                          std::initializer_list<const char*> other_keys) {
  RequireKnownKeys(value, {"model", "width", "height", "fov_deg", "fx", "fy", "cx", "cy",
                           "distortion", "xi", "skew"},
                   at, other_keys);
  LensCamera camera;
  // "model" may be left out for a pinhole (stack.json files were read so).
  std::string model_name = "pinhole";
  if (auto it = value.find("model"); it != value.end()) model_name = ReadJsonString(*it, at / "model");
  camera.model = ParseLensModel(model_name, (at / "model").Text());
  camera.width = ReadJsonInt(RequireMember(value, "width", at), at / "width", 1, kMaxImageSide);
  camera.height = ReadJsonInt(RequireMember(value, "height", at), at / "height", 1, kMaxImageSide);
  const bool has_any_intrinsic = value.contains("fx") || value.contains("fy") ||
                                 value.contains("cx") || value.contains("cy");
  const bool lens_by_fov = value.contains("fov_deg") && !camera.IsPinhole();
  if (value.contains("fov_deg") && has_any_intrinsic) {
    at.Fail("give either fov_deg or fx, fy, cx, cy, not both");
  }
  if (lens_by_fov) {
    // A lens model's fov_deg goes through its radial map (LensFromFov), once its distortion
    // and xi are read (below), as a scene's camera does.
  } else if (value.contains("fov_deg")) {
    const double fov_deg = ReadJsonNumber(value["fov_deg"], at / "fov_deg");
    if (!(fov_deg > 0.0 && fov_deg < 180.0)) {
      (at / "fov_deg").Fail("must be in (0, 180) degrees (got " + FormatNumber(fov_deg) + ")");
    }
    const PinholeCamera pinhole = PinholeCamera::FromFov(camera.width, camera.height, fov_deg);
    camera.fx = pinhole.fx;
    camera.fy = pinhole.fy;
    camera.cx = pinhole.cx;
    camera.cy = pinhole.cy;
  } else {
    if (!has_any_intrinsic) at.Fail("needs fx, fy, cx, cy or fov_deg");
    camera.fx = ReadJsonNumber(RequireMember(value, "fx", at), at / "fx");
    camera.fy = ReadJsonNumber(RequireMember(value, "fy", at), at / "fy");
    camera.cx = ReadJsonNumber(RequireMember(value, "cx", at), at / "cx");
    camera.cy = ReadJsonNumber(RequireMember(value, "cy", at), at / "cy");
  }
  if (auto it = value.find("distortion"); it != value.end()) {
    if (!it->is_array() || it->size() > 5) {
      (at / "distortion").Fail("expected an array of at most 5 numbers, got " + DescribeJson(*it));
    }
    for (size_t i = 0; i < it->size(); ++i) {
      camera.distortion[i] = ReadJsonNumber((*it)[i], at / "distortion" / i);
    }
  }
  if (auto it = value.find("xi"); it != value.end()) camera.xi = ReadJsonNumber(*it, at / "xi");
  if (auto it = value.find("skew"); it != value.end()) camera.skew = ReadJsonNumber(*it, at / "skew");
  if (lens_by_fov) {
    const double fov_deg = ReadJsonNumber(value["fov_deg"], at / "fov_deg");
    const double skew = camera.skew;
    camera = LensFromFov(camera.model, camera.width, camera.height, fov_deg, camera.distortion,
                         camera.xi, at.Text());
    camera.skew = skew;
  }
  if (camera.IsPinhole() &&
      (camera.xi != 0.0 || camera.skew != 0.0 ||
       camera.distortion != std::array<double, 5>{0, 0, 0, 0, 0})) {
    at.Fail("distortion/xi/skew: a pinhole camera has none (all zero or absent; model radtan, "
            "fisheye or omnidir for a lens)");
  }
  camera.Finalize(at.Text());
  return camera;
}

ordered_json CameraToJson(const LensCamera& camera) {
  ordered_json j = {{"model", LensModelName(camera.model)},
                    {"width", camera.width},
                    {"height", camera.height},
                    {"fx", camera.fx},
                    {"fy", camera.fy},
                    {"cx", camera.cx},
                    {"cy", camera.cy}};
  if (!camera.IsPinhole()) {
    j["distortion"] = camera.distortion;
    j["xi"] = camera.xi;
    j["skew"] = camera.skew;
  }
  return j;
}

}  // namespace aos
