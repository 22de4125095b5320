#pragma once
// Progress reporting from long computations. The algorithm calls Start() once per stage from the
// calling thread, then Advance() from any worker thread (implementations must be thread-safe), and
// polls Cancelled(); when it returns true the algorithm throws aos::Cancelled. A null sink is
// allowed everywhere and means "report nothing".
#include <atomic>
#include <cstdint>
#include <string>

namespace aos {

class ProgressSink {
 public:
  virtual ~ProgressSink() = default;
  // A new stage with `total` units of work (e.g. "render", 64 tiles).
  virtual void Start(const std::string& stage, int64_t total) = 0;
  // `units` more units are done. Called concurrently from worker threads.
  virtual void Advance(int64_t units) = 0;
  // True when the caller wants the work stopped.
  virtual bool Cancelled() { return false; }
};

// Null-safe helpers used by the algorithms.
void ProgressStart(ProgressSink* sink, const std::string& stage, int64_t total);
void ProgressAdvance(ProgressSink* sink, int64_t units);
// Returns true if the sink asked to stop; the caller throws aos::Cancelled outside parallel regions.
bool ProgressCancelled(ProgressSink* sink);

}  // namespace aos
