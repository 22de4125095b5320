#include "aos/util/memory.h"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <string>

#include <sys/resource.h>
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

// What the address-space limit (RLIMIT_AS, `ulimit -v`) leaves of this process's virtual size,
// or UINT64_MAX without one: past it every allocation fails (std::bad_alloc) whatever memory the
// machine has.
uint64_t AddressSpaceLeft() {
  struct rlimit limit {};
  if (::getrlimit(RLIMIT_AS, &limit) != 0 || limit.rlim_cur == RLIM_INFINITY) {
    return std::numeric_limits<uint64_t>::max();
  }
  std::ifstream statm("/proc/self/statm");
  uint64_t pages = 0;
  statm >> pages;
  const long page_size = ::sysconf(_SC_PAGE_SIZE);
  const uint64_t used = pages * static_cast<uint64_t>(page_size > 0 ? page_size : 4096);
  const uint64_t cap = static_cast<uint64_t>(limit.rlim_cur);
  return cap > used ? cap - used : 0;
}

}  // namespace

uint64_t MemoryBudgetBytes() {
  const uint64_t limit = EnvironmentLimit();
  return std::min(limit > 0 ? limit : AvailableFromKernel(), AddressSpaceLeft());
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
  const uint64_t memory = limit > 0 ? limit : AvailableFromKernel();
  const uint64_t address_space = AddressSpaceLeft();
  const uint64_t budget = std::min(memory, address_space);
  if (needed_bytes <= budget) return;
  ThrowInvalid(what + ": needs " + FormatBytes(needed_bytes) + " of memory (" + detail +
               ") but only " + FormatBytes(budget) + " are available (" +
               (address_space < memory ? "the address-space limit RLIMIT_AS (ulimit -v)"
                : limit > 0           ? "the limit AOS_MEMORY_LIMIT_MB"
                                      : "MemAvailable of this machine") +
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
