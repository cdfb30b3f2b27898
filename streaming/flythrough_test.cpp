#include "streaming/flythrough.h"

#include <gtest/gtest.h>

#include <set>
#include <utility>

#include "core/error.h"

namespace lfgi::streaming {
namespace {

SyntheticSourceOptions world1km() {
  SyntheticSourceOptions o;
  o.layout = {{0.0f, 0.0f}, 64.0f, {16, 16}};
  o.probeSpacing = 16.0f;
  o.layers = 2;
  o.resolution = 2;
  o.irradianceResolution = 4;
  return o;
}

FlythroughOptions quickFlight(float speed) {
  FlythroughOptions o;
  o.speed = speed;
  o.seconds = 6.0f;
  o.fps = 30.0f;
  o.streaming.ioThreads = 0;
  o.streaming.maxInlineLoadsPerFrame = 1;
  o.streaming.decodeRadius = 130.0f;
  o.streaming.keepRadius = 180.0f;
  o.sampleRaysX = 8;
  o.sampleRaysY = 4;
  return o;
}

TEST(Flythrough, NoFrameWithoutGiAndBudgetsHold) {
  SyntheticCellSource source(world1km());
  FlythroughOptions o = quickFlight(50.0f);
  o.streaming.memoryBudgetBytes = 40 * source.maxCellBytes();
  size_t maxBytes = 0;
  int frames = 0;
  FlythroughSummary s = runFlythrough(source, o, [&](const FlythroughFrame& f) {
    maxBytes = std::max(maxBytes, f.stats.bytesResident);
    ++frames;
    EXPECT_GT(f.visibleSamples, 0);
  });
  EXPECT_EQ(s.frames, 180);
  EXPECT_EQ(frames, 180);
  EXPECT_EQ(s.framesMissingGi, 0);
  EXPECT_LE(maxBytes, o.streaming.memoryBudgetBytes);
  EXPECT_GT(s.cellsRequested, 10);
  EXPECT_LT(s.fallbackFraction, 0.2);  // after the first frames the view is covered by full cells
}

TEST(Flythrough, FasterFlightUsesTheFallbackMoreWhenIoIsScarce) {
  SyntheticCellSource source(world1km());
  FlythroughOptions slow = quickFlight(10.0f), fast = quickFlight(400.0f);
  slow.streaming.prefetchSeconds = fast.streaming.prefetchSeconds = 0.0f;
  slow.streaming.maxInlineLoadsPerFrame = fast.streaming.maxInlineLoadsPerFrame = 1;
  slow.streaming.maxIoInFlight = fast.streaming.maxIoInFlight = 1;
  slow.fps = fast.fps = 4.0f;  // 4 cells per second of IO bandwidth
  FlythroughSummary a = runFlythrough(source, slow), b = runFlythrough(source, fast);
  EXPECT_GT(b.fallbackFraction, a.fallbackFraction + 0.05);
  EXPECT_EQ(a.framesMissingGi, 0);
  EXPECT_EQ(b.framesMissingGi, 0);  // the fallback still lights everything
}

TEST(Flythrough, LoopPathIsClosedAndBadOptionsAreNamed) {
  SyntheticCellSource source(world1km());
  FlythroughOptions o = quickFlight(10.0f);
  glm::vec3 a = flythroughPosition(source.layout(), o, 0.0), b = flythroughPosition(source.layout(), o, 1e6);
  EXPECT_TRUE(source.layout().contains(source.layout().cellOf(a)));
  EXPECT_TRUE(source.layout().contains(source.layout().cellOf(b)));
  o.path = "zigzag";
  try {
    runFlythrough(source, o);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("--path 'zigzag'"), std::string::npos) << e.what();
  }
}

TEST(Flythrough, PathCellsCoverEveryCameraPositionAndNothingFar) {
  const WorldLayout layout = world1km().layout;
  for (const char* path : {"loop", "line"}) {
    FlythroughOptions o = quickFlight(10.0f);
    o.path = path;
    const float radius = 100.0f;
    const std::vector<glm::ivec2> cells = flightPathCells(layout, o, radius);
    std::set<std::pair<int, int>> set;
    for (glm::ivec2 c : cells) {
      EXPECT_TRUE(layout.contains(c)) << path;
      EXPECT_TRUE(set.insert({c.x, c.y}).second) << path << ": cell " << c.x << "," << c.y << " listed twice";
    }
    // The first cell holds the start; every cell within the radius of a camera position is listed.
    const glm::vec3 start = flythroughPosition(layout, o, 0.0);
    EXPECT_EQ(layout.distanceToCell(start, cells.front()), 0.0f) << path;  // (the line starts on a border)
    const double length = flightPathLength(layout, o);
    EXPECT_GT(length, 500.0) << path;
    std::set<std::pair<int, int>> near;
    for (double s = 0.0; s <= length; s += 0.5) {
      const glm::vec3 p = flythroughPosition(layout, o, s);
      for (int z = 0; z < layout.cells.y; ++z)
        for (int x = 0; x < layout.cells.x; ++x)
          if (layout.distanceToCell(p, {x, z}) <= radius - 0.5f) {
            EXPECT_TRUE(set.count({x, z}))
                << path << ": cell " << x << "," << z << " at s = " << s << " missing";
            near.insert({x, z});
          } else if (layout.distanceToCell(p, {x, z}) <= radius + 0.5f) {
            near.insert({x, z});
          }
    }
    // ... and nothing farther: every listed cell is within the radius of some point of the path.
    for (auto c : set)
      EXPECT_TRUE(near.count(c)) << path << ": cell " << c.first << "," << c.second
                                 << " is far from the path";
    // A wider radius lists a superset; radius 0 lists only the cells the path crosses.
    const std::vector<glm::ivec2> wide = flightPathCells(layout, o, 2.0f * radius),
                                  crossed = flightPathCells(layout, o, 0.0f);
    EXPECT_GT(wide.size(), cells.size()) << path;
    EXPECT_LT(crossed.size(), cells.size()) << path;
  }
  FlythroughOptions bad = quickFlight(10.0f);
  EXPECT_THROW(flightPathCells(layout, bad, -1.0f), Error);
  bad.path = "spiral";
  EXPECT_THROW(flightPathCells(layout, bad, 10.0f), Error);
}

}  // namespace
}  // namespace lfgi::streaming
