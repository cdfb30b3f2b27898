// Asynchronous relight of resident cells (StreamingManager step 5, CellSource::relightInto).
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <thread>

#include "core/error.h"
#include "streaming/streaming_manager.h"

namespace lfgi::streaming {
namespace {

SyntheticSourceOptions todWorld() {
  SyntheticSourceOptions o;
  o.layout = {{0.0f, 0.0f}, 64.0f, {16, 16}};
  o.probeSpacing = 8.0f;
  o.layers = 2;
  o.irradianceResolution = 8;
  o.timeOfDayGain = 0.5f;  // 8 h: x0.833, 14 h: x1.083
  return o;
}

StreamingConfig baseConfig(int ioThreads) {
  StreamingConfig c;
  c.decodeRadius = 100.0f;
  c.keepRadius = 140.0f;
  c.ioThreads = ioThreads;
  c.maxInlineLoadsPerFrame = 64;
  c.maxActivationsPerFrame = 64;
  c.activateBudgetMs = 1e9;
  c.fadeSeconds = 0.0f;
  c.recordEvents = true;
  return c;
}

FrameInput at(glm::vec3 p, float tod, glm::vec3 v = glm::vec3(0.0f)) {
  FrameInput in;
  in.position = p;
  in.velocity = v;
  in.direction = glm::length(v) > 0.0f ? glm::normalize(v) : glm::vec3(0, 0, -1);
  in.timeOfDayHours = tod;
  in.dtSeconds = 0.1f;
  return in;
}

// Wraps a SyntheticCellSource: records the threads relightInto runs on and can hold relights at a gate.
class GatedSource final : public CellSource {
 public:
  explicit GatedSource(SyntheticSourceOptions o) : inner_(std::move(o)) {}
  WorldLayout layout() const override { return inner_.layout(); }
  ShL1 fallback(glm::ivec2 cell) const override { return inner_.fallback(cell); }
  size_t maxCellBytes() const override { return inner_.maxCellBytes(); }
  void load(glm::ivec2 cell, ProbeField& out) override { inner_.load(cell, out); }
  void setTimeOfDay(float hours) override { inner_.setTimeOfDay(hours); }
  void relightInto(glm::ivec2 cell, const ProbeField& current, ProbeField& out, float hours) override {
    std::unique_lock lock(mutex_);
    threads_.push_back(std::this_thread::get_id());
    ++waiting_;
    cv_.notify_all();
    cv_.wait(lock, [&] { return open_; });
    --waiting_;
    lock.unlock();
    inner_.relightInto(cell, current, out, hours);
  }
  void close() {
    std::lock_guard lock(mutex_);
    open_ = false;
  }
  void open() {
    {
      std::lock_guard lock(mutex_);
      open_ = true;
    }
    cv_.notify_all();
  }
  void waitForBlocked(int n) {
    std::unique_lock lock(mutex_);
    cv_.wait(lock, [&] { return waiting_ >= n; });
  }
  std::vector<std::thread::id> threads() {
    std::lock_guard lock(mutex_);
    return threads_;
  }
  SyntheticCellSource& inner() { return inner_; }

 private:
  SyntheticCellSource inner_;
  std::mutex mutex_;
  std::condition_variable cv_;
  bool open_ = true;
  int waiting_ = 0;
  std::vector<std::thread::id> threads_;
};

// Runs frames at `tod` until no relight is in flight and no resident cell is stale.
void settle(StreamingManager& m, glm::vec3 p, float tod) {
  for (int f = 0; f < 200; ++f) {
    FrameStats s = m.update(at(p, tod));
    if (f > 1 && s.relighting == 0 && s.relightBlending == 0 && s.relit == 0 && s.loading == 0) return;
    m.drainIo();
  }
  FAIL() << "relights did not settle";
}

TEST(StreamingRelight, RelitFieldEqualsAFreshLoadAtTheNewTime) {
  for (int threads : {0, 2}) {
    SyntheticCellSource source(todWorld());
    StreamingConfig c = baseConfig(threads);
    c.maxRelightsInFlight = 2;
    StreamingManager m(source, c);
    int checked = 0;
    SyntheticCellSource fresh(todWorld());
    ProbeField expect;
    m.onRelight = [&](glm::ivec2 cell, ProbeField& field, float hours) {
      fresh.setTimeOfDay(hours);
      fresh.load(cell, expect);
      EXPECT_EQ(field.irradiance, expect.irradiance) << cell.x << "," << cell.y;
      EXPECT_EQ(field.radiance, expect.radiance) << cell.x << "," << cell.y;
      EXPECT_EQ(field.grid.origin, expect.grid.origin);
      ++checked;
    };
    const glm::vec3 p(300.0f, 5.0f, 300.0f), q(310.0f, 3.0f, 290.0f), up(0.0f, 1.0f, 0.0f);
    settle(m, p, 8.0f);
    const int resident = m.update(at(p, 8.0f)).resident;
    ASSERT_GT(resident, 4);
    const glm::vec3 morning = m.sample(q, up).irradiance;
    EXPECT_NEAR(morning.x, source.timeOfDayScale(8.0f) * SyntheticCellSource::exactIrradiance(q, up).x,
                0.02f * morning.x);
    settle(m, p, 14.0f);
    EXPECT_EQ(checked, resident) << "threads " << threads;  // every resident cell relit once
    const glm::vec3 afternoon = m.sample(q, up).irradiance;
    EXPECT_NEAR(afternoon.x, source.timeOfDayScale(14.0f) * SyntheticCellSource::exactIrradiance(q, up).x,
                0.02f * afternoon.x)
        << "threads " << threads;
    EXPECT_EQ(source.relights(), uint64_t(resident));
  }
}

TEST(StreamingRelight, RelightRunsOffTheGameThreadAndOldLightingShadesMeanwhile) {
  GatedSource source(todWorld());
  StreamingConfig c = baseConfig(2);
  c.maxRelightsInFlight = 2;
  c.maxRelightsPerFrame = 2;
  StreamingManager m(source, c);
  std::vector<std::thread::id> onRelightThreads;
  m.onRelight = [&](glm::ivec2, ProbeField&, float) {
    onRelightThreads.push_back(std::this_thread::get_id());
  };
  const glm::vec3 p(300.0f, 5.0f, 300.0f), up(0.0f, 1.0f, 0.0f);
  settle(m, p, 8.0f);
  const glm::vec3 before = m.sample(p, up).irradiance;
  source.close();
  FrameStats s = m.update(at(p, 14.0f));  // starts two relights, which block in relightInto
  EXPECT_EQ(s.relighting, 2);
  EXPECT_EQ(s.relit, 0);
  source.waitForBlocked(2);
  // update() returned while both decodes are still blocked: the game thread does not wait for them,
  // and the cells shade with their old lighting.
  for (int f = 0; f < 3; ++f) {
    s = m.update(at(p, 14.0f));
    EXPECT_EQ(s.relighting, 2);
    EXPECT_EQ(s.relit, 0);
    EXPECT_EQ(m.sample(p, up).irradiance, before);
  }
  source.open();
  settle(m, p, 14.0f);
  EXPECT_NE(m.sample(p, up).irradiance, before);
  const std::thread::id game = std::this_thread::get_id();
  ASSERT_FALSE(source.threads().empty());
  for (std::thread::id t : source.threads()) EXPECT_NE(t, game);  // decode on the IO pool
  ASSERT_EQ(onRelightThreads.size(), source.threads().size());
  for (std::thread::id t : onRelightThreads) EXPECT_EQ(t, game);  // swap + hook on the game thread
}

TEST(StreamingRelight, EvictionDuringARelightIsSafe) {
  GatedSource source(todWorld());
  StreamingConfig c = baseConfig(1);
  StreamingManager m(source, c);
  const glm::vec3 p(300.0f, 5.0f, 300.0f), far(900.0f, 5.0f, 900.0f), up(0.0f, 1.0f, 0.0f);
  settle(m, p, 8.0f);
  source.close();
  FrameStats s = m.update(at(p, 14.0f));
  ASSERT_EQ(s.relighting, 1);
  source.waitForBlocked(1);
  const glm::ivec2 relitCell(4, 4);  // the camera's own cell goes first
  // Teleport away: every resident cell is evicted, including the one whose field the relight reads.
  s = m.update(at(far, 14.0f));
  EXPECT_FALSE(m.isResident(relitCell));
  EXPECT_EQ(s.relighting, 1);
  EXPECT_LE(s.bytesResident, c.memoryBudgetBytes);
  for (int f = 0; f < 3; ++f) m.update(at(far, 14.0f));
  source.open();
  m.drainIo();
  s = m.update(at(far, 14.0f));
  EXPECT_EQ(s.relighting, 0);
  EXPECT_EQ(s.relit, 0);  // the result of an evicted cell is dropped
  for (const StreamingEvent& e : m.events())
    EXPECT_FALSE(e.type == StreamingEventType::Relight && e.cell == relitCell);
  settle(m, far, 14.0f);
  // Back again: the cell loads afresh at the current time of day, and the draining slot was returned.
  settle(m, p, 14.0f);
  EXPECT_TRUE(m.isResident(relitCell));
  const glm::vec3 e = m.sample(p, up).irradiance;
  EXPECT_NEAR(e.x, source.inner().timeOfDayScale(14.0f) * SyntheticCellSource::exactIrradiance(p, up).x,
              0.02f * e.x);
  s = m.update(at(p, 14.0f));
  EXPECT_EQ(s.bytesResident, size_t(s.resident) * source.maxCellBytes());
}

TEST(StreamingRelight, BudgetHoldsWithRelightsInFlight) {
  SyntheticSourceOptions o = todWorld();
  o.loadDelayUs = 300;
  SyntheticCellSource source(o);
  StreamingConfig c = baseConfig(2);
  c.maxRelightsInFlight = 3;
  c.maxRelightsPerFrame = 2;
  c.relightThresholdHours = 0.05f;
  c.memoryBudgetBytes = 10 * source.maxCellBytes() + 100;  // 7 slots + 3 staging fields
  StreamingManager m(source, c);
  EXPECT_EQ(m.slotCount(), 7);
  EXPECT_EQ(m.stagingCount(), 3);
  glm::vec3 p(100.0f, 10.0f, 300.0f);
  int maxRelighting = 0, relit = 0;
  for (int f = 0; f < 300; ++f) {
    const glm::vec3 v(30.0f, 0.0f, 0.0f);
    FrameStats s = m.update(at(p, 6.0f + 0.05f * float(f), v));
    ASSERT_LE(s.bytesResident, c.memoryBudgetBytes) << "frame " << f;
    ASSERT_LE(s.relighting, 3);
    maxRelighting = std::max(maxRelighting, s.relighting);
    relit += s.relit;
    p += v * 0.1f;
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  m.drainIo();
  EXPECT_GT(relit, 0);
  EXPECT_GE(maxRelighting, 1);
}

TEST(StreamingRelight, InlineEventLogIsAPureFunctionOfTheInputs) {
  auto run = [] {
    SyntheticCellSource source(todWorld());
    StreamingConfig c = baseConfig(0);
    c.memoryBudgetBytes = 12 * source.maxCellBytes();
    c.maxRelightsPerFrame = 2;
    c.maxRelightsInFlight = 2;
    StreamingManager m(source, c);
    glm::vec3 p(100.0f, 20.0f, 100.0f);
    for (int f = 0; f < 200; ++f) {
      glm::vec3 v = f < 100 ? glm::vec3(40, 0, 0) : glm::vec3(0, 0, 40);
      m.update(at(p, 6.0f + 0.05f * float(f), v));
      p += v * 0.1f;
    }
    return m.events();
  };
  const std::vector<StreamingEvent> a = run(), b = run();
  int relights = 0, evicts = 0;
  for (const StreamingEvent& e : a) {
    relights += e.type == StreamingEventType::Relight;
    evicts += e.type == StreamingEventType::Evict;
  }
  EXPECT_GT(relights, 20);
  EXPECT_GT(evicts, 0);
  EXPECT_EQ(a, b);
}

TEST(StreamingRelight, RelightsYieldToLoadsInFlight) {
  for (bool yield : {true, false}) {
    SyntheticSourceOptions o = todWorld();
    o.loadDelayUs = 50000;  // a load started this frame is still in flight at the relight stage
    SyntheticCellSource source(o);
    StreamingConfig c = baseConfig(2);
    c.relightsYieldToLoads = yield;
    StreamingManager m(source, c);
    const glm::vec3 p(300.0f, 5.0f, 300.0f);
    settle(m, p, 8.0f);
    FrameStats s =
        m.update(at(p + glm::vec3(64.0f, 0.0f, 0.0f), 14.0f));  // a new column of cells + stale ones
    ASSERT_GT(s.requested, 0);
    EXPECT_EQ(s.relighting, yield ? 0 : 1);
    m.drainIo();
    settle(m, p + glm::vec3(64.0f, 0.0f, 0.0f), 14.0f);  // the relights come once the loads are in
    EXPECT_GT(source.relights(), 0u);
  }
}

TEST(StreamingRelight, BudgetMustHoldTheStagingFields) {
  SyntheticCellSource source(todWorld());
  StreamingConfig c = baseConfig(0);
  c.memoryBudgetBytes = 2 * source.maxCellBytes();
  c.maxRelightsInFlight = 2;
  EXPECT_THROW(StreamingManager(source, c), Error);
  c.maxRelightsPerFrame = 0;  // no relight: no staging
  EXPECT_EQ(StreamingManager(source, c).slotCount(), 2);
  c.maxRelightsPerFrame = 1;
  c.maxRelightsInFlight = 1;
  EXPECT_EQ(StreamingManager(source, c).slotCount(), 1);
}

// The swap of a relit field blends from the old lighting over relightFadeSeconds: the per-frame change of
// sample() at the swap is at most the lighting step x dt / relightFadeSeconds, and the new lighting is
// reached exactly; with relightFadeSeconds = 0 the whole step lands in one frame (what the blend removes).
TEST(StreamingRelight, CrossFadeAtTheSwapBoundsThePerFrameChange) {
  const glm::vec3 p(520.0f, 1.0f, 520.0f), n(0.0f, 1.0f, 0.0f);
  for (float fadeS : {0.5f, 0.0f}) {
    SyntheticCellSource source(todWorld());
    StreamingConfig c = baseConfig(0);
    c.relightFadeSeconds = fadeS;
    StreamingManager m(source, c);
    settle(m, p, 12.0f);
    const float before = m.sample(p, n).irradiance.x;
    const float after = before * source.timeOfDayScale(16.0f) / source.timeOfDayScale(12.0f);
    const float step = after - before;
    ASSERT_GT(step, 0.1f * before);
    float last = before, maxChange = 0.0f;
    bool sawBlend = false;
    for (int f = 0; f < 200; ++f) {
      const FrameStats st = m.update(at(p, 16.0f));
      EXPECT_LE(st.bytesResident, c.memoryBudgetBytes);
      if (m.previousLighting(m.layout().cellOf(p))) {
        sawBlend = true;
        EXPECT_LT(m.relightBlend(m.layout().cellOf(p)), 1.0f);
      }
      const float v = m.sample(p, n).irradiance.x;
      maxChange = std::max(maxChange, std::abs(v - last));
      last = v;
    }
    EXPECT_NEAR(last, after, 1e-5f * after) << "fade " << fadeS;
    EXPECT_EQ(m.relightBlend(m.layout().cellOf(p)), 1.0f);
    EXPECT_EQ(m.previousLighting(m.layout().cellOf(p)), nullptr);
    if (fadeS > 0.0f) {
      EXPECT_TRUE(sawBlend);
      // dt 0.1 s over 0.5 s: 5 frames of at most step / 5 each (+ float slack).
      EXPECT_LE(maxChange, step * 0.1f / fadeS * 1.001f + 1e-6f * after);
      EXPECT_GT(maxChange, step * 0.1f / fadeS * 0.9f);
    } else {
      EXPECT_FALSE(sawBlend);
      EXPECT_NEAR(maxChange, step, 1e-5f * after);
    }
  }
}

// Weather is a relight trigger of its own (FrameInput::weather, relightThresholdWeather) and reaches
// CellSource::relightWeatherInto; relightOnActivate relights a cell right after it arrives.
TEST(StreamingRelight, WeatherChangeAndActivationTriggerRelights) {
  class WeatherSource final : public CellSource {
   public:
    explicit WeatherSource(SyntheticSourceOptions o) : inner(std::move(o)) {}
    WorldLayout layout() const override { return inner.layout(); }
    ShL1 fallback(glm::ivec2 cell) const override { return inner.fallback(cell); }
    size_t maxCellBytes() const override { return inner.maxCellBytes(); }
    void load(glm::ivec2 cell, ProbeField& out) override { inner.load(cell, out); }
    void relightWeatherInto(glm::ivec2 cell, const ProbeField& current, ProbeField& out, float hours,
                            float weather) override {
      weathers.push_back(weather);
      inner.relightInto(cell, current, out, hours);
    }
    SyntheticCellSource inner;
    std::vector<float> weathers;
  };
  for (bool onActivate : {false, true}) {
    WeatherSource source(todWorld());
    StreamingConfig c = baseConfig(0);
    c.relightOnActivate = onActivate;
    c.relightFadeSeconds = 0.0f;
    StreamingManager m(source, c);
    const glm::vec3 p(520.0f, 1.0f, 520.0f);
    size_t resident = 0;
    for (int f = 0; f < 100; ++f) resident = size_t(m.update(at(p, 12.0f)).resident);
    ASSERT_GT(resident, 4u);
    EXPECT_EQ(source.weathers.size(), onActivate ? resident : 0u);
    source.weathers.clear();
    FrameInput in = at(p, 12.0f);
    in.weather = 0.03f;  // under the threshold
    for (int f = 0; f < 10; ++f) m.update(in);
    EXPECT_TRUE(source.weathers.empty());
    in.weather = 0.8f;
    for (int f = 0; f < 100; ++f) m.update(in);
    EXPECT_EQ(source.weathers.size(), resident);
    for (float w : source.weathers) EXPECT_EQ(w, 0.8f);
  }
}

}  // namespace
}  // namespace lfgi::streaming
