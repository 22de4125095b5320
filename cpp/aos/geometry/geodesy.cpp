#include "aos/geometry/geodesy.h"

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

std::string UtmCrs(int zone, bool north) {
  return "EPSG:" + std::to_string((north ? 32600 : 32700) + zone);
}

}  // namespace

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
    // Degrees: (longitude, latitude, height), projected to the UTM zone of the mean longitude.
    double longitude_sum = 0.0, latitude_sum = 0.0;
    for (const Vec3d& p : points_in_crs) {
      if (!(std::abs(p.x) <= 180.0) || !(std::abs(p.y) <= 90.0)) {
        ThrowInvalid(where + ": (" + FormatNumber(p.x) + ", " + FormatNumber(p.y) +
                     ") is not a longitude/latitude in degrees, as " + crs_name + " needs");
      }
      longitude_sum += p.x;
      latitude_sum += p.y;
    }
    const double latitude = latitude_sum / points_in_crs.size();
    if (latitude < -80.0 || latitude > 84.0) {
      ThrowInvalid(where + ": latitude " + FormatNumber(latitude) +
                   " is outside UTM's range [-80, 84] degrees");
    }
    const int zone = StandardZone(longitude_sum / points_in_crs.size());
    const bool north = latitude >= 0.0;
    const Pj transform = CreateTransform(ctx, crs, UtmCrs(zone, north), where);
    for (const Vec3d& p : points_in_crs) {
      result.points.push_back(Transform(ctx, transform.get(), p, where));
    }
    result.frame = "UTM " + std::to_string(zone) + (north ? "N" : "S") + " (" + crs_name + ")";
    result.from_degrees = true;
    return result;
  }
  if (type != PJ_TYPE_PROJECTED_CRS) {
    ThrowInvalid(where + ": " + crs_name + " is neither geographic (degrees) nor projected "
                                           "(metres); give positions in one of those");
  }
  // A projected CRS: its axes must be in metres.
  Pj system(proj_crs_get_coordinate_system(ctx.context, source.get()));
  const int axes = system ? proj_cs_get_axis_count(ctx.context, system.get()) : 0;
  for (int i = 0; i < axes; ++i) {
    double factor = 0.0;
    const char* unit = nullptr;
    proj_cs_get_axis_info(ctx.context, system.get(), i, nullptr, nullptr, nullptr, &factor,
                          &unit, nullptr, nullptr);
    if (factor != 1.0) {
      ThrowInvalid(where + ": " + crs_name + " has axes in " + (unit ? unit : "?") +
                   "; aos needs metres (give a metric CRS or convert)");
    }
  }
  result.points = points_in_crs;
  result.frame = crs_name;
  return result;
}

}  // namespace aos
