// Internal: the one loop that runs a long bake job's independent items (probes, image tiles) over TBB,
// stops between items on Ctrl-C (InterruptGuard::interrupted(), the caller installs the guard) and
// reports progress (core/progress.h) from whichever worker finishes an item.
#pragma once

#include <cstddef>
#include <functional>

namespace lfgi::bake::detail {

struct ParallelWorkResult {
  size_t done = 0;           // items whose work(i) returned
  bool interrupted = false;  // Ctrl-C stopped the run before every item was done
};

// Calls work(i) for every i in [0, count), in parallel, each exactly once unless interrupted. With
// showProgress, prints "<label> [...] done/count <unit>" to stderr.
ParallelWorkResult runParallelInterruptible(size_t count, const char* label, const char* unit,
                                            bool showProgress, const std::function<void(size_t)>& work);

}  // namespace lfgi::bake::detail
