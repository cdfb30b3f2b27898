#!/usr/bin/env bash
# Time-of-day sweep (issue 9): one view of the default world shaded from light-field probes from dawn to
# night, as a PNG sequence + an index page. Usage: scripts/tod_sweep.sh [OUT_DIR] [HOURS...]
# Needs the demo world (scripts/demo.sh builds it in out/demo/world). About 30 s per frame on 2 cores.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
source "$root/scripts/env.sh"
out="${1:-$root/out/tod}"
shift || true
hours=("$@")
[[ ${#hours[@]} -gt 0 ]] || hours=(5.5 6.5 8 10 12 14 16 17.5 18.5 19.5 21 23)
world="$root/out/demo/world"
[[ -f "$world/world.json" ]] || { echo "tod_sweep: no world at $world: run scripts/demo.sh first" >&2; exit 1; }
mkdir -p "$out"
index="$out/index.md"
echo "# Time-of-day sweep: city cell 1,1 shaded from probes (capture), $(date -u +%F)" > "$index.tmp"
echo >> "$index.tmp"
for h in "${hours[@]}"; do
  name=$(printf "city_%05.2f" "$h")
  "$root/build/bin/lfgi" render --world "$world" --cell 1,1 --camera 60,30,60,100,4,100 --fov 60 --time "$h" \
    --size 240x135 --spp 16 --out "$out/$name.exr" > "$out/$name.log" 2>&1
  echo "tod_sweep: $h h -> $out/$name.png"
  echo "**$h h** ![]($name.png)" >> "$index.tmp"
  echo >> "$index.tmp"
done
mv "$index.tmp" "$index"
echo "tod_sweep: $index"
