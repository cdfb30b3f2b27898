// StreamingManager: keeps the light field of the cells around the camera resident (docs/DESIGN.md §1).
// A game loop calls update() once per frame with the camera; the manager
//   1. wants every cell within decodeRadius of the camera or of its predicted position
//      (position + velocity * prefetchSeconds, at most maxPrefetchDistance ahead), ordered by priority =
//      distance x view-direction factor (cells near the prediction count half the look-ahead farther);
//   2. drops resident cells beyond keepRadius (> decodeRadius: a camera oscillating across a border does
//      not thrash) and, when the memory budget is full, the resident cell of worst priority if the
//      candidate is better;
//   3. reads + validates + decodes wanted cells on an IO thread pool (CellSource::load) into a fixed pool
//      of slots sized by the memory budget (floor(budget / source.maxCellBytes()) slots allocated up
//      front: resident bytes never exceed the budget, and no frame allocates);
//   4. activates loaded cells on the game thread (onActivate: GPU upload / GPU decode) within a per-frame
//      time budget, then cross-fades them in from the fallback over fadeSeconds (no pop);
//   5. relights resident cells whose lighting is stale (time of day moved by more than a threshold)
//      asynchronously: nearest (best priority) first, at most maxRelightsPerFrame started per frame and
//      maxRelightsInFlight at once, CellSource::relightInto decodes the cell at the new time of day on the
//      IO pool into a staging field while the cell keeps shading with its old lighting; the game thread
//      swaps the two fields (no copy, no allocation) when the job is done and calls onRelight. A cell
//      evicted while its relight runs waits in a Draining slot (its field is the job's `current`) until
//      the job returns, then the result is dropped. The staging fields come out of the memory budget:
//      slots = floor(budget / maxCellBytes) - maxRelightsInFlight (when relight is on).
//      The weather (FrameInput::weather, overcast) is a second trigger (relightThresholdWeather) and reaches
//      the source with the time of day (CellSource::relightWeatherInto); relightOnActivate makes a freshly
//      activated cell stale at once (a VIR relight replacing the codec's lighting). After the swap the old
//      lighting stays in its staging field and sample() cross-fades from it to the new one over
//      relightFadeSeconds (relightBlend / previousLighting for a GPU shading pass); that staging field is
//      busy until the blend ends (counted in bytesResident), so relights per second are bounded by
//      maxRelightsInFlight / relightFadeSeconds.
// Every cell's coarse fallback (SH L1, CellSource::fallback) is resident from construction on, so a point
// inside the world is never without GI; a source whose fallback follows the time of day
// (CellSource::fallbackFollowsTimeOfDay) has it re-read by update() whenever FrameInput's time moves. A cell
// whose load fails is logged, keeps its fallback and is never requested again.
//
// Seams: sample() interpolates across a cell border between the owning cell's last probe layer and the
// neighbour's field at the border (or the neighbour's fallback if it is not resident), so neighbouring
// resident cells give the same value at a shared point when their probe lattices match in x and z.
//
// Threading contract: construct, update(), sample(), stats() and every accessor on one thread (the
// game thread). The IO threads only run CellSource::load into slots the game thread handed them and does
// not touch until they are returned, and CellSource::relightInto into staging fields likewise, reading
// the resident field as `current` (the game thread only reads it meanwhile: sample(); it neither frees,
// reuses nor swaps that slot until the job is back). onActivate / onRelight run on the game thread inside
// update() (onRelight after the swap: e.g. a GPU re-upload or a VIR relight of the new field).
// With ioThreads = 0 loads run inline in update(), in priority order, and relights inline at the point
// they are started (after activation), swapped at once: the whole sequence of decisions is then a pure
// function of the inputs (tests use this); with IO threads the decisions of what to request and evict
// are still deterministic, only arrival frames vary.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <limits>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "streaming/cell_source.h"

namespace lfgi::streaming {

struct StreamingConfig {
  float decodeRadius = 160.0f;         // m, xz distance to a cell's square
  float keepRadius = 224.0f;           // m, > decodeRadius
  float prefetchSeconds = 2.0f;        // predicted position = position + velocity * this,
  float maxPrefetchDistance = 160.0f;  // ... at most this far ahead (m)
  float viewWeight = 0.5f;             // priority = distance * (1 - viewWeight * max(0, cos(view, to cell)))
  size_t memoryBudgetBytes = size_t(256) << 20;
  int ioThreads = 2;               // 0: inline loads (deterministic)
  int maxIoInFlight = 8;           // requests queued or loading at once
  int maxInlineLoadsPerFrame = 4;  // ioThreads = 0 only
  double activateBudgetMs = 2.0;   // per frame, game-thread time for onActivate
  int maxActivationsPerFrame = 8;
  float fadeSeconds = 0.5f;
  float relightThresholdHours = 0.25f;
  float relightThresholdWeather = 0.05f;  // overcast change that makes a cell stale
  // Cross-fade from the old to the new lighting after a relight swap (sample() and relightBlend(); 0: at
  // once). The old field stays in its staging field until the blend ends, so that staging field starts no
  // relight meanwhile.
  float relightFadeSeconds = 0.5f;
  // A freshly activated cell is stale at once (relit at the first chance): for relights that are better
  // than the load's lighting (VIR relight of codec cells at an unseen time or weather).
  bool relightOnActivate = false;
  int maxRelightsPerFrame = 1;  // relights started per frame (0: no relight)
  int maxRelightsInFlight = 1;  // staging fields (each maxCellBytes of the budget)
  // IO threads: start no relight while a load is in flight (loads fill holes, relights only refresh;
  // on 2 IO threads a relight would otherwise halve the load bandwidth of a fast flight).
  bool relightsYieldToLoads = true;
  bool recordEvents = false;  // keep an event log (tests, profiler)
  // Throws lfgi::Error naming the bad field.
  void validate() const;
};

struct FrameInput {
  glm::vec3 position{0.0f};
  glm::vec3 direction{0.0f, 0.0f, -1.0f};
  glm::vec3 velocity{0.0f};
  float timeOfDayHours = 12.0f;
  float weather = 0.0f;  // overcast [0, 1]: relights target it (CellSource::relightWeatherInto)
  float dtSeconds = 1.0f / 60.0f;
};

struct FrameStats {
  uint64_t frame = 0;
  int resident = 0;  // active (visible) cells
  int loading = 0;   // queued, loading or loaded-not-yet-active
  int requested = 0, activated = 0, evicted = 0, relit = 0, failed = 0;  // this frame (relit: swapped in)
  int relighting = 0;        // relights started and not yet swapped in / dropped
  int relightBlending = 0;   // cells cross-fading from their previous lighting (relightFadeSeconds)
  size_t bytesResident = 0;  // slots in use x their field bytes (<= memoryBudgetBytes)
  double ioMs = 0.0;         // IO-thread time of loads that completed this frame
  double relightIoMs = 0.0;  // relightInto time of relights that completed this frame (IO thread or inline)
  // relightMs: game-thread time of the relight stage (start, inline relightInto when ioThreads = 0, swap,
  // onRelight).
  double activateMs = 0.0, relightMs = 0.0, updateMs = 0.0;
};

enum class StreamingEventType : uint8_t { Request, Activate, Evict, Relight, Fail };
struct StreamingEvent {
  uint64_t frame = 0;
  StreamingEventType type = StreamingEventType::Request;
  glm::ivec2 cell{0};
  friend bool operator==(const StreamingEvent&, const StreamingEvent&) = default;
};

struct CellFailure {
  glm::ivec2 cell{0};
  std::string error;  // what load() threw (what the log line says)
};

struct IrradianceSample {
  glm::vec3 irradiance{0.0f};
  float fallbackWeight = 1.0f;  // 0: all from full cells, 1: all from fallbacks
  bool missing = false;         // outside the world: no fallback either
};

class StreamingManager {
 public:
  // Throws lfgi::Error for a bad config or a budget smaller than one cell.
  StreamingManager(CellSource& source, const StreamingConfig& config);
  ~StreamingManager();
  StreamingManager(const StreamingManager&) = delete;
  StreamingManager& operator=(const StreamingManager&) = delete;

  std::function<void(glm::ivec2 cell, const ProbeField& field)> onActivate;
  std::function<void(glm::ivec2 cell, ProbeField& field, float timeOfDayHours)> onRelight;

  FrameStats update(const FrameInput& input);

  // Irradiance at world point p for unit normal n from resident cells (trilinear over the active probes,
  // renormalised; all 8 inside solid: the fallback; no visibility term: this is the CPU view used for
  // statistics and tests, the GPU shading pass applies Chebyshev weights) blended with fallbacks by fade.
  IrradianceSample sample(glm::vec3 p, glm::vec3 n) const;

  bool isResident(glm::ivec2 cell) const;  // active (visible, maybe still fading in)
  float fade(glm::ivec2 cell) const;       // 0 not resident .. 1 fully faded in
  // Relight cross-fade of a resident cell: 1 when its field is all there is; below 1 right after a relight
  // swap, while previousLighting(cell) (the field before the swap) still blends in as (1 - blend). What a
  // GPU shading pass reads after onRelight: lerp(previousLighting, field, relightBlend).
  float relightBlend(glm::ivec2 cell) const;
  const ProbeField* previousLighting(glm::ivec2 cell) const;  // null when relightBlend is 1
  // The resident (active) field of the cell, null when it is not resident. Valid until the next update().
  const ProbeField* residentField(glm::ivec2 cell) const;
  // Changes whenever the cell's resident field does (activation, relight swap); 0 when not resident. A GPU
  // copy of the field made at version v is current while fieldVersion stays v.
  uint64_t fieldVersion(glm::ivec2 cell) const;
  int slotCount() const { return int(slots_.size()); }
  int stagingCount() const { return int(staging_.size()); }
  const std::vector<StreamingEvent>& events() const { return events_; }
  // Every failed load so far (at most one per cell: a failed cell is never requested again).
  const std::vector<CellFailure>& failures() const { return failures_; }
  const WorldLayout& layout() const { return layout_; }
  // Blocks until every queued IO request has finished (tests, shutdown).
  void drainIo();

 private:
  // Draining: evicted while a relight reads its field; freed when that job returns.
  enum class SlotState : uint8_t { Free, Loading, Loaded, Active, Draining };
  struct Slot {
    SlotState state = SlotState::Free;
    glm::ivec2 cell{0};
    ProbeField field;
    float fade = 0.0f;
    float litTimeOfDay = 0.0f;
    float litWeather = 0.0f;
    bool stale = false;  // relightOnActivate: relight at the first chance
    int blendFrom = -1;  // staging index holding the lighting before the last swap, or -1
    float relightBlend = 1.0f;
    uint64_t version = 0;  // fieldVersion(): set from fieldVersions_ at activation and relight swap
    float priority = 0.0f;
    bool cancelled = false;
    int relight = -1;   // staging index of the relight reading this slot's field, or -1
    std::string error;  // set by the IO thread on failure
    double ioMs = 0.0;
  };
  struct Staging {
    bool busy = false;
    bool blending = false;  // holds slot `slot`'s previous lighting for the relight cross-fade
    int slot = -1;
    float timeOfDay = 0.0f;
    float weather = 0.0f;
    bool cancelled = false;  // the slot was evicted: drop the result
    ProbeField field;
    std::string error;  // set by the IO thread on failure
    double ioMs = 0.0;
  };
  struct Candidate {
    float priority;
    glm::ivec2 cell;
  };

  float priorityOf(glm::ivec2 cell, const FrameInput& in, glm::vec3 predicted) const;
  void startLoad(int slot, glm::ivec2 cell, float priority, FrameStats& stats);
  void runLoad(int slot);
  void runRelight(int staging);
  void finishRelight(int staging, FrameStats& stats);
  void collectFinished(FrameStats& stats);
  // Stages of update, in order.
  void refreshFallbacks(const FrameInput& in);
  void advanceFades(const FrameInput& in);
  void dropFarCells(const FrameInput& in, glm::vec3 predicted, FrameStats& stats);
  void collectWanted(const FrameInput& in, glm::vec3 predicted);
  void requestWanted(FrameStats& stats);
  void activateLoaded(const FrameInput& in, FrameStats& stats);
  void startRelights(const FrameInput& in, FrameStats& stats);
  void countResidency(FrameStats& stats) const;
  void freeSlot(int slot);
  void record(StreamingEventType type, glm::ivec2 cell);
  // The slot's field at p (with its relight cross-fade); false when every probe around p is inside solid.
  bool sampleCell(int slot, glm::vec3 p, glm::vec3 n, glm::vec3& out) const;
  void endBlend(int slot);
  glm::vec3 cellValue(glm::ivec2 cell, glm::vec3 p, glm::vec3 n, float& fallbackWeight) const;
  void ioWorker();

  CellSource& source_;
  StreamingConfig config_;
  WorldLayout layout_;
  std::vector<ShL1> fallback_;
  uint64_t fieldVersions_ = 0;
  float fallbackTimeOfDay_ =
      std::numeric_limits<float>::quiet_NaN();  // fallback_ read at (NaN: not since construction)
  std::vector<int32_t> cellSlot_;               // per cell: slot index or -1
  std::vector<uint8_t> failed_;                 // per cell
  std::vector<Slot> slots_;
  std::vector<Staging> staging_;
  std::vector<Candidate> wanted_;  // reused every frame
  std::vector<StreamingEvent> events_;
  std::vector<CellFailure> failures_;
  uint64_t frame_ = 0;
  FrameInput last_{};

  std::mutex ioMutex_;
  std::condition_variable ioCv_, doneCv_;
  std::deque<int> ioQueue_;  // jobs: slot index s >= 0 (load) or -1 - staging index (relight)
  std::vector<int> ioDone_;
  std::vector<int> doneScratch_;
  int ioOutstanding_ = 0;
  bool stopping_ = false;
  std::vector<std::thread> ioThreads_;
};

}  // namespace lfgi::streaming
