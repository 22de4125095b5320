#include "progress_bar.h"

#include <atomic>
#include <csignal>
#include <cstdio>
#include <thread>

#include <unistd.h>

#include "aos/util/error.h"
#include "aos/util/file_util.h"

namespace aos::cli {
namespace {
volatile std::sig_atomic_t g_interrupted = 0;
volatile std::sig_atomic_t g_signal = 0;  // the first signal that came
// Set when a poll (Interrupted()) has seen the signal: the work is stopping on its own.
std::atomic<bool> g_seen{false};
void OnInterrupt(int signal_number) {
  if (g_signal == 0) g_signal = signal_number;
  g_interrupted = 1;
}
}  // namespace

void InstallInterruptHandler() {
  // Ctrl-C, and a polite kill or a closed terminal: the work stops at the next progress poll,
  // child processes (COLMAP) are stopped and temporary files removed. Without SA_RESTART, so a
  // system call blocked when the signal comes returns (EINTR) instead of resuming.
  struct sigaction action {};
  action.sa_handler = OnInterrupt;
  sigemptyset(&action.sa_mask);
  action.sa_flags = 0;
  for (const int signal_number : {SIGINT, SIGTERM, SIGHUP}) {
    sigaction(signal_number, &action, nullptr);
  }
  // The bound: work that has not reached a poll 1.5 s after the signal (a loop without one, a
  // library call) is ended here, its pending outputs removed, so that no command runs more than
  // 2 s after SIGTERM and none leaves a partial output. A child process (COLMAP) has had its
  // SIGTERM from RunProcess's poll by then.
  std::thread([] {
    while (g_interrupted == 0) std::this_thread::sleep_for(std::chrono::milliseconds(50));
    std::this_thread::sleep_for(std::chrono::milliseconds(1500));
    RemovePendingOutputs();
    // Said apart from the usual line when no poll has seen the signal (the table test,
    // test_cli_table.py, tells work stopped at a poll from work this ended); a command that saw
    // it and is still unwinding ends here too, with the usual line.
    static const char kMessage[] = "aos-render: interrupted; no output written\n";
    static const char kBetweenPolls[] =
        "aos-render: interrupted; no output written (ended 1.5 s after the signal, between "
        "polls)\n";
    if (g_seen.load()) {
      (void)!::write(STDERR_FILENO, kMessage, sizeof(kMessage) - 1);
    } else {
      (void)!::write(STDERR_FILENO, kBetweenPolls, sizeof(kBetweenPolls) - 1);
    }
    ::_exit(InterruptExitCode());
  }).detach();
}
bool Interrupted() {
  if (g_interrupted == 0) return false;
  g_seen.store(true);
  return true;
}
int InterruptExitCode() { return 128 + (g_signal != 0 ? static_cast<int>(g_signal) : SIGINT); }

ProgressBar::ProgressBar(bool quiet) : quiet_(quiet), terminal_(::isatty(STDERR_FILENO) != 0) {}

ProgressBar::~ProgressBar() {
  // Unfinished stage (an error or an interrupt): just end the bar's line.
  if (open_line_) std::fputc('\n', stderr);
}

void ProgressBar::Start(const std::string& stage, int64_t total) {
  Finish();
  stage_ = stage;
  total_ = total;
  done_ = 0;
  stage_start_ = std::chrono::steady_clock::now();
  if (quiet_) return;
  if (terminal_) {
    open_line_ = true;
    Draw(0, true);
  }
}

void ProgressBar::Advance(int64_t units) {
  const int64_t done = done_.fetch_add(units) + units;
  if (quiet_ || !terminal_) return;
  Draw(done, done >= total_);
}

void ProgressBar::Draw(int64_t done, bool force) {
  std::unique_lock<std::mutex> lock(draw_mutex_, std::try_to_lock);
  if (!lock.owns_lock()) return;
  const auto now = std::chrono::steady_clock::now();
  if (!force && now - last_draw_ < std::chrono::milliseconds(80)) return;
  last_draw_ = now;
  const int width = 30;
  const double fraction = total_ > 0 ? static_cast<double>(done) / total_ : 1.0;
  const int filled = static_cast<int>(fraction * width + 0.5);
  std::string bar(static_cast<size_t>(filled), '#');
  bar.resize(width, '.');
  std::fprintf(stderr, "\r%-8s [%s] %3d%%", stage_.c_str(), bar.c_str(),
               static_cast<int>(fraction * 100.0 + 0.5));
  std::fflush(stderr);
}

void ProgressBar::Finish() {
  if (stage_.empty() || quiet_) {
    stage_.clear();
    return;
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - stage_start_).count();
  if (terminal_) {
    Draw(done_.load(), true);
    if (open_line_) std::fprintf(stderr, " %.2f s\n", seconds);
    open_line_ = false;
  } else {
    std::fprintf(stderr, "%s: %lld steps done in %.2f s\n", stage_.c_str(),
                 static_cast<long long>(done_.load()), seconds);
  }
  stage_.clear();
}

bool ProgressBar::Cancelled() { return Interrupted(); }

}  // namespace aos::cli
