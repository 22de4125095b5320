#pragma once
// COLMAP sparse models: reading them, mapping their cameras to aos lens models, and turning the
// registered images into a light field.
//
// Input: a model folder as COLMAP writes it (e.g. sparse/0), in binary (cameras.bin, images.bin,
// points3D.bin) or text form (cameras.txt, images.txt, points3D.txt). As COLMAP's own
// Reconstruction::Read does, the binary files are used when all three exist, else the text files.
// Newer COLMAP versions also write rigs and frames files; they are not needed (images.bin/.txt
// still carry each image's full cam_from_world) and are ignored.
//
// Conventions (checked against COLMAP's source, src/colmap/sensor/models.h and
// src/colmap/scene/reconstruction_io_{binary,text}.cc)
// - Pixels: COLMAP's image origin is the upper-left corner of the upper-left pixel, whose centre
//   is at (0.5, 0.5) (models.h: "the upper left pixel center has coordinate (0.5, 0.5)"; its
//   default principal point is (width / 2, height / 2)). That is the aos convention (pinhole.h),
//   so principal points are taken over unchanged (no 0.5 shift, unlike OpenCV's).
// - Poses: an image's QW QX QY QZ TX TY TZ is cam_from_world (world -> camera, Hamilton quaternion
//   w first), camera axes x right, y down, z forward: the same as aos's cam_from_world. The
//   quaternion is normalised before use; a zero or non-finite one is an error.
// - Binary files are little-endian: counts uint64; camera: id uint32, model id int32, width and
//   height uint64, the model's parameters as doubles; image: id uint32, qvec 4 doubles, tvec 3
//   doubles, camera id uint32, name (bytes up to a NUL), num points2D uint64, then per point
//   x, y (doubles) and point3D id (uint64; all ones = none); point: id uint64, xyz 3 doubles,
//   rgb 3 uint8, error double, track length uint64, then (image id uint32, point2D index uint32).
// - Text files: '#' lines and blank lines are skipped; images.txt has two lines per image, the
//   second (possibly empty) listing X Y POINT3D_ID triples (-1 = none); a missing last second
//   line means no points. Names may contain spaces (the rest of the first line after CAMERA_ID).
// - mean_reprojection_error_px is COLMAP's Reconstruction::ComputeMeanReprojectionError: the
//   plain mean of the per-point errors over the points that have one (error != -1), not weighted
//   by track length; 0 when there are none.
//
// Camera models (parameter order from models.h) and their aos lens (lens.h):
//   SIMPLE_PINHOLE f cx cy, PINHOLE fx fy cx cy                        -> pinhole
//   SIMPLE_RADIAL f cx cy k, RADIAL f cx cy k1 k2,
//   OPENCV fx fy cx cy k1 k2 p1 p2,
//   FULL_OPENCV fx fy cx cy k1 k2 p1 p2 k3 k4 k5 k6 (only with k4 = k5 = k6 = 0, the rational
//   denominator)                                                    -> radtan {k1, k2, p1, p2, k3}
//                                                    (pinhole when every distortion term is 0)
//   OPENCV_FISHEYE fx fy cx cy k1 k2 k3 k4, SIMPLE_RADIAL_FISHEYE f cx cy k,
//   RADIAL_FISHEYE f cx cy k1 k2, SIMPLE_FISHEYE f cx cy, FISHEYE fx fy cx cy
//       (COLMAP's equidistant model theta_d = theta (1 + k1 theta^2 + k2 theta^4 + ...),
//       theta = atan(r / z))                                       -> fisheye {k1, k2, k3, k4}
//   Other models (FOV, THIN_PRISM_FISHEYE, RAD_TAN_THIN_PRISM_FISHEYE, SIMPLE_DIVISION, DIVISION,
//   EUCM, EQUIRECTANGULAR) are read but have no aos lens: LensFromColmapCamera refuses them.
//
// Errors: std::invalid_argument naming the file, the line (text) or entry (binary: index and
// id) and the field, e.g. "sparse/0/images.txt: line 7: image 3: QW..QZ: zero quaternion" or
// "sparse/0/points3D.bin: point 12 of 40 (id 977): track[2]: file ends early (...)". Counts
// in binary files are checked against the bytes left before anything is allocated, so a damaged
// file fails cleanly. Also refused: duplicate ids or image names, an image whose camera id is
// not in the cameras file, non-finite numbers, sizes beyond 2^31 - 1 pixels, trailing bytes.
// Cross-references between images and points are not required to be complete (a model whose
// points3D file was emptied still reads).
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "aos/geometry/lens.h"
#include "aos/geometry/rigid.h"
#include "aos/lightfield/lightfield.h"
#include "aos/util/progress.h"

namespace aos {

struct ColmapCamera {
  uint32_t camera_id = 0;
  std::string model;           // COLMAP's model name, e.g. "OPENCV"
  int width = 0;               // pixels
  int height = 0;
  std::vector<double> params;  // in COLMAP's order for `model` (see above)
};

struct ColmapImage {
  uint32_t image_id = 0;
  std::string name;            // relative to the images folder COLMAP was given
  uint32_t camera_id = 0;
  Rigid3d cam_from_world;      // from the normalised quaternion and the translation
  size_t num_points2d = 0;     // keypoints listed for the image
  size_t num_observations = 0; // those with a 3-D point
};

struct ColmapPoint {
  uint64_t point_id = 0;
  Vec3d position{0.0};               // model (world) coordinates
  std::array<uint8_t, 3> color{};    // RGB
  double error_px = -1.0;            // COLMAP's mean reprojection error of the point; -1 = none
  size_t track_length = 0;           // number of observations
};

struct ColmapModel {
  // Where it was read from (empty for a model built in memory); used in messages.
  std::string folder;
  std::string format;  // "binary" or "text"
  std::string cameras_path, images_path, points_path;

  std::vector<ColmapCamera> cameras;  // in file order
  std::vector<ColmapImage> images;    // registered images, in file order
  std::vector<ColmapPoint> points;    // in file order
  size_t num_observations = 0;        // sum of the images' num_observations
  double mean_reprojection_error_px = 0.0;  // COLMAP's definition (see above)

  // The camera with `camera_id`, or nullptr.
  const ColmapCamera* FindCamera(uint32_t camera_id) const;
};

// Reads the model in `folder` (binary preferred, see above). Throws std::invalid_argument naming
// the folder when the files are missing (with a hint when they sit in a numbered subfolder).
// `progress` is polled for cancellation every 4096 lines or entries (throws aos::Cancelled).
ColmapModel ReadColmapModel(const std::string& folder, ProgressSink* progress = nullptr);

// The model names COLMAP knows, by binary model id (0..17); "" for an unknown id.
std::string ColmapModelName(int model_id);
// The number of parameters of a COLMAP model, or -1 for an unknown name.
int ColmapModelNumParams(const std::string& model_name);

// The aos lens for a COLMAP camera (table above), finalised (LensCamera::Finalize). Throws
// std::invalid_argument "<where>: camera <id> (<model>): <reason>" for models aos cannot
// represent, FULL_OPENCV with a non-zero k4/k5/k6, a wrong parameter count or bad values.
LensCamera LensFromColmapCamera(const ColmapCamera& camera, const std::string& where);

// The frames under `folder` (searched recursively; .png .jpg .jpeg .tif .tiff .exr in any case),
// as paths relative to `folder` with '/' separators, in natural order (NaturalLess in
// util/file_util.h: "2.png" before "10.png"). Throws std::invalid_argument if
// `folder` is not a folder.
std::vector<std::string> ListFrameFiles(const std::string& folder);

// The view order of `frames` (given in natural name order) from their capture times: by time
// (stable: ties keep name order) when every frame has one, else by name. Warns when only some
// frames have a time, or when the two orders disagree (with an example).
struct FrameOrder {
  std::vector<size_t> order;         // view i is frames[order[i]]
  std::string by = "name";           // "time" (capture times) or "name"
  std::string time_source;           // where the times came from, when by time
  std::vector<std::string> warnings;
};
FrameOrder CaptureTimeOrder(const std::vector<std::string>& frames,
                            const std::vector<std::optional<double>>& times,
                            const std::string& time_source);

struct ColmapImportOptions {
  // Frames are decoded when true; false reads poses and cameras only (the frame files are still
  // required and their headers checked against the cameras; images stay empty).
  bool load_images = true;
  // Worker threads for decoding frames; -1 = all cores.
  int num_threads = -1;
  void Check() const;
};

struct ColmapImport {
  // One view per registered image, in capture-time order (else by name): image_path = images_dir / name, camera and
  // lens from LensFromColmapCamera (pinhole models: View::lens is the plain pinhole), the
  // image's cam_from_world. origin stays 0: the model's frame is the light field's.
  LightField light_field;
  std::vector<std::string> registered;    // image names, in view order
  // Frames in images_dir (ListFrameFiles) that the model does not register.
  std::vector<std::string> unregistered;
  // The view order: "time" when every registered frame has an EXIF capture time
  // (DateTimeOriginal + SubSecTimeOriginal, ReadCaptureTime), else "name" (natural order). A
  // malformed time tag counts as none, with a warning naming the file (COLMAP needs no time).
  std::string order = "name";
  std::string time_source;
  std::vector<std::string> warnings;      // the order's (CaptureTimeOrder)
};

// Builds the light field of `model`'s registered images found in `images_dir`. Throws
// std::invalid_argument naming the image for a missing or unreadable frame, a frame whose size
// differs from its COLMAP camera, an unsupported camera model, or a model with no images.
ColmapImport ImportColmapModel(const ColmapModel& model, const std::string& images_dir,
                               const ColmapImportOptions& options = {},
                               ProgressSink* progress = nullptr);

}  // namespace aos
