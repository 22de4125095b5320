#pragma once
// The JSON form of a FocalSurface (for Options structs holding one: lightfield/options_json.h).
//
// Contract
// - A plane is {"plane": {"point": [x, y, z], "normal": [x, y, z]}} (local frame).
// - A mesh or DEM read from a file as it is (FocalSurface::file()) is {"file": "<path>"}, read
//   back with FocalSurface::Read: what the CLI hands to Python (`view`, `map --workers`). A
//   receiver that needs the surface in the light field's CRS transforms it (InCrs) as the CLI
//   does.
// - A number is read as the horizontal plane z = that number.
// - Anything else (a surface built in memory, transformed between CRSs, a depth map) has no JSON
//   form: writing it throws std::invalid_argument saying so. Reading refuses other keys, naming
//   the JSON pointer.
//
// Internal header: it includes nlohmann/json (through options_json.h).
#include <string>

#include "aos/lightfield/options_json.h"
#include "aos/render/focal_surface.h"

namespace aos {

template <>
struct JsonForm<FocalSurface> {
  static nlohmann::ordered_json ToJson(const FocalSurface& surface) {
    nlohmann::ordered_json object = nlohmann::ordered_json::object();
    if (surface.kind() == FocalSurfaceKind::kPlane) {
      object["plane"] = PlaneToJson(surface.plane());
    } else if (!surface.file().empty()) {
      object["file"] = surface.file();
    } else {
      ThrowInvalid(std::string("a ") + FocalSurfaceKindName(surface.kind()) +
                   " surface not read from a file as it is has no JSON form (hand over the "
                   "file it came from)");
    }
    return object;
  }

  static FocalSurface FromJson(const nlohmann::json& json, const JsonPath& at) {
    if (json.is_number()) {
      return FromPlane(Plane::AtHeight(json.get<double>()), at);
    }
    if (!json.is_object() || json.size() != 1 || !(json.contains("plane") || json.contains("file"))) {
      at.Fail("expected a number (the height of a horizontal plane), {\"plane\": {...}} or "
              "{\"file\": PATH}, got " + DescribeJson(json));
    }
    if (json.contains("plane")) return FromPlane(ReadPlaneJson(json["plane"], at / "plane"), at);
    const nlohmann::json& file = json["file"];
    if (!file.is_string()) (at / "file").Fail("expected a path, got " + DescribeJson(file));
    try {
      return FocalSurface::Read(file.get<std::string>());
    } catch (const std::invalid_argument& error) {
      (at / "file").Fail(error.what());
    }
  }

 private:
  static FocalSurface FromPlane(const Plane& plane, const JsonPath& at) {
    try {
      return FocalSurface::FromPlane(plane);
    } catch (const std::invalid_argument& error) {
      at.Fail(error.what());
    }
  }
};

}  // namespace aos
