#include "aos/util/progress.h"

namespace aos {

void ProgressStart(ProgressSink* sink, const std::string& stage, int64_t total) {
  if (sink != nullptr) sink->Start(stage, total);
}

void ProgressAdvance(ProgressSink* sink, int64_t units) {
  if (sink != nullptr) sink->Advance(units);
}

bool ProgressCancelled(ProgressSink* sink) { return sink != nullptr && sink->Cancelled(); }

}  // namespace aos
