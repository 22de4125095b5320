#pragma once
// Flight planning: the waypoints of a synthetic aperture (where the drone stops to take each
// image), the flight's length and time, and the ground sampling resolution (Eq. 2) at its
// altitude; exported as CSV, GeoJSON and KML in WGS84 and drawn as a PNG map.
//
// Contract
// - Frame. Positions are planned in a metric WORLD frame: x east, y north (a projected CRS in
//   metres such as UTM, named by `crs`, or a local frame when `crs` is empty). With
//   coordinates = "latlon" the shape is given as (latitude, longitude) pairs in degrees (WGS84);
//   it is projected through PROJ to the UTM zone of its centre, which becomes the plan's CRS.
//   Headings and bearings are compass degrees: clockwise from +y (north).
// - Shapes (the aperture, the area the images are taken over):
//     circle     centre and radius_m;
//     sector     centre (the apex), radius_m, sector_start_deg (bearing of its first edge) and
//                sector_angle_deg (0, 360], clockwise from the first edge;
//     rectangle  centre, width_m (across the heading) and length_m (along heading_deg);
//     polygon    `vertices` (>= 3, closed implicitly, not self-intersecting);
//     line       `vertices` (>= 2): a polyline flown from the first vertex to the last.
//   Boundaries count as inside (tolerance 1e-6 m).
// - Patterns (for every shape but line). Spacings grow linearly with the distance r from the
//   growth centre (the circle's or sector's centre, the rectangle's centre, the polygon's vertex
//   mean): s(r) = s0 (1 + (outer_scale - 1) min(r / R, 1)), R the largest distance from the
//   growth centre to the shape's boundary; outer_scale = 1 keeps them constant.
//     scan     parallel lines along heading_deg, spacing_m apart (across), shots along_spacing_m
//              apart on each line; both lattices are anchored at the growth centre (a line and
//              a shot through it, the others stepped outwards), so shots line up across lines.
//              Lines are flown alternately in opposite directions (boustrophedon); a line with
//              fewer than min_shots_per_line shots inside the shape is not flown.
//     grid     the scan pattern with along_spacing_m = spacing_m (a square lattice).
//     circles  concentric rings around the growth centre, spacing_m apart (a shot at the centre
//              when it is inside), shots about along_spacing_m apart on each ring (an integer
//              number per full ring, starting at bearing 0), kept where inside the shape, rings
//              flown alternately clockwise and anticlockwise.
//   The line shape takes shots every along_spacing_m from its first vertex (and at its last).
// - Altitude. altitude_m is the height above the ground (AGL). Without a DEM the ground is the
//   plane z = ground_height_m. With `dem` (a mesh, OBJ or PLY, or a raster GDAL reads, in the
//   plan's world frame) the ground under each shot is the DEM's height there: altitude_mode
//   "terrain" keeps the AGL at every shot, "constant" flies at one altitude, altitude_m above
//   the DEM at the growth centre (refused where that is less than min_clearance_m above the
//   terrain under a shot). terrain_up says which way the DEM's z points ("+z", or "-z" for frames
//   with z down such as JKU's F0).
// - Time. The path is the polyline through the shots in order (no take-off or landing legs);
//   flight time = length / ground_speed_mps + shots x hover_s. frames_per_minute = shots / time.
// - Resolution: Eq. 2 (metrics/resolution.h) of a pinhole camera of image_width x image_height
//   pixels and a horizontal field of view fov_deg (square pixels) looking straight down from
//   altitude_m. The defaults are the AOS paper's camera (Appendix A: 1871 x 1871, 80 degrees).
// - Bounds. Before a waypoint is stored, a first pass walks the pattern without storing it (only
//   the positions that can lie inside the shape are visited: the chord of each scan line, the
//   arc of each ring within a sector) and counts the shots and the path's length. A plan of more
//   than max_waypoints shots, more scan lines or rings across the aperture than max_waypoints, a
//   plan over the battery budget (without a DEM, or at a constant altitude, where the length is
//   known before the heights) or one whose waypoints would not fit the memory budget
//   (util/memory.h: AOS_MEMORY_LIMIT_MB) is refused then, with its figures, before anything is
//   allocated for it. The count is the generated plan's, exactly (the two passes share one walk).
// - Cancellation. PlanFlight and the writers poll `progress` (Cancelled(): Ctrl-C from the CLI
//   or Python) in every loop over shots, lines or pixels and throw aos::Cancelled.
// - Warnings (FlightPlanResult::warnings): the spacing is wider than the aperture (one line or
//   ring), the plan takes more than 90% of the battery, terrain-following changes the altitude.
//
// Throws std::invalid_argument naming the field ("spacing_m: ...", "vertices: ...") for bad
// options: non-finite or non-positive spacings, speeds and altitudes, sector angles outside
// (0, 360], open (fewer than 3 distinct vertices) or self-intersecting polygons, coordinates in
// degrees given as metres of a projected CRS (or metres given as latitudes), a shot outside the
// DEM or below the terrain, no shot at all, a plan over the battery budget (battery_min), over
// max_waypoints or over the memory budget.
// Nothing is written by PlanFlight; the writers below write one file each, atomically.
#include <array>
#include <cstdint>
#include <iosfwd>
#include <string>
#include <vector>

#include "aos/image/image.h"
#include "aos/util/progress.h"
#include "aos/util/option_fields.h"

namespace aos {

struct FlightPlanOptions {
  // Aperture shape: circle, sector, rectangle, polygon or line.
  std::string shape = "circle";
  // How centre and vertices are given: "world" (x, y metres in `crs` or a local frame) or
  // "latlon" (latitude, longitude degrees, WGS84).
  std::string coordinates = "world";
  // CRS of the world frame ("EPSG:32633", any projected CRS in metres PROJ knows); empty = a
  // local frame (no WGS84 export). Set by the plan for coordinates = "latlon".
  std::string crs;
  // Centre of a circle, sector or rectangle: (x, y) metres, or (latitude, longitude) degrees.
  std::array<double, 2> center{0.0, 0.0};
  // Radius of a circle or sector, metres (> 0).
  double radius_m = 15.0;
  // Sector: bearing of its first edge, compass degrees; and its angle, degrees in (0, 360].
  double sector_start_deg = 0.0;
  double sector_angle_deg = 90.0;
  // Rectangle: size across and along heading_deg, metres (> 0).
  double width_m = 30.0;
  double length_m = 30.0;
  // Polygon corners or line points, (x, y) or (latitude, longitude) each.
  std::vector<std::array<double, 2>> vertices;

  // Pattern: scan, grid or circles (not used by the line shape).
  std::string pattern = "scan";
  // Distance between scan lines or rings at the growth centre, metres (> 0).
  double spacing_m = 3.0;
  // Distance between shots along a line or ring at the growth centre, metres (> 0); 0 = spacing_m.
  double along_spacing_m = 1.0;
  // Spacing at the aperture's edge over spacing at its centre (>= 1; 1 = constant spacing).
  double outer_scale = 1.0;
  // Direction of the scan lines (and of the rectangle's length), compass degrees.
  double heading_deg = 0.0;
  // Scan lines with fewer shots inside the shape are not flown (>= 1; a line grazing the edge).
  int min_shots_per_line = 2;

  // Height above the ground, metres (> 0).
  double altitude_m = 20.0;
  // "terrain" (constant height above the DEM) or "constant" (one altitude); without a DEM the
  // two agree.
  std::string altitude_mode = "terrain";
  // Terrain: a mesh (OBJ, PLY) or raster (GeoTIFF, ...) in the world frame; empty = flat ground.
  std::string dem;
  // Height of the flat ground without a DEM, world z metres.
  double ground_height_m = 0.0;
  // Which way the DEM's (and the world's) z points: "+z" (up) or "-z" (down, JKU's F0).
  std::string terrain_up = "+z";
  // A constant-altitude shot must be at least this high above the terrain under it, metres (>= 0).
  double min_clearance_m = 2.0;

  // Ground speed between shots, metres per second (> 0).
  double ground_speed_mps = 1.0;
  // Time spent at each shot to stabilise and take the image, seconds (>= 0).
  double hover_s = 1.0;
  // Flight time one battery allows, minutes (> 0; infinity = no budget): a longer plan is
  // refused. 25 min: a mid-size survey drone's endurance with a reserve.
  double battery_min = 25.0;
  // Most shots a plan may have (>= 1), and most scan lines or rings across the aperture: a larger
  // plan is refused before it is generated. 10^6 shots: about 6 days of flying at 2 s a shot,
  // 64 MB of waypoints and 100 MB of CSV.
  int64_t max_waypoints = 1000000;

  // Camera for the sampling resolution (Eq. 2): image size, pixels, and horizontal field of view,
  // degrees in (0, 180). Default: the AOS paper's camera (Appendix A).
  int image_width = 1871;
  int image_height = 1871;
  double fov_deg = 80.0;

  // Throws std::invalid_argument naming the field.
  void Check() const;
  // The field table (util/option_fields.h): every field once, in declaration order.
  template <class Visit>
  static void Fields(Visit&& field) {
    using O = FlightPlanOptions;
    field(OptionField("shape", &O::shape, "", Range::OneOf("circle|sector|rectangle|polygon|line"),
                      "circle, sector, rectangle, polygon or line."));
    field(OptionField("coordinates", &O::coordinates, "", Range::OneOf("world|latlon"),
                      "world (x, y metres) or latlon (latitude, longitude degrees, WGS84)."));
    field(OptionField("crs", &O::crs, "", Range::Any(),
                      "CRS of world coordinates (projected, metres); '' = local frame."));
    field(OptionField("center", &O::center, "", Range::Any(),
                      "Centre of a circle, sector or rectangle: (x, y) or (lat, lon)."));
    field(OptionField("radius_m", &O::radius_m, "m", Range::Any(),
                      "Radius of a circle or sector, metres (> 0)."));
    field(OptionField("sector_start_deg", &O::sector_start_deg, "deg", Range::Any(),
                      "Sector: bearing of its first edge, degrees."));
    field(OptionField("sector_angle_deg", &O::sector_angle_deg, "deg", Range::Any(),
                      "Sector: its angle, degrees in (0, 360]."));
    field(OptionField("width_m", &O::width_m, "m", Range::Any(),
                      "Rectangle: size across the heading, metres."));
    field(OptionField("length_m", &O::length_m, "m", Range::Any(),
                      "Rectangle: size along the heading, metres."));
    field(OptionField("vertices", &O::vertices, "", Range::Any(),
                      "Polygon corners or line points, (x, y) or (lat, lon)."));
    field(OptionField("pattern", &O::pattern, "", Range::OneOf("scan|grid|circles"),
                      "scan, grid or circles."));
    field(OptionField("spacing_m", &O::spacing_m, "m", Range::Any(),
                      "Distance between lines or rings at the centre, metres."));
    field(OptionField("along_spacing_m", &O::along_spacing_m, "m", Range::Any(),
                      "Distance between shots along a line or ring at the centre, metres; 0 = "
                      "spacing_m."));
    field(OptionField("outer_scale", &O::outer_scale, "", Range::Any(),
                      "Spacing at the edge over spacing at the centre (>= 1)."));
    field(OptionField("heading_deg", &O::heading_deg, "deg", Range::Any(),
                      "Compass direction of the scan lines, degrees."));
    field(OptionField("min_shots_per_line", &O::min_shots_per_line, "", Range::AtLeast(1),
                      "Scan lines with fewer shots inside the shape are not flown (>= 1)."));
    field(OptionField("altitude_m", &O::altitude_m, "m", Range::Any(),
                      "Height above the ground, metres (> 0)."));
    field(OptionField("altitude_mode", &O::altitude_mode, "", Range::OneOf("terrain|constant"),
                      "terrain or constant."));
    field(OptionField("dem", &O::dem, "", Range::Any(),
                      "Terrain mesh (OBJ, PLY) or raster path; '' = flat ground."));
    field(OptionField("ground_height_m", &O::ground_height_m, "m", Range::Any(),
                      "Flat ground's z without a DEM, metres."));
    field(OptionField("terrain_up", &O::terrain_up, "", Range::OneOf("+z|-z"),
                      "+z or -z (z down, JKU's F0)."));
    field(OptionField("min_clearance_m", &O::min_clearance_m, "m", Range::Any(),
                      "Least height above the terrain of a constant-altitude shot, metres."));
    field(OptionField("ground_speed_mps", &O::ground_speed_mps, "m/s", Range::Any(),
                      "Ground speed, m/s (> 0)."));
    field(OptionField("hover_s", &O::hover_s, "s", Range::Any(),
                      "Time at each shot, seconds (>= 0)."));
    field(OptionField("battery_min", &O::battery_min, "", Range::Any(),
                      "Flight time one battery allows, minutes (inf: none)."));
    field(OptionField("max_waypoints", &O::max_waypoints, "", Range::Any(),
                      "Most shots (and scan lines or rings) a plan may have; a larger one is "
                      "refused first."));
    field(OptionField("image_width", &O::image_width, "", Range::AtLeast(1),
                      "Camera for Eq. 2: width, pixels."));
    field(OptionField("image_height", &O::image_height, "", Range::AtLeast(1),
                      "Camera for Eq. 2: height, pixels."));
    field(OptionField("fov_deg", &O::fov_deg, "deg", Range::Any(),
                      "Camera for Eq. 2: horizontal field of view, degrees."));
  }
};

struct Waypoint {
  double x = 0.0, y = 0.0, z = 0.0;  // world frame, metres
  double ground_z = 0.0;             // terrain (or flat ground) height under the shot, world z
  double agl_m = 0.0;                // height above that ground, metres
  double latitude_deg = 0.0;         // WGS84; NaN without a CRS
  double longitude_deg = 0.0;
  int line = 0;                      // scan line or ring index (0 for the line shape)
};

struct FlightPlanResult {
  std::vector<Waypoint> waypoints;  // the shots, in flight order
  std::string crs;                  // the world frame's CRS (empty: local)
  // The aperture's outline in the world frame (closed polygon; the polyline for a line).
  std::vector<std::array<double, 2>> outline;
  std::array<double, 2> growth_center{0.0, 0.0};  // world x, y
  double aperture_radius_m = 0.0;   // R: largest distance from the growth centre to the outline
  double aperture_area_m2 = 0.0;    // area of the outline (0 for a line)
  int64_t images = 0;
  int64_t lines = 0;                // scan lines or rings flown
  double length_m = 0.0;            // path through the shots
  double flight_time_s = 0.0;
  double frames_per_minute = 0.0;
  double battery_fraction = 0.0;    // flight time / battery budget (0 without one)
  double min_step_m = 0.0, max_step_m = 0.0;  // shortest and longest leg between shots
  double eq2_samples_per_m2 = 0.0;  // Eq. 2 at altitude_m
  double eq2_sample_size_m = 0.0;
  double min_agl_m = 0.0, max_agl_m = 0.0;
  std::vector<std::string> warnings;
};

std::ostream& operator<<(std::ostream& stream, const FlightPlanResult& result);

// Plans the flight (see the contract above). Reads options.dem when set. `progress` (may be
// null) is polled for cancellation.
FlightPlanResult PlanFlight(const FlightPlanOptions& options, ProgressSink* progress = nullptr);

// The first pass of PlanFlight alone (see "Bounds"): the number of shots and of lines or rings
// flown, and the path's length in the xy plane (the plan's length without terrain, to rounding),
// without storing a shot. over_max: the plan has more than max_waypoints shots, or more lines or
// rings across the aperture (images and lines are then where the count stopped). Throws what
// PlanFlight throws for the options and the shape.
struct FlightPlanCount {
  int64_t images = 0;
  int64_t lines = 0;
  double length_m = 0.0;
  bool over_max = false;
};
FlightPlanCount CountFlightPlan(const FlightPlanOptions& options, ProgressSink* progress = nullptr);

// The waypoints as text. CSV: a header line, then one row per shot:
//   index,latitude,longitude,altitude_agl_m,x_m,y_m,z_m,ground_z_m,line
// (latitude/longitude empty without a CRS). GeoJSON (RFC 7946): a FeatureCollection of one
// LineString (the path) and one Point per shot, coordinates [longitude, latitude, height above
// ground] in WGS84. KML: a Document with the path (LineString, altitudeMode relativeToGround) and
// one Placemark per shot. GeoJSON and KML throw std::invalid_argument without a CRS. Each checks
// the text's size against the memory budget first and polls `progress` for cancellation.
std::string FlightPlanCsv(const FlightPlanResult& result, ProgressSink* progress = nullptr);
std::string FlightPlanGeoJson(const FlightPlanResult& result, ProgressSink* progress = nullptr);
std::string FlightPlanKml(const FlightPlanResult& result, ProgressSink* progress = nullptr);

// A picture of the plan, 8-bit RGB, north up: the DEM's hillshade (options.dem) or a blank map,
// the outline, the path, the shots, the growth centre, a scale bar and an arrow to north (+y,
// labelled so, in a local frame). `size_px` is the longer side (>= 64); the picture is checked
// against the memory budget first, and `progress` is polled for cancellation.
Image FlightPlanMap(const FlightPlanOptions& options, const FlightPlanResult& result,
                    int size_px = 800, ProgressSink* progress = nullptr);

}  // namespace aos
