#include "streaming/streaming_manager.h"

#include <gtest/gtest.h>

#include <cmath>

#include "core/error.h"

namespace lfgi::streaming {
namespace {

SyntheticSourceOptions smallWorld() {
  SyntheticSourceOptions o;
  o.layout = {{0.0f, 0.0f}, 64.0f, {16, 16}};  // 1 km x 1 km
  o.probeSpacing = 8.0f;
  o.layers = 2;
  o.irradianceResolution = 8;  // texel-centre discretisation of E(n) is ~1 % at 8 x 8 (6 % at 4 x 4)
  return o;
}

StreamingConfig inlineConfig() {
  StreamingConfig c;
  c.decodeRadius = 100.0f;
  c.keepRadius = 140.0f;
  c.ioThreads = 0;
  c.maxInlineLoadsPerFrame = 64;
  c.maxActivationsPerFrame = 64;
  c.activateBudgetMs = 1e9;
  c.fadeSeconds = 0.0f;
  c.recordEvents = true;
  return c;
}

FrameInput at(glm::vec3 p, glm::vec3 v = glm::vec3(0.0f), float tod = 12.0f) {
  FrameInput in;
  in.position = p;
  in.velocity = v;
  in.direction = glm::length(v) > 0.0f ? glm::normalize(v) : glm::vec3(0, 0, -1);
  in.timeOfDayHours = tod;
  in.dtSeconds = 0.1f;
  return in;
}

// A scripted flight: along x, then a turn along z, at 40 m/s, 10 fps.
std::vector<FrameInput> scriptedPath() {
  std::vector<FrameInput> path;
  glm::vec3 p(100.0f, 20.0f, 100.0f);
  for (int f = 0; f < 200; ++f) {
    glm::vec3 v = f < 100 ? glm::vec3(40, 0, 0) : glm::vec3(0, 0, 40);
    path.push_back(at(p, v, 6.0f + 0.05f * float(f)));
    p += v * 0.1f;
  }
  return path;
}

TEST(StreamingManager, SameInputsGiveTheSameDecisions) {
  auto run = [] {
    SyntheticCellSource source(smallWorld());
    StreamingConfig c = inlineConfig();
    c.memoryBudgetBytes = 30 * source.maxCellBytes();
    c.maxInlineLoadsPerFrame = 3;
    c.maxActivationsPerFrame = 2;
    StreamingManager m(source, c);
    for (const FrameInput& in : scriptedPath()) m.update(in);
    return m.events();
  };
  auto a = run(), b = run();
  ASSERT_EQ(a.size(), b.size());
  EXPECT_TRUE(a == b);
  int requests = 0, evictions = 0;
  for (const auto& e : a) {
    requests += e.type == StreamingEventType::Request;
    evictions += e.type == StreamingEventType::Evict;
  }
  EXPECT_GT(requests, 20);
  EXPECT_GT(evictions, 5);  // the flight leaves cells behind
}

TEST(StreamingManager, OscillatingAtABorderDoesNotThrash) {
  SyntheticCellSource source(smallWorld());
  StreamingManager m(source, inlineConfig());
  int lateRequests = 0, lateEvictions = 0;
  for (int f = 0; f < 300; ++f) {
    float x = 512.0f + ((f / 5) % 2 ? 6.0f : -6.0f);  // +-6 m across the border at x = 512, every 5 frames
    FrameStats s = m.update(at({x, 20.0f, 500.0f}));
    if (f >= 10) {
      lateRequests += s.requested;
      lateEvictions += s.evicted;
    }
  }
  EXPECT_EQ(lateRequests, 0);
  EXPECT_EQ(lateEvictions, 0);
}

TEST(StreamingManager, MemoryBudgetIsNeverExceeded) {
  for (int threads : {0, 3}) {
    SyntheticSourceOptions o = smallWorld();
    o.loadDelayUs = threads ? 200 : 0;
    SyntheticCellSource source(o);
    StreamingConfig c = inlineConfig();
    c.ioThreads = threads;
    // 7 slots (fewer than the ~12 wanted cells) + 1 relight staging field.
    c.memoryBudgetBytes = 8 * source.maxCellBytes() + 100;
    StreamingManager m(source, c);
    EXPECT_EQ(m.slotCount(), 7);
    size_t peak = 0;
    for (const FrameInput& in : scriptedPath()) {
      FrameStats s = m.update(in);
      peak = std::max(peak, s.bytesResident);
      ASSERT_LE(s.bytesResident, c.memoryBudgetBytes) << "frame " << s.frame;
      ASSERT_LE(s.resident + s.loading, 7);
    }
    m.drainIo();
    EXPECT_GT(peak, 4 * source.maxCellBytes());  // the budget was used, not avoided
  }
}

TEST(StreamingManager, FallbackFirstThenCrossFadeToTheFullCell) {
  SyntheticCellSource source(smallWorld());
  StreamingConfig c = inlineConfig();
  c.fadeSeconds = 0.5f;  // 5 frames at 0.1 s
  c.maxInlineLoadsPerFrame = 1;
  StreamingManager m(source, c);
  const glm::vec3 p(300.0f, 4.0f, 300.0f), n(0, 1, 0);
  IrradianceSample before = m.sample(p, n);
  EXPECT_FALSE(before.missing);
  EXPECT_EQ(before.fallbackWeight, 1.0f);
  EXPECT_GT(before.irradiance.x, 0.0f);  // never unlit, even before any load
  const glm::vec3 exact = SyntheticCellSource::exactIrradiance(p, n);
  EXPECT_NEAR(before.irradiance.x, exact.x, 0.25f * exact.x);  // coarse but right in magnitude
  glm::vec3 prev = before.irradiance;
  float maxStep = 0.0f;
  std::vector<float> weights;
  for (int f = 0; f < 20; ++f) {
    m.update(at(p));
    IrradianceSample s = m.sample(p, n);
    weights.push_back(s.fallbackWeight);
    maxStep = std::max(maxStep, glm::length(s.irradiance - prev));
    prev = s.irradiance;
  }
  EXPECT_EQ(weights.back(), 0.0f);
  EXPECT_TRUE(std::any_of(weights.begin(), weights.end(), [](float w) { return w > 0.05f && w < 0.95f; }));
  EXPECT_NEAR(prev.x, exact.x, 0.02f * exact.x);  // trilinear of a smooth field + 8 x 8 map
  // no pop: the change from fallback to full is spread over >= 4 frames
  EXPECT_LE(maxStep, 0.3f * glm::length(prev - before.irradiance) + 1e-6f);
}

TEST(StreamingManager, NeighbouringCellsAgreeAtTheirBorder) {
  SyntheticCellSource source(smallWorld());
  StreamingManager m(source, inlineConfig());
  m.update(at({512.0f, 10.0f, 500.0f}));
  ASSERT_TRUE(m.isResident({7, 7}));
  ASSERT_TRUE(m.isResident({8, 7}));
  ASSERT_TRUE(m.isResident({8, 8}));
  for (float z : {450.0f, 460.5f, 510.0f, 511.9f}) {
    for (glm::vec3 n : {glm::vec3(0, 1, 0), glm::vec3(1, 0, 0), glm::vec3(0, -1, 0)}) {
      IrradianceSample a = m.sample({512.0f - 1e-3f, 6.0f, z}, n), b = m.sample({512.0f, 6.0f, z}, n);
      EXPECT_EQ(a.fallbackWeight, 0.0f);
      EXPECT_NEAR(a.irradiance.x, b.irradiance.x, 1e-3f * b.irradiance.x) << "z " << z;
      EXPECT_NEAR(a.irradiance.z, b.irradiance.z, 1e-3f * b.irradiance.z) << "z " << z;
    }
  }
  // Corner of four cells, approached from inside the lower-left one.
  IrradianceSample a = m.sample({512.0f - 1e-3f, 6.0f, 512.0f - 1e-3f}, {0, 1, 0}),
                   b = m.sample({512, 6, 512}, {0, 1, 0});
  EXPECT_NEAR(a.irradiance.y, b.irradiance.y, 1e-3f * b.irradiance.y);
}

TEST(StreamingManager, CorruptCellKeepsItsFallbackAndIsNotRetried) {
  SyntheticSourceOptions o = smallWorld();
  o.corruptCells = {{4, 4}};
  SyntheticCellSource source(o);
  StreamingManager m(source, inlineConfig());
  const glm::vec3 p(4 * 64 + 30.0f, 5.0f, 4 * 64 + 30.0f);
  int failed = 0;
  for (int f = 0; f < 10; ++f) failed += m.update(at(p)).failed;
  EXPECT_EQ(failed, 1);
  EXPECT_FALSE(m.isResident({4, 4}));
  EXPECT_TRUE(m.isResident({5, 4}));
  IrradianceSample s = m.sample(p, {0, 1, 0});
  EXPECT_FALSE(s.missing);
  EXPECT_EQ(s.fallbackWeight, 1.0f);
  EXPECT_TRUE(std::isfinite(s.irradiance.x) && s.irradiance.x > 0.0f);
}

TEST(StreamingManager, VelocityPrefetchRequestsCellsAhead) {
  SyntheticCellSource source(smallWorld());
  StreamingConfig c = inlineConfig();
  c.prefetchSeconds = 3.0f;
  c.maxPrefetchDistance = 400.0f;
  StreamingManager m(source, c);
  for (int f = 0; f < 10; ++f)
    m.update(at({100.0f, 20.0f, 500.0f}, {100.0f, 0.0f, 0.0f}));  // predicted x = 400
  EXPECT_TRUE(m.isResident({6, 7}));  // x 384..448: 284 m ahead of the camera, near the prediction
  StreamingManager still(source, inlineConfig());
  for (int f = 0; f < 10; ++f) still.update(at({100.0f, 20.0f, 500.0f}));
  EXPECT_FALSE(still.isResident({6, 7}));
}

TEST(StreamingManager, RelightIsAmortisedNearestFirst) {
  SyntheticCellSource source(smallWorld());
  StreamingConfig c = inlineConfig();
  c.maxRelightsPerFrame = 2;
  c.relightFadeSeconds = 0.0f;  // a cross-fade holds its staging field (CrossFadeAtTheSwap... tests that)
  StreamingManager m(source, c);
  std::vector<glm::ivec2> order;
  m.onRelight = [&](glm::ivec2 cell, ProbeField&, float) { order.push_back(cell); };
  const glm::vec3 p(300.0f, 5.0f, 300.0f);
  FrameStats s = m.update(at(p, {}, 8.0f));
  const int resident = s.resident;
  ASSERT_GT(resident, 6);
  int total = 0;
  for (int f = 0; f < 20; ++f) {
    FrameStats t = m.update(at(p, {}, 9.0f));
    EXPECT_LE(t.relit, 2);
    total += t.relit;
  }
  EXPECT_EQ(total, resident);
  ASSERT_FALSE(order.empty());
  EXPECT_EQ(order.front(), glm::ivec2(4, 4));  // the camera's own cell first
}

TEST(StreamingManager, ThreadedLoadsArriveAndPassThroughOnActivate) {
  SyntheticSourceOptions o = smallWorld();
  o.loadDelayUs = 500;
  SyntheticCellSource source(o);
  StreamingConfig c = inlineConfig();
  c.ioThreads = 2;
  int activated = 0;
  StreamingManager m(source, c);
  m.onActivate = [&](glm::ivec2, const ProbeField& f) {
    activated++;
    EXPECT_NO_THROW(f.validate());
  };
  const glm::vec3 p(300.0f, 5.0f, 300.0f);
  FrameStats s;
  for (int f = 0; f < 400 && (f < 2 || s.loading > 0); ++f) {
    s = m.update(at(p));
    if (s.loading > 0) m.drainIo();
  }
  EXPECT_EQ(s.loading, 0);
  EXPECT_EQ(activated, s.resident);
  EXPECT_TRUE(m.isResident({4, 4}));
}

TEST(StreamingManager, BadConfigNamesTheField) {
  SyntheticCellSource source(smallWorld());
  StreamingConfig c;
  c.keepRadius = 10.0f;
  try {
    StreamingManager m(source, c);
    FAIL() << "accepted keepRadius < decodeRadius";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("keepRadius"), std::string::npos) << e.what();
  }
  c = StreamingConfig{};
  c.memoryBudgetBytes = 10;
  EXPECT_THROW(StreamingManager(source, c), Error);
  EXPECT_TRUE(StreamingManager(source, StreamingConfig{}).sample({-5.0f, 0.0f, 3.0f}, {0, 1, 0}).missing);
}

}  // namespace
}  // namespace lfgi::streaming
