#include "aos/image/radiometry.h"

#include <cmath>
#include <cstdlib>

#include "aos/util/error.h"

namespace aos {

void Radiometry::Check(const std::string& where) const {
  if (!(kelvin_per_unit > 0.0) || !std::isfinite(kelvin_per_unit)) {
    ThrowInvalid(where + ": kelvin_per_unit: must be > 0 kelvin per unit of pixel value (got " +
                 FormatNumber(kelvin_per_unit) + ")");
  }
  if (!std::isfinite(kelvin_offset)) {
    ThrowInvalid(where + ": kelvin_offset: must be finite (got " + FormatNumber(kelvin_offset) +
                 ")");
  }
}

std::string Radiometry::Describe() const {
  return "kelvin = " + FormatNumber(kelvin_per_unit) + " * value + " + FormatNumber(kelvin_offset);
}

std::optional<Radiometry> RadiometryFromDescription(const std::string& text) {
  const std::string key = "kelvin = ";
  const size_t at = text.rfind(key);
  if (at == std::string::npos) return std::nullopt;
  const char* start = text.c_str() + at + key.size();
  char* end = nullptr;
  Radiometry radiometry;
  radiometry.kelvin_per_unit = std::strtod(start, &end);
  const std::string middle = " * value + ";
  if (end == start || std::string(end).compare(0, middle.size(), middle) != 0) return std::nullopt;
  start = end + middle.size();
  radiometry.kelvin_offset = std::strtod(start, &end);
  if (end == start) return std::nullopt;
  if (!(radiometry.kelvin_per_unit > 0.0) || !std::isfinite(radiometry.kelvin_per_unit) ||
      !std::isfinite(radiometry.kelvin_offset)) {
    return std::nullopt;
  }
  return radiometry;
}

}  // namespace aos
