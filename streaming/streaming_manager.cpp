#include "streaming/streaming_manager.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include <spdlog/spdlog.h>

#include "core/error.h"
#include "core/octahedral.h"

namespace lfgi::streaming {

namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

// Shortest distance between two times of day on the 24 h circle.
float hoursApart(float a, float b) {
  float d = std::fmod(std::fabs(a - b), 24.0f);
  return std::min(d, 24.0f - d);
}

}  // namespace

void StreamingConfig::validate() const {
  if (!(decodeRadius > 0.0f)) fail("StreamingConfig.decodeRadius = {} must be > 0", decodeRadius);
  if (!(keepRadius >= decodeRadius))
    fail("StreamingConfig.keepRadius = {} must be >= decodeRadius = {} (hysteresis)", keepRadius,
         decodeRadius);
  if (!(prefetchSeconds >= 0.0f)) fail("StreamingConfig.prefetchSeconds = {} must be >= 0", prefetchSeconds);
  if (!(maxPrefetchDistance >= 0.0f))
    fail("StreamingConfig.maxPrefetchDistance = {} must be >= 0", maxPrefetchDistance);
  if (!(viewWeight >= 0.0f && viewWeight < 1.0f))
    fail("StreamingConfig.viewWeight = {} outside [0, 1)", viewWeight);
  if (ioThreads < 0 || ioThreads > 64) fail("StreamingConfig.ioThreads = {} outside [0, 64]", ioThreads);
  if (maxIoInFlight < 1) fail("StreamingConfig.maxIoInFlight = {} must be >= 1", maxIoInFlight);
  if (maxInlineLoadsPerFrame < 1)
    fail("StreamingConfig.maxInlineLoadsPerFrame = {} must be >= 1", maxInlineLoadsPerFrame);
  if (maxActivationsPerFrame < 1)
    fail("StreamingConfig.maxActivationsPerFrame = {} must be >= 1", maxActivationsPerFrame);
  if (!(activateBudgetMs >= 0.0))
    fail("StreamingConfig.activateBudgetMs = {} must be >= 0", activateBudgetMs);
  if (!(fadeSeconds >= 0.0f)) fail("StreamingConfig.fadeSeconds = {} must be >= 0", fadeSeconds);
  if (maxRelightsPerFrame < 0)
    fail("StreamingConfig.maxRelightsPerFrame = {} must be >= 0", maxRelightsPerFrame);
  if (maxRelightsInFlight < 1)
    fail("StreamingConfig.maxRelightsInFlight = {} must be >= 1", maxRelightsInFlight);
  if (!(relightThresholdWeather >= 0.0f))
    fail("StreamingConfig.relightThresholdWeather = {} must be >= 0", relightThresholdWeather);
  if (!(relightFadeSeconds >= 0.0f))
    fail("StreamingConfig.relightFadeSeconds = {} must be >= 0", relightFadeSeconds);
}

StreamingManager::StreamingManager(CellSource& source, const StreamingConfig& config)
    : source_(source), config_(config), layout_(source.layout()) {
  config_.validate();
  const size_t cellBytes = source_.maxCellBytes();
  if (cellBytes == 0) fail("StreamingManager: the cell source reports 0 bytes per cell");
  // Relight staging fields are part of the budget: resident + staging bytes never exceed it.
  const size_t staging = config_.maxRelightsPerFrame > 0 ? size_t(config_.maxRelightsInFlight) : 0;
  const size_t total = config_.memoryBudgetBytes / cellBytes;
  if (total < 1 + staging)
    fail(
        "StreamingConfig.memoryBudgetBytes = {} is smaller than one cell plus {} relight staging field(s) "
        "({} bytes each; see maxRelightsInFlight)",
        config_.memoryBudgetBytes, staging, cellBytes);
  const size_t slots = total - staging;
  const size_t cells = size_t(layout_.cells.x) * size_t(layout_.cells.y);
  fallback_.resize(cells);
  for (int z = 0; z < layout_.cells.y; ++z)
    for (int x = 0; x < layout_.cells.x; ++x)
      fallback_[size_t(layout_.linear({x, z}))] = source_.fallback({x, z});
  cellSlot_.assign(cells, -1);
  failed_.assign(cells, 0);
  slots_.resize(slots);
  staging_.resize(staging);
  wanted_.reserve(1024);
  for (int i = 0; i < config_.ioThreads; ++i) ioThreads_.emplace_back([this] { ioWorker(); });
}

StreamingManager::~StreamingManager() {
  {
    std::lock_guard lock(ioMutex_);
    stopping_ = true;
    ioQueue_.clear();
  }
  ioCv_.notify_all();
  for (auto& t : ioThreads_) t.join();
}

void StreamingManager::record(StreamingEventType type, glm::ivec2 cell) {
  if (config_.recordEvents) events_.push_back({frame_, type, cell});
}

float StreamingManager::priorityOf(glm::ivec2 cell, const FrameInput& in, glm::vec3 predicted) const {
  // A cell near the prediction counts as if it were half the look-ahead farther away: the camera's own
  // surroundings come first, what lies ahead next.
  const float lookahead = glm::length(predicted - in.position);
  float d = std::min(layout_.distanceToCell(in.position, cell),
                     layout_.distanceToCell(predicted, cell) + 0.5f * lookahead);
  glm::vec2 centre = layout_.cellMin(cell) + 0.5f * layout_.cellSize;
  glm::vec2 to = centre - glm::vec2(in.position.x, in.position.z), view(in.direction.x, in.direction.z);
  float cosView = 0.0f;
  if (glm::length(to) > 1e-3f && glm::length(view) > 1e-3f)
    cosView = glm::dot(glm::normalize(to), glm::normalize(view));
  return d * (1.0f - config_.viewWeight * std::max(0.0f, cosView));
}

void StreamingManager::runLoad(int s) {
  Slot& slot = slots_[size_t(s)];
  auto t0 = Clock::now();
  try {
    source_.load(slot.cell, slot.field);
    if (slot.field.bytes() > source_.maxCellBytes())
      fail("cell {},{}: {} bytes exceed the source's slot size {}", slot.cell.x, slot.cell.y,
           slot.field.bytes(), source_.maxCellBytes());
  } catch (const std::exception& e) {
    slot.error = e.what();
    if (slot.error.empty()) slot.error = "unknown error";
  }
  slot.ioMs = msSince(t0);
}

void StreamingManager::runRelight(int i) {
  Staging& st = staging_[size_t(i)];
  const Slot& slot = slots_[size_t(st.slot)];
  auto t0 = Clock::now();
  try {
    source_.relightWeatherInto(slot.cell, slot.field, st.field, st.timeOfDay, st.weather);
    if (st.field.bytes() > source_.maxCellBytes())
      fail("cell {},{}: relit field of {} bytes exceeds the source's slot size {}", slot.cell.x, slot.cell.y,
           st.field.bytes(), source_.maxCellBytes());
  } catch (const std::exception& e) {
    st.error = e.what();
    if (st.error.empty()) st.error = "unknown error";
  }
  st.ioMs = msSince(t0);
}

// Game thread: the job of staging field i is back.
void StreamingManager::finishRelight(int i, FrameStats& stats) {
  Staging& st = staging_[size_t(i)];
  Slot& slot = slots_[size_t(st.slot)];
  slot.relight = -1;
  slot.stale = false;
  stats.relightIoMs += st.ioMs;
  bool blend = false;
  if (st.cancelled) {
    // Evicted meanwhile (Draining): free the slot now. cellSlot_ was cleared at eviction and may already
    // name another slot holding a new load of the same cell.
    slot.state = SlotState::Free;
    slot.cancelled = false;
    slot.fade = 0.0f;
  } else if (!st.error.empty()) {
    spdlog::warn("streaming: relight of cell {},{} failed, keeping its lighting: {}", slot.cell.x,
                 slot.cell.y, st.error);
    slot.litTimeOfDay = st.timeOfDay;  // no retry every frame: the next try waits for the next threshold
    slot.litWeather = st.weather;
  } else {
    std::swap(slot.field, st.field);  // the old lighting stays in the staging field for reuse
    slot.version = ++fieldVersions_;
    slot.litTimeOfDay = st.timeOfDay;
    slot.litWeather = st.weather;
    if (config_.relightFadeSeconds > 0.0f) {  // blend from the old lighting, still in st.field
      blend = true;
      slot.blendFrom = i;
      slot.relightBlend = 0.0f;
    }
    if (onRelight) onRelight(slot.cell, slot.field, st.timeOfDay);
    ++stats.relit;
    record(StreamingEventType::Relight, slot.cell);
  }
  st.busy = false;
  st.blending = blend;
  if (!blend) st.slot = -1;
  st.cancelled = false;
  st.error.clear();
}

void StreamingManager::endBlend(int s) {
  Slot& slot = slots_[size_t(s)];
  if (slot.blendFrom < 0) return;
  Staging& st = staging_[size_t(slot.blendFrom)];
  st.blending = false;
  st.slot = -1;
  slot.blendFrom = -1;
  slot.relightBlend = 1.0f;
}

void StreamingManager::ioWorker() {
  for (;;) {
    int s;
    {
      std::unique_lock lock(ioMutex_);
      ioCv_.wait(lock, [this] { return stopping_ || !ioQueue_.empty(); });
      if (stopping_) return;
      s = ioQueue_.front();
      ioQueue_.pop_front();
    }
    if (s >= 0)
      runLoad(s);
    else
      runRelight(-1 - s);
    {
      std::lock_guard lock(ioMutex_);
      ioDone_.push_back(s);
      --ioOutstanding_;
    }
    doneCv_.notify_all();
  }
}

void StreamingManager::drainIo() {
  std::unique_lock lock(ioMutex_);
  doneCv_.wait(lock, [this] { return ioOutstanding_ == 0; });
}

void StreamingManager::startLoad(int s, glm::ivec2 cell, float priority, FrameStats& stats) {
  Slot& slot = slots_[size_t(s)];
  slot.state = SlotState::Loading;
  slot.cell = cell;
  slot.priority = priority;
  slot.cancelled = false;
  slot.error.clear();
  slot.fade = 0.0f;
  cellSlot_[size_t(layout_.linear(cell))] = s;
  ++stats.requested;
  record(StreamingEventType::Request, cell);
  if (config_.ioThreads == 0) {
    runLoad(s);
    ioDone_.push_back(s);
    return;
  }
  {
    std::lock_guard lock(ioMutex_);
    ioQueue_.push_back(s);
    ++ioOutstanding_;
  }
  ioCv_.notify_one();
}

void StreamingManager::freeSlot(int s) {
  endBlend(s);
  Slot& slot = slots_[size_t(s)];
  cellSlot_[size_t(layout_.linear(slot.cell))] = -1;
  if (slot.relight >= 0) {  // a relight reads the field: keep it until the job returns
    staging_[size_t(slot.relight)].cancelled = true;
    slot.state = SlotState::Draining;
    return;
  }
  slot.state = SlotState::Free;
  slot.cancelled = false;
  slot.fade = 0.0f;
}

void StreamingManager::collectFinished(FrameStats& stats) {
  std::vector<int>& done = doneScratch_;  // swapped with ioDone_ under the lock: both keep their capacity
  done.clear();
  {
    std::lock_guard lock(ioMutex_);
    done.swap(ioDone_);
  }
  std::sort(done.begin(), done.end());  // deterministic processing order (relights first)
  for (int s : done) {
    if (s < 0) {
      auto t0 = Clock::now();
      finishRelight(-1 - s, stats);
      stats.relightMs += msSince(t0);
      continue;
    }
    Slot& slot = slots_[size_t(s)];
    stats.ioMs += slot.ioMs;
    if (!slot.error.empty()) {
      spdlog::warn("streaming: cell {},{} failed to load, keeping its fallback: {}", slot.cell.x, slot.cell.y,
                   slot.error);
      failed_[size_t(layout_.linear(slot.cell))] = 1;
      failures_.push_back({slot.cell, slot.error});
      ++stats.failed;
      record(StreamingEventType::Fail, slot.cell);
      freeSlot(s);
    } else if (slot.cancelled) {
      freeSlot(s);
    } else {
      slot.state = SlotState::Loaded;
    }
  }
}

FrameStats StreamingManager::update(const FrameInput& in) {
  auto t0 = Clock::now();
  ++frame_;
  FrameStats stats;
  stats.frame = frame_;
  last_ = in;
  source_.setTimeOfDay(in.timeOfDayHours);
  refreshFallbacks(in);
  // Straight-line extrapolation, capped: on a curved path a long look-ahead lands off the path (at 400 m/s
  // on a 1.4 km radius loop, 2 s ahead is ~230 m off it) and would spend IO on cells never visited.
  glm::vec3 ahead = in.velocity * config_.prefetchSeconds;
  if (float len = glm::length(ahead); len > config_.maxPrefetchDistance)
    ahead *= config_.maxPrefetchDistance / len;
  const glm::vec3 predicted = in.position + ahead;

  advanceFades(in);
  dropFarCells(in, predicted, stats);
  collectWanted(in, predicted);
  requestWanted(stats);
  collectFinished(stats);
  activateLoaded(in, stats);
  startRelights(in, stats);
  countResidency(stats);
  stats.updateMs = msSince(t0);
  return stats;
}

void StreamingManager::refreshFallbacks(const FrameInput& in) {
  // A source whose fallback follows the time of day (CellFileSource's per-key SH): re-read the resident
  // fallbacks when it moved (a cheap interpolation per cell, game thread; no allocation).
  if (source_.fallbackFollowsTimeOfDay() && !(in.timeOfDayHours == fallbackTimeOfDay_)) {
    for (int z = 0; z < layout_.cells.y; ++z)
      for (int x = 0; x < layout_.cells.x; ++x)
        fallback_[size_t(layout_.linear({x, z}))] = source_.fallback({x, z});
    fallbackTimeOfDay_ = in.timeOfDayHours;
  }
}

void StreamingManager::advanceFades(const FrameInput& in) {
  // Fade in what is visible (before this frame's activations, which start at 0).
  for (size_t s = 0; s < slots_.size(); ++s) {
    Slot& slot = slots_[s];
    if (slot.state != SlotState::Active) continue;
    slot.fade =
        config_.fadeSeconds > 0.0f ? std::min(1.0f, slot.fade + in.dtSeconds / config_.fadeSeconds) : 1.0f;
    // Relight cross-fade (swaps of this frame start at 0 below).
    if (slot.blendFrom >= 0) {
      slot.relightBlend = std::min(1.0f, slot.relightBlend + in.dtSeconds / config_.relightFadeSeconds);
      if (slot.relightBlend >= 1.0f) endBlend(int(s));
    }
  }
}

void StreamingManager::dropFarCells(const FrameInput& in, glm::vec3 predicted, FrameStats& stats) {
  // Drop what is beyond the keep radius of both the camera and its prediction.
  for (size_t s = 0; s < slots_.size(); ++s) {
    Slot& slot = slots_[s];
    if (slot.state == SlotState::Free || slot.state == SlotState::Draining) continue;
    float d = std::min(layout_.distanceToCell(in.position, slot.cell),
                       layout_.distanceToCell(predicted, slot.cell));
    slot.priority = priorityOf(slot.cell, in, predicted);
    if (d <= config_.keepRadius) continue;
    if (slot.state == SlotState::Loading) {
      slot.cancelled = true;
    } else {
      ++stats.evicted;
      record(StreamingEventType::Evict, slot.cell);
      freeSlot(int(s));
    }
  }
}

void StreamingManager::collectWanted(const FrameInput& in, glm::vec3 predicted) {
  // Wanted cells by priority (ties by index: deterministic).
  wanted_.clear();
  const float r = config_.decodeRadius;
  glm::vec3 lo = glm::min(in.position, predicted) - r, hi = glm::max(in.position, predicted) + r;
  glm::ivec2 c0 = glm::max(layout_.cellOf(lo), glm::ivec2(0)),
             c1 = glm::min(layout_.cellOf(hi), layout_.cells - 1);
  for (int z = c0.y; z <= c1.y; ++z)
    for (int x = c0.x; x <= c1.x; ++x) {
      glm::ivec2 c{x, z};
      float d = std::min(layout_.distanceToCell(in.position, c), layout_.distanceToCell(predicted, c));
      if (d > r || failed_[size_t(layout_.linear(c))]) continue;
      int s = cellSlot_[size_t(layout_.linear(c))];
      if (s >= 0) {
        slots_[size_t(s)].cancelled = false;  // wanted again while loading
        continue;
      }
      wanted_.push_back({priorityOf(c, in, predicted), c});
    }
  std::sort(wanted_.begin(), wanted_.end(), [this](const Candidate& a, const Candidate& b) {
    return a.priority != b.priority ? a.priority < b.priority
                                    : layout_.linear(a.cell) < layout_.linear(b.cell);
  });
}

// Starts loads of wanted_ in order, into free slots or in place of worse resident cells, within the IO caps.
void StreamingManager::requestWanted(FrameStats& stats) {
  int inFlight = 0;
  for (const Slot& slot : slots_) inFlight += slot.state == SlotState::Loading;
  int inlineLoads = 0;
  for (const Candidate& cand : wanted_) {
    if (inFlight >= config_.maxIoInFlight) break;
    if (config_.ioThreads == 0 && inlineLoads >= config_.maxInlineLoadsPerFrame) break;
    int target = -1;
    for (size_t s = 0; s < slots_.size() && target < 0; ++s)
      if (slots_[s].state == SlotState::Free) target = int(s);
    if (target < 0) {  // budget full: replace the worst resident cell if the candidate is better
      float worst = cand.priority;
      for (size_t s = 0; s < slots_.size(); ++s) {
        const Slot& slot = slots_[s];
        if ((slot.state == SlotState::Active || slot.state == SlotState::Loaded) && slot.relight < 0 &&
            slot.priority > worst) {
          worst = slot.priority;
          target = int(s);
        }
      }
      if (target < 0) break;  // everything resident matters more: the rest waits (budget holds)
      ++stats.evicted;
      record(StreamingEventType::Evict, slots_[size_t(target)].cell);
      freeSlot(target);
    }
    startLoad(target, cand.cell, cand.priority, stats);
    ++inFlight;
    ++inlineLoads;
  }
}

void StreamingManager::activateLoaded(const FrameInput& in, FrameStats& stats) {
  // Activate loaded cells, best priority first, within the per-frame time budget.
  auto ta = Clock::now();
  for (int n = 0; n < config_.maxActivationsPerFrame; ++n) {
    if (n > 0 && msSince(ta) >= config_.activateBudgetMs) break;
    int best = -1;
    for (size_t s = 0; s < slots_.size(); ++s)
      if (slots_[s].state == SlotState::Loaded &&
          (best < 0 || slots_[s].priority < slots_[size_t(best)].priority))
        best = int(s);
    if (best < 0) break;
    Slot& slot = slots_[size_t(best)];
    if (onActivate) onActivate(slot.cell, slot.field);
    slot.state = SlotState::Active;
    slot.version = ++fieldVersions_;
    slot.fade = config_.fadeSeconds > 0.0f ? 0.0f : 1.0f;
    slot.litTimeOfDay = in.timeOfDayHours;
    slot.litWeather = in.weather;
    slot.stale = config_.relightOnActivate;
    slot.blendFrom = -1;
    slot.relightBlend = 1.0f;
    ++stats.activated;
    record(StreamingEventType::Activate, slot.cell);
  }
  stats.activateMs = msSince(ta);
}

void StreamingManager::startRelights(const FrameInput& in, FrameStats& stats) {
  // Start relights of stale cells, nearest first, amortised over frames and capped in flight.
  auto tr = Clock::now();
  bool loadsInFlight = false;
  for (const Slot& slot : slots_) loadsInFlight = loadsInFlight || slot.state == SlotState::Loading;
  const bool yield = config_.ioThreads > 0 && config_.relightsYieldToLoads && loadsInFlight;
  for (int n = 0; n < config_.maxRelightsPerFrame && !yield; ++n) {
    int st = -1;
    for (size_t i = 0; i < staging_.size() && st < 0; ++i)
      if (!staging_[i].busy && !staging_[i].blending) st = int(i);
    if (st < 0) break;
    int best = -1;
    for (size_t s = 0; s < slots_.size(); ++s) {
      const Slot& slot = slots_[s];
      const bool stale = slot.stale ||
                         hoursApart(slot.litTimeOfDay, in.timeOfDayHours) > config_.relightThresholdHours ||
                         std::fabs(slot.litWeather - in.weather) > config_.relightThresholdWeather;
      if (slot.state == SlotState::Active && slot.relight < 0 && slot.blendFrom < 0 && stale &&
          (best < 0 || slot.priority < slots_[size_t(best)].priority))
        best = int(s);
    }
    if (best < 0) break;
    Staging& stage = staging_[size_t(st)];
    stage.busy = true;
    stage.slot = best;
    stage.timeOfDay = in.timeOfDayHours;
    stage.weather = in.weather;
    stage.cancelled = false;
    stage.error.clear();
    slots_[size_t(best)].relight = st;
    if (config_.ioThreads == 0) {
      runRelight(st);
      finishRelight(st, stats);
      continue;
    }
    {
      std::lock_guard lock(ioMutex_);
      ioQueue_.push_back(-1 - st);
      ++ioOutstanding_;
    }
    ioCv_.notify_one();
  }
  stats.relightMs += msSince(tr);
}

void StreamingManager::countResidency(FrameStats& stats) const {
  for (const Slot& slot : slots_) {
    if (slot.state == SlotState::Active) ++stats.resident;
    if (slot.state == SlotState::Loading || slot.state == SlotState::Loaded) ++stats.loading;
    // A loading slot's field belongs to its IO thread: count it at the slot size (an upper bound).
    if (slot.state == SlotState::Loading)
      stats.bytesResident += source_.maxCellBytes();
    else if (slot.state != SlotState::Free)
      stats.bytesResident += slot.field.bytes();
  }
  // A staging field in use belongs to its IO thread (or holds a cross-fade's old lighting): count it at
  // the slot size too.
  for (const Staging& st : staging_) {
    if (st.busy) ++stats.relighting;
    if (st.blending) ++stats.relightBlending;
    if (st.busy || st.blending) stats.bytesResident += source_.maxCellBytes();
  }
}

bool StreamingManager::isResident(glm::ivec2 cell) const {
  if (!layout_.contains(cell)) return false;
  int s = cellSlot_[size_t(layout_.linear(cell))];
  return s >= 0 && slots_[size_t(s)].state == SlotState::Active;
}

float StreamingManager::fade(glm::ivec2 cell) const {
  return isResident(cell) ? slots_[size_t(cellSlot_[size_t(layout_.linear(cell))])].fade : 0.0f;
}

namespace {

// Irradiance of field f at p for normal n: trilinear over probes, bilinear within the octahedral map.
// Trilinear over the active probes of p's cube (probes inside solid left out, the weights renormalised over
// the others, as the GPU shading pass does); false when all 8 are inactive.
bool sampleField(const ProbeField& f, glm::vec3 p, glm::vec3 n, glm::vec3& out) {
  TrilinearProbes tri = f.grid.trilinear(p);
  float sum = 0.0f;
  for (int k = 0; k < 8; ++k)
    if (!f.isActive(tri.indices[size_t(k)]))
      tri.weights[size_t(k)] = 0.0f;
    else
      sum += tri.weights[size_t(k)];
  if (!(sum > 0.0f)) return false;
  const int m = f.irradianceResolution, bm = octBorderedSize(m);
  thread_local std::vector<float> bordered;  // one probe's irradiance map with its border, reused
  bordered.resize(octBorderedFloats(m, 3));
  glm::vec3 e(0.0f);
  for (int k = 0; k < 8; ++k) {
    if (tri.weights[size_t(k)] == 0.0f) continue;
    const float* src = &f.irradiance[size_t(tri.indices[size_t(k)]) * size_t(m * m) * 3];
    for (int j = 0; j < m; ++j)
      std::copy_n(src + size_t(j * m) * 3, size_t(m) * 3, &bordered[(size_t(j + 1) * size_t(bm) + 1) * 3]);
    fillBorder(bordered.data(), m, 3);
    float v[3];
    octSampleBilinear(bordered.data(), m, 3, n, v);
    e += tri.weights[size_t(k)] * glm::vec3(v[0], v[1], v[2]);
  }
  out = e / sum;
  return true;
}

}  // namespace

bool StreamingManager::sampleCell(int s, glm::vec3 p, glm::vec3 n, glm::vec3& out) const {
  const Slot& slot = slots_[size_t(s)];
  glm::vec3 e(0.0f), before(0.0f);
  if (!sampleField(slot.field, p, n, e)) return false;
  out = e;
  if (slot.blendFrom >= 0 && sampleField(staging_[size_t(slot.blendFrom)].field, p, n, before))
    out = slot.relightBlend * e + (1.0f - slot.relightBlend) * before;
  return true;
}

float StreamingManager::relightBlend(glm::ivec2 cell) const {
  if (!isResident(cell)) return 1.0f;
  return slots_[size_t(cellSlot_[size_t(layout_.linear(cell))])].relightBlend;
}

const ProbeField* StreamingManager::previousLighting(glm::ivec2 cell) const {
  if (!isResident(cell)) return nullptr;
  const Slot& slot = slots_[size_t(cellSlot_[size_t(layout_.linear(cell))])];
  return slot.blendFrom >= 0 ? &staging_[size_t(slot.blendFrom)].field : nullptr;
}

const ProbeField* StreamingManager::residentField(glm::ivec2 cell) const {
  if (!isResident(cell)) return nullptr;
  return &slots_[size_t(cellSlot_[size_t(layout_.linear(cell))])].field;
}

uint64_t StreamingManager::fieldVersion(glm::ivec2 cell) const {
  if (!isResident(cell)) return 0;
  return slots_[size_t(cellSlot_[size_t(layout_.linear(cell))])].version;
}

// The cell's value at p: full field blended with the (bilinear-over-cell-centres) fallback by fade.
glm::vec3 StreamingManager::cellValue(glm::ivec2 cell, glm::vec3 p, glm::vec3 n,
                                      float& fallbackWeight) const {
  // Fallback: bilinear between the irradiance of the 4 nearest cell centres (no step at borders).
  glm::vec2 g = (glm::vec2(p.x, p.z) - layout_.originXZ) / layout_.cellSize - 0.5f;
  glm::ivec2 b = glm::ivec2(glm::floor(g));
  glm::vec2 t = g - glm::vec2(b);
  glm::vec3 fb(0.0f);
  for (int k = 0; k < 4; ++k) {
    glm::ivec2 c = glm::clamp(b + glm::ivec2(k & 1, k >> 1), glm::ivec2(0), layout_.cells - 1);
    float w = ((k & 1) ? t.x : 1.0f - t.x) * ((k >> 1) ? t.y : 1.0f - t.y);
    fb += w * shIrradiance(fallback_[size_t(layout_.linear(c))], n);
  }
  int s = layout_.contains(cell) ? cellSlot_[size_t(layout_.linear(cell))] : -1;
  glm::vec3 e(0.0f);
  if (s < 0 || slots_[size_t(s)].state != SlotState::Active || !sampleCell(s, p, n, e)) {
    fallbackWeight = 1.0f;  // not resident, or every probe around p inside solid
    return fb;
  }
  float f = slots_[size_t(s)].fade;
  fallbackWeight = 1.0f - f;
  return f * e + (1.0f - f) * fb;
}

IrradianceSample StreamingManager::sample(glm::vec3 p, glm::vec3 n) const {
  IrradianceSample out;
  const glm::ivec2 a = layout_.cellOf(p);
  if (!layout_.contains(a) || !std::isfinite(p.x + p.y + p.z)) {
    out.missing = true;
    return out;
  }
  // Seam-free across x/z borders: in the last probe interval before the owning cell's far face, blend
  // towards the neighbour's value at the face (its first probe layer when lattices match).
  glm::vec2 tFar(0.0f);
  glm::vec3 lastProbe = p;
  int s = cellSlot_[size_t(layout_.linear(a))];
  if (s >= 0 && slots_[size_t(s)].state == SlotState::Active) {
    const ProbeGrid& g = slots_[size_t(s)].field.grid;
    glm::vec3 last = g.probePosition(g.dims - 1), far = g.boxMax();
    for (int axis : {0, 2}) {
      int k = axis == 0 ? 0 : 1;
      if (p[axis] > last[axis] && far[axis] > last[axis]) {
        tFar[k] = std::min(1.0f, (p[axis] - last[axis]) / (far[axis] - last[axis]));
        lastProbe[axis] = last[axis];
      }
    }
  }
  const glm::vec3 farFace(layout_.cellMin(a + 1).x, p.y, layout_.cellMin(a + 1).y);
  glm::vec3 value(0.0f);
  float fallbackWeight = 0.0f;
  for (int k = 0; k < 4; ++k) {
    int dx = k & 1, dz = k >> 1;
    float w = (dx ? tFar.x : 1.0f - tFar.x) * (dz ? tFar.y : 1.0f - tFar.y);
    if (w <= 0.0f) continue;
    glm::ivec2 c = a + glm::ivec2(dx, dz);
    glm::vec3 q(dx ? farFace.x : lastProbe.x, p.y, dz ? farFace.z : lastProbe.z);
    if (!layout_.contains(c)) c = a, q = lastProbe;  // world edge: clamp to the owning cell
    float fw = 1.0f;
    value += w * cellValue(c, q, n, fw);
    fallbackWeight += w * fw;
  }
  out.irradiance = value;
  out.fallbackWeight = fallbackWeight;
  return out;
}

}  // namespace lfgi::streaming
