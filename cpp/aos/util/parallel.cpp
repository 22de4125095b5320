#include "aos/util/parallel.h"

#include <omp.h>

#include <algorithm>
#include <atomic>
#include <exception>
#include <mutex>

#include "aos/util/error.h"

namespace aos {

int ResolveThreadCount(int num_threads) {
  CheckThreadCount(num_threads);  // a bad count never reaches OpenMP, checked or not
  return num_threads == -1 ? std::max(1, std::min(omp_get_max_threads(), kMaxThreads))
                           : num_threads;
}

void CheckThreadCount(int num_threads) {
  if (num_threads == -1 || (num_threads >= 1 && num_threads <= kMaxThreads)) return;
  ThrowInvalid("num_threads: must be " + kThreadCountRange.Text() + ", got " +
               std::to_string(num_threads));
}

namespace {

template <typename Fn>
void RunParallel(int64_t n, int num_threads, ProgressSink* progress, const Fn& fn) {
  CheckThreadCount(num_threads);
  std::atomic<int64_t> first_error_index{n};
  std::exception_ptr first_error;
  std::mutex error_mutex;
  std::atomic<bool> cancelled{false};
#pragma omp parallel for schedule(dynamic, 1) num_threads(ResolveThreadCount(num_threads))
  for (int64_t i = 0; i < n; ++i) {
    if (omp_get_thread_num() == 0 && !cancelled.load() && ProgressCancelled(progress)) {
      cancelled.store(true);
    }
    if (cancelled.load() || i > first_error_index.load()) continue;
    try {
      fn(i, omp_get_thread_num());
      ProgressAdvance(progress, 1);
    } catch (...) {
      std::lock_guard<std::mutex> lock(error_mutex);
      if (i < first_error_index.load()) {
        first_error_index.store(i);
        first_error = std::current_exception();
      }
    }
  }
  if (cancelled.load() || ProgressCancelled(progress)) throw Cancelled();
  if (first_error) std::rethrow_exception(first_error);
}

}  // namespace

void ParallelFor(int64_t n, int num_threads, ProgressSink* progress,
                 const std::function<void(int64_t)>& fn) {
  RunParallel(n, num_threads, progress, [&](int64_t i, int) { fn(i); });
}

void ParallelForPerThread(int64_t n, int num_threads, ProgressSink* progress,
                          const std::function<void(int64_t, int)>& fn) {
  RunParallel(n, num_threads, progress, fn);
}

}  // namespace aos
