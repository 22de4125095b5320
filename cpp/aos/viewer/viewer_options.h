#pragma once
// The browser viewer's own settings (the server in python/aos/viewer: where it listens, how many
// pages it serves, whether it opens a browser). Declared here, in the one field table every
// option has (util/option_fields.h), so that `aos-render view`'s flags, `aos.ViewerOptions` and
// `aos.view(...)`'s defaults, and the CLI's hand-off to Python come from one definition.
//
// Contract
// - host: the address to listen on; a loopback address by default. Anything else makes the
//   viewer reachable from other machines (the viewer warns); never empty.
// - port: TCP port, 0..65535; 0 = any free port.
// - max_pages: pages (browser tabs, WebSockets) served at once, 1..4096; the next is refused
//   until one closes.
// - render_workers: threads rendering page requests, 1..64.
// - open_browser: true / false, or unset = where a desktop session exists.
// Check() throws std::invalid_argument naming the field.
//
// ViewParams: what one page request of the viewer may set (python/aos/viewer/session.py turns
// the page's JSON or query text into these fields by their table and calls Check). Focus,
// aperture, the views' time window, the virtual camera and the display mapping; the table's
// ranges keep one request from asking for unbounded work (at most 2048 x 2048 pixels).
// Check(view_count) also needs pose_view < view_count and
// 0 <= view_first < view_last <= view_count.
#include <limits>
#include <optional>
#include <string>

#include "aos/util/error.h"
#include "aos/util/option_fields.h"

namespace aos {

struct ViewerOptions {
  std::string host = "127.0.0.1";
  int port = 0;
  int max_pages = 32;
  int render_workers = 1;
  std::optional<bool> open_browser;

  void Check() const {
    CheckFieldRanges(*this);
    if (host.empty()) ThrowInvalid("host: must name an address (127.0.0.1 = this machine only)");
  }

  // The field table (util/option_fields.h): every field once, in declaration order.
  template <class Visit>
  static void Fields(Visit&& field) {
    using O = ViewerOptions;
    field(OptionField("host", &O::host, "", Range::Any(),
                      "Address to listen on; anything but a loopback address makes the viewer "
                      "reachable from other machines (a warning says so)."));
    field(OptionField("port", &O::port, "", Range::Closed(0, 65535),
                      "TCP port; 0 = any free port."));
    field(OptionField("max_pages", &O::max_pages, "", Range::Closed(1, 4096),
                      "Pages (browser tabs) served at once; the next is refused until one "
                      "closes."));
    field(OptionField("render_workers", &O::render_workers, "", Range::Closed(1, 64),
                      "Threads rendering the pages' requests."));
    field(OptionField("open_browser", &O::open_browser, "", Range::Any(),
                      "Open a browser on the viewer's page: True, False, or None = where a "
                      "desktop session exists."));
  }
};

struct ViewParams {
  std::string mode = "perspective";
  double focal_height = 0.0;
  double tilt_x_deg = 0.0;
  double tilt_y_deg = 0.0;
  bool surface = false;
  double surface_offset = 0.0;
  double aperture_radius = std::numeric_limits<double>::infinity();
  int view_first = 0;
  int view_last = 0;  // exclusive; the session sets it to the view count
  int pose_view = 0;
  double orbit_deg = 0.0;
  double tilt_deg = 0.0;
  double pan_x = 0.0;
  double pan_y = 0.0;
  double pan_z = 0.0;
  double fov_deg = 0.0;
  int width = 0;
  int height = 0;
  std::string range = "views";
  double gain = 1.0;
  double offset = 0.0;
  std::string colormap = "grey";
  bool preview = false;

  void Check(int view_count) const {
    CheckFieldRanges(*this);
    if (pose_view >= view_count) {
      ThrowInvalid("pose_view: no view " + std::to_string(pose_view) + " (the light field has " +
                   std::to_string(view_count) + " views)");
    }
    if (!(view_first < view_last && view_last <= view_count)) {
      ThrowInvalid("view_first, view_last: need 0 <= first < last <= " +
                   std::to_string(view_count) + ", got " + std::to_string(view_first) + ", " +
                   std::to_string(view_last));
    }
  }

  // The field table (util/option_fields.h): every field once, in declaration order.
  template <class Visit>
  static void Fields(Visit&& field) {
    using O = ViewParams;
    constexpr double kMaxCoordinate = 1.0e7;  // metres (UTM northings are < 1e7)
    field(OptionField("mode", &O::mode, "", Range::OneOf("perspective|map"),
                      "perspective (a pinhole virtual camera) or map (render_map: orthographic, "
                      "looking straight down, north-up in the frame's own x/y)."));
    field(OptionField("focal_height", &O::focal_height, "m",
                      Range::Closed(-kMaxCoordinate, kMaxCoordinate),
                      "The focal plane z = H, local frame, metres."));
    field(OptionField("tilt_x_deg", &O::tilt_x_deg, "deg", Range::Closed(-80.0, 80.0),
                      "The focal plane's normal tilted about the y axis, degrees, about the "
                      "point (pivot x, pivot y, H) under the base camera."));
    field(OptionField("tilt_y_deg", &O::tilt_y_deg, "deg", Range::Closed(-80.0, 80.0),
                      "The focal plane's normal tilted about the x axis, degrees."));
    field(OptionField("surface", &O::surface, "", Range::Any(),
                      "Focus on the session's focal surface (a mesh or DEM given at start) "
                      "instead of the plane."));
    field(OptionField("surface_offset", &O::surface_offset, "m", Range::Closed(-1.0e4, 1.0e4),
                      "The focal surface moved this far up (towards the views), metres."));
    field(OptionField("aperture_radius", &O::aperture_radius, "m", Range::AtLeast(0.0),
                      "Radius of the synthetic aperture, metres (the renders' aperture_radius, "
                      "render/aperture.h); inf = every view."));
    field(OptionField("view_first", &O::view_first, "", Range::AtLeast(0),
                      "First view of the half-open range of view indices to integrate (a time "
                      "window of the flight)."));
    field(OptionField("view_last", &O::view_last, "", Range::AtLeast(0),
                      "One past the last view of that range."));
    field(OptionField("pose_view", &O::pose_view, "", Range::AtLeast(0),
                      "The base pose of the virtual camera: a recorded view."));
    field(OptionField("orbit_deg", &O::orbit_deg, "deg", Range::Closed(-360.0, 360.0),
                      "Orbit about the vertical axis through the point where the base camera's "
                      "axis meets the focal plane, degrees."));
    field(OptionField("tilt_deg", &O::tilt_deg, "deg", Range::Closed(-89.0, 89.0),
                      "Tilt about the camera's x axis through that point, degrees."));
    field(OptionField("pan_x", &O::pan_x, "m", Range::Closed(-1.0e5, 1.0e5),
                      "Camera moved along the world x axis, metres."));
    field(OptionField("pan_y", &O::pan_y, "m", Range::Closed(-1.0e5, 1.0e5),
                      "Camera moved along the world y axis, metres."));
    field(OptionField("pan_z", &O::pan_z, "m", Range::Closed(-1.0e5, 1.0e5),
                      "Camera moved along the world z axis, metres."));
    field(OptionField("fov_deg", &O::fov_deg, "deg", Range::Closed(0.0, 179.0),
                      "Horizontal field of view (zoom), degrees; 0 = the pose view's."));
    field(OptionField("width", &O::width, "px", Range::Closed(8, 2048).Or(0),
                      "Image width, pixels; 0 = the pose view's."));
    field(OptionField("height", &O::height, "px", Range::Closed(8, 2048).Or(0),
                      "Image height, pixels; 0 = the pose view's."));
    field(OptionField("range", &O::range, "", Range::OneOf("views|auto"),
                      "Display range: views (the frames' type range, 0..255 for 8-bit) or auto "
                      "(1st..99th percentile of the covered pixels)."));
    field(OptionField("gain", &O::gain, "", Range::Closed(0.01, 100.0),
                      "Display: multiplies the normalised value about offset."));
    field(OptionField("offset", &O::offset, "", Range::Closed(-10.0, 10.0),
                      "Display: the normalised value gain scales about."));
    field(OptionField("colormap", &O::colormap, "", Range::OneOf("grey|turbo|iron"),
                      "Display colour map of single-channel data."));
    field(OptionField("preview", &O::preview, "", Range::Any(),
                      "A control is being dragged: the full-size image from a spread subset of "
                      "the selected views (every k-th along the flight, as many as fit the "
                      "frame budget), never a downscaled image."));
  }
};

}  // namespace aos
