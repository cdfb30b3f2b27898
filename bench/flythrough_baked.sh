#!/usr/bin/env bash
# bench flythrough_baked (run by scripts/bench.sh flythrough_baked [--quick] [--world DIR]): the streaming
# fly-through over BAKED cell files: the 4096 m x 4096 m synthetic world (seed 1, 64 x 64 cells
# of 64 m) baked only where the flight goes — `lfgi bake --path line --path-radius 128` (the cells within
# 128 m of the west -> east line, 276 cells; the whole world, 4096 cells, is ~15x that and too slow for a
# 2-core machine) — then lfgi_bench_flythrough --world at 2 / 10 / 25 / 50 / 100 m/s with a 6 -> 20 h sweep,
# 2 IO threads reading + decoding cells, frames paced to real time (results.csv, frames.csv, summary.json).
# Bake settings (fast, coarse: the benchmark measures streaming, bench codec measures the codec):
# resolution 8, 4 spp, 2 bounces, keys 8,12,17.5, one generator candidate z4 C32 with 200 steps, error
# target 25 % (cells that miss it keep the lower-error of SH L1 and z4 C32). The bake resumes: a second
# run with the same world reuses every cell file (the input hash is unchanged).
# --quick: a 1024 m world (16 x 16 cells), 15 s flights. --world DIR: use (and bake into) DIR.
# Usage: bench/flythrough_baked.sh OUT_DIR LFGI_BINARY [--quick] [--world DIR]
set -euo pipefail
out="$1"
lfgi="$2"
shift 2
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
quick=false
world=""
while [[ $# -gt 0 ]]; do
  case "$1" in
    --quick) quick=true ;;
    --world) world="$2"; shift ;;
    *) echo "flythrough_baked: unknown argument $1" >&2; exit 2 ;;
  esac
  shift
done
size=4096
if $quick; then size=1024; fi
if [[ -z "$world" ]]; then world="$root/out/worlds/path_${size}m"; fi
bake_flags=(--path line --path-radius 128 --resolution 8 --spp 4 --bounces 2 --keys 8,12,17.5 --max-steps 200
            --threads 2 --error-target 0.25 --model-widths 32 --model-latents 4)
if [[ ! -f "$world/world.json" ]]; then
  "$lfgi" world generate --size "$size" --cell 64 --seed 1 --out "$world" >/dev/null
fi
echo "bench flythrough_baked: 1/2 bake the path cells of $world (resumable)" >&2
t0=$(date +%s)
"$lfgi" bake --world "$world" "${bake_flags[@]}" >"$out/bake.txt" 2>"$out/bake.log" ||
  { tail -5 "$out/bake.log" >&2; exit 1; }
bake_s=$(( $(date +%s) - t0 ))
"$lfgi" bake-status --world "$world" "${bake_flags[@]}" -q >"$out/bake_status.txt" 2>&1 || true
"$root/scripts/build.sh" "$root/build" lfgi_bench_flythrough >/dev/null
echo "bench flythrough_baked: 2/2 fly" >&2
extra=()
if $quick; then extra+=(--quick); fi
"$root/build/bin/lfgi_bench_flythrough" --out "$out" --world "$world" "${extra[@]}"
# The bake's own numbers beside the flight's (this run's bake wall time: 0 when every cell was reused).
# The bake packs its cells into region files: "pack: ... N bytes (...) ...: ..., container C B/cell -> DIR".
region_bytes=$(sed -n 's/^pack: .*), \([0-9]*\) bytes (.*/\1/p' "$out/bake.txt")
container=$(sed -n 's/^pack: .*container \([0-9.]*\) B\/cell.*/\1/p' "$out/bake.txt")
python3 - "$out/summary.json" "$world" "$bake_s" "${bake_flags[*]}" "${region_bytes:-0}" "${container:-0}" <<'PY'
import json, sys, glob, os
path, world, bake_s, flags = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]
region_bytes, container = int(sys.argv[5]), float(sys.argv[6])
s = json.load(open(path))
recs = [json.load(open(f)) for f in glob.glob(os.path.join(world, "baked", "cells", "*.json"))]
s["bake"] = {"flags": flags, "cells": len(recs), "this_run_wall_s": bake_s,
             "cell_seconds_total": round(sum(r["seconds"]["total"] for r in recs), 1),
             "cells_with_network": sum(1 for r in recs if r.get("network")),
             "bytes_total": sum(r["bytes"] for r in recs)}
cell_km2 = 0.064 * 0.064
if recs:
    area = len(recs) * cell_km2
    s["cell_file_bytes_per_km2"] = s["bake"]["bytes_total"] / area
    if region_bytes:
        s["bytes_per_km2"] = region_bytes / area
        s["bytes_per_km2_note"] = "region files + regions.json (all-in: light field, probe masks, container) over the baked cells' area"
        s["container_bytes_per_cell"] = container
    else:
        s["bytes_per_km2"] = s["cell_file_bytes_per_km2"]
        s["bytes_per_km2_note"] = "cell files (the bake did not pack regions) over the baked cells' area"
    s["bake_s_per_km2"] = s["bake"]["cell_seconds_total"] / area
tmp = path + ".tmp"
json.dump(s, open(tmp, "w"), indent=2)
os.replace(tmp, path)
PY
