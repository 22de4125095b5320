#pragma once
// Camera files: one lens camera as JSON (written by `aos-render calibrate`, by `aos-render
// camera` for a known lens without a checkerboard, and by aos.write_camera_file; read by
// `rectify --camera`, `poses --camera-file` and aos.read_camera_file). The format, key by key:
// docs/terrain-and-maps.md, "Known lenses without a checkerboard".
//
//   {"format": "aos-camera", "version": 1, "model": "radtan" | "pinhole" | "fisheye" | "omnidir",
//    "width": 640, "height": 480, "fx": ..., "fy": ..., "cx": ..., "cy": ...,
//    "distortion": [up to 5 numbers, see lens.h], "xi": 0, "skew": 0,   // lens models
//    "calibration": {...}}   // optional, free-form (RMS error, frames used)
//
// The camera fields are the shared codec's (json_codec.h), as in a light field's "cameras": a
// pinhole may give "fov_deg" instead of fx, fy, cx, cy; distortion, xi and skew are optional
// (written for lens models only). cx, cy follow aos's pixel convention (pixel centres at +0.5;
// OpenCV's cx + 0.5). Unknown keys are refused; errors name the file and the key path
// ("cam.json: /fxx: unknown key").
#include <string>

#include "aos/geometry/lens.h"

namespace aos {

LensCamera ReadCameraFile(const std::string& path);

// Writes atomically; `calibration_json` (a JSON object's text, or empty) is stored as is.
void WriteCameraFile(const std::string& path, const LensCamera& camera,
                     const std::string& calibration_json = "");

}  // namespace aos
