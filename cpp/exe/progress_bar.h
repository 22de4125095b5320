#pragma once
// The CLI's progress sink: a bar on stderr when it is a terminal, plain start/end lines when it
// is not. Ctrl-C (SIGINT), SIGTERM and SIGHUP ask the running computation to stop.
#include <atomic>
#include <chrono>
#include <mutex>
#include <string>

#include "aos/util/progress.h"

namespace aos::cli {

class ProgressBar : public ProgressSink {
 public:
  explicit ProgressBar(bool quiet);
  ~ProgressBar() override;
  void Start(const std::string& stage, int64_t total) override;
  void Advance(int64_t units) override;
  bool Cancelled() override;
  // Ends the current stage's line.
  void Finish();

 private:
  void Draw(int64_t done, bool force);

  bool quiet_;
  bool terminal_;
  std::string stage_;
  int64_t total_ = 0;
  std::atomic<int64_t> done_{0};
  std::mutex draw_mutex_;
  std::chrono::steady_clock::time_point last_draw_{};
  std::chrono::steady_clock::time_point stage_start_{};
  bool open_line_ = false;
};

// Installs a handler for SIGINT, SIGTERM and SIGHUP that makes every ProgressBar report
// Cancelled() (the one cancellation source of the CLI; commands poll it through their sink),
// and a watchdog thread that ends the process 1.5 s after the signal if the work has not
// stopped by then (pending outputs removed, exit code as below).
void InstallInterruptHandler();
bool Interrupted();
// The exit code for the signal that came: 128 + its number (130 SIGINT, 143 SIGTERM, 129
// SIGHUP), the shell's convention; 130 when none came (a Cancelled from elsewhere).
int InterruptExitCode();

}  // namespace aos::cli
