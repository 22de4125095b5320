#include "aos/util/memory.h"

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <string>

#include <unistd.h>

#include "aos/util/error.h"

namespace aos {
namespace {

// The limit in bytes from AOS_MEMORY_LIMIT_MB, or 0 when unset. A malformed value is an error,
// not silently ignored.
uint64_t EnvironmentLimit() {
  const char* text = std::getenv("AOS_MEMORY_LIMIT_MB");
  if (text == nullptr || *text == '\0') return 0;
  char* end = nullptr;
  const unsigned long long mib = std::strtoull(text, &end, 10);
  if (end == text || *end != '\0' || mib == 0 || mib > (uint64_t{1} << 40)) {
    ThrowInvalid("AOS_MEMORY_LIMIT_MB: expected a whole number of MiB >= 1 (got '" +
                 std::string(text) + "')");
  }
  return static_cast<uint64_t>(mib) << 20;
}

uint64_t AvailableFromKernel() {
  std::ifstream meminfo("/proc/meminfo");
  std::string key;
  uint64_t kib = 0;
  std::string unit;
  while (meminfo >> key >> kib >> unit) {
    if (key == "MemAvailable:") return kib * 1024;
  }
  const long pages = ::sysconf(_SC_PHYS_PAGES);
  const long page_size = ::sysconf(_SC_PAGE_SIZE);
  if (pages > 0 && page_size > 0) return static_cast<uint64_t>(pages) * page_size;
  return std::numeric_limits<uint64_t>::max();
}

}  // namespace

uint64_t MemoryBudgetBytes() {
  const uint64_t limit = EnvironmentLimit();
  return limit > 0 ? limit : AvailableFromKernel();
}

std::string FormatBytes(uint64_t bytes) {
  char text[64];
  if (bytes >= (uint64_t{1} << 30)) {
    std::snprintf(text, sizeof(text), "%.1f GiB", static_cast<double>(bytes) / (1 << 30));
  } else if (bytes >= (uint64_t{1} << 20)) {
    std::snprintf(text, sizeof(text), "%.0f MiB", static_cast<double>(bytes) / (1 << 20));
  } else if (bytes >= 1024) {
    std::snprintf(text, sizeof(text), "%.0f KiB", static_cast<double>(bytes) / 1024);
  } else {
    std::snprintf(text, sizeof(text), "%llu bytes", static_cast<unsigned long long>(bytes));
  }
  return text;
}

void CheckMemoryBudget(uint64_t needed_bytes, const std::string& what, const std::string& detail) {
  const uint64_t limit = EnvironmentLimit();
  const uint64_t budget = limit > 0 ? limit : AvailableFromKernel();
  if (needed_bytes <= budget) return;
  ThrowInvalid(what + ": needs " + FormatBytes(needed_bytes) + " of memory (" + detail +
               ") but only " + FormatBytes(budget) + " are available (" +
               (limit > 0 ? "the limit AOS_MEMORY_LIMIT_MB" : "MemAvailable of this machine") +
               "); make it smaller");
}

uint64_t SaturatingProduct(std::initializer_list<uint64_t> factors) {
  uint64_t product = 1;
  for (const uint64_t factor : factors) {
    if (factor != 0 && product > std::numeric_limits<uint64_t>::max() / factor) {
      return std::numeric_limits<uint64_t>::max();
    }
    product *= factor;
  }
  return product;
}

}  // namespace aos
