#pragma once
// Geodesy for geo-referencing: WGS84 latitude/longitude to UTM (a metric map frame in which a
// light field's origin and camera positions live; lightfield.h keeps the origin in double).
//
// Contract
// - UtmFromWgs84 projects with Krueger's series for the transverse Mercator projection to
//   order n^4 (Karney 2011, "Transverse Mercator with an accuracy of a few nanometers"),
//   accurate to well below a millimetre within a zone; k0 = 0.9996, false easting 500 km,
//   false northing 0 (northern hemisphere) or 10,000 km (southern).
// - zone 0 picks the standard zone of the longitude (1..60, no Norway/Svalbard exceptions);
//   a given zone (1..60) forces it, so that points near a zone edge share one frame.
//
// Throws std::invalid_argument for a latitude outside [-80, 84] degrees (UTM's range), a
// non-finite value or a zone outside 0..60.
#include <string>

namespace aos {

struct UtmCoordinate {
  int zone = 0;
  bool north = true;
  double easting = 0.0;   // metres
  double northing = 0.0;  // metres
};

UtmCoordinate UtmFromWgs84(double latitude_deg, double longitude_deg, int zone = 0,
                           const std::string& where = "position");

}  // namespace aos
