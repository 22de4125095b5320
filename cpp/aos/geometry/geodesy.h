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
// - A flight's zone: FlightCentre gives the robust centre of a set of positions (the median
//   latitude and longitude, longitudes unwrapped around each other so that a flight across the
//   180th meridian is centred there, not near 0). Its zone serves the whole flight: PROJ takes
//   longitudes on the other side of 180 (or of a zone edge) relative to that zone's central
//   meridian, so every view lands within the flight's extent.
// - MetricFromCrs takes points in a CRS given as PROJ understands it ("EPSG:4326", "EPSG:25833",
//   a WKT or PROJ string). A geographic CRS (degrees) is projected to the UTM zone of the points'
//   centre (FlightCentre); a projected CRS in metres is kept as it is; other units are refused. Points are
//   (x, y, z) in the CRS's "visualisation" order: longitude/easting first. The result names the
//   metric frame's EPSG code when it has one (MetricPoints::crs, e.g. "EPSG:32633").
// - TransformPoints moves points between any two CRSs PROJ can relate (a DEM raster's CRS into a
//   light field's, positions into UTM, ...), in double precision, visualisation order on both
//   sides (longitude/easting first, whatever the CRS's official axis order). Heights pass
//   through unchanged unless both CRSs have a vertical component PROJ can relate.
// - A light field's CRS (LightField::crs) is "EPSG:<code>" of a projected CRS with metre axes
//   (or a compound CRS whose horizontal part is one): its local frame is metric, x east-ish,
//   y north-ish, z up. CheckLightFieldCrs refuses anything else, geographic CRSs (degrees)
//   included.
//
// Throws std::invalid_argument for a latitude outside [-80, 84] degrees (UTM's range), a
// non-finite value, a zone outside 0..60, or a CRS PROJ does not know or cannot transform,
// naming `where`.
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

// A WGS84 position, degrees.
struct GeographicPosition {
  double latitude_deg = 0.0;
  double longitude_deg = 0.0;  // [-180, 180)
};

// The robust centre of positions (see the contract): the median latitude, and the median of the
// longitudes unwrapped around their circular mean (then around that median again), returned in
// [-180, 180). A minority of wild positions (swapped, in radians, another hemisphere) barely
// moves it. Throws std::invalid_argument for no positions or a non-finite value, naming `where`.
GeographicPosition FlightCentre(const std::vector<GeographicPosition>& positions,
                                const std::string& where);

// The longitude `longitude_deg` plus a multiple of 360 that is nearest to `around_deg`:
// within (around - 180, around + 180].
double UnwrapLongitude(double longitude_deg, double around_deg);

// The great-circle distance between two WGS84 positions on the sphere of the Earth's mean radius
// (6,371,008.8 m), metres; within 0.5% of the ellipsoid's. For plausibility checks, not
// geodetic work.
double GreatCircleDistance(const GeographicPosition& a, const GeographicPosition& b);

struct MetricPoints {
  std::vector<Vec3d> points;  // metres (easting, northing, height)
  std::string frame;          // e.g. "UTM 33N (WGS84)" or the projected CRS's name
  bool from_degrees = false;  // the input CRS was geographic
  std::string crs;            // "EPSG:<code>" of the metric frame; empty when it has no code
};

MetricPoints MetricFromCrs(const std::vector<Vec3d>& points_in_crs, const std::string& crs,
                           const std::string& where);

// Whether PROJ takes `crs` as a geographic (degrees) CRS; throws for an unknown CRS.
bool IsGeographicCrs(const std::string& crs, const std::string& where);

// "EPSG:326zz" (north) or "EPSG:327zz" (south) for WGS84 / UTM zone zz (1..60).
std::string UtmEpsg(int zone, bool north);

// Points (x, y, z) in `from_crs` to `to_crs` (any CRS PROJ understands: "EPSG:25833", WKT,
// PROJ strings), longitude/easting first on both sides, double precision. Throws
// std::invalid_argument naming `where` for an unknown CRS, a pair PROJ cannot relate, a
// non-finite input or a point PROJ cannot transform (outside the projection's domain).
std::vector<Vec3d> TransformPoints(const std::vector<Vec3d>& points, const std::string& from_crs,
                                   const std::string& to_crs, const std::string& where);

// The "EPSG:<code>" that identifies `crs` (given as PROJ understands it), or "" when PROJ knows
// no EPSG code for it. Throws for a CRS PROJ does not know, naming `where`.
std::string EpsgOfCrs(const std::string& crs, const std::string& where);

// `crs` for messages: "EPSG:31255 (MGI / Austria GK Central)" (its EPSG code where PROJ knows
// one, and its name), or its name alone; `crs` itself when PROJ does not know it.
std::string DescribeCrs(const std::string& crs);

// Checks a light field's CRS (see the contract above): "" (not geo-referenced) or
// "EPSG:<code>" of a metric projected CRS. Throws std::invalid_argument "<where>: ..." naming
// the code and why it is refused (unknown to PROJ, geographic, not metric, not an EPSG code).
void CheckLightFieldCrs(const std::string& crs, const std::string& where);

// The grid bearing of true north at a WGS84 point in a projected CRS: radians, clockwise from
// the grid's +y (northing) axis; minus the meridian convergence (negative east of a UTM zone's
// central meridian in the northern hemisphere). A direction at compass heading h (clockwise
// from true north) has grid bearing h + GridBearingOfNorth. Computed through PROJ from the
// point and one 1e-5 degrees further north (exact to ~1e-9 rad).
double GridBearingOfNorth(double latitude_deg, double longitude_deg, const std::string& crs,
                          const std::string& where);

}  // namespace aos
