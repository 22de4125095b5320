#pragma once
// The synthetic aperture: which views every render integrates at a focal point, and how. One
// block shared by the options of every render as their base (IntegralOptions in integral.h,
// MapOptions in map.h, PointIntegralOptions in surface_integral.h), so that its fields, their
// defaults, ranges and help are declared here only; each render reads them through its own
// options (options.aperture_radius), Python and the CLI under the same names.
//
// Contract
// - aperture_radius: metres, >= 0 or infinity. A perspective virtual camera takes the views
//   whose line from the focal point X through their centre crosses its lens plane within the
//   radius of the lens centre; an orthographic map, the views whose centre lies within the
//   radius of the vertical line through X. 0 takes the single nearest view, infinity every view.
// - view_indices: the views to integrate (indices into the light field, each once); empty = all.
// - min_view_angle_deg: rays meeting the focal plane (or the surface's up axis) at less than
//   this angle are ignored, [0, 90).
// - lens_tolerance_px: views with a lens model (lens.h): the largest error of a sample position,
//   view pixels, where the exact lens projection is replaced by local maps
//   (surface_integral.h), [0, 1]; 0 = project every sample exactly. Pinhole views ignore it.
// - num_threads: worker threads, -1 = all cores (util/parallel.h: kThreadCountRange).
// Ranges are checked by each render's Check() (CheckFieldRanges over its table, which lists
// these fields through ApertureOptions::Fields).
#include <limits>
#include <vector>

#include "aos/util/option_fields.h"
#include "aos/util/parallel.h"

namespace aos {

struct ApertureOptions {
  double aperture_radius = std::numeric_limits<double>::infinity();
  std::vector<int> view_indices;
  double min_view_angle_deg = 1.0;
  double lens_tolerance_px = 0.02;
  int num_threads = -1;

  // The field table (util/option_fields.h); the renders' tables include it.
  template <class Visit>
  static void Fields(Visit&& field) {
    using O = ApertureOptions;
    field(OptionField("aperture_radius", &O::aperture_radius, "m", Range::AtLeast(0.0),
                      "Radius of the synthetic aperture, metres: on the lens plane of a "
                      "perspective virtual camera, around the vertical line through the focal "
                      "point for a map; 0 = the single nearest view, inf = every view."));
    field(OptionField("view_indices", &O::view_indices, "", Range::Any(),
                      "Views to integrate (indices into the light field); empty means all "
                      "views. Reading returns a new list: assign a list to change it."));
    field(OptionField("min_view_angle_deg", &O::min_view_angle_deg, "deg",
                      Range::ClosedOpen(0.0, 90.0),
                      "Minimum angle between a view's ray and the focal plane, degrees, [0, "
                      "90); smaller (grazing) rays are ignored."));
    field(OptionField("lens_tolerance_px", &O::lens_tolerance_px, "px", Range::Closed(0.0, 1.0),
                      "Views with a lens model: the largest error of a sample position, view "
                      "pixels, [0, 1], where the exact lens projection is replaced by local "
                      "maps; 0 = project every sample exactly."));
    field(OptionField("num_threads", &O::num_threads, "", kThreadCountRange,
                      "Worker threads; -1 = all cores."));
  }
};

}  // namespace aos
