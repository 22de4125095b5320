// A flight's centre and zone (geometry/geodesy.h) where longitudes wrap: the robust centre of
// positions across the 180th meridian, a minority of wild positions, and positions in degrees
// projected to one zone that keeps them within the flight's extent.
#include "aos/geometry/geodesy.h"

#include <cmath>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "error_of.h"

namespace aos {
namespace {

using ::testing::HasSubstr;
using test_util::ErrorOf;

TEST(Geodesy, UnwrapLongitudeTakesTheTurnNearest) {
  EXPECT_DOUBLE_EQ(UnwrapLongitude(-179.0, 179.0), 181.0);
  EXPECT_DOUBLE_EQ(UnwrapLongitude(179.0, -179.0), -181.0);
  EXPECT_DOUBLE_EQ(UnwrapLongitude(15.0, 14.0), 15.0);
  EXPECT_DOUBLE_EQ(UnwrapLongitude(15.0 + 720.0, 0.0), 15.0);
  EXPECT_DOUBLE_EQ(UnwrapLongitude(-180.0, 0.0), 180.0);  // (around - 180, around + 180]
}

TEST(Geodesy, FlightCentreIsTheMedianOnTheCircle) {
  // Across 180: the centre is at 180 (not near 0, as a plain mean would put it).
  const GeographicPosition across =
      FlightCentre({{-16.5, 179.9999}, {-16.5, -179.9999}, {-16.4, 179.9998}}, "t");
  EXPECT_NEAR(across.latitude_deg, -16.5, 1e-12);
  EXPECT_NEAR(UnwrapLongitude(across.longitude_deg, 180.0), 179.9999, 1e-9);
  EXPECT_GE(across.longitude_deg, -180.0);
  EXPECT_LT(across.longitude_deg, 180.0);
  // A minority of wild positions (swapped, radians) does not move it off the flight: latitudes
  // 0.838, 15, 48, 48.001, 48.002 and longitudes 0.262, 15, 15.001, 15.002, 48 have the medians
  // 48 and 15.001.
  const GeographicPosition robust = FlightCentre(
      {{48.0, 15.0}, {48.001, 15.001}, {15.0, 48.0}, {48.002, 15.002}, {0.838, 0.262}}, "t");
  EXPECT_NEAR(robust.latitude_deg, 48.0, 1e-12);
  EXPECT_NEAR(robust.longitude_deg, 15.001, 1e-12);
  // Even counts: the mean of the middle two.
  const GeographicPosition two = FlightCentre({{10.0, 20.0}, {12.0, 22.0}}, "t");
  EXPECT_NEAR(two.latitude_deg, 11.0, 1e-12);
  EXPECT_NEAR(two.longitude_deg, 21.0, 1e-12);
  EXPECT_THAT(ErrorOf([] { FlightCentre({}, "t"); }), HasSubstr("t: no positions"));
  EXPECT_THAT(ErrorOf([] { FlightCentre({{std::nan(""), 1.0}}, "t"); }), HasSubstr("finite"));
}

TEST(Geodesy, GreatCircleDistanceOfADegree) {
  // A degree of a great circle on the mean sphere: 6371008.8 x pi / 180 = 111195.08 m; across
  // 180 the short way.
  EXPECT_NEAR(GreatCircleDistance({0.0, 0.0}, {1.0, 0.0}), 111195.08, 0.01);
  EXPECT_NEAR(GreatCircleDistance({0.0, 179.5}, {0.0, -179.5}), 111195.08, 0.01);
  EXPECT_NEAR(GreatCircleDistance({48.0, 15.0}, {48.0, 15.0}), 0.0, 1e-9);
}

TEST(Geodesy, DegreesAcrossTheAntimeridianProjectToOneZoneNearby) {
  // Issue 31: positions at +-179.9999 took the zone of their mean longitude (0), half a world
  // away. Now one of the zones meeting at 180, with the points 21 m apart as on the ground
  // (0.0002 degrees of longitude at 16.5 S: 0.0002 x 111.32 km x cos 16.5 = 21.35 m, the UTM scale
  // 3 degrees from a central meridian within 0.1%), due east turned by the convergence there
  // (3 x sin 16.5 = 0.85 degrees: 21.35 m x sin 0.85 = 0.32 m of northing).
  const MetricPoints metric = MetricFromCrs(
      {Vec3d(179.9999, -16.5, 10.0), Vec3d(-179.9999, -16.5, 10.0)}, "EPSG:4326", "t");
  EXPECT_THAT(metric.crs, ::testing::AnyOf("EPSG:32760", "EPSG:32701"));
  const Vec3d step = metric.points[1] - metric.points[0];
  EXPECT_NEAR(glm::length(step), 0.0002 * 111320.0 * std::cos(16.5 * std::acos(-1.0) / 180.0),
              0.05);
  EXPECT_NEAR(std::abs(step.y), 0.32, 0.01);
  EXPECT_GT(metric.points[0].y, 8000000.0);  // a southern northing near 16.5 S, not ~20,000 km
  EXPECT_LT(metric.points[0].y, 8300000.0);
}

}  // namespace
}  // namespace aos
