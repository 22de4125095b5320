#pragma once
// Rectification: resample a raw frame taken through a lens model (lens.h) into the perspective
// (pinhole) image of a virtual camera at the same centre, with a chosen field of view,
// resolution and orientation; e.g. the paper's 80 degrees out of a 178-degree omni lens.
//
// Contract
// - The rectified camera is PinholeCamera::FromFov(width, height, fov_deg), turned relative to
//   the lens: a ray d in its frame is R d in the lens's frame, R = Rz(roll) Rx(pitch) Ry(yaw)
//   (yaw about the y axis, pitch about x, roll about the optical axis z; degrees).
// - Every output pixel centre's ray must project into the raw frame inside its valid field and
//   its image area [0, w] x [0, h]; else the requested view is not covered and it is an error
//   naming the field of view and RectifyOptions::fill (nothing is resampled outside the lens's
//   image). With fill, such pixels are 0 (black) instead, and Rectifier::uncovered counts them.
// - Values: bilinear interpolation (cv::remap, replicated border), in the input's type and
//   channels (8/16-bit rounded to nearest, float unchanged).
//
// - Memory: the maps (8 bytes an output pixel) and RectifyLightField's new views are checked
//   against the memory budget (util/memory.h) before they are allocated.
//
// Throws std::invalid_argument naming the option or the uncovered view, or the memory needed.
#include "aos/geometry/lens.h"
#include <vector>

#include "aos/image/image.h"
#include "aos/lightfield/lightfield.h"
#include "aos/util/progress.h"
#include "aos/util/option_fields.h"

namespace aos {

struct RectifyOptions {
  // Horizontal field of view of the rectified image, degrees, (0, 180).
  double fov_deg = 80.0;
  // Output size, pixels; 0 = the raw frame's size.
  int width = 0;
  int height = 0;
  // Orientation of the rectified camera relative to the lens, degrees.
  double yaw_deg = 0.0;
  double pitch_deg = 0.0;
  double roll_deg = 0.0;
  // Pixels the lens does not cover become 0 (black) instead of an error: explicitly requested
  // (a rectified view wider than the lens, e.g. to keep a fisheye's corners in a wide frame).
  bool fill = false;

  void Check() const;
  // The field table (util/option_fields.h): every field once, in declaration order.
  template <class Visit>
  static void Fields(Visit&& field) {
    using O = RectifyOptions;
    field(OptionField("fov_deg", &O::fov_deg, "deg", Range::Any(),
                      "Horizontal field of view of the rectified image, degrees, (0, 180).")
              .Flag("rectified-fov-deg"));  // not the raw frames'
    field(OptionField("width", &O::width, "", Range::Any(),
                      "Output width, pixels; 0 = the raw frame's."));
    field(OptionField("height", &O::height, "", Range::Any(),
                      "Output height, pixels; 0 = the raw frame's."));
    field(OptionField("yaw_deg", &O::yaw_deg, "deg", Range::Any(),
                      "Turn about the lens's y axis, degrees."));
    field(OptionField("pitch_deg", &O::pitch_deg, "deg", Range::Any(),
                      "Turn about the lens's x axis, degrees."));
    field(OptionField("roll_deg", &O::roll_deg, "deg", Range::Any(),
                      "Turn about the optical axis, degrees."));
    field(OptionField("fill", &O::fill, "", Range::Any(),
                      "Pixels the lens does not cover become 0 (black) instead of an error."));
  }
};

struct Rectifier {
  PinholeCamera camera;          // the rectified camera
  Mat3d lens_from_rectified{1.0};
  // Raw-frame sample positions per output pixel (pixel-index space, OpenCV's convention).
  std::vector<float> map_x, map_y;
  int64_t uncovered = 0;  // output pixels outside the lens's coverage (0 unless options.fill)
};

// Builds the resampling maps once for a lens and options (reused for every frame).
// `progress` is polled for cancellation (aos::Cancelled) once per row of the maps.
Rectifier MakeRectifier(const LensCamera& lens, const RectifyOptions& options,
                        ProgressSink* progress = nullptr);

// The rectified size for `lens` under `options` (options.width/height, 0 = the lens's), and the
// bytes MakeRectifier's maps take for it.
void RectifiedSize(const LensCamera& lens, const RectifyOptions& options, int* width, int* height);
uint64_t RectifierBytes(const LensCamera& lens, const RectifyOptions& options);

// Resamples one raw frame (the lens's size; any type but uint32, 1..4 channels).
Image Rectify(const Rectifier& rectifier, const Image& raw);

struct RectifyLightFieldResult {
  LightField light_field;   // every view pinhole: lens views rectified, pinhole views as they were
  int rectified_views = 0;  // views that went through a lens model
};

// Rectifies every lens view of `light_field` (one Rectifier per distinct lens): its image is
// resampled, its camera becomes the rectified pinhole camera and its pose turns with it
// (cam_from_world of the rectified camera = lens_from_rectified^T * the lens's); pinhole views
// are copied unchanged. Names, origin and pose source are kept (rectified views have no
// image_path: their pixels are new). Throws
// std::invalid_argument "<field>: ... (view <name>)" for a lens the options do not fit, and
// "rectify: ..." when the new views and maps exceed the memory budget; the
// progress stage is "rectify" (one unit per view), and cancellation throws aos::Cancelled.
RectifyLightFieldResult RectifyLightField(const LightField& light_field,
                                          const RectifyOptions& options,
                                          ProgressSink* progress = nullptr);

}  // namespace aos
