#pragma once
// A light field: views, each an image with a camera (pinhole or lens model) and a cam_from_world
// pose.
//
// World frame. Poses and every geometric input of the renderer (virtual camera, focal plane) are
// in the light field's local frame, metres. `origin` is where that local frame's zero lies in
// the user's world (geo-referenced) coordinates, e.g. UTM easting/northing/altitude; it is kept
// in double precision and never enters float arithmetic: world = origin + local. Poses far from
// zero (millions of metres) also work, since the renderer composes transforms in double precision
// relative to the virtual camera, but a local origin keeps files readable.
#include <optional>
#include <string>
#include <vector>

#include "aos/geometry/lens.h"
#include "aos/geometry/pinhole.h"
#include "aos/geometry/rigid.h"
#include "aos/image/image.h"
#include "aos/image/radiometry.h"

namespace aos {

struct View {
  std::string name;        // a label for messages (file name for loaded views)
  std::string image_path;  // source file, if the view was loaded from one (else empty)
  // The view's one camera model; its size must match the image. kPinhole (fx, fy, cx, cy, no
  // distortion) is the plain pinhole camera, camera.Pinhole() its PinholeCamera; other models
  // (raw frames through a lens) are sampled through the lens (direct sampling, integral.h) and
  // must be finalized (LensCamera::Finalize).
  LensCamera camera;
  Rigid3d cam_from_world;  // local frame -> camera (OpenCV axes)
  Image image;             // native pixel type, border 1 (see Image)
};

// Where estimated poses came from and how good they are (aos-render poses, sfm/); stored in
// the light-field file as "pose_source".
struct PoseSource {
  std::string method;                     // e.g. "colmap"
  double mean_reprojection_error_px = 0.0;
  double median_depth = 0.0;              // of the reconstructed points, light-field units
  double pose_error = 0.0;                // e = error_px * median_depth / fx, light-field units
  bool georeferenced = false;             // units are metres (else the method's arbitrary scale)
  double georeference_rms_m = 0.0;        // centre residuals of the geo-referencing
  // A description of the world frame when it has no EPSG code (e.g. "the frame of gps.csv":
  // metres in a frame the positions file did not name); empty when LightField::crs says it.
  // Superseded by LightField::crs: files written before it carried "UTM 33N (WGS84)" here,
  // which the reader turns into crs = "EPSG:32633".
  std::string world_frame;
  std::vector<std::string> unregistered;  // frames that got no pose
};

struct LightField {
  Vec3d origin{0.0};  // world position of the local frame's zero (double; e.g. UTM)
  std::string crs;  // "EPSG:<code>" of the world coordinates (origin + local), or empty = not geo-referenced
  std::vector<View> views;
  std::optional<PoseSource> pose_source;  // set when the poses were estimated
  // The views' last channel is a mask weight and the others are premultiplied by it (loaded
  // with LoadOptions::mask or mask_dir, formats.h): a frame of C channels holds
  // (v_1 m, ..., v_C m, m * full range) with m 1 on valid pixels, 0 on masked ones. The
  // renderer (integral.h) divides by the weight and returns C channels.
  bool masked = false;
  // The frames are read as grey (one-channel luminance, LoadOptions::grey) whenever this light
  // field is loaded from its file: false-colour thermal frames imported with `grey`
  // (import-telemetry --grey). Stored in the file as "grey": true.
  bool grey = false;
  // Set when the pixel values measure temperature (radiometric thermal frames: FLIR radiometric
  // JPEGs converted at import, 16-bit counts with a linear calibration): kelvin =
  // kelvin_per_unit * value + kelvin_offset, for the frames and every render of them. The frames
  // then have one channel (two when masked). Stored in the file as "radiometry".
  std::optional<Radiometry> radiometry;

  // Total bytes of the decoded frames (width * height * channels * value size, summed).
  size_t ImageBytes() const;
};

// Every field of `light_field` but its views (origin, crs, pose_source, masked, grey, radiometry): the start of a
// light field derived from it view by view (rectify), so that none of its fields is dropped.
// A field added to LightField is added here (test_python_api.py checks that every field bound
// in Python survives rectify, copy, pickle and files).
LightField EmptyLike(const LightField& light_field);

// Builds a view from an image, checking it. The image is copied with a replicated border if it
// has none (else its pixels are shared). Throws std::invalid_argument naming `name` and the field
// for a bad camera, a camera that disagrees with the image size, an invalid pose, or a
// non-finite pixel in a float image (loaded frames are checked the same way).
// A lens camera is used as given (finalized here if it was not); a PinholeCamera becomes
// LensCamera::FromPinhole(camera).
View MakeView(std::string name, const LensCamera& camera, const Rigid3d& cam_from_world,
              Image image, std::string image_path = "");
View MakeView(std::string name, const PinholeCamera& camera, const Rigid3d& cam_from_world,
              Image image, std::string image_path = "");

// Checks one view (camera fields, a lens model finalized, camera vs image size, pose finite and orthonormal, image
// present with border >= 1). `where` prefixes the message, e.g. "lf.json: view 3 (a.png)".
void CheckView(const View& view, const std::string& where);

// The index of the view named `name`: its View::name or that name's file name, with or without
// the extension ("DJI_0042", "DJI_0042.JPG", "images/DJI_0042.JPG"), or its frame file
// (image_path: its file name, stem, or trailing folders and file name, "views/0004.png"); exact
// matches first, then ignoring case. Throws std::invalid_argument "<where>: ..." when no view or more than one
// matches, listing the matching names or, for an unknown name, up to five close ones.
int FindViewByName(const LightField& light_field, const std::string& name,
                   const std::string& where = "view");
// How FindViewByName lists a view: "name (view i)", or "name (view i, file folder/file.png)"
// where its frame file is named otherwise.
std::string ViewNameAndFile(const View& view, int index);

// Checks every view and that all views share one channel count (at least 2 when masked).
void CheckLightField(const LightField& light_field, const std::string& where = "light field");

}  // namespace aos
