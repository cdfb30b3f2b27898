#!/usr/bin/env bash
# The one benchmark entry point: scripts/bench.sh NAME [--quick] [extra args]
# Builds if needed, runs build/bin/lfgi_bench_NAME, writes out/bench/NAME/{results.csv,summary.json}
# and draws bench/NAME.gp into out/bench/NAME/*.png with gnuplot.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
source "$root/scripts/env.sh"
if [[ $# -lt 1 ]]; then
  echo "usage: scripts/bench.sh NAME [--quick]   (NAME: $(ls bench/*.gp 2>/dev/null | xargs -n1 basename | sed 's/\.gp$//' | tr '\n' ' '))" >&2
  exit 2
fi
name="$1"
shift
"$root/scripts/setup.sh" >/dev/null
out="$root/out/bench/$name"
mkdir -p "$out"
export LFGI_COMMIT="$(git -C "$root" rev-parse --short HEAD 2>/dev/null || echo unknown)"
if [[ -f "$root/bench/$name.sh" ]]; then
  # A benchmark of the lfgi command line itself (bench/bake.sh: bakes, Slurm-free determinism, cost model).
  "$root/scripts/build.sh" "$root/build" lfgi lfgi_shaders >/dev/null
  bash "$root/bench/$name.sh" "$out" "$root/build/bin/lfgi" "$@"
else
  "$root/scripts/build.sh" "$root/build" "lfgi_bench_$name" lfgi_shaders >/dev/null
  "$root/build/bin/lfgi_bench_$name" --out "$out" "$@"
fi
if [[ -f "$root/bench/$name.gp" ]]; then
  device=$(sed -n 's/.*"device": "\(.*\)",*/\1/p' "$out/summary.json" | head -1)
  gnuplot -e "dir='$out'; device='$device'" "$root/bench/$name.gp"
fi
echo "bench: $out/summary.json"
cat "$out/summary.json"
