#include "core/progress.h"

#include <gtest/gtest.h>

#include <cmath>
#include <csignal>
#include <string>
#include <thread>
#include <vector>

namespace lfgi {
namespace {

TEST(Progress, FormatsDurations) {
  EXPECT_EQ(Progress::formatDuration(12.4), "12s");
  EXPECT_EQ(Progress::formatDuration(185.0), "3m05s");
  EXPECT_EQ(Progress::formatDuration(3720.0), "1h02m");
  EXPECT_EQ(Progress::formatDuration(-1.0), "?");
  EXPECT_EQ(Progress::formatDuration(NAN), "?");
}

// Workers report concurrently and out of order; the final line shows the highest count.
TEST(Progress, ConcurrentUpdatesNeverGoBackwards) {
  testing::internal::CaptureStderr();
  {
    Progress p("work", 400, "items");
    std::vector<std::thread> pool;
    for (int t = 0; t < 4; ++t)
      pool.emplace_back([&p, t] {
        for (size_t i = 0; i <= 100; ++i) p.update(size_t(t) * 100 + i);
      });
    for (auto& th : pool) th.join();
    p.update(5);  // a late, stale report
    p.finish();
  }
  std::string err = testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("400/400 items"), std::string::npos) << err;
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
