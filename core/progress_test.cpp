#include "core/progress.h"

#include <gtest/gtest.h>

#include <cmath>
#include <csignal>

namespace lfgi {
namespace {

TEST(Progress, FormatsDurations) {
  EXPECT_EQ(Progress::formatDuration(12.4), "12s");
  EXPECT_EQ(Progress::formatDuration(185.0), "3m05s");
  EXPECT_EQ(Progress::formatDuration(3720.0), "1h02m");
  EXPECT_EQ(Progress::formatDuration(-1.0), "?");
  EXPECT_EQ(Progress::formatDuration(NAN), "?");
}

// SIGINT inside the guard sets the flag instead of killing the test process; outside it, the old
// handler is back.
TEST(InterruptGuard, SignalSetsFlagAndHandlersAreRestored) {
  struct sigaction before {};
  sigaction(SIGINT, nullptr, &before);
  {
    InterruptGuard guard;
    EXPECT_FALSE(InterruptGuard::interrupted());
    std::raise(SIGINT);
    EXPECT_TRUE(InterruptGuard::interrupted());
    InterruptGuard::reset();
    EXPECT_FALSE(InterruptGuard::interrupted());
  }
  struct sigaction after {};
  sigaction(SIGINT, nullptr, &after);
  EXPECT_EQ(before.sa_handler, after.sa_handler);
}

}  // namespace
}  // namespace lfgi
