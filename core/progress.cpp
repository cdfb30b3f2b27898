#include "core/progress.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <csignal>
#include <cstdio>

#include <fmt/format.h>

namespace lfgi {
namespace {

std::atomic<bool> gInterrupted{false};
struct sigaction gOldInt, gOldTerm;

void onSignal(int) {
  if (gInterrupted.exchange(true)) _exit(130);  // second signal: stop now
}

}  // namespace

Progress::Progress(std::string label, size_t total, std::string unit, size_t alreadyDone)
    : label_(std::move(label)),
      unit_(std::move(unit)),
      total_(total),
      done_(alreadyDone),
      startDone_(alreadyDone),
      tty_(::isatty(STDERR_FILENO) == 1),
      start_(std::chrono::steady_clock::now()),
      lastPrint_(start_) {}

std::string Progress::formatDuration(double s) {
  if (!std::isfinite(s) || s < 0.0) return "?";
  long t = std::lround(s);
  if (t >= 3600) return fmt::format("{}h{:02}m", t / 3600, (t % 3600) / 60);
  if (t >= 60) return fmt::format("{}m{:02}s", t / 60, t % 60);
  return fmt::format("{}s", t);
}

void Progress::update(size_t done) {
  size_t prev = done_.load();
  while (prev < done && !done_.compare_exchange_weak(prev, done)) {
  }
  std::unique_lock lock(mutex_, std::try_to_lock);
  if (!lock.owns_lock()) return;  // someone else is printing; the count is recorded
  auto now = std::chrono::steady_clock::now();
  double since = std::chrono::duration<double>(now - lastPrint_).count();
  if (since >= (tty_ ? 0.2 : 5.0)) print(false);
}

void Progress::finish() {
  std::lock_guard lock(mutex_);
  print(true);
}

void Progress::print(bool final) {
  lastPrint_ = std::chrono::steady_clock::now();
  double elapsed = std::chrono::duration<double>(lastPrint_ - start_).count();
  const size_t done = done_.load();
  double rate = elapsed > 0.0 ? double(done - startDone_) / elapsed : 0.0;
  double eta = rate > 0.0 ? double(total_ - done) / rate : -1.0;
  const int width = 30;
  int filled = total_ ? int(double(width) * double(done) / double(total_)) : width;
  std::string bar = std::string(size_t(filled), '#') + std::string(size_t(width - filled), '.');
  std::string line = fmt::format("{} [{}] {}/{} {} {:.1f}/s elapsed {} eta {}", label_, bar, done, total_,
                                 unit_, rate, formatDuration(elapsed), final ? "0s" : formatDuration(eta));
  std::fprintf(stderr, tty_ ? "\r%s%s" : "%s%s", line.c_str(), (final || !tty_) ? "\n" : "");
  std::fflush(stderr);
}

InterruptGuard::InterruptGuard() {
  gInterrupted = false;
  struct sigaction sa {};
  sa.sa_handler = onSignal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, &gOldInt);
  sigaction(SIGTERM, &sa, &gOldTerm);
}

InterruptGuard::~InterruptGuard() {
  sigaction(SIGINT, &gOldInt, nullptr);
  sigaction(SIGTERM, &gOldTerm, nullptr);
}

bool InterruptGuard::interrupted() {
  return gInterrupted.load();
}
void InterruptGuard::reset() {
  gInterrupted = false;
}

}  // namespace lfgi
