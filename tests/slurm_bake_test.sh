#!/usr/bin/env bash
# ctest slurm.bake_default_world (label slurm): a real single-node Slurm cluster
# (scripts/slurm/local-cluster.sh) bakes the small default world as a 4-task job array
# (scripts/slurm/bake.sbatch) at tiny settings; all 16 cell files must be byte-identical to a
# single-process bake of the same world. The cluster is stopped on every exit path (trap).
# Usage: tests/slurm_bake_test.sh LFGI_BINARY WORK_DIR        Exit 77 (ctest SKIP) when not root.
set -euo pipefail
lfgi="$(realpath "$1")"
work="$2"
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
if [[ $(id -u) -ne 0 ]]; then
  echo "SKIP: slurm.bake_default_world needs root: local-cluster.sh runs munged, slurmctld and slurmd as root"
  exit 77
fi
# Own directory and ports, so a cluster someone brought up by hand is left alone.
export LFGI_SLURM_DIR="$(mktemp -d /tmp/lfgi-slurm-test.XXXXXX)"
export LFGI_SLURM_PORT=16827
cluster="$root/scripts/slurm/local-cluster.sh"
trap 'bash "$cluster" down' EXIT
trap 'exit 143' TERM INT  # ctest's timeout: still run the EXIT trap
rm -rf "$work"
mkdir -p "$work/logs"
bash "$cluster" up
export SLURM_CONF="$LFGI_SLURM_DIR/slurm.conf"

"$lfgi" world generate --size 256 --cell 64 --seed 1 --out "$work/world" >/dev/null
# Tiny capture settings; --error-target 1 accepts the first model tried (SH L1), so no generator is
# trained: the bake is capture-bound and the whole world fits the test's time (with the default target,
# training is ~90 % of a tiny bake, ~20 s per cell here; its bit-exactness per seed is tested in
# lfgi_bake_tests). --reproducible keeps timings out of the files (they stay in cells/cell_X_Z.json).
settings=(--resolution 8 --spp 2 --bounces 1 --max-steps 40 --keys 12 --error-target 1)
flags=("${settings[@]}" --reproducible)
tasks=4

start=$(date +%s%N)
"$lfgi" bake --world "$work/world" --out "$work/single" "${flags[@]}" 2>"$work/logs/single.log"
single_ms=$(( ($(date +%s%N) - start) / 1000000 ))

start=$(date +%s%N)
set +e
LFGI_BIN="$lfgi" sbatch --wait --quiet --array=0-$((tasks - 1)) --chdir="$work" --output="$work/logs/bake_%A_%a.log" \
  "$root/scripts/slurm/bake.sbatch" --world "$work/world" --out "$work/slurm" "${flags[@]}"
rc=$?
set -e
slurm_ms=$(( ($(date +%s%N) - start) / 1000000 ))
if [[ $rc -ne 0 ]]; then
  echo "FAIL: sbatch --wait exited $rc; task logs:"
  tail -n 20 "$work"/logs/bake_*.log
  exit 1
fi

logs=$(ls "$work"/logs/bake_*.log | wc -l)
[[ $logs -eq $tasks ]] || { echo "FAIL: expected $tasks per-task logs, found $logs"; exit 1; }
for i in $(seq 0 $((tasks - 1))); do
  grep -q "task $i of $tasks" "$work"/logs/bake_*_"$i".log || { echo "FAIL: no log line of task $i"; exit 1; }
done
n=0
for f in "$work"/single/cells/*.vdb; do
  other="$work/slurm/cells/$(basename "$f")"
  [[ -f "$other" ]] || { echo "FAIL: the Slurm bake has no $(basename "$f")"; exit 1; }
  cmp -s "$f" "$other" || { echo "FAIL: $(basename "$f") differs between the single-process and the Slurm bake"; exit 1; }
  [[ -f "${other%.vdb}.json" ]] || { echo "FAIL: no bake record beside $other"; exit 1; }
  n=$((n + 1))
done
[[ $n -eq 16 ]] || { echo "FAIL: expected 16 cell files, found $n"; exit 1; }
"$lfgi" bake-status --world "$work/world" --out "$work/slurm" "${settings[@]}" --quiet | tee "$work/logs/status.log"
grep -q "cells: 16  done 16 " "$work/logs/status.log" || { echo "FAIL: bake-status does not report 16 done"; exit 1; }
hash_single=$(cat "$work"/single/cells/*.vdb | sha256sum | cut -c1-16)
hash_slurm=$(cat "$work"/slurm/cells/*.vdb | sha256sum | cut -c1-16)
echo "slurm.bake_default_world: 16 cells byte-identical (sha256 of all cell files $hash_single = $hash_slurm);" \
  "single process ${single_ms} ms, Slurm array of $tasks tasks ${slurm_ms} ms (wall)"
