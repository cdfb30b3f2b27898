// Progress and interruption for long operations (world generation, bakes, captures).
//
// Progress prints to stderr: an updating "\r" line on a terminal, or one line every few seconds when
// stderr is a file or pipe (CI logs), with done/total, rate and ETA.
// Interruption: InterruptGuard installs SIGINT/SIGTERM handlers that only set a flag; long loops poll
// interrupted() between work items, write what they finished, and exit so that a rerun resumes.
#pragma once

#include <atomic>
#include <chrono>
#include <cstddef>
#include <mutex>
#include <string>

namespace lfgi {

class Progress {
 public:
  // alreadyDone: items finished by an earlier, interrupted run (counted in done/total, not in the rate).
  Progress(std::string label, size_t total, std::string unit = "items", size_t alreadyDone = 0);
  // Records that `done` items are finished and prints if due. Thread-safe: any worker may call it; a
  // call that finds another one printing returns at once, and the count never goes backwards.
  void update(size_t done);
  // Prints the final line (always). Thread-safe.
  void finish();
  // "1h02m", "3m05s", "12s"; "?" for a negative or non-finite value.
  static std::string formatDuration(double seconds);

 private:
  void print(bool final);
  std::string label_, unit_;
  size_t total_;
  std::atomic<size_t> done_{0};  // highest count reported so far (recorded even when not printing)
  size_t startDone_ = 0;
  bool tty_;
  std::chrono::steady_clock::time_point start_, lastPrint_;
  std::mutex mutex_;
};

// While alive, SIGINT and SIGTERM set a flag instead of killing the process; restores the previous
// handlers on destruction. A second signal while the flag is set exits immediately (code 130).
class InterruptGuard {
 public:
  InterruptGuard();
  InterruptGuard(const InterruptGuard&) = delete;
  InterruptGuard& operator=(const InterruptGuard&) = delete;
  ~InterruptGuard();
  static bool interrupted();
  static void reset();  // for tests
};

}  // namespace lfgi
