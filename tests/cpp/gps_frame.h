#pragma once
// Test helper: a small 8-bit grey frame with the EXIF GPS tags a drone writes (degrees, minutes,
// seconds and hemisphere letters; altitude and its reference when given), for the readers of
// GPS tags (ReadGpsTag) in the C++ tests and the fuzz seed corpus. Header-only.
#include <cmath>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <OpenImageIO/imageio.h>

namespace aos::testing_util {

// Writes `path` (the extension picks the format) of width x height pixels valued (i * 5) mod 256;
// returns false if OpenImageIO cannot write it. `capture_time` ("YYYY:MM:DD HH:MM:SS") and
// `subsec` become EXIF DateTimeOriginal and SubSecTimeOriginal when given.
inline bool WriteGpsTaggedFrame(const std::string& path, int width, int height, double lat,
                                double lon, std::optional<double> altitude,
                                const std::string& capture_time = "",
                                const std::string& subsec = "") {
  OIIO::ImageSpec spec(width, height, 1, OIIO::TypeDesc::UINT8);
  if (!capture_time.empty()) spec.attribute("Exif:DateTimeOriginal", capture_time);
  if (!subsec.empty()) spec.attribute("Exif:SubsecTimeOriginal", subsec);
  const auto dms = [](double value, float out[3]) {
    value = std::abs(value);
    out[0] = static_cast<float>(std::floor(value));
    out[1] = static_cast<float>(std::floor((value - out[0]) * 60.0));
    out[2] = static_cast<float>((value - out[0] - out[1] / 60.0) * 3600.0);
  };
  float lat_dms[3], lon_dms[3];
  dms(lat, lat_dms);
  dms(lon, lon_dms);
  spec.attribute("GPS:Latitude", OIIO::TypeDesc(OIIO::TypeDesc::FLOAT, 3), lat_dms);
  spec.attribute("GPS:LatitudeRef", lat < 0 ? "S" : "N");
  spec.attribute("GPS:Longitude", OIIO::TypeDesc(OIIO::TypeDesc::FLOAT, 3), lon_dms);
  spec.attribute("GPS:LongitudeRef", lon < 0 ? "W" : "E");
  if (altitude) {
    spec.attribute("GPS:Altitude", static_cast<float>(std::abs(*altitude)));
    spec.attribute("GPS:AltitudeRef", *altitude < 0 ? 1 : 0);
  }
  std::vector<uint8_t> pixels(static_cast<size_t>(width) * height);
  for (size_t i = 0; i < pixels.size(); ++i) pixels[i] = static_cast<uint8_t>(i * 5);
  auto output = OIIO::ImageOutput::create(path);
  const bool written = output && output->open(path, spec) &&
                       output->write_image(OIIO::TypeDesc::UINT8, pixels.data());
  if (output) output->close();
  return written;
}

}  // namespace aos::testing_util
