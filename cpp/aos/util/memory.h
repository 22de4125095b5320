#pragma once
// Memory budget: jobs estimate what they will allocate before they allocate it, and refuse with a
// clear message instead of being killed by the kernel part-way.
//
// The budget is the AOS_MEMORY_LIMIT_MB environment variable when it is set (a whole number of
// MiB, e.g. for a shared machine or a test), else the memory the kernel reports as available
// (MemAvailable in /proc/meminfo), else the physical memory; and never more than an address-space
// limit (RLIMIT_AS, `ulimit -v`) leaves of the process's current virtual size, since past that
// every allocation fails whatever the machine has.
#include <cstdint>
#include <initializer_list>
#include <string>

namespace aos {

// Bytes a job may allocate now (see the header comment).
uint64_t MemoryBudgetBytes();

// "1.5 GiB", "320 MiB", "12 KiB", "17 bytes".
std::string FormatBytes(uint64_t bytes);

// Throws std::invalid_argument "<what>: needs <X> (<detail>) but only <Y> are available (...)"
// when `needed_bytes` exceeds MemoryBudgetBytes(). `what` names the options that decide the
// figure ("width/height: 65536 x 65536 pixels"), so the CLI can name its flags.
void CheckMemoryBudget(uint64_t needed_bytes, const std::string& what, const std::string& detail);

// a * b * ..., saturating at UINT64_MAX instead of wrapping (sizes from untrusted headers).
uint64_t SaturatingProduct(std::initializer_list<uint64_t> factors);

}  // namespace aos
