#!/usr/bin/env bash
# Interruption test for `lfgi bake`: a bake stopped mid-cell by SIGINT (Ctrl-C) or
# SIGKILL and then rerun must end with cell files byte-identical to an uninterrupted bake (cell files hold
# no wall-clock time by default), and leave no temporary files behind.
#   SIGINT:  exit 130 and a "run the same command again to resume" message; the cell in flight is not
#            written (a half-trained model under the final input hash would be skipped by every rerun).
#            Its model search's training checkpoints stay (cells/cell_X_Z.train.candidateI) and the rerun
#            resumes from them, then removes them.
#   SIGKILL: nothing to clean up beyond what atomic writes guarantee.
# With stderr going to a file, the log has a line per cell before it bakes and the training's own lines.
# Usage: tests/interrupt_bake.sh LFGI_BINARY WORLD_DIR WORK_DIR   (WORLD_DIR: the cli_world fixture)
set -uo pipefail
lfgi="$1"
world="$2"
work="$3"
# Tiny bake settings on 3 of the 4 cells, with the generator codec (the default sh-l1 bakes a cell in a
# blink; training is the long work an interruption lands in) and more training steps (these cells miss the
# 5 % target, so every candidate model trains for all of them) so that a cell takes a few seconds and a
# signal sent 1 s after a cell starts lands inside it.
args=(bake --world "$world" --cells 0-2 --codec per-cell --resolution 8 --spp 2 --bounces 1 --max-steps 100
  --keys 12)
rm -rf "$work"
mkdir -p "$work"

die() {
  echo "interrupt_bake: FAIL: $*"
  for f in "$work"/*.log; do echo "--- $f"; tail -15 "$f"; done
  exit 1
}
cells() { find "$1/cells" -name '*.vdb' 2>/dev/null | wc -l; }

t0=$(date +%s.%N)
"$lfgi" "${args[@]}" --out "$work/reference" >"$work/reference.log" 2>&1 || die "uninterrupted bake failed"
total=$(cells "$work/reference")
per_cell=$(awk -v a="$t0" -v b="$(date +%s.%N)" -v n="$total" 'BEGIN { print (b - a) / n }')
printf 'interrupt_bake: uninterrupted bake: %d cells, %.1f s per cell\n' "$total" "$per_cell"
[[ "$total" -ge 2 ]] || die "expected at least 2 cells, got $total"

# Starts a bake into $1, waits until $3 cells are finished, lets the next cell run for $4 s, then sends
# signal $2. Sets rc (exit status) and done_before (cells finished when the signal was sent).
interrupt() {
  local dir="$1" sig="$2" after="$3" delay="$4" pid
  "$lfgi" "${args[@]}" --out "$dir" >"$dir.log" 2>&1 &
  pid=$!
  for _ in $(seq 1 1200); do
    [[ "$(cells "$dir")" -ge "$after" ]] && break
    kill -0 "$pid" 2>/dev/null || break
    sleep 0.1
  done
  sleep "$delay"
  kill -0 "$pid" 2>/dev/null || die "$sig: the bake ended before the signal (cells too fast to interrupt)"
  done_before=$(cells "$dir")
  kill "-$sig" "$pid"
  wait "$pid"
  rc=$?
}

# SIGINT in the middle of the second cell.
interrupt "$work/sigint" INT 1 1.0
[[ "$rc" -eq 130 ]] || die "SIGINT: exit $rc, expected 130"
grep -q "run the same command again to resume" "$work/sigint.log" || die "SIGINT: no resume message"
after_int=$(cells "$work/sigint")
[[ "$after_int" -eq "$done_before" ]] ||
  die "SIGINT: $after_int cell files after the interrupt, $done_before were finished before it (the cell in flight was written)"
echo "interrupt_bake: SIGINT after $done_before cells: exit 130, resume message, $after_int cell files"
grep -q "^cell [0-9]*,[0-9]* ([a-z]*): baking, $done_before of $total cells done" "$work/sigint.log" ||
  die "SIGINT: no line naming the cell in flight in the log"
grep -q "train generator" "$work/sigint.log" || die "SIGINT: no training progress in the log"
ckpts=$(find "$work/sigint/cells" -name '*.train.candidate*' | wc -l)
[[ "$ckpts" -ge 1 ]] || die "SIGINT: the interrupted cell left no training checkpoint"
"$lfgi" "${args[@]}" --out "$work/sigint" >>"$work/sigint.log" 2>&1 || die "SIGINT: the rerun failed"
grep -q "($after_int already baked" "$work/sigint.log" || die "SIGINT: the rerun did not skip the $after_int finished cells"
left=$(find "$work/sigint/cells" -name '*.train.candidate*' | wc -l)
[[ "$left" -eq 0 ]] || die "SIGINT: $left training checkpoints left after the rerun"
echo "interrupt_bake: SIGINT kept $ckpts training checkpoint(s); the rerun resumed and removed them"

# SIGKILL in the middle of the first cell, and again in the middle of a later one.
interrupt "$work/sigkill" KILL 0 1.0
[[ "$rc" -eq 137 ]] || die "SIGKILL: exit $rc, expected 137"
kill1=$(cells "$work/sigkill")
interrupt "$work/sigkill" KILL $((kill1 + 1)) 1.0
[[ "$rc" -eq 137 ]] || die "second SIGKILL: exit $rc, expected 137"
kill2=$(cells "$work/sigkill")
echo "interrupt_bake: SIGKILL after $kill1 and then $kill2 cells: exit 137"
"$lfgi" "${args[@]}" --out "$work/sigkill" >>"$work/sigkill.log" 2>&1 || die "SIGKILL: the rerun failed"

# Same cell files with the same bytes: the bake stores no wall-clock time in them (timings live in the
# cells/*.json records beside them, which are not compared).
for run in sigint sigkill; do
  expected=$(cd "$work/reference" && find . -name '*.vdb' | sort)
  actual=$(cd "$work/$run" && find . -name '*.vdb' | sort)
  [[ "$expected" == "$actual" ]] || die "$run: cell files differ from the uninterrupted bake: $expected vs $actual"
  identical=0
  for f in $expected; do
    cmp -s "$work/reference/$f" "$work/$run/$f" || die "$run: $f differs from the uninterrupted bake: $(cmp "$work/reference/$f" "$work/$run/$f" 2>&1 | head -1)"
    identical=$((identical + 1))
  done
  temps=$(find "$work/$run" -name '*.tmp.*' | wc -l)
  [[ "$temps" -eq 0 ]] || die "$run: $temps temporary files left behind: $(find "$work/$run" -name '*.tmp.*')"
  echo "interrupt_bake: $run: $(echo "$expected" | wc -w) cell files equal to the uninterrupted bake (all $identical byte-identical), no temporary files"
done
echo "interrupt_bake: PASS"
