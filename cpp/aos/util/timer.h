#pragma once
// Wall-clock timing of a stage: one steady clock for the core (never adjusted, so a stage's
// seconds cannot go negative when the system clock is set).
#include <chrono>

namespace aos {

// Starts on construction; Seconds() is the time since then (or since the last Restart()), in
// seconds.
class Timer {
 public:
  Timer() : start_(Clock::now()) {}
  void Restart() { start_ = Clock::now(); }
  double Seconds() const { return std::chrono::duration<double>(Clock::now() - start_).count(); }

 private:
  using Clock = std::chrono::steady_clock;
  Clock::time_point start_;
};

}  // namespace aos
