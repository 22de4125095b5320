#include "aos/geometry/geodesy.h"

#include <algorithm>
#include <cmath>
#include <memory>

#include <proj.h>

#include "aos/util/error.h"

namespace aos {
namespace {

// A PROJ context per call (contexts are not thread-safe; these calls are rare and cheap), with
// PROJ's own logging silenced: its errors come back through proj_context_errno.
struct Context {
  PJ_CONTEXT* context = proj_context_create();
  Context() { proj_log_level(context, PJ_LOG_NONE); }
  ~Context() { proj_context_destroy(context); }
  std::string LastError() const {
    const char* text = proj_context_errno_string(context, proj_context_errno(context));
    return text != nullptr ? text : "unknown PROJ error";
  }
};

struct PjDeleter {
  void operator()(PJ* pj) const { proj_destroy(pj); }
};
using Pj = std::unique_ptr<PJ, PjDeleter>;

Pj CreateCrs(Context& ctx, const std::string& crs, const std::string& where) {
  Pj pj(proj_create(ctx.context, crs.c_str()));
  if (!pj) ThrowInvalid(where + ": CRS '" + crs + "' is not known to PROJ (" + ctx.LastError() + ")");
  const PJ_TYPE type = proj_get_type(pj.get());
  const bool is_crs = type == PJ_TYPE_GEOGRAPHIC_2D_CRS || type == PJ_TYPE_GEOGRAPHIC_3D_CRS ||
                      type == PJ_TYPE_PROJECTED_CRS || type == PJ_TYPE_COMPOUND_CRS ||
                      type == PJ_TYPE_GEOCENTRIC_CRS;
  if (!is_crs) ThrowInvalid(where + ": '" + crs + "' is not a coordinate reference system");
  return pj;
}

// A transformation from `from` to `to` with longitude/easting first on both sides.
Pj CreateTransform(Context& ctx, const std::string& from, const std::string& to,
                   const std::string& where) {
  Pj raw(proj_create_crs_to_crs(ctx.context, from.c_str(), to.c_str(), nullptr));
  if (!raw) {
    ThrowInvalid(where + ": PROJ cannot transform from " + from + " to " + to + " (" +
                 ctx.LastError() + ")");
  }
  Pj normalised(proj_normalize_for_visualization(ctx.context, raw.get()));
  if (!normalised) ThrowInvalid(where + ": PROJ: " + ctx.LastError());
  return normalised;
}

Vec3d Transform(Context& ctx, PJ* transform, const Vec3d& point, const std::string& where) {
  const PJ_COORD out = proj_trans(transform, PJ_FWD, proj_coord(point.x, point.y, point.z, 0.0));
  if (!std::isfinite(out.xyz.x) || !std::isfinite(out.xyz.y) || !std::isfinite(out.xyz.z)) {
    ThrowInvalid(where + ": PROJ cannot transform (" + FormatNumber(point.x) + ", " +
                 FormatNumber(point.y) + ", " + FormatNumber(point.z) + ") (" + ctx.LastError() +
                 ")");
  }
  return Vec3d(out.xyz.x, out.xyz.y, out.xyz.z);
}

int StandardZone(double longitude_deg) {
  double lon = std::fmod(longitude_deg + 180.0, 360.0);
  if (lon < 0.0) lon += 360.0;
  return std::min(60, static_cast<int>(std::floor(lon / 6.0)) + 1);
}

std::string UtmCrs(int zone, bool north) { return UtmEpsg(zone, north); }

// "EPSG:<code>" of a CRS object, from its own identifier or PROJ's identification (an
// equivalent EPSG entry with 100% confidence); "" when there is none.
std::string EpsgOf(Context& ctx, PJ* crs) {
  for (int i = 0;; ++i) {
    const char* authority = proj_get_id_auth_name(crs, i);
    if (authority == nullptr) break;
    const char* code = proj_get_id_code(crs, i);
    if (std::string(authority) == "EPSG" && code != nullptr) return std::string("EPSG:") + code;
  }
  int* confidence = nullptr;
  PJ_OBJ_LIST* candidates = proj_identify(ctx.context, crs, "EPSG", nullptr, &confidence);
  std::string result;
  if (candidates != nullptr) {
    const int count = proj_list_get_count(candidates);
    for (int i = 0; i < count && result.empty(); ++i) {
      if (confidence[i] < 100) continue;
      Pj candidate(proj_list_get(ctx.context, candidates, i));
      const char* code = candidate ? proj_get_id_code(candidate.get(), 0) : nullptr;
      if (code != nullptr) result = std::string("EPSG:") + code;
    }
    proj_int_list_destroy(confidence);
    proj_list_destroy(candidates);
  }
  return result;
}

// Whether every axis of the coordinate system of `crs` (a projected CRS) is in metres; *unit
// gets the first other unit's name.
bool AxesInMetres(Context& ctx, PJ* crs, std::string* unit) {
  Pj system(proj_crs_get_coordinate_system(ctx.context, crs));
  const int axes = system ? proj_cs_get_axis_count(ctx.context, system.get()) : 0;
  for (int i = 0; i < axes; ++i) {
    double factor = 0.0;
    const char* name = nullptr;
    proj_cs_get_axis_info(ctx.context, system.get(), i, nullptr, nullptr, nullptr, &factor,
                          &name, nullptr, nullptr);
    if (factor != 1.0) {
      *unit = name != nullptr ? name : "?";
      return false;
    }
  }
  return axes > 0;
}

}  // namespace

std::string UtmEpsg(int zone, bool north) {
  if (zone < 1 || zone > 60) ThrowInvalid("UTM zone must be 1..60, got " + std::to_string(zone));
  return "EPSG:" + std::to_string((north ? 32600 : 32700) + zone);
}

std::vector<Vec3d> TransformPoints(const std::vector<Vec3d>& points, const std::string& from_crs,
                                   const std::string& to_crs, const std::string& where) {
  Context ctx;
  CreateCrs(ctx, from_crs, where);  // each CRS named on its own when unknown
  CreateCrs(ctx, to_crs, where);
  const Pj transform = CreateTransform(ctx, from_crs, to_crs, where);
  std::vector<Vec3d> result;
  result.reserve(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    const Vec3d& p = points[i];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
      ThrowInvalid(where + ": point " + std::to_string(i) + " is not finite");
    }
    result.push_back(Transform(ctx, transform.get(), p,
                               where + ": point " + std::to_string(i) + " from " + from_crs +
                                   " to " + to_crs));
  }
  return result;
}

std::string EpsgOfCrs(const std::string& crs, const std::string& where) {
  Context ctx;
  const Pj pj = CreateCrs(ctx, crs, where);
  return EpsgOf(ctx, pj.get());
}

std::string DescribeCrs(const std::string& crs) {
  if (crs.empty()) return "";
  Context ctx;
  Pj pj(proj_create(ctx.context, crs.c_str()));
  if (!pj) return crs;
  const char* raw_name = proj_get_name(pj.get());
  const std::string name = raw_name != nullptr ? raw_name : "";
  const std::string epsg = EpsgOf(ctx, pj.get());
  if (!epsg.empty()) return name.empty() ? epsg : epsg + " (" + name + ")";
  return name.empty() ? crs : name;
}

void CheckLightFieldCrs(const std::string& crs, const std::string& where) {
  if (crs.empty()) return;
  const std::string prefix = "EPSG:";
  const bool digits = crs.size() > prefix.size() && crs.compare(0, prefix.size(), prefix) == 0 &&
                      crs.find_first_not_of("0123456789", prefix.size()) == std::string::npos;
  if (!digits) {
    ThrowInvalid(where + ": \"" + crs + "\" is not an EPSG code (expected \"EPSG:<code>\", e.g. "
                 "\"EPSG:32633\" for UTM 33N)");
  }
  Context ctx;
  Pj pj(proj_create(ctx.context, crs.c_str()));
  if (!pj) ThrowInvalid(where + ": " + crs + " is not known to PROJ (" + ctx.LastError() + ")");
  PJ_TYPE type = proj_get_type(pj.get());
  const char* raw_name = proj_get_name(pj.get());
  const std::string name = crs + " (" + (raw_name != nullptr ? raw_name : "?") + ")";
  Pj horizontal;
  if (type == PJ_TYPE_COMPOUND_CRS) {
    horizontal.reset(proj_crs_get_sub_crs(ctx.context, pj.get(), 0));
    if (horizontal) type = proj_get_type(horizontal.get());
  }
  PJ* planar = horizontal ? horizontal.get() : pj.get();
  if (type == PJ_TYPE_GEOGRAPHIC_2D_CRS || type == PJ_TYPE_GEOGRAPHIC_3D_CRS) {
    ThrowInvalid(where + ": " + name + " is geographic (degrees); a light field's local frame is "
                 "metric: give a projected CRS in metres (e.g. the UTM zone's EPSG:326zz)");
  }
  if (type != PJ_TYPE_PROJECTED_CRS) {
    ThrowInvalid(where + ": " + name + " is not a projected CRS; a light field's world frame is "
                 "easting, northing, height in metres");
  }
  std::string unit;
  if (!AxesInMetres(ctx, planar, &unit)) {
    ThrowInvalid(where + ": " + name + " has axes in " + unit + "; a light field's world frame "
                 "is in metres");
  }
}

double GridBearingOfNorth(double latitude_deg, double longitude_deg, const std::string& crs,
                          const std::string& where) {
  const double step_deg = 1e-5;
  const std::vector<Vec3d> grid = TransformPoints(
      {Vec3d(longitude_deg, latitude_deg, 0.0), Vec3d(longitude_deg, latitude_deg + step_deg, 0.0)},
      "EPSG:4326", crs, where);
  return std::atan2(grid[1].x - grid[0].x, grid[1].y - grid[0].y);
}

UtmCoordinate UtmFromWgs84(double latitude_deg, double longitude_deg, int zone,
                           const std::string& where) {
  if (!std::isfinite(latitude_deg) || !std::isfinite(longitude_deg)) {
    ThrowInvalid(where + ": latitude/longitude must be finite");
  }
  if (latitude_deg < -80.0 || latitude_deg > 84.0) {
    ThrowInvalid(where + ": latitude " + FormatNumber(latitude_deg) +
                 " is outside UTM's range [-80, 84] degrees");
  }
  if (zone < 0 || zone > 60) ThrowInvalid(where + ": UTM zone must be 1..60 (0 = automatic)");
  UtmCoordinate result;
  result.zone = zone > 0 ? zone : StandardZone(longitude_deg);
  result.north = latitude_deg >= 0.0;
  Context ctx;
  const Pj transform = CreateTransform(ctx, "EPSG:4326", UtmCrs(result.zone, result.north), where);
  const Vec3d utm = Transform(ctx, transform.get(), Vec3d(longitude_deg, latitude_deg, 0.0), where);
  result.easting = utm.x;
  result.northing = utm.y;
  return result;
}

double UnwrapLongitude(double longitude_deg, double around_deg) {
  double offset = std::fmod(longitude_deg - around_deg, 360.0);
  if (offset > 180.0) offset -= 360.0;
  if (offset <= -180.0) offset += 360.0;
  return around_deg + offset;
}

GeographicPosition FlightCentre(const std::vector<GeographicPosition>& positions,
                                const std::string& where) {
  if (positions.empty()) ThrowInvalid(where + ": no positions to centre");
  const double deg = std::acos(-1.0) / 180.0;
  double sin_sum = 0.0, cos_sum = 0.0;
  std::vector<double> latitudes;
  for (const GeographicPosition& p : positions) {
    if (!std::isfinite(p.latitude_deg) || !std::isfinite(p.longitude_deg)) {
      ThrowInvalid(where + ": latitude/longitude must be finite");
    }
    latitudes.push_back(p.latitude_deg);
    sin_sum += std::sin(p.longitude_deg * deg);
    cos_sum += std::cos(p.longitude_deg * deg);
  }
  const auto median = [](std::vector<double> values) {
    const size_t m = values.size();
    std::nth_element(values.begin(), values.begin() + m / 2, values.end());
    const double upper = values[m / 2];
    if (m % 2 == 1) return upper;
    return 0.5 * (*std::max_element(values.begin(), values.begin() + m / 2) + upper);
  };
  // The circular mean is only a reference for unwrapping (a minority of wild longitudes may pull
  // it, but not by half a turn); the median around it, and around itself again, is the centre.
  double around = (sin_sum == 0.0 && cos_sum == 0.0) ? positions.front().longitude_deg
                                                     : std::atan2(sin_sum, cos_sum) / deg;
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<double> longitudes;
    for (const GeographicPosition& p : positions) {
      longitudes.push_back(UnwrapLongitude(p.longitude_deg, around));
    }
    around = median(longitudes);
  }
  GeographicPosition centre;
  centre.latitude_deg = median(latitudes);
  centre.longitude_deg = UnwrapLongitude(around, 0.0);
  if (centre.longitude_deg >= 180.0) centre.longitude_deg -= 360.0;
  return centre;
}

double GreatCircleDistance(const GeographicPosition& a, const GeographicPosition& b) {
  const double deg = std::acos(-1.0) / 180.0, radius_m = 6371008.8;
  const double phi_a = a.latitude_deg * deg, phi_b = b.latitude_deg * deg;
  const double half_dphi = 0.5 * (phi_b - phi_a);
  const double half_dlambda = 0.5 * (b.longitude_deg - a.longitude_deg) * deg;
  // Haversine: well conditioned for the small distances a plausibility check compares.
  const double h = std::sin(half_dphi) * std::sin(half_dphi) +
                   std::cos(phi_a) * std::cos(phi_b) * std::sin(half_dlambda) *
                       std::sin(half_dlambda);
  return 2.0 * radius_m * std::asin(std::min(1.0, std::sqrt(h)));
}

bool IsGeographicCrs(const std::string& crs, const std::string& where) {
  Context ctx;
  const Pj pj = CreateCrs(ctx, crs, where);
  const PJ_TYPE type = proj_get_type(pj.get());
  return type == PJ_TYPE_GEOGRAPHIC_2D_CRS || type == PJ_TYPE_GEOGRAPHIC_3D_CRS;
}

MetricPoints MetricFromCrs(const std::vector<Vec3d>& points_in_crs, const std::string& crs,
                           const std::string& where) {
  MetricPoints result;
  if (points_in_crs.empty()) return result;
  Context ctx;
  const Pj source = CreateCrs(ctx, crs, where);
  const PJ_TYPE type = proj_get_type(source.get());
  const char* name = proj_get_name(source.get());
  const std::string crs_name = name != nullptr ? name : crs;
  if (type == PJ_TYPE_GEOGRAPHIC_2D_CRS || type == PJ_TYPE_GEOGRAPHIC_3D_CRS) {
    // Degrees: (longitude, latitude, height), projected to the UTM zone of the points' centre
    // (one zone for all, also across the 180th meridian).
    std::vector<GeographicPosition> positions;
    for (const Vec3d& p : points_in_crs) {
      if (!(std::abs(p.x) <= 180.0) || !(std::abs(p.y) <= 90.0)) {
        ThrowInvalid(where + ": (" + FormatNumber(p.x) + ", " + FormatNumber(p.y) +
                     ") is not a longitude/latitude in degrees, as " + crs_name + " needs");
      }
      positions.push_back({p.y, p.x});
    }
    const GeographicPosition centre = FlightCentre(positions, where);
    const double latitude = centre.latitude_deg;
    if (latitude < -80.0 || latitude > 84.0) {
      ThrowInvalid(where + ": latitude " + FormatNumber(latitude) +
                   " is outside UTM's range [-80, 84] degrees");
    }
    const int zone = StandardZone(centre.longitude_deg);
    const bool north = latitude >= 0.0;
    const Pj transform = CreateTransform(ctx, crs, UtmCrs(zone, north), where);
    for (const Vec3d& p : points_in_crs) {
      result.points.push_back(Transform(ctx, transform.get(), p, where));
    }
    result.frame = "UTM " + std::to_string(zone) + (north ? "N" : "S") + " (" + crs_name + ")";
    result.from_degrees = true;
    result.crs = UtmCrs(zone, north);
    return result;
  }
  if (type != PJ_TYPE_PROJECTED_CRS) {
    ThrowInvalid(where + ": " + crs_name + " is neither geographic (degrees) nor projected "
                                           "(metres); give positions in one of those");
  }
  // A projected CRS: its axes must be in metres.
  std::string unit;
  if (!AxesInMetres(ctx, source.get(), &unit)) {
    ThrowInvalid(where + ": " + crs_name + " has axes in " + unit +
                 "; aos needs metres (give a metric CRS or convert)");
  }
  result.points = points_in_crs;
  result.frame = crs_name;
  result.crs = EpsgOf(ctx, source.get());
  return result;
}

}  // namespace aos
