#include "bake/parallel_work.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <atomic>
#include <optional>

#include "core/progress.h"

namespace lfgi::bake::detail {

ParallelWorkResult runParallelInterruptible(size_t count, const char* label, const char* unit,
                                            bool showProgress, const std::function<void(size_t)>& work) {
  std::atomic<size_t> finished{0};
  std::atomic<bool> stopped{false};
  std::optional<Progress> progress;
  if (showProgress) progress.emplace(label, count, unit);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, count, 1), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i < r.end(); ++i) {
      if (InterruptGuard::interrupted()) {
        stopped.store(true);
        return;
      }
      work(i);
      finished.fetch_add(1);
      if (progress) progress->update(finished.load());
    }
  });
  if (progress) {
    progress->update(finished.load());
    progress->finish();
  }
  ParallelWorkResult result;
  result.done = finished.load();
  result.interrupted = stopped.load() && result.done < count;
  return result;
}

}  // namespace lfgi::bake::detail
