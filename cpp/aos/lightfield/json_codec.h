#pragma once
// The one JSON codec for the shapes aos's file formats share: a camera (LensCamera, every model),
// a pose (Rigid3d, cam_from_world), a Vec3 and a plane. The light field (formats.h), the camera
// file (camera_file.h), the focal stack's stack.json (focal_stack.h), the pose record
// (the light field's "pose_source") and the simulator's truth.json read and write them only here,
// so every format accepts the same fields by the same rules.
//
// Shapes
//   camera: {"model": "pinhole" | "radtan" | "fisheye" | "omnidir", "width": W, "height": H,
//            "fx": .., "fy": .., "cx": .., "cy": ..,                 (or, for a pinhole only,
//            "fov_deg": F: square pixels, centred principal point, 0 < F < 180)
//            "distortion": [up to 5 numbers, see lens.h], "xi": .., "skew": ..}
//     "model" may be left out for a pinhole. width/height: whole numbers 1..kMaxImageSide. distortion/xi/skew are optional (0); a
//     pinhole takes them only as zeros (the camera file wrote them so). cx, cy follow aos's pixel
//     convention (pixel centres at +0.5). The camera is finalized (LensCamera::Finalize).
//   pose:   {"rotation": [[3], [3], [3]] (rows), "translation": [3]}, a rigid transform
//           (finite, orthonormal, no reflection).
//   vec3:   [x, y, z], finite numbers.
//   plane:  {"point": vec3, "normal": vec3 (not zero)}.
//
// Errors: every reader refuses keys it does not define and throws std::invalid_argument naming
// the file and the key path as a JSON pointer: "stack.json: /camera/fxx: unknown key (known:
// ...)", "lf.json: /views/3/cam_from_world/rotation: expected 3 rows of 3 numbers".
//
// Internal header: it includes nlohmann/json (through json_file.h), a private dependency of the
// core.
#include <initializer_list>
#include <string>
#include <utility>

#include "aos/geometry/lens.h"
#include "aos/geometry/rigid.h"
#include "aos/util/json_file.h"

namespace aos {

// A place in a JSON file: the file and a JSON pointer ("" is the document).
class JsonPath {
 public:
  explicit JsonPath(std::string file, std::string pointer = "")
      : file_(std::move(file)), pointer_(std::move(pointer)) {}
  // The member `key` (escaped as RFC 6901 says: ~ -> ~0, / -> ~1) or the element `index`.
  JsonPath operator/(const std::string& key) const;
  JsonPath operator/(const char* key) const { return *this / std::string(key); }
  JsonPath operator/(size_t index) const;

  // The same place with a note for people, kept by every child path and written after the
  // pointer: "lf.json: /views/3/cam_from_world (view 3: a.png): ...".
  JsonPath Noted(std::string note) const {
    JsonPath noted = *this;
    noted.note_ = std::move(note);
    return noted;
  }

  const std::string& file() const { return file_; }
  const std::string& pointer() const { return pointer_; }
  // "file: /a/b" ("file" for the document).
  std::string Text() const;
  // Throws std::invalid_argument "file: /a/b: reason".
  [[noreturn]] void Fail(const std::string& reason) const;

 private:
  std::string file_;
  std::string pointer_;
  std::string note_;
};

// A JSON value as short text for messages.
std::string DescribeJson(const nlohmann::json& value);

// `value` must be an object whose keys are all in `known` (or `more`); else "<at>/<key>: unknown
// key (known: ...)". Also refuses a value that is not an object.
void RequireKnownKeys(const nlohmann::json& value, std::initializer_list<const char*> known,
                      const JsonPath& at, std::initializer_list<const char*> more = {});

// The member `key` of the object `value`; "<at>/<key>: missing" if absent.
const nlohmann::json& RequireMember(const nlohmann::json& value, const char* key,
                                    const JsonPath& at);

// Scalars: a finite number; a whole number in [lo, hi]; a non-empty string.
double ReadJsonNumber(const nlohmann::json& value, const JsonPath& at);
int ReadJsonInt(const nlohmann::json& value, const JsonPath& at, int lo, int hi);
std::string ReadJsonString(const nlohmann::json& value, const JsonPath& at);

Vec3d ReadVec3Json(const nlohmann::json& value, const JsonPath& at);
nlohmann::ordered_json Vec3ToJson(const Vec3d& value);

Rigid3d ReadPoseJson(const nlohmann::json& value, const JsonPath& at);
nlohmann::ordered_json PoseToJson(const Rigid3d& cam_from_world);

Plane ReadPlaneJson(const nlohmann::json& value, const JsonPath& at);
nlohmann::ordered_json PlaneToJson(const Plane& plane);

// Reads the camera whose fields are the members of `value`; `other_keys` are members the caller
// reads itself (the camera file's "format", for example) and are not refused here.
LensCamera ReadCameraJson(const nlohmann::json& value, const JsonPath& at,
                          std::initializer_list<const char*> other_keys = {});
// The camera's fields (model, size, intrinsics; distortion, xi and skew for lens models).
nlohmann::ordered_json CameraToJson(const LensCamera& camera);

}  // namespace aos
