#include "aos/geometry/geodesy.h"

#include <cmath>

#include "aos/util/error.h"

namespace aos {

UtmCoordinate UtmFromWgs84(double latitude_deg, double longitude_deg, int zone,
                           const std::string& where) {
  constexpr double kPi = 3.14159265358979323846;
  if (!std::isfinite(latitude_deg) || !std::isfinite(longitude_deg)) {
    ThrowInvalid(where + ": latitude/longitude must be finite");
  }
  if (latitude_deg < -80.0 || latitude_deg > 84.0) {
    ThrowInvalid(where + ": latitude " + FormatNumber(latitude_deg) +
                 " is outside UTM's range [-80, 84] degrees");
  }
  if (zone < 0 || zone > 60) ThrowInvalid(where + ": UTM zone must be 1..60 (0 = automatic)");
  double lon = std::fmod(longitude_deg + 180.0, 360.0);
  if (lon < 0.0) lon += 360.0;
  lon -= 180.0;  // [-180, 180)
  UtmCoordinate result;
  result.zone = zone > 0 ? zone : std::min(60, static_cast<int>(std::floor((lon + 180.0) / 6.0)) + 1);
  result.north = latitude_deg >= 0.0;
  double dlon = lon - (6.0 * result.zone - 183.0);  // from the zone's central meridian
  dlon = std::remainder(dlon, 360.0);

  // WGS84.
  constexpr double a = 6378137.0;
  constexpr double f = 1.0 / 298.257223563;
  constexpr double k0 = 0.9996;
  const double n = f / (2.0 - f);
  const double n2 = n * n, n3 = n2 * n, n4 = n3 * n;
  const double A = a / (1.0 + n) * (1.0 + n2 / 4.0 + n4 / 64.0);
  const double alpha[4] = {n / 2.0 - 2.0 * n2 / 3.0 + 5.0 * n3 / 16.0 + 41.0 * n4 / 180.0,
                           13.0 * n2 / 48.0 - 3.0 * n3 / 5.0 + 557.0 * n4 / 1440.0,
                           61.0 * n3 / 240.0 - 103.0 * n4 / 140.0,
                           49561.0 * n4 / 161280.0};
  const double phi = latitude_deg * kPi / 180.0;
  const double lambda = dlon * kPi / 180.0;
  // Conformal latitude (as its tangent) from the geodetic one.
  const double c = 2.0 * std::sqrt(n) / (1.0 + n);
  const double t = std::sinh(std::atanh(std::sin(phi)) - c * std::atanh(c * std::sin(phi)));
  const double xi_prime = std::atan2(t, std::cos(lambda));
  const double eta_prime = std::atanh(std::sin(lambda) / std::sqrt(1.0 + t * t));
  double xi = xi_prime, eta = eta_prime;
  for (int j = 1; j <= 4; ++j) {
    xi += alpha[j - 1] * std::sin(2.0 * j * xi_prime) * std::cosh(2.0 * j * eta_prime);
    eta += alpha[j - 1] * std::cos(2.0 * j * xi_prime) * std::sinh(2.0 * j * eta_prime);
  }
  result.easting = 500000.0 + k0 * A * eta;
  result.northing = k0 * A * xi + (result.north ? 0.0 : 10000000.0);
  return result;
}

}  // namespace aos
