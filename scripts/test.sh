#!/usr/bin/env bash
# Installs what is missing, builds, and runs the whole test suite with CTest; then rebuilds the file
# readers' and decoders' tests (core: EXR; worlds: Draco surfels, glTF) under AddressSanitizer +
# UndefinedBehaviorSanitizer and runs them (tests named *Slow* are skipped there); then, when clang and
# libFuzzer are installed, fuzzes the cell-file reader, surfel decoder and world manifest parser for a
# bounded time (scripts/fuzz.sh; LFGI_SKIP_FUZZ=1 skips it, LFGI_FUZZ_SECONDS sets the time).
# Usage: scripts/test.sh [ctest args...]      (e.g. -L lfgi_core, -R Octahedral, -LE slow)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
source "$root/scripts/env.sh"
"$root/scripts/setup.sh"
jobs="${LFGI_JOBS:-$(nproc)}"

start=$(date +%s)
"$root/scripts/build.sh" "$root/build"
ctest --test-dir "$root/build" --output-on-failure -j "$jobs" "$@"
echo "tests: main suite took $(( $(date +%s) - start )) s (build included)"

if [[ "${LFGI_SKIP_SANITIZERS:-0}" != "1" ]]; then
  start=$(date +%s)
  LFGI_SANITIZE=address,undefined "$root/scripts/build.sh" "$root/build-asan" lfgi_core_tests lfgi_worlds_tests
  # Sanitized run of the readers/decoders: any report aborts the test (-fno-sanitize-recover).
  ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1 \
    ctest --test-dir "$root/build-asan" --output-on-failure -j "$jobs" -L 'lfgi_core|lfgi_worlds' -E Slow
  echo "tests: sanitizer suite took $(( $(date +%s) - start )) s (build included)"
fi

if [[ "${LFGI_SKIP_FUZZ:-0}" != "1" ]]; then
  LFGI_JOBS="$jobs" "$root/scripts/fuzz.sh" "$root/build-fuzz-clang"
fi
