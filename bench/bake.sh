#!/usr/bin/env bash
# bench bake (run by scripts/bench.sh bake [--quick]): the world bake's cost on this machine and the
# cost model projected to 16, 100 and 400 km^2 (BENCHMARKS.md `bake`).
#   1. single-process `lfgi bake --reproducible` of the small default world (256 m, 16 cells of 64 m),
#      timed; its cells/cell_X_Z.json records feed the cost model (`bake_s_per_km2` = this wall time / km2);
#      the bake packs its cells into region files (`bytes_per_km2` all-in, `container_bytes_per_cell`);
#   2. determinism: cells 0-3 (row z = 0) baked again as 2 array shares in 2 processes: every file must
#      be byte-identical to bake 1's (`deterministic`);
#   3. rebake: a capture-only bake (--error-target 1: SH L1, no training; the count does not depend on the
#      model) of the world, one building added in cell 1,2 (`lfgi world edit`), baked again: the cells
#      baked again (`rebake_cells_touched_after_one_cell_edit`; 9 expected for an interior cell);
#   4. `lfgi bake-status --plan --nodes 32` on bake 1's records: measured seconds per cell by kind x the
#      kind mix of larger worlds -> projected hours on 1 and 32 nodes (plan.csv = results.csv, plan.json).
# --quick bakes at tiny settings (resolution 8, 2 spp, 1 bounce, 40 training steps, one lighting key):
# cheap, so the projection is far below a production bake; without it, lfgi bake's defaults (hours).
# Usage: bench/bake.sh OUT_DIR LFGI_BINARY [--quick]
set -euo pipefail
out="$1"
lfgi="$2"
shift 2
quick=false
for a in "$@"; do [[ "$a" == --quick ]] && quick=true; done
if $quick; then
  flags=(--resolution 8 --spp 2 --bounces 1 --max-steps 40 --keys 12)
  settings="tiny: --resolution 8 --spp 2 --bounces 1 --max-steps 40 --keys 12"
else
  flags=()
  settings="lfgi bake defaults (--resolution 16 --spp 16 --bounces 4 --max-steps 1500 --keys 8,12,17.5)"
fi
work="$out/work"
rm -rf "$work"
mkdir -p "$work"
"$lfgi" world generate --size 256 --cell 64 --seed 1 --out "$work/world" >/dev/null

ms() { echo $(( $(date +%s%N) / 1000000 )); }  # bash 64-bit arithmetic (mawk's %d caps at 2^31)
echo "bench bake: 1/4 single-process bake of the default world ($settings)" >&2
t0=$(ms)
"$lfgi" bake --world "$work/world" --out "$work/single" "${flags[@]}" --reproducible 2>"$work/single.log" |
  tee "$work/single.txt"
bake_ms=$(( $(ms) - t0 ))
# The bake packs its cells into region files: "pack: ... N bytes (...) ...: ..., container C B/cell -> DIR"
region_bytes=$(sed -n 's/^pack: .*), \([0-9]*\) bytes (.*/\1/p' "$work/single.txt")
container=$(sed -n 's/^pack: .*container \([0-9.]*\) B\/cell.*/\1/p' "$work/single.txt")
cell_file_bytes=$(cat "$work"/single/cells/*.vdb | wc -c)
[[ -n "$region_bytes" && -n "$container" ]] || { echo "bench bake: the bake did not pack its cells" >&2; exit 1; }
echo "bench bake: 2/4 cells 0-3 again in 2 processes" >&2
for i in 0 1; do
  "$lfgi" bake --world "$work/world" --out "$work/shares" --cells 0-3 --array-index $i --array-size 2 "${flags[@]}" \
    --reproducible 2>"$work/shares_$i.log"
done
deterministic=true
for f in "$work"/shares/cells/*.vdb; do
  cmp -s "$f" "$work/single/cells/$(basename "$f")" || { deterministic=false; echo "bench bake: $(basename "$f") differs" >&2; }
done
[[ $(ls "$work"/shares/cells/*.vdb | wc -l) -eq 4 ]] || deterministic=false

touched=null
if "$lfgi" world edit --help >/dev/null 2>&1; then
  echo "bench bake: 3/4 one-building edit, rebake" >&2
  capture_only=("${flags[@]}" --error-target 1)
  cp -r "$work/world" "$work/edited"
  "$lfgi" bake --world "$work/edited" --out "$work/edited_baked" "${capture_only[@]}" 2>"$work/edited_first.log" >/dev/null
  "$lfgi" world edit "$work/edited" --add-building 96,150,110,166,3 >"$work/edit.txt"
  "$lfgi" bake --world "$work/edited" --out "$work/edited_baked" "${capture_only[@]}" >"$work/rebake.txt" 2>"$work/rebake.log"
  # "done: 16 cells (7 already baked, ..." -> 16 - 7 cells baked again
  touched=$(sed -n 's/^done: \([0-9]*\) cells (\([0-9]*\) already baked.*/\1 \2/p' "$work/rebake.txt" | awk '{ print $1 - $2 }')
  [[ -n "$touched" ]] || touched=null
fi

echo "bench bake: 4/4 cost model" >&2
"$lfgi" bake-status --world "$work/world" --out "$work/single" "${flags[@]}" --plan --nodes 32 \
  --size-km2 16 --size-km2 100 --size-km2 400 --plan-out "$out" | tee "$work/plan.txt"
cp "$out/plan.csv" "$out/results.csv"
# hours for SIZE on NODES from plan.csv (size_km2,...,nodes,hours)
hours() { awk -F, -v s="$1" -v n="$2" 'NR > 1 && $1 == s && $10 == n { print $11 }' "$out/plan.csv"; }
km2=0.065536
cores=$(nproc)
commit="${LFGI_COMMIT:-$(git -C "$(dirname "$0")/.." rev-parse --short HEAD 2>/dev/null || echo unknown)}"
cat > "$out/summary.json.tmp" <<JSON
{
  "bake_s_per_km2": $(awk -v ms="$bake_ms" -v a="$km2" 'BEGIN { printf "%.1f", ms / 1000 / a }'),
  "bytes_per_km2": $(awk -v b="$region_bytes" -v a="$km2" 'BEGIN { printf "%.0f", b / a }'),
  "bytes_per_km2_note": "region files + regions.json (all-in: light field, probe masks, container) over the world's area",
  "cell_file_bytes_per_km2": $(awk -v b="$cell_file_bytes" -v a="$km2" 'BEGIN { printf "%.0f", b / a }'),
  "container_bytes_per_cell": $container,
  "rebake_cells_touched_after_one_cell_edit": $touched,
  "deterministic": $deterministic,
  "measured_on": "small default world (256 m, 16 cells of 64 m, seed 1), single process, $settings",
  "default_world_bake_s": $(awk -v ms="$bake_ms" 'BEGIN { printf "%.2f", ms / 1000 }'),
  "projected_hours_16km2_1_node": $(hours 16 1),
  "projected_hours_100km2_1_node": $(hours 100 1),
  "projected_hours_100km2_32_nodes": $(hours 100 32),
  "projected_hours_400km2_32_nodes": $(hours 400 32),
  "projection": "measured s/cell by cell kind x the kind mix of the larger world / nodes; nodes like this one, one cell at a time",
  "device": "CPU, $cores cores (the bake runs on Embree + libtorch, no Vulkan)",
  "commit": "$commit",
  "quick": $quick
}
JSON
mv "$out/summary.json.tmp" "$out/summary.json"
