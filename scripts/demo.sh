#!/usr/bin/env bash
# One command from a fresh machine to a result: installs what is missing, builds, runs the main job and
# writes its report and pictures under out/demo/ (read out/demo/report.md first).
#   1. lfgi demo     sky probe on the GPU vs CPU/SH, the 256 m default world built, top-down preview
#   2. lfgi vir      one park cell relit (sun shadow map + probe bounces) and splatted into its probes
#   3. lfgi bake     the same cell captured, its smallest model chosen, int8, written as a cell file
#   4. lfgi render   a city view shaded from probes, compared with the path-traced reference
#   5. lfgi profile  the streaming manager flying over the 4 km world layout (Perfetto trace, charts)
# About 3 minutes after the build on 2 cores. Every step is resumable or cheap to rerun.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
source "$root/scripts/env.sh"
"$root/scripts/setup.sh"
"$root/scripts/build.sh" "$root/build"
lfgi="$root/build/bin/lfgi"
out="$root/out/demo"
"$lfgi" device
"$lfgi" demo --out "$out" "$@"
world="$out/world"
report="$out/report.md"

"$lfgi" vir --world "$world" --cell 3,1 --time 15.5 --resolution 16 --bounces 2 --out "$out/vir" | tee "$out/vir.txt"
"$lfgi" bake --world "$world" --cells 3,1 --resolution 8 --spp 8 --bounces 3 --max-steps 300 --out "$out/baked" \
  2> >(grep -v '^bake \[' >&2) | tee "$out/bake.txt"
"$lfgi" inspect "$out/baked/cells/cell_3_1.vdb" | tee "$out/cell_3_1_inspect.txt"
"$lfgi" render --world "$world" --cell 1,1 --camera 60,30,60,100,4,100 --fov 60 --time 15.5 --size 240x135 \
  --spp 16 --reference-spp 16 --compare --out "$out/render/city.exr" | tee "$out/render.txt"
"$lfgi" profile --seconds 20 --speed 50 --out "$out/profile" | tee "$out/profile.txt"

{
  echo
  echo "## VIR: relight + splat of park cell 3,1 (lfgi vir)"
  echo
  echo '```'; cat "$out/vir.txt"; echo '```'
  echo
  echo "![VIR contact sheet: one octahedral radiance map per probe](vir/contact_sheet.png)"
  echo
  echo "Atlases (EXR): vir/radiance.exr, distance.exr, normal.exr, albedo.exr, irradiance.exr."
  echo
  echo "## Codec: cell 3,1 baked into a cell file (lfgi bake, lfgi inspect)"
  echo
  echo '```'; cat "$out/bake.txt" "$out/cell_3_1_inspect.txt"; echo '```'
  echo
  echo "## Shading from probes vs path tracing (lfgi render --compare)"
  echo
  echo '```'; cat "$out/render.txt"; echo '```'
  echo
  echo "| probes | path-traced reference | error |"
  echo "|---|---|---|"
  echo "| ![](render/city.png) | ![](render/city_reference.png) | ![](render/city_error.png) |"
  echo "| ![](render/city_indirect.png) | ![](render/city_reference_indirect.png) | indirect only |"
  echo
  echo "## Streaming profile (lfgi profile): 20 s at 50 m/s over the 4 km world layout"
  echo
  echo '```'; cat "$out/profile.txt"; echo '```'
  echo
  echo "![memory, time and fallback per frame](profile/profile.png)"
  echo
  echo "Open profile/trace.json in https://ui.perfetto.dev; profile/summary.html is the one-page summary."
} >> "$report"
# Failure modes (bench/stability): streaming pops/seams/burst, one leak configuration, generator
# fallback; ~1 min. The whole suite: scripts/bench.sh stability [--quick].
"$root/build/bin/lfgi_bench_stability" --quick --sections streaming,leak,fallback --leak-walls 0.1 --leak-spacings 1 \
  --out "$out/stability" > "$out/stability.txt" 2>&1
{
  echo
  echo "## Failure modes (lfgi_bench_stability --quick, a subset; the suite: scripts/bench.sh stability)"
  echo
  echo "0.1 m wall between a sunlit and a sealed room, 1 m probes; streaming on synthetic cells; a generator that"
  echo "misses its target (20 steps), collapses (learning rate 1e3) or diverges (1e6). Columns: section, method, wall_m, spacing_m,"
  echo "probe_setup, chebyshev, time_h, overcast, metric, value."
  echo
  echo '```'
  grep -E '^(leak|streaming|fallback),' "$out/stability/results.csv" |
    grep -E 'leak_ratio|pop_|seam_|frames_to_recovery|budget_held|missing|chosen|reached|diverged' || true
  echo '```'
} >> "$report"
echo "demo: report at out/demo/report.md"
