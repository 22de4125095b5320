#pragma once
// Light-field files.
//
// 1. The aos format (JSON, written by WriteLightField):
//   {
//     "format": "aos-lightfield", "version": 1,
//     "origin": [x, y, z],                 // world position of the local zero, double (e.g. UTM)
//     "crs": "EPSG:32633",                 // optional: CRS of origin + local (LightField::crs)
//     "cameras": {"cam0": {"model": "pinhole", "width": 512, "height": 512,
//                          "fx": 535.7, "fy": 535.7, "cx": 256, "cy": 256}},
//     "views": [{"image": "views/0000.png",  // relative to the JSON file's folder, or absolute
//                "name": "15.png",                // optional: View::name; default = "image"
//                "camera": "cam0",
//                "cam_from_world": {"rotation": [[r00, r01, r02], [r10, r11, r12], [r20, r21, r22]],
//                                   "translation": [t0, t1, t2]}}]
//   }
//   Optional "pose_source" (PoseSource in lightfield.h) says where estimated poses came from:
//   {"method": "colmap", "mean_reprojection_error_px", "median_depth", "pose_error",
//    "georeferenced", "georeference_rms_m", "world_frame", "unregistered": [frame names]}.
//   "crs" must be "EPSG:<code>" of a projected CRS in metres that PROJ knows (geodesy.h,
//   CheckLightFieldCrs); anything else is refused naming the file and "crs". "world_frame" only
//   describes a frame without an EPSG code ("the frame of gps.csv"); files written before "crs"
//   existed carried "UTM 33N (WGS84)" there: without a "crs", such a label (or a projected CRS's
//   name PROJ identifies) is read as crs "EPSG:32633" (a note says so) and world_frame emptied.
//   Poses map the local frame (world - origin) to OpenCV camera axes, metres. Cameras, poses,
//   the origin and the pose record are read and written by the shared codec (json_codec.h: the
//   same camera fields as a camera file, "fov_deg" for a pinhole, lens models with
//   "distortion", "xi", "skew"); a view's camera is View::camera. Unknown keys are refused,
//   named by their JSON pointer ("lf.json: /cameras/cam0/fxx: unknown key").
//
// 2. The JKU-ICG/AOS poses.json: {"images": [{"imagefile": "a.tiff", "M3x4": [[...], [...], [...]]}]}
//   M3x4 is the world-to-camera matrix [R | t] (numbers or numeric strings), OpenCV axes. The
//   file has no intrinsics: LoadOptions::fov_deg gives the horizontal field of view and the image
//   size comes from the frames (principal point at the centre). A frame is looked up by its name,
//   then by the same stem with another image extension (.png, .tif, .tiff, .jpg, .jpeg, .exr); a
//   note says which file was used. The frames folder defaults to ../images beside the poses
//   folder, then the poses file's own folder.
//
// Frame lookup (both formats): a frame whose file is missing under its exact name is found under
// the one name that differs only in case (a.jpg -> a.JPG; a note says so); two such files are an
// error naming both. With LoadOptions::load_images false, the aos format opens no frame at all
// (poses and cameras only; a missing frame is no error), and a JKU poses file opens only the
// first frame it finds, to size its one camera. Such views have no image: the renderer refuses
// them naming the view ("view 3 (a.png): image: no pixels (image not loaded)").
//
// Masks (LoadOptions::mask, mask_dir) apply to decoded frames only: without load_images they
// are not opened. A mask with no valid pixel is no error (the frame contributes nothing) but a
// note says so. WriteLightField refuses a masked light field (its frames hold premultiplied
// values and a weight channel, which the aos JSON cannot describe): write the light field loaded
// without the mask and give the mask again when loading it.
//
// Errors name the file, the entry and the field: "poses.json: image 17 (B05.tiff): M3x4:
// rotation is not orthonormal (max |R^T R - I| = 0.3)".
#include <string>
#include <vector>

#include "aos/lightfield/lightfield.h"
#include "aos/util/option_fields.h"
#include "aos/util/parallel.h"
#include "aos/util/progress.h"

namespace aos {

struct LoadOptions {
  // Horizontal field of view of the frames in degrees, (0, 180); required for JKU poses.json,
  // ignored for the aos format (which stores its cameras). 0 = not given.
  double fov_deg = 0.0;
  // Folder holding the frames of a JKU poses.json; empty = look beside the poses file (see above).
  std::string images_dir;
  // Frames are decoded when true; false loads poses and cameras only (images stay empty, and
  // the frame files need not exist; see "Frame lookup" above).
  bool load_images = true;
  // Frames become one-channel luminance at load (LuminanceImage in image.h: Rec. 601 weights
  // 0.299 R + 0.587 G + 0.114 B, alpha dropped; grey frames unchanged), e.g. false-colour thermal
  // frames integrated as grey. The pixel type is kept.
  bool grey = false;
  // One mask image for every frame (mask.h): non-zero pixels are valid, zero ones (a letterbox,
  // a burnt-in logo) are left out of every average; the mask must be the frames' size. Frames
  // (after grey) of C <= 3 channels become C + 1 (a premultiplied weight channel) and the light
  // field is masked (lightfield.h). Empty = no mask. Not with mask_dir.
  std::string mask;
  // A folder with one mask per frame, found by the frame's file name without its extension
  // (a.JPG -> a.png, any image extension, case ignored); a frame without one is an error
  // naming it. Empty = none. Not with mask.
  std::string mask_dir;
  // Worker threads for decoding frames; -1 = all cores.
  int num_threads = -1;
  void Check() const;

  // The field table (util/option_fields.h): every field once, in declaration order.
  template <class Visit>
  static void Fields(Visit&& field) {
    using O = LoadOptions;
    field(OptionField("fov_deg", &O::fov_deg, "deg", Range::Open(0.0, 180.0).Or(0.0),
                      "Horizontal field of view of the frames, degrees (JKU poses.json only); "
                      "0 = not given.")
              .Flag("frames-fov-deg"));  // beside the virtual camera's --fov-deg
    field(OptionField("images_dir", &O::images_dir, "", Range::Any(),
                      "Folder of the frames (JKU poses.json); '' = ../images beside it."));
    field(OptionField("load_images", &O::load_images, "", Range::Any(),
                      "Decode the frames; false loads poses and cameras only."));
    field(OptionField("grey", &O::grey, "", Range::Any(),
                      "Integrate the frames as grey: RGB(A) frames become one-channel luminance "
                      "at load, Rec. 601 weights 0.299 R + 0.587 G + 0.114 B (e.g. false-colour "
                      "thermal frames)."));
    field(OptionField("mask", &O::mask, "", Range::Any(),
                      "Mask image for every frame, the frames' size: zero pixels (a letterbox, a "
                      "burnt-in logo) are left out of every average, non-zero ones are valid; "
                      "'' = none. Not with mask_dir."));
    field(OptionField("mask_dir", &O::mask_dir, "", Range::Any(),
                      "Folder with one mask per frame, named like the frame (any image "
                      "extension, case ignored; a frame without one is an error); '' = none."));
    field(OptionField("num_threads", &O::num_threads, "", kThreadCountRange,
                      "Worker threads decoding frames; -1 = all cores."));
  }
};

struct LoadResult {
  LightField light_field;
  std::string format;               // "aos" or "jku"
  std::vector<std::string> notes;   // things the user should know (e.g. substituted frame names)
};

// Loads a light field, detecting the format from the JSON content.
LoadResult LoadLightField(const std::string& path, const LoadOptions& options = {},
                          ProgressSink* progress = nullptr);

// Decodes the frames of views `indices` of a light field loaded without images (or with some),
// from their image_path, as LoadLightField does with `options` (grey, mask, mask_dir,
// num_threads; the other fields are ignored), and stores them in those views; the light field
// becomes masked when a mask is given. Views with an image are decoded again. What a process
// that renders part of a large light field uses to hold only the frames it needs
// (python/aos/distributed.py). Throws std::invalid_argument naming the view and its file (an
// unreadable or missing frame, a size that disagrees with the camera, channels that differ
// between the frames decoded together), or "indices" for an index that is no view.
void LoadViewImages(LightField& light_field, const std::vector<int>& indices,
                    const LoadOptions& options = {});

// Drops the decoded images of views `indices` (their poses, cameras and image_path stay).
void DropViewImages(LightField& light_field, const std::vector<int>& indices);

struct WriteLightFieldOptions {
  // Folder (relative to the JSON file's folder) where view images are written when they have no
  // image_path; views with an image_path are referenced, not rewritten.
  std::string images_subdir = "views";
  // Image file extension for written views.
  std::string image_extension = ".png";
};

// Writes `light_field` in the aos format to `path` (and frames without a source file into
// images_subdir). Atomic per file; refuses to overwrite any view's source image.
void WriteLightField(const std::string& path, const LightField& light_field,
                     const WriteLightFieldOptions& options = {});

// Parses a number that may be written as a JSON number or a numeric string; throws
// std::invalid_argument "<where>: <text> is not a number" otherwise (exposed for tests).
double ParseNumberText(const std::string& text, const std::string& where);

}  // namespace aos
