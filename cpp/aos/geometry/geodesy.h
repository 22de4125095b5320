#pragma once
// Geodesy for geo-referencing, through PROJ (Debian's libproj-dev): WGS84 latitude/longitude to
// UTM (a metric map frame in which a light field's origin and camera positions live;
// lightfield.h keeps the origin in double), and positions in any CRS PROJ knows to a metric
// frame.
//
// Contract
// - UtmFromWgs84 projects with PROJ's transverse Mercator (EPSG:326zz north, EPSG:327zz south:
//   k0 = 0.9996, false easting 500 km, false northing 0 or 10,000 km), accurate to well below a
//   millimetre within a zone.
// - zone 0 picks the standard zone of the longitude (1..60, no Norway/Svalbard exceptions);
//   a given zone (1..60) forces it, so that points near a zone edge share one frame.
// - MetricFromCrs takes points in a CRS given as PROJ understands it ("EPSG:4326", "EPSG:25833",
//   a WKT or PROJ string). A geographic CRS (degrees) is projected to the UTM zone of the points'
//   mean longitude; a projected CRS in metres is kept as it is; other units are refused. Points are
//   (x, y, z) in the CRS's "visualisation" order: longitude/easting first.
//
// Throws std::invalid_argument for a latitude outside [-80, 84] degrees (UTM's range), a
// non-finite value, a zone outside 0..60, or a CRS PROJ does not know, naming `where`.
#include <string>
#include <vector>

#include "aos/geometry/rigid.h"

namespace aos {

struct UtmCoordinate {
  int zone = 0;
  bool north = true;
  double easting = 0.0;   // metres
  double northing = 0.0;  // metres
};

UtmCoordinate UtmFromWgs84(double latitude_deg, double longitude_deg, int zone = 0,
                           const std::string& where = "position");

struct MetricPoints {
  std::vector<Vec3d> points;  // metres (easting, northing, height)
  std::string frame;          // e.g. "UTM 33N (WGS84)" or the projected CRS's name
  bool from_degrees = false;  // the input CRS was geographic
};

MetricPoints MetricFromCrs(const std::vector<Vec3d>& points_in_crs, const std::string& crs,
                           const std::string& where);

// Whether PROJ takes `crs` as a geographic (degrees) CRS; throws for an unknown CRS.
bool IsGeographicCrs(const std::string& crs, const std::string& where);

}  // namespace aos
