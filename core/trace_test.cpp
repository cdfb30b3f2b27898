#include "core/trace.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <set>
#include <thread>

#include "core/file_util.h"

namespace lfgi {
namespace {

namespace fs = std::filesystem;

nlohmann::json saveAndParse(const TraceWriter& trace, const std::string& name) {
  const fs::path path = fs::path(LFGI_TEST_TMP_DIR) / "trace_test" / name;
  trace.save(path);
  const std::vector<std::byte> bytes = readFileBytes(path);
  return nlohmann::json::parse(reinterpret_cast<const char*>(bytes.data()),
                               reinterpret_cast<const char*>(bytes.data()) + bytes.size());
}

TEST(Trace, SavedJsonHasEventsWithPhaseTimesAndArgs) {
  TraceWriter trace;
  trace.setThreadName("main");
  trace.complete("decode", "gpu", 1000.0, 250.5, {{"probes", 4096}});
  trace.counter("resident MB", 1500.0, {{"cells", 12.5}, {"surfels", 3.0}});
  {
    TraceScope scope(&trace, "scoped", "cpu");
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  TraceScope nothing(nullptr, "ignored");  // a null writer records nothing
  EXPECT_EQ(trace.eventCount(), 4u);

  const nlohmann::json j = saveAndParse(trace, "basic.json");
  EXPECT_EQ(j.at("displayTimeUnit"), "ms");
  const nlohmann::json& events = j.at("traceEvents");
  ASSERT_EQ(events.size(), 4u);
  EXPECT_EQ(events[0].at("ph"), "M");
  EXPECT_EQ(events[0].at("args").at("name"), "main");
  const nlohmann::json& decode = events[1];
  EXPECT_EQ(decode.at("name"), "decode");
  EXPECT_EQ(decode.at("cat"), "gpu");
  EXPECT_EQ(decode.at("ph"), "X");
  EXPECT_DOUBLE_EQ(decode.at("ts").get<double>(), 1000.0);
  EXPECT_DOUBLE_EQ(decode.at("dur").get<double>(), 250.5);
  EXPECT_EQ(decode.at("args").at("probes"), 4096);
  EXPECT_TRUE(decode.at("pid").is_number_integer());
  EXPECT_TRUE(decode.at("tid").is_number_integer());
  const nlohmann::json& counter = events[2];
  EXPECT_EQ(counter.at("ph"), "C");
  EXPECT_DOUBLE_EQ(counter.at("ts").get<double>(), 1500.0);
  EXPECT_DOUBLE_EQ(counter.at("args").at("cells").get<double>(), 12.5);
  EXPECT_FALSE(counter.contains("dur"));
  const nlohmann::json& scoped = events[3];
  EXPECT_EQ(scoped.at("ph"), "X");
  EXPECT_GE(scoped.at("dur").get<double>(), 2000.0);  // slept 2 ms
  EXPECT_GE(scoped.at("ts").get<double>(), 0.0);
  EXPECT_FALSE(scoped.contains("args"));
}

TEST(Trace, ConcurrentEventsFromSeveralThreadsAreAllPresent) {
  TraceWriter trace;
  constexpr int kThreads = 4, kEvents = 500;
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&trace, t] {
      trace.setThreadName("worker " + std::to_string(t));
      for (int e = 0; e < kEvents; ++e) {
        TraceScope scope(&trace, "work", "test", {{"thread", t}, {"event", e}});
      }
    });
  }
  for (std::thread& th : threads) th.join();
  const nlohmann::json j = saveAndParse(trace, "threads.json");
  std::set<std::pair<int, int>> seen;
  std::set<int> tids;
  for (const nlohmann::json& e : j.at("traceEvents")) {
    if (e.at("ph") != "X") continue;
    seen.emplace(e.at("args").at("thread").get<int>(), e.at("args").at("event").get<int>());
    tids.insert(e.at("tid").get<int>());
    EXPECT_GE(e.at("dur").get<double>(), 0.0);
  }
  EXPECT_EQ(seen.size(), std::size_t(kThreads * kEvents));
  EXPECT_EQ(tids.size(), std::size_t(kThreads));
}

}  // namespace
}  // namespace lfgi
