#pragma once
// Parallel loops over independent items (frames to decode, views to write) with deterministic
// errors and cancellation.
//
// Contract
// - ParallelFor runs fn(i) for i in [0, n) on `num_threads` OpenMP threads (-1 = all cores),
//   advancing `progress` by one per finished item. An exception stays inside the parallel
//   region: the one from the lowest failing index is rethrown after the loop, so the error
//   reported does not depend on scheduling; indices above a known failure are skipped.
// - Cancellation is polled from the calling thread (OpenMP thread 0) only; the loop then stops
//   taking items and throws aos::Cancelled.
// - ParallelForPerThread is the same loop, items taken one at a time (schedule(dynamic, 1): for
//   tiles of uneven cost), with fn(i, thread) also given the OpenMP thread's index in
//   [0, ResolveThreadCount(num_threads)): the caller keeps per-thread scratch (tile buffers,
//   counters) in a vector of that many entries and merges it after the loop.
#include <cstdint>
#include <functional>

#include "aos/util/option_fields.h"
#include "aos/util/progress.h"

namespace aos {

// -1 -> all cores (at least 1, at most kMaxThreads); other values unchanged, after
// CheckThreadCount (it throws for a count out of range). The one place a thread count is
// resolved.
int ResolveThreadCount(int num_threads);

// Most worker threads a job may ask for: 1024, whatever the machine. More than the cores gains
// nothing, and OpenMP creates every thread asked for (libgomp fails at a few thousand, "Thread
// creation failed", and crashed with SIGSEGV at 100000, taking the Python interpreter with it);
// a fixed bound keeps the same command line valid on every machine.
inline constexpr int kMaxThreads = 1024;
// The values of every num_threads field (the range of its row in every field table).
inline constexpr Range kThreadCountRange = Range::Closed(1, kMaxThreads).Or(-1);

// Throws std::invalid_argument "num_threads: must be in [1, 1024] or -1, got N"
// otherwise. The one check every Options::Check() with a num_threads field calls (and the CLI's
// --threads, and ParallelFor for callers that check nothing).
void CheckThreadCount(int num_threads);

void ParallelFor(int64_t n, int num_threads, ProgressSink* progress,
                 const std::function<void(int64_t)>& fn);

void ParallelForPerThread(int64_t n, int num_threads, ProgressSink* progress,
                          const std::function<void(int64_t, int)>& fn);

}  // namespace aos
