#include "aos/util/error.h"

#include <cstdio>

namespace aos {

void ThrowInvalid(const std::string& message) { throw std::invalid_argument(message); }

std::string Where(const std::string& where, const std::string& message) {
  return where.empty() ? message : where + ": " + message;
}

std::string FormatNumber(double value) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.10g", value);
  return buffer;
}

}  // namespace aos
