// Flight planning (flight_plan.h): shapes, patterns, terrain, time, exports and the map.
#include "aos/plan/flight_plan.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <ostream>
#include <sstream>

#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include "aos/geometry/geodesy.h"
#include "aos/geometry/heightfield.h"
#include "aos/geometry/mesh.h"
#include "aos/geometry/pinhole.h"
#include "aos/util/error.h"
#include "aos/util/memory.h"

namespace aos {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kInsideTolerance = 1e-6;  // metres: boundaries count as inside
// max_waypoints above this is a typo: 10^12 shots are 64 TB of waypoints.
constexpr int64_t kMaxWaypointsBound = 1000000000000;
using Point2 = std::array<double, 2>;

std::string Num(double value) { return FormatNumber(value); }

void CheckFinite(double value, const char* field) {
  if (!std::isfinite(value)) ThrowInvalid(std::string(field) + ": must be finite (got " + Num(value) + ")");
}
void CheckPositive(double value, const char* field) {
  if (!(std::isfinite(value) && value > 0.0)) {
    ThrowInvalid(std::string(field) + ": must be a finite number > 0 (got " + Num(value) + ")");
  }
}

// Direction of compass bearing `deg` (clockwise from +y) as (x, y).
Point2 Bearing(double deg) {
  const double a = deg * kPi / 180.0;
  return {std::sin(a), std::cos(a)};
}

double Cross(const Point2& o, const Point2& a, const Point2& b) {
  return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]);
}

// Whether segments ab and cd intersect (proper or touching).
bool SegmentsIntersect(const Point2& a, const Point2& b, const Point2& c, const Point2& d) {
  const double d1 = Cross(c, d, a), d2 = Cross(c, d, b), d3 = Cross(a, b, c), d4 = Cross(a, b, d);
  if (((d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0)) && ((d3 > 0 && d4 < 0) || (d3 < 0 && d4 > 0))) {
    return true;
  }
  auto on = [](const Point2& p, const Point2& q, const Point2& r, double cr) {
    return cr == 0.0 && std::min(p[0], q[0]) <= r[0] && r[0] <= std::max(p[0], q[0]) &&
           std::min(p[1], q[1]) <= r[1] && r[1] <= std::max(p[1], q[1]);
  };
  return on(c, d, a, d1) || on(c, d, b, d2) || on(a, b, c, d3) || on(a, b, d, d4);
}

double DistanceToSegment(const Point2& p, const Point2& a, const Point2& b) {
  const double dx = b[0] - a[0], dy = b[1] - a[1];
  const double len2 = dx * dx + dy * dy;
  double t = len2 > 0 ? ((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / len2 : 0.0;
  t = std::clamp(t, 0.0, 1.0);
  return std::hypot(p[0] - a[0] - t * dx, p[1] - a[1] - t * dy);
}

// The aperture in the world frame.
struct Shape {
  std::string kind;
  Point2 center{0, 0};
  double radius = 0, start_deg = 0, angle_deg = 360;
  std::vector<Point2> polygon;  // rectangle and polygon corners; line points

  bool Inside(const Point2& p) const {
    if (kind == "circle" || kind == "sector") {
      const double dx = p[0] - center[0], dy = p[1] - center[1];
      const double r = std::hypot(dx, dy);
      if (r > radius + kInsideTolerance) return false;
      if (kind == "circle" || angle_deg >= 360.0 || r <= kInsideTolerance) return true;
      double bearing = std::atan2(dx, dy) * 180.0 / kPi - start_deg;
      bearing = std::fmod(std::fmod(bearing, 360.0) + 360.0, 360.0);
      // Within the wedge, or within the tolerance of one of its edges.
      if (bearing <= angle_deg) return true;
      const double off = std::min(bearing - angle_deg, 360.0 - bearing) * kPi / 180.0;
      return off < kPi / 2 && r * std::sin(off) <= kInsideTolerance;
    }
    // Even-odd rule, boundary within the tolerance inside.
    bool inside = false;
    const size_t n = polygon.size();
    for (size_t i = 0, j = n - 1; i < n; j = i++) {
      const Point2& a = polygon[i];
      const Point2& b = polygon[j];
      if (DistanceToSegment(p, a, b) <= kInsideTolerance) return true;
      if ((a[1] > p[1]) != (b[1] > p[1]) &&
          p[0] < (b[0] - a[0]) * (p[1] - a[1]) / (b[1] - a[1]) + a[0]) {
        inside = !inside;
      }
    }
    return inside;
  }

  std::vector<Point2> Outline() const {
    if (kind == "circle" || kind == "sector") {
      std::vector<Point2> out;
      const bool full = kind == "circle" || angle_deg >= 360.0;
      const int n = std::max(8, static_cast<int>(std::ceil((full ? 360.0 : angle_deg) / 0.5)));
      if (!full) out.push_back(center);
      for (int i = 0; i <= n - (full ? 1 : 0); ++i) {
        const Point2 d = Bearing(start_deg + (full ? 360.0 : angle_deg) * i / n);
        out.push_back({center[0] + radius * d[0], center[1] + radius * d[1]});
      }
      return out;
    }
    return polygon;
  }
};

double PolygonArea(const std::vector<Point2>& polygon) {
  double twice = 0.0;
  for (size_t i = 0, j = polygon.size() - 1; i < polygon.size(); j = i++) {
    twice += polygon[j][0] * polygon[i][1] - polygon[i][0] * polygon[j][1];
  }
  return std::abs(twice) / 2.0;
}

// Terrain heights under (x, y): the DEM's triangles in a bucket grid over their xy bounds.
class Terrain {
 public:
  Terrain(Mesh mesh, double up) : mesh_(std::move(mesh)), up_(up) {
    min_x_ = min_y_ = std::numeric_limits<double>::infinity();
    double max_x = -min_x_, max_y = -min_y_;
    for (const Vec3d& v : mesh_.vertices) {
      min_x_ = std::min(min_x_, v.x), min_y_ = std::min(min_y_, v.y);
      max_x = std::max(max_x, v.x), max_y = std::max(max_y, v.y);
    }
    side_ = std::max(1, static_cast<int>(std::sqrt(static_cast<double>(mesh_.triangles.size()))));
    cell_x_ = std::max((max_x - min_x_) / side_, 1e-9);
    cell_y_ = std::max((max_y - min_y_) / side_, 1e-9);
    buckets_.resize(static_cast<size_t>(side_) * side_);
    for (size_t t = 0; t < mesh_.triangles.size(); ++t) {
      double lo_x = 1e300, lo_y = 1e300, hi_x = -1e300, hi_y = -1e300;
      for (int corner : mesh_.triangles[t]) {
        const Vec3d& v = mesh_.vertices[static_cast<size_t>(corner)];
        lo_x = std::min(lo_x, v.x), lo_y = std::min(lo_y, v.y);
        hi_x = std::max(hi_x, v.x), hi_y = std::max(hi_y, v.y);
      }
      for (int j = Cell(lo_y, min_y_, cell_y_); j <= Cell(hi_y, min_y_, cell_y_); ++j) {
        for (int i = Cell(lo_x, min_x_, cell_x_); i <= Cell(hi_x, min_x_, cell_x_); ++i) {
          buckets_[static_cast<size_t>(j) * side_ + i].push_back(static_cast<int>(t));
        }
      }
    }
  }

  // World z of the terrain under (x, y) (the highest along `up` where surfaces overlap); NaN
  // outside the DEM.
  double HeightAt(double x, double y) const {
    double best = std::numeric_limits<double>::quiet_NaN();
    if (x < min_x_ - 1e-9 || y < min_y_ - 1e-9) return best;
    const int i = Cell(x, min_x_, cell_x_), j = Cell(y, min_y_, cell_y_);
    if (x > min_x_ + cell_x_ * side_ + 1e-9 || y > min_y_ + cell_y_ * side_ + 1e-9) return best;
    for (int t : buckets_[static_cast<size_t>(j) * side_ + i]) {
      const auto& tri = mesh_.triangles[static_cast<size_t>(t)];
      const Vec3d& a = mesh_.vertices[static_cast<size_t>(tri[0])];
      const Vec3d& b = mesh_.vertices[static_cast<size_t>(tri[1])];
      const Vec3d& c = mesh_.vertices[static_cast<size_t>(tri[2])];
      const double det = (b.y - c.y) * (a.x - c.x) + (c.x - b.x) * (a.y - c.y);
      if (det == 0.0) continue;
      const double l1 = ((b.y - c.y) * (x - c.x) + (c.x - b.x) * (y - c.y)) / det;
      const double l2 = ((c.y - a.y) * (x - c.x) + (a.x - c.x) * (y - c.y)) / det;
      const double l3 = 1.0 - l1 - l2;
      const double eps = -1e-9;
      if (l1 < eps || l2 < eps || l3 < eps) continue;
      const double z = l1 * a.z + l2 * b.z + l3 * c.z;
      if (std::isnan(best) || (z - best) * up_ > 0) best = z;
    }
    return best;
  }

 private:
  int Cell(double value, double origin, double size) const {
    return std::clamp(static_cast<int>(std::floor((value - origin) / size)), 0, side_ - 1);
  }
  Mesh mesh_;
  double up_;
  double min_x_, min_y_, cell_x_, cell_y_;
  int side_ = 1;
  std::vector<std::vector<int>> buckets_;
};

Terrain ReadTerrain(const FlightPlanOptions& options) {
  const double up = options.terrain_up == "-z" ? -1.0 : 1.0;
  if (IsMeshFile(options.dem)) return Terrain(ReadMesh(options.dem), up);
  return Terrain(HeightfieldToMesh(ReadHeightfield(options.dem), options.dem), up);
}

bool LooksLikeDegrees(const Point2& p) { return std::abs(p[0]) <= 90.0 && std::abs(p[1]) <= 180.0; }

// The shape in the world frame (latlon projected to UTM); sets `crs`.
Shape BuildShape(const FlightPlanOptions& o, std::string& crs) {
  Shape shape;
  shape.kind = o.shape;
  crs = o.crs;
  Point2 center = o.center;
  std::vector<Point2> vertices = o.vertices;
  if (o.coordinates == "latlon") {
    auto check = [](const Point2& p, const std::string& field) {
      if (!(std::abs(p[0]) <= 90.0 && std::abs(p[1]) <= 180.0)) {
        ThrowInvalid(field + ": (" + Num(p[0]) + ", " + Num(p[1]) +
                     ") is not a (latitude, longitude) in degrees; metres given as degrees? "
                     "(coordinates = world takes metres)");
      }
    };
    const bool uses_center = o.shape == "circle" || o.shape == "sector" || o.shape == "rectangle";
    Point2 reference = center;
    if (uses_center) {
      check(center, "center");
    } else {
      reference = {0, 0};
      for (size_t i = 0; i < vertices.size(); ++i) {
        check(vertices[i], "vertices[" + std::to_string(i) + "]");
        reference[0] += vertices[i][0] / vertices.size();
        reference[1] += vertices[i][1] / vertices.size();
      }
    }
    const UtmCoordinate zone = UtmFromWgs84(reference[0], reference[1], 0, "center");
    auto project = [&](const Point2& p, const std::string& field) -> Point2 {
      const UtmCoordinate utm = UtmFromWgs84(p[0], p[1], zone.zone, field);
      return {utm.easting, utm.northing};
    };
    crs = UtmEpsg(zone.zone, zone.north);
    if (uses_center) center = project(center, "center");
    for (size_t i = 0; i < vertices.size(); ++i) {
      vertices[i] = project(vertices[i], "vertices[" + std::to_string(i) + "]");
    }
  } else if (!crs.empty()) {
    if (IsGeographicCrs(crs, "crs")) {
      ThrowInvalid("crs: " + crs + " is geographic (degrees); give a projected CRS in metres, or "
                   "coordinates = latlon");
    }
    // Degrees given as metres: every coordinate within latitude/longitude range in a projected
    // CRS (a UTM easting is at least 160 km; a point within 180 m of a projection's origin is
    // not what a user of a projected CRS means).
    const bool uses_center = o.shape == "circle" || o.shape == "sector" || o.shape == "rectangle";
    bool all_small = uses_center ? LooksLikeDegrees(center) : !vertices.empty();
    for (const Point2& v : vertices) all_small = all_small && (uses_center || LooksLikeDegrees(v));
    if (all_small) {
      const Point2 p = uses_center ? center : vertices[0];
      ThrowInvalid(std::string(uses_center ? "center" : "vertices") + ": (" + Num(p[0]) + ", " +
                   Num(p[1]) + ") look like degrees given as metres of " + crs +
                   "; use coordinates = latlon");
    }
  }
  if (o.shape == "circle" || o.shape == "sector") {
    shape.center = center;
    shape.radius = o.radius_m;
    if (o.shape == "sector") {
      shape.start_deg = o.sector_start_deg;
      shape.angle_deg = o.sector_angle_deg;
    }
  } else if (o.shape == "rectangle") {
    shape.center = center;
    const Point2 d = Bearing(o.heading_deg), n = Bearing(o.heading_deg + 90.0);
    const double hl = o.length_m / 2, hw = o.width_m / 2;
    for (const auto& [a, b] : {std::pair{-1, -1}, std::pair{1, -1}, std::pair{1, 1}, std::pair{-1, 1}}) {
      shape.polygon.push_back({center[0] + a * hl * d[0] + b * hw * n[0],
                               center[1] + a * hl * d[1] + b * hw * n[1]});
    }
  } else {
    shape.polygon = vertices;
    if (o.shape == "polygon") {
      // Closed implicitly: a repeated last vertex is dropped.
      if (shape.polygon.size() > 1 && shape.polygon.front() == shape.polygon.back()) {
        shape.polygon.pop_back();
      }
      if (shape.polygon.size() < 3) {
        ThrowInvalid("vertices: a polygon needs at least 3 distinct vertices (got " +
                     std::to_string(shape.polygon.size()) + ")");
      }
      const size_t n = shape.polygon.size();
      for (size_t i = 0; i < n; ++i) {
        if (shape.polygon[i] == shape.polygon[(i + 1) % n]) {
          ThrowInvalid("vertices: vertices " + std::to_string(i) + " and " +
                       std::to_string((i + 1) % n) + " are the same point");
        }
        for (size_t j = i + 1; j < n; ++j) {
          if (j == i + 1 || (i == 0 && j == n - 1)) continue;  // neighbours share a corner
          if (SegmentsIntersect(shape.polygon[i], shape.polygon[(i + 1) % n], shape.polygon[j],
                                shape.polygon[(j + 1) % n])) {
            ThrowInvalid("vertices: the polygon intersects itself (edge " + std::to_string(i) +
                         "-" + std::to_string((i + 1) % n) + " crosses edge " +
                         std::to_string(j) + "-" + std::to_string((j + 1) % n) + ")");
          }
        }
      }
      if (PolygonArea(shape.polygon) <= 1e-9) ThrowInvalid("vertices: the polygon has no area");
      Point2 mean{0, 0};
      for (const Point2& v : shape.polygon) {
        mean[0] += v[0] / n;
        mean[1] += v[1] / n;
      }
      shape.center = mean;
    } else {  // line
      if (shape.polygon.size() < 2) {
        ThrowInvalid("vertices: a line needs at least 2 points (got " +
                     std::to_string(shape.polygon.size()) + ")");
      }
      shape.center = shape.polygon.front();
    }
  }
  return shape;
}

struct Shot {
  Point2 p;
  int line;
};

// A whole number with thousands separators: "113,097,336".
std::string Grouped(double value) {
  char buffer[400];
  std::snprintf(buffer, sizeof buffer, "%.0f", value);
  const std::string digits = buffer;
  std::string out;
  for (size_t i = 0; i < digits.size(); ++i) {
    if (i > 0 && (digits.size() - i) % 3 == 0) out += ',';
    out += digits[i];
  }
  return out;
}

// s(r) = s0 (1 + (outer_scale - 1) min(|r| / R, 1)) (flight_plan.h).
struct Spacing {
  double s0 = 1.0, scale = 1.0, radius = 0.0;
  double operator()(double r) const {
    return s0 * (1.0 + (scale - 1.0) * std::min(std::abs(r) / std::max(radius, 1e-12), 1.0));
  }
  bool Constant() const { return scale == 1.0; }
};

struct Interval {
  double lo, hi;
};

// Sorts and merges overlapping intervals in place.
void MergeIntervals(std::vector<Interval>& intervals) {
  std::sort(intervals.begin(), intervals.end(),
            [](const Interval& a, const Interval& b) { return a.lo < b.lo; });
  size_t kept = 0;
  for (const Interval& next : intervals) {
    if (next.hi < next.lo) continue;
    if (kept > 0 && next.lo <= intervals[kept - 1].hi) {
      intervals[kept - 1].hi = std::max(intervals[kept - 1].hi, next.hi);
    } else {
      intervals[kept++] = next;
    }
  }
  intervals.resize(kept);
}

// Positions along an axis stepped outwards from 0: p_1 < p_2 < ... <= limit (p_k = k s0 for a
// constant spacing, p_{k+1} = p_k + s(hypot(p_k, offset)) otherwise). Calls visit(p) for each;
// stops when visit returns false.
template <class Visit>
void ForEachOutward(const Spacing& spacing, double offset, double limit, Visit&& visit) {
  if (spacing.Constant()) {
    for (int64_t k = 1;; ++k) {
      const double p = static_cast<double>(k) * spacing.s0;
      if (p > limit || !visit(p)) return;
    }
  }
  for (double p = 0.0;;) {
    p += spacing(offset == 0.0 ? p : std::hypot(p, offset));
    if (p > limit || !visit(p)) return;
  }
}

// One walk over a pattern's shots in flight order (flight_plan.h, "Bounds"). Count() visits them
// without storing any and sums the path's length; Generate() stores them. Both go through the
// same candidates and the same Shape::Inside() decisions, so the count is the generated plan's.
// Only candidates that can lie inside the shape are visited: on a scan line the intervals where
// it meets the shape (widened by `slack_`), on a ring the arc within a sector.
class PatternWalk {
 public:
  struct Totals {
    int64_t shots = 0;
    int64_t lines = 0;      // lines or rings flown
    double length_m = 0.0;  // the path through the shots in the xy plane
    bool over = false;      // stopped: more than the limit
  };

  PatternWalk(const Shape& shape, const FlightPlanOptions& o, double radius, ProgressSink* progress)
      : shape_(shape), options_(o), radius_(radius), progress_(progress) {
    const double across0 = o.spacing_m;
    const double along0 = o.pattern == "grid" || o.along_spacing_m == 0.0 ? across0 : o.along_spacing_m;
    across_ = {across0, o.outer_scale, radius};
    along_ = {along0, o.outer_scale, radius};
    d_ = Bearing(o.heading_deg);
    n_ = Bearing(o.heading_deg + 90.0);
    limit_ = radius + kInsideTolerance;
    // Twice the boundary tolerance, plus the rounding of coordinates of this magnitude.
    slack_ = 2.0 * kInsideTolerance +
             1e-10 * (std::abs(shape.center[0]) + std::abs(shape.center[1]) + radius);
    for (const Point2& p : shape.polygon) {
      const double x = p[0] - shape.center[0], y = p[1] - shape.center[1];
      frame_.push_back({x * d_[0] + y * d_[1], x * n_[0] + y * n_[1]});
    }
  }

  double across0() const { return across_.s0; }
  double along0() const { return along_.s0; }

  // Scan lines or rings across the aperture (an upper bound with a growing spacing): each one
  // flown takes a shot, so more than max_waypoints is refused without a walk.
  double LinesAcross() const {
    if (shape_.kind == "line") return 1.0;
    const double across = std::floor(limit_ / across_.s0);
    return options_.pattern == "circles" ? across + 1.0 : 2.0 * across + 1.0;
  }

  // Refuses more positions along one line or ring than coordinates resolve (10^15).
  void CheckAlong() const {
    const double along = 2.0 * std::ceil(limit_ / along_.s0) * (options_.pattern == "circles" ? kPi : 1.0);
    if (along > 1e15) {
      ThrowInvalid(std::string(options_.pattern == "grid" || options_.along_spacing_m == 0.0
                                   ? "spacing_m"
                                   : "along_spacing_m") +
                   ": " + Num(along_.s0) + " m gives " + Grouped(along) +
                   " positions along a line or ring (aperture radius " + Num(radius_) +
                   " m), more than 10^15 (finer than the coordinates resolve); widen it");
    }
  }

  // Counts the shots and sums the path's length (xy) without storing a shot; stops with
  // over = true as soon as there are more than `limit`.
  Totals Count(int64_t limit) { return Walk(limit, nullptr); }
  // The shots in flight order (after Count() accepted the plan).
  std::vector<Shot> Generate(int64_t expected, Totals* totals) {
    std::vector<Shot> shots;
    shots.reserve(static_cast<size_t>(expected));
    *totals = Walk(std::numeric_limits<int64_t>::max(), &shots);
    return shots;
  }

 private:
  void Poll() {
    if (++polls_ % 1024 == 0 && ProgressCancelled(progress_)) throw Cancelled();
  }

  Point2 OnLine(double u, double v) const {
    return {shape_.center[0] + u * d_[0] + v * n_[0], shape_.center[1] + u * d_[1] + v * n_[1]};
  }

  // Totals of the walk; adds the leg from the previous line's last shot to `first`.
  void Leg(const Point2& first, const Point2& last, Totals& t) {
    if (has_last_) {
      const double dx = first[0] - last_[0], dy = first[1] - last_[1];
      t.length_m += std::sqrt(dx * dx + dy * dy);
    }
    last_ = last;
    has_last_ = true;
  }

  Totals Walk(int64_t limit, std::vector<Shot>* out) {
    Totals t;
    has_last_ = false;
    if (shape_.kind == "line") {
      WalkLineShape(limit, out, t);
      t.lines = 1;
    } else if (options_.pattern == "circles") {
      WalkRings(limit, out, t);
    } else {
      WalkScanLines(limit, out, t);
    }
    return t;
  }

  // The line shape: shots every `along` from the first vertex (and at the last).
  void WalkLineShape(int64_t limit, std::vector<Shot>* out, Totals& t) {
    const double along = along_.s0;
    bool first = true;
    Point2 previous{0, 0};
    auto emit = [&](const Point2& p) {
      Poll();
      if (t.shots >= limit) {
        t.over = true;
        return false;
      }
      ++t.shots;
      if (out != nullptr) out->push_back({p, 0});
      if (!first) {
        const double dx = p[0] - previous[0], dy = p[1] - previous[1];
        t.length_m += std::sqrt(dx * dx + dy * dy);
      }
      first = false;
      previous = p;
      return true;
    };
    if (!emit(shape_.polygon.front())) return;
    double carried = 0.0;  // distance since the last shot
    for (size_t i = 0; i + 1 < shape_.polygon.size(); ++i) {
      const Point2 a = shape_.polygon[i], b = shape_.polygon[i + 1];
      const double len = std::hypot(b[0] - a[0], b[1] - a[1]);
      double t_along = along - carried;
      while (t_along <= len + kInsideTolerance) {
        if (!emit({a[0] + (b[0] - a[0]) * t_along / len, a[1] + (b[1] - a[1]) * t_along / len})) return;
        t_along += along;
      }
      carried = len - (t_along - along);
    }
    if (carried > kInsideTolerance) emit(shape_.polygon.back());
  }

  // Where the scan line at offset v can meet the shape (u along the heading from the growth
  // centre), as sorted, disjoint intervals within |u| <= limit_: a superset of the u where
  // Shape::Inside() holds.
  void LineIntervals(double v, std::vector<Interval>& intervals) {
    intervals.clear();
    const double w = slack_;
    if (shape_.kind == "circle" || shape_.kind == "sector") {
      const double h2 = (shape_.radius + w) * (shape_.radius + w) - v * v;
      if (h2 < 0.0) return;
      const double h = std::sqrt(h2) + w;
      intervals.push_back({-h, h});
      if (shape_.kind == "sector" && shape_.angle_deg < 360.0) ClipToWedge(v, intervals);
    } else {
      crossings_.clear();
      const size_t count = frame_.size();
      for (size_t i = 0, j = count - 1; i < count; j = i++) {
        const Point2& a = frame_[j];
        const Point2& b = frame_[i];
        if ((a[1] > v) != (b[1] > v)) {
          crossings_.push_back(a[0] + (v - a[1]) * (b[0] - a[0]) / (b[1] - a[1]));
        }
        // The part of the edge within w of the line (where the boundary tolerance can keep a
        // shot), widened by w along it.
        if (std::max(a[1], b[1]) < v - w || std::min(a[1], b[1]) > v + w) continue;
        double t0 = 0.0, t1 = 1.0;
        if (b[1] != a[1]) {
          t0 = std::clamp((v - w - a[1]) / (b[1] - a[1]), 0.0, 1.0);
          t1 = std::clamp((v + w - a[1]) / (b[1] - a[1]), 0.0, 1.0);
        }
        const double u0 = a[0] + t0 * (b[0] - a[0]), u1 = a[0] + t1 * (b[0] - a[0]);
        intervals.push_back({std::min(u0, u1) - w, std::max(u0, u1) + w});
      }
      // Even-odd along the line: the inside lies between crossings 0-1, 2-3, ...
      std::sort(crossings_.begin(), crossings_.end());
      for (size_t k = 0; k + 1 < crossings_.size(); k += 2) {
        intervals.push_back({crossings_[k] - w, crossings_[k + 1] + w});
      }
    }
    for (Interval& i : intervals) {
      i.lo = std::max(i.lo, -limit_);
      i.hi = std::min(i.hi, limit_);
    }
    MergeIntervals(intervals);
  }

  // A sector's wedge: points within w of it satisfy a u + b >= -w for both edges' inward normals
  // (angle <= 180 degrees, a convex wedge); a reflex wedge excludes only where both fail.
  void ClipToWedge(double v, std::vector<Interval>& intervals) const {
    const double w = slack_;
    const Point2 n1 = Bearing(shape_.start_deg + 90.0);
    const Point2 n2 = Bearing(shape_.start_deg + shape_.angle_deg - 90.0);
    // {u : a u + b >= -w} as an interval.
    auto half = [&](const Point2& normal) -> Interval {
      const double a = d_[0] * normal[0] + d_[1] * normal[1];
      const double b = v * (n_[0] * normal[0] + n_[1] * normal[1]);
      const double inf = std::numeric_limits<double>::infinity();
      if (a == 0.0) return b >= -w ? Interval{-inf, inf} : Interval{inf, -inf};
      const double x = (-w - b) / a;
      return a > 0.0 ? Interval{x - w, inf} : Interval{-inf, x + w};
    };
    const Interval h1 = half(n1), h2 = half(n2);
    Interval& chord = intervals.front();
    if (shape_.angle_deg <= 180.0) {
      chord.lo = std::max({chord.lo, h1.lo, h2.lo});
      chord.hi = std::min({chord.hi, h1.hi, h2.hi});
      if (chord.hi < chord.lo) intervals.clear();
      return;
    }
    // Reflex: drop the open interval where both half-planes fail (the complement of each
    // half-interval is one ray; their intersection is an interval).
    auto complement = [](const Interval& h) -> Interval {
      const double inf = std::numeric_limits<double>::infinity();
      if (h.lo > h.hi) return {-inf, inf};        // fails everywhere
      if (std::isinf(h.lo) && std::isinf(h.hi)) return {inf, -inf};  // holds everywhere
      return std::isinf(h.lo) ? Interval{h.hi, inf} : Interval{-inf, h.lo};
    };
    const Interval c1 = complement(h1), c2 = complement(h2);
    const Interval drop{std::max(c1.lo, c2.lo), std::min(c1.hi, c2.hi)};
    if (drop.hi <= drop.lo) return;
    const Interval whole = chord;
    intervals.clear();
    if (whole.lo <= std::min(whole.hi, drop.lo)) intervals.push_back({whole.lo, std::min(whole.hi, drop.lo)});
    if (std::max(whole.lo, drop.hi) <= whole.hi) intervals.push_back({std::max(whole.lo, drop.hi), whole.hi});
  }

  // Calls visit(u) for every candidate u on the line at offset v (|u| <= limit_, within the
  // line's intervals), ascending for a constant spacing; stops when visit returns false.
  template <class Visit>
  void ForEachCandidate(double v, const std::vector<Interval>& intervals, Visit&& visit) {
    if (intervals.empty()) return;
    auto within = [&](double u) {
      for (const Interval& i : intervals) {
        if (u >= i.lo && u <= i.hi) return true;
      }
      return false;
    };
    if (along_.Constant()) {
      const double s = along_.s0;
      for (const Interval& i : intervals) {
        for (auto k = static_cast<int64_t>(std::ceil(i.lo / s)) - 1;; ++k) {
          const double u = static_cast<double>(k) * s;
          if (u > i.hi) break;
          if (u < i.lo || std::abs(u) > limit_) continue;
          if (!visit(u)) return;
        }
      }
      return;
    }
    // Growing spacing: the positions are stepped from the centre outwards.
    if (within(0.0) && !visit(0.0)) return;
    const double reach = std::max(-intervals.front().lo, intervals.back().hi);
    bool go_on = true;
    ForEachOutward(along_, v, std::min(reach, limit_), [&](double q) {
      Poll();
      if (within(-q) && !visit(-q)) return go_on = false;
      if (within(q) && !visit(q)) return go_on = false;
      return true;
    });
  }

  void WalkScanLines(int64_t limit, std::vector<Shot>* out, Totals& t) {
    std::vector<double> offsets;  // v of the lines, ascending
    ForEachOutward(across_, 0.0, limit_, [&](double p) {
      offsets.push_back(p);
      return true;
    });
    const size_t half = offsets.size();
    offsets.resize(2 * half + 1);
    for (size_t k = 0; k < half; ++k) offsets[2 * half - k] = offsets[half - 1 - k];
    offsets[half] = 0.0;
    for (size_t k = 0; k < half; ++k) offsets[k] = -offsets[2 * half - k];
    std::vector<Interval> intervals;
    std::vector<double> kept;
    for (const double v : offsets) {
      Poll();
      LineIntervals(v, intervals);
      // The line's shots: how many, and the first and last along +u.
      int64_t count = 0;
      double u_min = 0.0, u_max = 0.0;
      ForEachCandidate(v, intervals, [&](double u) {
        Poll();
        if (!shape_.Inside(OnLine(u, v))) return true;
        if (count == 0 || u < u_min) u_min = u;
        if (count == 0 || u > u_max) u_max = u;
        ++count;
        // Over once the line is sure to be flown.
        if (t.shots + count > limit && count >= options_.min_shots_per_line) t.over = true;
        return !t.over;
      });
      if (t.over) return;
      if (count < options_.min_shots_per_line) continue;
      const bool reversed = t.lines % 2 == 1;
      const int line = static_cast<int>(t.lines);
      t.shots += count;
      ++t.lines;
      const Point2 first = OnLine(reversed ? u_max : u_min, v);
      const Point2 last = OnLine(reversed ? u_min : u_max, v);
      Leg(first, last, t);
      t.length_m += u_max - u_min;  // collinear shots
      if (out == nullptr) continue;
      kept.clear();
      ForEachCandidate(v, intervals, [&](double u) {
        Poll();
        if (shape_.Inside(OnLine(u, v))) kept.push_back(u);
        return true;
      });
      std::sort(kept.begin(), kept.end());
      if (reversed) std::reverse(kept.begin(), kept.end());
      for (const double u : kept) out->push_back({OnLine(u, v), line});
    }
  }

  // Point j of the ring of radius r with n points (at bearing 360 j / n).
  Point2 RingPoint(double r, int64_t j, int64_t n) const {
    const Point2 d = Bearing(360.0 * static_cast<double>(j) / static_cast<double>(n));
    return {shape_.center[0] + r * d[0], shape_.center[1] + r * d[1]};
  }

  using IndexRanges = std::vector<std::pair<int64_t, int64_t>>;

  // Adds the indices lo..hi (modulo n) to `ranges`; false when they cover the whole ring.
  static bool AddIndices(int64_t lo, int64_t hi, int64_t n, IndexRanges& ranges) {
    if (hi - lo + 1 >= n) return false;
    const int64_t a = ((lo % n) + n) % n, b = ((hi % n) + n) % n;
    if (a <= b) {
      ranges.push_back({a, b});
    } else {
      ranges.push_back({0, b});
      ranges.push_back({a, n - 1});
    }
    return true;
  }
  // The indices of the compass degrees [from, to] (and one more on each side) to `ranges`.
  static bool AddDegrees(double from, double to, int64_t n, IndexRanges& ranges) {
    if (to - from >= 360.0) return false;
    const double shift = 360.0 * std::floor(from / 360.0);  // from into [0, 360)
    const double scale = static_cast<double>(n) / 360.0;
    return AddIndices(static_cast<int64_t>(std::floor((from - shift) * scale)) - 1,
                      static_cast<int64_t>(std::ceil((to - shift) * scale)) + 1, n, ranges);
  }
  static void MergeIndices(IndexRanges& ranges) {
    std::sort(ranges.begin(), ranges.end());
    size_t kept = 0;
    for (const auto& next : ranges) {
      if (kept > 0 && next.first <= ranges[kept - 1].second + 1) {
        ranges[kept - 1].second = std::max(ranges[kept - 1].second, next.second);
      } else {
        ranges[kept++] = next;
      }
    }
    ranges.resize(kept);
  }

  // Indices of the ring's n points that can lie inside the shape, as ascending, disjoint
  // [first, last] ranges: a sector's arc; for a polygon the arcs within w of an edge (the
  // ring's crossings with the annulus r +- w around them) and, between those, the arcs that are
  // inside (wholly inside or wholly outside, as no edge comes within w: one point decides).
  void RingCandidates(double r, int64_t n, IndexRanges& ranges) const {
    ranges.clear();
    const double w = slack_;
    if (r > 4.0 * w && shape_.kind == "sector" && shape_.angle_deg < 360.0) {
      const double spread = 2.0 * w / r * 180.0 / kPi;  // degrees, > asin(tolerance / r)
      if (AddDegrees(shape_.start_deg - spread, shape_.start_deg + shape_.angle_deg + spread, n,
                     ranges)) {
        MergeIndices(ranges);
        return;
      }
      ranges.clear();
    }
    if (r > 4.0 * w && (shape_.kind == "polygon" || shape_.kind == "rectangle") &&
        PolygonRingCandidates(r, n, ranges)) {
      return;
    }
    ranges.assign(1, {0, n - 1});
  }

  bool PolygonRingCandidates(double r, int64_t n, IndexRanges& ranges) const {
    const double w = slack_;
    // A point of the ring within w of a boundary point q: q lies in the annulus, and its bearing
    // is within asin(w / (r - w)) < spread of the point's.
    const double spread = 2.0 * w / (r - w) * 180.0 / kPi;
    IndexRanges near;
    const size_t count = shape_.polygon.size();
    for (size_t i = 0, j = count - 1; i < count; j = i++) {
      const double ax = shape_.polygon[j][0] - shape_.center[0], ay = shape_.polygon[j][1] - shape_.center[1];
      const double ex = shape_.polygon[i][0] - shape_.polygon[j][0], ey = shape_.polygon[i][1] - shape_.polygon[j][1];
      const double qa = ex * ex + ey * ey, qb = 2.0 * (ax * ex + ay * ey), qc = ax * ax + ay * ay;
      if (qa == 0.0) continue;
      // t in [0, 1] where |a + t e| = rho: the roots of qa t^2 + qb t + qc - rho^2.
      auto roots = [&](double rho, double& t0, double& t1) {
        const double disc = qb * qb - 4.0 * qa * (qc - rho * rho);
        if (disc < 0.0) return false;
        t0 = (-qb - std::sqrt(disc)) / (2.0 * qa);
        t1 = (-qb + std::sqrt(disc)) / (2.0 * qa);
        return true;
      };
      double t1 = 0.0, t2 = 0.0, t3 = 0.0, t4 = 0.0;
      if (!roots(r + w, t1, t2)) continue;
      t1 = std::max(t1, 0.0);
      t2 = std::min(t2, 1.0);
      if (t1 > t2) continue;
      std::pair<double, double> pieces[2] = {{t1, t2}, {1.0, 0.0}};
      if (roots(r - w, t3, t4)) {  // without the part inside r - w
        pieces[0] = {t1, std::min(t2, t3)};
        pieces[1] = {std::max(t1, t4), t2};
      }
      for (const auto& [ta, tb] : pieces) {
        if (ta > tb) continue;
        const double bearing_a = std::atan2(ax + ta * ex, ay + ta * ey) * 180.0 / kPi;
        const double bearing_b = std::atan2(ax + tb * ex, ay + tb * ey) * 180.0 / kPi;
        const double sweep = std::remainder(bearing_b - bearing_a, 360.0);
        const double from = sweep >= 0.0 ? bearing_a : bearing_b;
        if (!AddDegrees(from - spread, from + std::abs(sweep) + spread, n, near)) return false;
      }
    }
    MergeIndices(near);
    ranges = near;
    // The arcs between: in or out as a whole.
    if (near.empty()) {
      if (shape_.Inside(RingPoint(r, 0, n))) ranges.assign(1, {0, n - 1});
      return true;
    }
    for (size_t k = 0; k < near.size(); ++k) {
      const int64_t from = near[k].second + 1;
      const int64_t to = k + 1 < near.size() ? near[k + 1].first - 1 : near[0].first - 1 + n;
      if (from > to) continue;
      if (shape_.Inside(RingPoint(r, (from + (to - from) / 2) % n, n))) AddIndices(from, to, n, ranges);
    }
    MergeIndices(ranges);
    return true;
  }

  void WalkRings(int64_t limit, std::vector<Shot>* out, Totals& t) {
    IndexRanges ranges;
    std::vector<int64_t> inside;
    auto ring_point = [&](double r, int64_t j, int64_t n) { return RingPoint(r, j, n); };
    auto walk_ring = [&](double r) {
      Poll();
      if (r == 0.0) {
        if (!shape_.Inside(shape_.center)) return true;
        if (t.shots + 1 > limit) return !(t.over = true);
        const int ring = static_cast<int>(t.lines);
        ++t.shots;
        ++t.lines;
        Leg(shape_.center, shape_.center, t);
        if (out != nullptr) out->push_back({shape_.center, ring});
        return true;
      }
      const int64_t n = std::max<int64_t>(1, std::llround(2 * kPi * r / along_(r)));
      RingCandidates(r, n, ranges);
      // The kept points, in index order: how many; the first after a gap (the flight starts
      // there, so that an arc crossing bearing 0 stays in one piece) and the chord lengths
      // between neighbours along the flight.
      int64_t count = 0, first_kept = -1, last_kept = -1, previous = -1;
      int64_t start = -1, start_gap = 0;  // first kept j > 0 after a gap; its gap in indices
      double chords = 0.0;
      auto chord = [&](int64_t gap) { return 2.0 * r * std::sin(kPi * static_cast<double>(gap) / static_cast<double>(n)); };
      for (const auto& [a, b] : ranges) {
        for (int64_t j = a; j <= b; ++j) {
          Poll();
          if (!shape_.Inside(ring_point(r, j, n))) continue;
          if (++count + t.shots > limit) return !(t.over = true);
          if (first_kept < 0) first_kept = j;
          if (previous >= 0) chords += chord(j - previous);
          if (j > 0 && previous != j - 1 && start < 0) {
            start = j;
            start_gap = previous >= 0 ? j - previous : -1;
          }
          previous = last_kept = j;
        }
      }
      if (count == 0) return true;
      // The flight starts at j = 0 when it is kept and n - 1 is not, else at the first kept
      // point after a gap (at j = 0 when every point is kept).
      int64_t begin = first_kept, end_index = begin;
      if (!(first_kept == 0 && last_kept != n - 1) && start >= 0) begin = start;
      double length = 0.0;
      if (count > 1) {
        const double wrap = chord(first_kept + n - last_kept);
        // Every neighbour pair around the ring but the one entering `begin`.
        const double entering = begin == first_kept ? wrap : chord(start_gap);
        length = chords + wrap - entering;
        end_index = begin == first_kept ? last_kept : begin - start_gap;
      }
      const bool reversed = t.lines % 2 == 1;
      const int ring = static_cast<int>(t.lines);
      t.shots += count;
      ++t.lines;
      const Point2 p_begin = ring_point(r, begin, n), p_end = ring_point(r, end_index, n);
      Leg(reversed ? p_end : p_begin, reversed ? p_begin : p_end, t);
      t.length_m += length;
      if (out == nullptr) return true;
      inside.clear();
      for (const auto& [a, b] : ranges) {
        for (int64_t j = a; j <= b; ++j) {
          Poll();
          if (shape_.Inside(ring_point(r, j, n))) inside.push_back(j);
        }
      }
      const auto at = std::find(inside.begin(), inside.end(), begin);
      std::rotate(inside.begin(), at, inside.end());
      if (reversed) std::reverse(inside.begin(), inside.end());
      for (const int64_t j : inside) out->push_back({ring_point(r, j, n), ring});
      return true;
    };
    if (!walk_ring(0.0)) return;
    ForEachOutward(across_, 0.0, limit_, walk_ring);
  }

  const Shape& shape_;
  const FlightPlanOptions& options_;
  double radius_;
  ProgressSink* progress_;
  Spacing across_, along_;
  Point2 d_{0, 1}, n_{1, 0};
  double limit_ = 0.0, slack_ = 0.0;
  std::vector<Point2> frame_;  // polygon vertices as (u, v) from the growth centre
  std::vector<double> crossings_;
  int64_t polls_ = 0;
  Point2 last_{0, 0};
  bool has_last_ = false;
};

// R: the largest distance from the growth centre to the shape's boundary.
double ApertureRadius(const Shape& shape) {
  if (shape.kind == "circle" || shape.kind == "sector") return shape.radius;
  double radius = 0.0;
  for (const Point2& v : shape.polygon) {
    radius = std::max(radius, std::hypot(v[0] - shape.center[0], v[1] - shape.center[1]));
  }
  return radius;
}

// Refuses a flight of `length_m` and `images` shots over the battery budget: when its time
// exceeds `margin` times the budget (the count's length agrees with the path's to rounding).
void RefuseOverBattery(const FlightPlanOptions& options, double length_m, int64_t images,
                       double margin) {
  if (!std::isfinite(options.battery_min)) return;
  const double time_s = length_m / options.ground_speed_mps +
                        static_cast<double>(images) * options.hover_s;
  if (time_s / (60.0 * options.battery_min) <= margin) return;
  ThrowInvalid("battery_min: the plan takes " + Num(std::round(time_s / 6.0) / 10.0) + " min (" +
               std::to_string(images) + " images, " + Num(std::round(length_m)) +
               " m), over the battery budget of " + Num(options.battery_min) +
               " min; widen the spacing or split the aperture");
}

}  // namespace

void FlightPlanOptions::Check() const {
  CheckFieldChoices(*this);  // shape, pattern, ...: the table's choices (flight_plan.h)
  CheckFinite(center[0], "center");
  CheckFinite(center[1], "center");
  for (size_t i = 0; i < vertices.size(); ++i) {
    if (!std::isfinite(vertices[i][0]) || !std::isfinite(vertices[i][1])) {
      ThrowInvalid("vertices[" + std::to_string(i) + "]: must be finite");
    }
  }
  if (shape == "circle" || shape == "sector") CheckPositive(radius_m, "radius_m");
  if (shape == "sector") {
    CheckFinite(sector_start_deg, "sector_start_deg");
    if (!(sector_angle_deg > 0.0 && sector_angle_deg <= 360.0)) {
      ThrowInvalid("sector_angle_deg: must be in (0, 360] degrees (got " + Num(sector_angle_deg) + ")");
    }
  }
  if (shape == "rectangle") {
    CheckPositive(width_m, "width_m");
    CheckPositive(length_m, "length_m");
  }
  if ((shape == "polygon" || shape == "line") == vertices.empty()) {
    ThrowInvalid(std::string("vertices: ") + (vertices.empty() ? "a " + shape + " needs vertices"
                                                                : "only a polygon or line takes vertices"));
  }
  CheckPositive(spacing_m, "spacing_m");
  if (!(std::isfinite(along_spacing_m) && along_spacing_m >= 0.0)) {
    ThrowInvalid("along_spacing_m: must be > 0, or 0 for spacing_m (got " + Num(along_spacing_m) + ")");
  }
  if (!(std::isfinite(outer_scale) && outer_scale >= 1.0)) {
    ThrowInvalid("outer_scale: must be a finite number >= 1 (got " + Num(outer_scale) + ")");
  }
  CheckFinite(heading_deg, "heading_deg");
  if (min_shots_per_line < 1) ThrowInvalid("min_shots_per_line: must be >= 1");
  CheckPositive(altitude_m, "altitude_m");
  CheckFinite(ground_height_m, "ground_height_m");
  if (!(std::isfinite(min_clearance_m) && min_clearance_m >= 0.0)) {
    ThrowInvalid("min_clearance_m: must be a finite number >= 0 (got " + Num(min_clearance_m) + ")");
  }
  CheckPositive(ground_speed_mps, "ground_speed_mps");
  if (!(std::isfinite(hover_s) && hover_s >= 0.0)) {
    ThrowInvalid("hover_s: must be a finite number >= 0 (got " + Num(hover_s) + ")");
  }
  if (max_waypoints < 1 || max_waypoints > kMaxWaypointsBound) {
    ThrowInvalid("max_waypoints: must be in [1, 10^12] (got " + std::to_string(max_waypoints) + ")");
  }
  if (!(battery_min > 0.0)) ThrowInvalid("battery_min: must be > 0 minutes, or inf (got " + Num(battery_min) + ")");
  if (image_width < 1 || image_height < 1) ThrowInvalid("image_width: image size must be >= 1 pixel");
  if (!(fov_deg > 0.0 && fov_deg < 180.0)) {
    ThrowInvalid("fov_deg: must be in (0, 180) degrees (got " + Num(fov_deg) + ")");
  }
  CheckFieldRanges(*this);  // what the conditions above leave (NaN in a field they skip)
}

FlightPlanResult PlanFlight(const FlightPlanOptions& options, ProgressSink* progress) {
  options.Check();
  FlightPlanResult result;
  const Shape shape = BuildShape(options, result.crs);
  result.outline = shape.Outline();
  result.growth_center = shape.center;
  const double radius = ApertureRadius(shape);
  if (shape.kind == "circle" || shape.kind == "sector") {
    result.aperture_area_m2 = kPi * shape.radius * shape.radius * shape.angle_deg / 360.0;
  } else if (shape.kind != "line") {
    result.aperture_area_m2 = PolygonArea(shape.polygon);
  }
  result.aperture_radius_m = radius;

  // Count first, storing nothing: refuse a plan too large for max_waypoints, the battery or the
  // memory budget before a waypoint is allocated.
  PatternWalk walk(shape, options, radius, progress);
  const double across0 = walk.across0(), along0 = walk.along0();
  const double lines_across = walk.LinesAcross();
  const bool too_many_lines = lines_across > static_cast<double>(options.max_waypoints);
  if (!too_many_lines) walk.CheckAlong();
  const PatternWalk::Totals counted =
      too_many_lines ? PatternWalk::Totals{} : walk.Count(options.max_waypoints);
  if (too_many_lines || counted.over) {
    std::string about;
    if (shape.kind == "line") {
      double length = 0.0;
      for (size_t i = 0; i + 1 < shape.polygon.size(); ++i) {
        length += std::hypot(shape.polygon[i + 1][0] - shape.polygon[i][0],
                             shape.polygon[i + 1][1] - shape.polygon[i][1]);
      }
      about = "about " + Grouped(std::floor(length / along0) + 1.0) + ": length " +
              Num(std::round(length)) + " m / along_spacing_m " + Num(along0) + " m";
    } else {
      about = std::string(options.outer_scale == 1.0 ? "about " : "at most about ") +
              Grouped(std::round(result.aperture_area_m2 / (across0 * along0))) + ": area " +
              Grouped(std::round(result.aperture_area_m2)) + " m^2 / (spacing_m " + Num(across0) +
              " m x along_spacing_m " + Num(along0) + " m)";
    }
    if (shape.kind == "circle" || shape.kind == "sector") about += "; radius_m " + Num(shape.radius);
    if (too_many_lines) {
      about += "; " + Grouped(lines_across) +
               (options.pattern == "circles" ? " rings" : " scan lines") + " across it";
    }
    ThrowInvalid("max_waypoints: the plan has more than " +
                 Grouped(static_cast<double>(options.max_waypoints)) + " waypoints (" + about +
                 "); raise max_waypoints or the spacings");
  }
  if (counted.shots == 0) {
    ThrowInvalid("spacing_m: no shot lies inside the " + shape.kind + " (spacing " + Num(across0) +
                 " m, along " + Num(along0) + " m)");
  }
  // Without terrain the heights are one, and the count's length is the path's.
  if (options.dem.empty() || options.altitude_mode == "constant") {
    RefuseOverBattery(options, counted.length_m, counted.shots, 1.0 + 1e-9);
  }
  {
    const uint64_t per_shot =
        sizeof(Shot) + sizeof(Waypoint) + (result.crs.empty() ? 0 : 2 * sizeof(Vec3d));
    CheckMemoryBudget(SaturatingProduct({static_cast<uint64_t>(counted.shots), per_shot}),
                      "spacing_m/along_spacing_m",
                      Grouped(static_cast<double>(counted.shots)) + " waypoints x " +
                          std::to_string(per_shot) + " bytes");
  }
  PatternWalk::Totals generated;
  const std::vector<Shot> shots = walk.Generate(counted.shots, &generated);
  result.lines = generated.lines;
  if (generated.shots != counted.shots || static_cast<int64_t>(shots.size()) != counted.shots) {
    throw std::logic_error("PlanFlight: the count pass and the plan disagree");
  }
  if (shape.kind != "line" && across0 > 2.0 * radius) {
    result.warnings.push_back("spacing_m (" + Num(across0) + " m) exceeds the aperture's width (" +
                              Num(2.0 * radius) + " m): one line or ring only");
  }

  // Heights.
  const double up = options.terrain_up == "-z" ? -1.0 : 1.0;
  std::unique_ptr<Terrain> terrain;
  if (!options.dem.empty()) terrain = std::make_unique<Terrain>(ReadTerrain(options));
  auto ground_at = [&](const Point2& p, const std::string& what) {
    if (!terrain) return options.ground_height_m;
    const double z = terrain->HeightAt(p[0], p[1]);
    if (std::isnan(z)) {
      ThrowInvalid(options.dem + ": " + what + " at (" + Num(p[0]) + ", " + Num(p[1]) +
                   ") is outside the DEM (is the plan in the DEM's frame?)");
    }
    return z;
  };
  double constant_z = 0.0;
  if (options.altitude_mode == "constant") {
    constant_z = ground_at(shape.center, "the growth centre") + up * options.altitude_m;
  }
  result.min_agl_m = std::numeric_limits<double>::infinity();
  result.max_agl_m = -result.min_agl_m;
  double ground_lo = result.min_agl_m, ground_hi = result.max_agl_m;
  result.waypoints.reserve(shots.size());
  for (size_t i = 0; i < shots.size(); ++i) {
    if (i % 4096 == 0 && ProgressCancelled(progress)) throw Cancelled();
    Waypoint w;
    w.x = shots[i].p[0];
    w.y = shots[i].p[1];
    w.line = shots[i].line;
    w.ground_z = ground_at(shots[i].p, "shot " + std::to_string(i));
    w.z = options.altitude_mode == "constant" ? constant_z : w.ground_z + up * options.altitude_m;
    w.agl_m = up * (w.z - w.ground_z);
    if (options.altitude_mode == "constant" && w.agl_m < options.min_clearance_m) {
      ThrowInvalid("altitude_m: shot " + std::to_string(i) + " at (" + Num(w.x) + ", " + Num(w.y) +
                   ") would be " + Num(w.agl_m) + " m above the terrain (" +
                   (w.agl_m < 0 ? "below it" : "under min_clearance_m " + Num(options.min_clearance_m) + " m") +
                   "); fly higher or use altitude_mode = terrain");
    }
    result.min_agl_m = std::min(result.min_agl_m, w.agl_m);
    result.max_agl_m = std::max(result.max_agl_m, w.agl_m);
    ground_lo = std::min(ground_lo, w.ground_z);
    ground_hi = std::max(ground_hi, w.ground_z);
    result.waypoints.push_back(w);
  }
  if (terrain && options.altitude_mode == "terrain" && ground_hi - ground_lo > 0.5) {
    result.warnings.push_back("terrain-following: the altitude changes by " +
                              Num(std::round((ground_hi - ground_lo) * 10) / 10) +
                              " m over the plan");
  }

  // WGS84.
  if (!result.crs.empty()) {
    std::vector<Vec3d> points;
    for (const Waypoint& w : result.waypoints) points.push_back({w.x, w.y, 0.0});
    const std::vector<Vec3d> lonlat = TransformPoints(points, result.crs, "EPSG:4326", "crs");
    for (size_t i = 0; i < lonlat.size(); ++i) {
      result.waypoints[i].longitude_deg = lonlat[i].x;
      result.waypoints[i].latitude_deg = lonlat[i].y;
    }
  } else {
    for (Waypoint& w : result.waypoints) {
      w.latitude_deg = w.longitude_deg = std::numeric_limits<double>::quiet_NaN();
    }
  }

  // Length and time.
  result.images = static_cast<int64_t>(result.waypoints.size());
  result.min_step_m = std::numeric_limits<double>::infinity();
  result.max_step_m = 0.0;
  for (size_t i = 1; i < result.waypoints.size(); ++i) {
    if (i % 65536 == 0 && ProgressCancelled(progress)) throw Cancelled();
    const Waypoint& a = result.waypoints[i - 1];
    const Waypoint& b = result.waypoints[i];
    const double step = std::sqrt((b.x - a.x) * (b.x - a.x) + (b.y - a.y) * (b.y - a.y) +
                                  (b.z - a.z) * (b.z - a.z));
    result.length_m += step;
    result.min_step_m = std::min(result.min_step_m, step);
    result.max_step_m = std::max(result.max_step_m, step);
  }
  if (result.waypoints.size() < 2) result.min_step_m = 0.0;
  result.flight_time_s =
      result.length_m / options.ground_speed_mps + static_cast<double>(result.images) * options.hover_s;
  result.frames_per_minute =
      result.flight_time_s > 0 ? static_cast<double>(result.images) * 60.0 / result.flight_time_s : 0.0;
  if (std::isfinite(options.battery_min)) {
    result.battery_fraction = result.flight_time_s / (60.0 * options.battery_min);
    RefuseOverBattery(options, result.length_m, result.images, 1.0);
    if (result.battery_fraction > 0.9) {
      result.warnings.push_back("the plan takes " +
                                Num(std::round(result.battery_fraction * 100.0)) +
                                "% of the battery budget");
    }
  }

  // Eq. 2 at the planned height above the ground: n / A = fx fy / d^2 (metrics/resolution.h; its
  // SamplingResolution also back-projects every pixel, which a plan does not need).
  const PinholeCamera camera =
      PinholeCamera::FromFov(options.image_width, options.image_height, options.fov_deg);
  result.eq2_samples_per_m2 = camera.fx * camera.fy / (options.altitude_m * options.altitude_m);
  result.eq2_sample_size_m = 1.0 / std::sqrt(result.eq2_samples_per_m2);
  return result;
}

FlightPlanCount CountFlightPlan(const FlightPlanOptions& options, ProgressSink* progress) {
  options.Check();
  std::string crs;
  const Shape shape = BuildShape(options, crs);
  PatternWalk walk(shape, options, ApertureRadius(shape), progress);
  if (walk.LinesAcross() > static_cast<double>(options.max_waypoints)) {
    return {options.max_waypoints, 0, 0.0, true};
  }
  walk.CheckAlong();
  const PatternWalk::Totals totals = walk.Count(options.max_waypoints);
  return {totals.shots, totals.lines, totals.length_m, totals.over};
}

std::ostream& operator<<(std::ostream& stream, const FlightPlanResult& r) {
  return stream << "FlightPlanResult(images=" << r.images << ", lines=" << r.lines
                << ", length_m=" << r.length_m << ", flight_time_s=" << r.flight_time_s
                << ", frames_per_minute=" << r.frames_per_minute << ")";
}

namespace {
void RequireCrs(const FlightPlanResult& result, const char* what) {
  if (result.crs.empty()) {
    ThrowInvalid(std::string(what) +
                 ": the plan is in a local frame (no crs): give crs (a projected CRS) or "
                 "coordinates = latlon for WGS84 waypoints");
  }
}
// Bytes an export needs per shot, at most (the text; for GeoJSON the JSON document built
// before it is written, about 1 KB a shot, and the text).
constexpr uint64_t kCsvBytesPerShot = 160;
constexpr uint64_t kKmlBytesPerShot = 320;
constexpr uint64_t kGeoJsonBytesPerShot = 2048;
void CheckExportBytes(const FlightPlanResult& result, uint64_t per_shot, const char* what) {
  const auto shots = static_cast<uint64_t>(result.waypoints.size());
  CheckMemoryBudget(SaturatingProduct({shots, per_shot}), what,
                    std::to_string(shots) + " waypoints x " + std::to_string(per_shot) + " bytes");
}
void PollExport(size_t i, ProgressSink* progress) {
  if (i % 4096 == 0 && ProgressCancelled(progress)) throw Cancelled();
}
std::string Fixed(double value, int decimals) {
  if (!std::isfinite(value)) return "";
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, "%.*f", decimals, value);
  return buffer;
}
}  // namespace

std::string FlightPlanCsv(const FlightPlanResult& result, ProgressSink* progress) {
  CheckExportBytes(result, kCsvBytesPerShot, "csv");
  std::string out = "index,latitude,longitude,altitude_agl_m,x_m,y_m,z_m,ground_z_m,line\n";
  out.reserve(result.waypoints.size() * kCsvBytesPerShot / 2);
  for (size_t i = 0; i < result.waypoints.size(); ++i) {
    PollExport(i, progress);
    const Waypoint& w = result.waypoints[i];
    out += std::to_string(i) + "," + Fixed(w.latitude_deg, 10) + "," + Fixed(w.longitude_deg, 10) +
           "," + Fixed(w.agl_m, 3) + "," + Fixed(w.x, 4) + "," + Fixed(w.y, 4) + "," +
           Fixed(w.z, 4) + "," + Fixed(w.ground_z, 4) + "," + std::to_string(w.line) + "\n";
  }
  return out;
}

std::string FlightPlanGeoJson(const FlightPlanResult& result, ProgressSink* progress) {
  RequireCrs(result, "geojson");
  CheckExportBytes(result, kGeoJsonBytesPerShot, "geojson");
  nlohmann::ordered_json path = nlohmann::ordered_json::array();
  nlohmann::ordered_json features = nlohmann::ordered_json::array();
  for (size_t i = 0; i < result.waypoints.size(); ++i) {
    PollExport(i, progress);
    const Waypoint& w = result.waypoints[i];
    path.push_back({w.longitude_deg, w.latitude_deg, w.agl_m});
  }
  features.push_back({{"type", "Feature"},
                      {"properties", {{"name", "path"}, {"images", result.images},
                                      {"length_m", result.length_m},
                                      {"flight_time_s", result.flight_time_s}}},
                      {"geometry", {{"type", "LineString"}, {"coordinates", path}}}});
  for (size_t i = 0; i < result.waypoints.size(); ++i) {
    PollExport(i, progress);
    const Waypoint& w = result.waypoints[i];
    features.push_back(
        {{"type", "Feature"},
         {"properties", {{"index", i}, {"altitude_agl_m", w.agl_m}, {"line", w.line}}},
         {"geometry",
          {{"type", "Point"}, {"coordinates", {w.longitude_deg, w.latitude_deg, w.agl_m}}}}});
  }
  nlohmann::ordered_json doc = {{"type", "FeatureCollection"}, {"features", features}};
  return doc.dump(1) + "\n";
}

std::string FlightPlanKml(const FlightPlanResult& result, ProgressSink* progress) {
  RequireCrs(result, "kml");
  CheckExportBytes(result, kKmlBytesPerShot, "kml");
  std::string out =
      "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
      "<kml xmlns=\"http://www.opengis.net/kml/2.2\">\n<Document>\n<name>aos flight plan</name>\n"
      "<Placemark>\n<name>path</name>\n<LineString>\n<altitudeMode>relativeToGround</altitudeMode>\n"
      "<coordinates>\n";
  for (size_t i = 0; i < result.waypoints.size(); ++i) {
    PollExport(i, progress);
    const Waypoint& w = result.waypoints[i];
    out += Fixed(w.longitude_deg, 10) + "," + Fixed(w.latitude_deg, 10) + "," + Fixed(w.agl_m, 3) + "\n";
  }
  out += "</coordinates>\n</LineString>\n</Placemark>\n";
  for (size_t i = 0; i < result.waypoints.size(); ++i) {
    PollExport(i, progress);
    const Waypoint& w = result.waypoints[i];
    out += "<Placemark>\n<name>" + std::to_string(i) +
           "</name>\n<Point>\n<altitudeMode>relativeToGround</altitudeMode>\n<coordinates>" +
           Fixed(w.longitude_deg, 10) + "," + Fixed(w.latitude_deg, 10) + "," + Fixed(w.agl_m, 3) +
           "</coordinates>\n</Point>\n</Placemark>\n";
  }
  out += "</Document>\n</kml>\n";
  return out;
}

Image FlightPlanMap(const FlightPlanOptions& options, const FlightPlanResult& result, int size_px,
                    ProgressSink* progress) {
  if (size_px < 64) ThrowInvalid("size_px: must be >= 64 (got " + std::to_string(size_px) + ")");
  // The canvas, the picture and (over a DEM) a double per pixel; a side is at most size_px.
  const auto side = static_cast<uint64_t>(size_px);
  CheckMemoryBudget(SaturatingProduct({side, side, options.dem.empty() ? 6u : 14u}), "size_px",
                    std::to_string(size_px) + " x " + std::to_string(size_px) + " pixels");
  double lo_x = 1e300, lo_y = 1e300, hi_x = -1e300, hi_y = -1e300;
  auto extend = [&](double x, double y) {
    lo_x = std::min(lo_x, x), hi_x = std::max(hi_x, x), lo_y = std::min(lo_y, y), hi_y = std::max(hi_y, y);
  };
  for (const auto& p : result.outline) extend(p[0], p[1]);
  for (const Waypoint& w : result.waypoints) extend(w.x, w.y);
  const double span = std::max({hi_x - lo_x, hi_y - lo_y, 1.0});
  const double margin = 0.12 * span;
  lo_x -= margin, lo_y -= margin, hi_x += margin, hi_y += margin;
  const double scale = size_px / std::max(hi_x - lo_x, hi_y - lo_y);  // pixels per metre
  const int width = std::max(64, static_cast<int>(std::ceil((hi_x - lo_x) * scale)));
  const int height = std::max(64, static_cast<int>(std::ceil((hi_y - lo_y) * scale)));
  // Pixel centres at +0.5: pixel (i, j) shows world (lo_x + (i + 0.5) / scale, hi_y - (j + 0.5) / scale).
  auto to_px = [&](double x, double y) {
    return cv::Point2d((x - lo_x) * scale - 0.5, (hi_y - y) * scale - 0.5);
  };
  cv::Mat canvas(height, width, CV_8UC3, cv::Scalar(245, 245, 240));
  if (!options.dem.empty()) {
    const double up = options.terrain_up == "-z" ? -1.0 : 1.0;
    const Terrain terrain = ReadTerrain(options);
    cv::Mat heights(height, width, CV_64F);
    for (int j = 0; j < height; ++j) {
      if (ProgressCancelled(progress)) throw Cancelled();
      for (int i = 0; i < width; ++i) {
        heights.at<double>(j, i) =
            up * terrain.HeightAt(lo_x + (i + 0.5) / scale, hi_y - (j + 0.5) / scale);
      }
    }
    // Hillshade: light from the north-west, 45 degrees up.
    const double light[3] = {-0.5, 0.5, std::sqrt(0.5)};
    for (int j = 1; j + 1 < height; ++j) {
      for (int i = 1; i + 1 < width; ++i) {
        // Slopes exaggerated 3 times, so that gentle forest terrain shows.
        const double dzdx = (heights.at<double>(j, i + 1) - heights.at<double>(j, i - 1)) * scale * 1.5;
        const double dzdy = (heights.at<double>(j - 1, i) - heights.at<double>(j + 1, i)) * scale * 1.5;
        if (!std::isfinite(dzdx) || !std::isfinite(dzdy)) continue;
        const double norm = std::sqrt(dzdx * dzdx + dzdy * dzdy + 1.0);
        const double shade =
            std::max(0.0, (-dzdx * light[0] - dzdy * light[1] + light[2]) / norm);
        const auto grey = static_cast<unsigned char>(std::clamp(60.0 + 180.0 * shade, 0.0, 255.0));
        canvas.at<cv::Vec3b>(j, i) = cv::Vec3b(grey, grey, grey);
      }
    }
  }
  const int shift = 4;
  auto fixed = [&](double x, double y) {
    const cv::Point2d p = to_px(x, y);
    return cv::Point(static_cast<int>(std::lround((p.x + 0.5) * (1 << shift))),
                     static_cast<int>(std::lround((p.y + 0.5) * (1 << shift))));
  };
  std::vector<cv::Point> outline;
  for (const auto& p : result.outline) outline.push_back(fixed(p[0], p[1]));
  // OpenCV draws BGR; the image is written as RGB below.
  cv::polylines(canvas, outline, options.shape != "line", cv::Scalar(200, 90, 20), 2, cv::LINE_AA, shift);
  std::vector<cv::Point> path;
  for (size_t i = 0; i < result.waypoints.size(); ++i) {
    PollExport(i, progress);
    path.push_back(fixed(result.waypoints[i].x, result.waypoints[i].y));
  }
  cv::polylines(canvas, path, false, cv::Scalar(40, 40, 220), 1, cv::LINE_AA, shift);
  const int dot = std::clamp(static_cast<int>(0.25 * scale), 1, 4);
  for (const cv::Point& p : path) cv::circle(canvas, p, dot << shift, cv::Scalar(20, 20, 150), cv::FILLED, cv::LINE_AA, shift);
  const cv::Point c = fixed(result.growth_center[0], result.growth_center[1]);
  cv::drawMarker(canvas, cv::Point(c.x >> shift, c.y >> shift), cv::Scalar(0, 120, 0), cv::MARKER_CROSS, 12, 2);
  // Scale bar: 1, 2 or 5 x 10^k metres, about a quarter of the width.
  const double target = (width / scale) / 4.0;
  const double power = std::pow(10.0, std::floor(std::log10(target)));
  double bar = power;
  for (double f : {2.0, 5.0, 10.0}) {
    if (f * power <= target) bar = f * power;
  }
  const int bar_px = static_cast<int>(std::lround(bar * scale));
  const int x0 = 12, y0 = height - 14;
  cv::rectangle(canvas, cv::Point(x0 - 4, y0 - 22), cv::Point(x0 + bar_px + 4, y0 + 8),
                cv::Scalar(255, 255, 255), cv::FILLED);
  cv::rectangle(canvas, cv::Point(x0, y0 - 3), cv::Point(x0 + bar_px, y0 + 3), cv::Scalar(0, 0, 0), cv::FILLED);
  char label[32];
  std::snprintf(label, sizeof label, "%g m", bar);
  cv::putText(canvas, label, cv::Point(x0, y0 - 8), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  // North arrow.
  cv::arrowedLine(canvas, cv::Point(width - 20, 40), cv::Point(width - 20, 12), cv::Scalar(0, 0, 0), 2, cv::LINE_AA, 0, 0.3);
  // North in a CRS; in a local frame the arrow is +y (not known to be north).
  cv::putText(canvas, result.crs.empty() ? "+y" : "N", cv::Point(width - 26, 56), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  cv::cvtColor(canvas, canvas, cv::COLOR_BGR2RGB);
  Image image(width, height, 3, PixelType::kU8);
  image.CopyFrom(canvas.data, static_cast<ptrdiff_t>(canvas.step1()));
  return image;
}

}  // namespace aos
