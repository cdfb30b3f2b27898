#include "core/trace.h"

#include <sys/syscall.h>
#include <unistd.h>

#include "core/error.h"
#include "core/file_util.h"

namespace lfgi {

namespace {

int currentThreadId() {
  thread_local const int tid = static_cast<int>(::syscall(SYS_gettid));
  return tid;
}

}  // namespace

TraceWriter::TraceWriter() : start_(std::chrono::steady_clock::now()), pid_(static_cast<int>(::getpid())) {}

double TraceWriter::nowUs() const {
  return std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - start_).count();
}

void TraceWriter::add(Event event) {
  const std::lock_guard lock(mutex_);
  events_.push_back(std::move(event));
}

void TraceWriter::complete(std::string name, std::string category, double tsUs, double durUs,
                           nlohmann::json args) {
  add({std::move(name), std::move(category), 'X', tsUs, durUs, currentThreadId(), std::move(args)});
}

void TraceWriter::counter(std::string name, double tsUs, nlohmann::json values) {
  add({std::move(name), "counter", 'C', tsUs, 0.0, currentThreadId(), std::move(values)});
}

void TraceWriter::setThreadName(std::string name) {
  add({"thread_name", "__metadata", 'M', 0.0, 0.0, currentThreadId(),
       nlohmann::json{{"name", std::move(name)}}});
}

std::size_t TraceWriter::eventCount() const {
  const std::lock_guard lock(mutex_);
  return events_.size();
}

nlohmann::json TraceWriter::toJson() const {
  nlohmann::json events = nlohmann::json::array();
  {
    const std::lock_guard lock(mutex_);
    for (const Event& e : events_) {
      nlohmann::json j = {{"name", e.name}, {"cat", e.category}, {"ph", std::string(1, e.phase)},
                          {"ts", e.ts},     {"pid", pid_},       {"tid", e.tid}};
      if (e.phase == 'X') j["dur"] = e.dur;
      if (!e.args.is_null()) j["args"] = e.args;
      events.push_back(std::move(j));
    }
  }
  return {{"traceEvents", std::move(events)}, {"displayTimeUnit", "ms"}};
}

void TraceWriter::save(const std::filesystem::path& path) const {
  std::string text;
  try {
    text = toJson().dump();
  } catch (const std::exception& e) {
    // nlohmann throws on invalid UTF-8 in names or args.
    fail("{}: cannot serialise trace ({})", path.string(), e.what());
  }
  writeFileAtomic(path, text);
}

TraceScope::TraceScope(TraceWriter* writer, std::string name, std::string category, nlohmann::json args)
    : writer_(writer) {
  if (!writer_) return;
  name_ = std::move(name);
  category_ = std::move(category);
  args_ = std::move(args);
  startUs_ = writer_->nowUs();
}

TraceScope::~TraceScope() {
  if (!writer_) return;
  const double end = writer_->nowUs();
  writer_->complete(std::move(name_), std::move(category_), startUs_, end - startUs_, std::move(args_));
}

}  // namespace lfgi
