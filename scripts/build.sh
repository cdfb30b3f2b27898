#!/usr/bin/env bash
# Configures and builds lfgi. Usage: scripts/build.sh [BUILD_DIR [TARGET...]]   (default: build/, all)
# Environment: LFGI_WERROR=ON (warnings are errors; CI), LFGI_SANITIZE=address,undefined,
# LFGI_BUILD_TYPE (default RelWithDebInfo), LFGI_JOBS (default: all cores).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${1:-$root/build}"
shift || true
targets=()
for t in "$@"; do targets+=(--target "$t"); done
start=$(date +%s)
launcher=()
# ccache only when present (developer machines; CI starts clean and does not install it).
if command -v ccache >/dev/null 2>&1; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi
# LFGI_WERROR unset keeps the build directory's setting (a fresh one: OFF), so `scripts/bench.sh` or
# `scripts/demo.sh` after a CI-style -Werror build does not reconfigure and rebuild everything.
werror=()
if [[ -n "${LFGI_WERROR:-}" ]]; then werror=(-DLFGI_WERROR="$LFGI_WERROR"); fi
cmake -S "$root" -B "$build" -G Ninja "${launcher[@]}" -DCMAKE_BUILD_TYPE="${LFGI_BUILD_TYPE:-RelWithDebInfo}" \
  "${werror[@]}" -DLFGI_SANITIZE="${LFGI_SANITIZE:-}" >/dev/null
cmake --build "$build" -j "${LFGI_JOBS:-$(nproc)}" "${targets[@]}"
echo "build: $build done in $(( $(date +%s) - start )) s"
