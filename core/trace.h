// TraceWriter: Chrome trace-event JSON ("JSON Object Format" of the Trace Event Format spec), which
// Perfetto (ui.perfetto.dev) and chrome://tracing open directly. Records complete events ("ph":"X"),
// counters ("ph":"C") and thread names ("ph":"M"); save() writes {"traceEvents":[...],
// "displayTimeUnit":"ms"}.
//
// Threading: every member function may be called from any thread concurrently (one mutex; an event
// costs one short critical section, so keep events coarser than ~10 us). Timestamps are microseconds
// since the writer was constructed, from std::chrono::steady_clock. pid is the process id, tid the
// Linux thread id, so traces line up with perf and top.
#pragma once

#include <chrono>
#include <cstddef>
#include <filesystem>
#include <mutex>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace lfgi {

class TraceWriter {
 public:
  TraceWriter();
  TraceWriter(const TraceWriter&) = delete;
  TraceWriter& operator=(const TraceWriter&) = delete;

  // Microseconds since construction (steady clock).
  double nowUs() const;

  // A span [tsUs, tsUs + durUs) on the calling thread. args: a JSON object shown in the event's detail
  // pane (null for none).
  void complete(std::string name, std::string category, double tsUs, double durUs,
                nlohmann::json args = nullptr);
  // A counter sample at tsUs: values is a JSON object of name -> number, drawn as stacked series.
  void counter(std::string name, double tsUs, nlohmann::json values);
  // Names the calling thread in the viewer.
  void setThreadName(std::string name);

  std::size_t eventCount() const;
  // The whole trace as the JSON object save() writes.
  nlohmann::json toJson() const;
  // Writes toJson() atomically (temp file + rename). Throws lfgi::Error "<path>: <problem>".
  void save(const std::filesystem::path& path) const;

 private:
  struct Event {
    std::string name;
    std::string category;
    char phase;
    double ts;
    double dur;
    int tid;
    nlohmann::json args;
  };
  void add(Event event);

  std::chrono::steady_clock::time_point start_;
  int pid_;
  mutable std::mutex mutex_;
  std::vector<Event> events_;
};

// Records a complete event covering this object's lifetime on the constructing thread. A null writer
// makes it a no-op, so call sites need no "tracing enabled?" branches. Not movable: the scope is lexical.
class TraceScope {
 public:
  TraceScope(TraceWriter* writer, std::string name, std::string category = "lfgi",
             nlohmann::json args = nullptr);
  ~TraceScope();
  TraceScope(const TraceScope&) = delete;
  TraceScope& operator=(const TraceScope&) = delete;

 private:
  TraceWriter* writer_;
  std::string name_;
  std::string category_;
  nlohmann::json args_;
  double startUs_ = 0.0;
};

}  // namespace lfgi
