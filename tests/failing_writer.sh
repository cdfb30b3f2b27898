#!/usr/bin/env bash
# A writer that fails mid-file leaves no partial output (docs/ARCHITECTURE.md "Bad input and interruption"): `lfgi profile` with a gnuplot that
# writes half a PNG and fails must finish (exit 0, a warning), write its other outputs, and leave neither
# profile.png nor a temporary file behind. Usage: tests/failing_writer.sh LFGI_BINARY WORK_DIR
set -uo pipefail
lfgi="$1"
out="$2"
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
rm -rf "$out"
PATH="$here/bad_inputs/failing_gnuplot:$PATH" "$lfgi" profile --seconds 1 --speed 50 --budget-mb 16 --resolution 4 \
  --out "$out" >"$out.log" 2>&1
rc=$?
fail() { echo "failing_writer: FAIL: $*"; cat "$out.log"; ls -la "$out"; exit 1; }
[[ "$rc" -eq 0 ]] || fail "lfgi profile exited $rc"
grep -q "gnuplot failed" "$out.log" || fail "no warning about the failed chart"
[[ -e "$out/summary.html" && -e "$out/trace.json" ]] || fail "the other outputs are missing"
[[ ! -e "$out/profile.png" ]] || fail "a partial profile.png was left behind"
temps=$(find "$out" -name '*.tmp.*' | wc -l)
[[ "$temps" -eq 0 ]] || fail "$temps temporary files left behind"
echo "failing_writer: PASS (no profile.png, no temporary file, other outputs written)"
