// Radiometry (value -> kelvin) and FLIR's raw-count model (image/radiometry.h, image/flir.h).
#include <cmath>

#include <gtest/gtest.h>

#include "aos/image/flir.h"
#include "aos/image/radiometry.h"

namespace aos {
namespace {

FlirCalibration Typical() {
  FlirCalibration c;
  c.planck_r1 = 21106.77;
  c.planck_r2 = 0.012545258;
  c.planck_b = 1501.0;
  c.planck_f = 1.0;
  c.planck_o = -7340.0;
  c.emissivity = 0.95;
  c.object_distance_m = 30.0;
  c.window_transmission = 0.9;
  c.window_temperature_k = kZeroCelsiusK + 25.0;
  return c;
}

TEST(Flir, KelvinOfRawInvertsRawOfKelvin) {
  const FlirCalibration c = Typical();
  c.Check("typical");
  for (double kelvin = 240.0; kelvin <= 400.0; kelvin += 7.5) {
    const double raw = FlirRawOfKelvin(kelvin, c);
    EXPECT_NEAR(FlirKelvinOfRaw(raw, c), kelvin, 1e-9 * kelvin) << kelvin;
  }
}

TEST(Flir, BlackBodyWithoutAtmosphereIsPlanck) {
  // Emissivity 1, no distance, a clear window: the counts are W(T) itself.
  FlirCalibration c = Typical();
  c.emissivity = 1.0;
  c.object_distance_m = 0.0;
  c.window_transmission = 1.0;
  const double kelvin = 310.15;
  const double planck = c.planck_r1 / (c.planck_r2 * (std::exp(c.planck_b / kelvin) - c.planck_f)) -
                        c.planck_o;
  EXPECT_NEAR(FlirRawOfKelvin(kelvin, c), planck, 1e-9 * planck);
}

TEST(Flir, CountsOutsideTheModelGiveNaN) {
  const FlirCalibration c = Typical();
  EXPECT_TRUE(std::isnan(FlirKelvinOfRaw(-1e6, c)));
}

TEST(Flir, CheckNamesTheTag) {
  FlirCalibration c = Typical();
  c.emissivity = 1.5;
  try {
    c.Check("x.jpg");
    FAIL();
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("x.jpg: Emissivity"), std::string::npos);
  }
}

TEST(Radiometry, DescriptionRoundTrips) {
  const Radiometry radiometry{0.04, -1.5};
  EXPECT_EQ(RadiometryFromDescription("aos integral image (float32); temperatures: " +
                                      radiometry.Describe()),
            radiometry);
  EXPECT_FALSE(RadiometryFromDescription("aos integral image").has_value());
  EXPECT_FALSE(RadiometryFromDescription("kelvin = 0 * value + 1").has_value());
  EXPECT_NEAR(radiometry.Celsius(radiometry.ValueOfCelsius(36.6)), 36.6, 1e-12);
  EXPECT_THROW(Radiometry({0.0, 0.0}).Check(), std::invalid_argument);
}

}  // namespace
}  // namespace aos
