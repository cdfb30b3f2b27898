#!/usr/bin/env bash
# Time-of-day sweep: one view of the default world shaded from light-field probes from dawn to
# night, as a PNG sequence + an index page + (when ImageMagick's `convert` is installed) an animated GIF
# (gifsicle and ffmpeg are not installed here; no new package is added for a GIF).
# Usage: scripts/tod_sweep.sh [OUT_DIR] [HOURS...]
# Environment: EXPOSURE=EV fixes the exposure of every frame; default: the exposure `lfgi render` picks
# automatically for the noon frame (rendered first), then used for all frames, so night is dark and dawn
# brightens (EXPOSURE=auto: every frame auto-exposed, as before). PROBES=capture|vir|codec (default capture).
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
lfgi="${LFGI:-$root/build/bin/lfgi}"
probes="${PROBES:-capture}"
[[ -f "$world/world.json" ]] || { echo "tod_sweep: no world at $world: run scripts/demo.sh first" >&2; exit 1; }
mkdir -p "$out"
render() {  # hour name [extra args...]
  local h="$1" name="$2"
  shift 2
  "$lfgi" render --world "$world" --cell 1,1 --camera 60,30,60,100,4,100 --fov 60 --time "$h" --probes "$probes" \
    --size 240x135 --spp 16 --out "$out/$name.exr" "$@" > "$out/$name.log" 2>&1
}
exposure="${EXPOSURE:-}"
if [[ -z "$exposure" ]]; then
  render 12 noon_auto
  exposure=$(sed -n 's/.*PNG exposure \([-0-9.]*\) EV.*/\1/p' "$out/noon_auto.log" | tail -1)
  [[ -n "$exposure" ]] || { echo "tod_sweep: no exposure in $out/noon_auto.log" >&2; exit 1; }
fi
exposure_args=()
[[ "$exposure" == auto ]] || exposure_args=(--exposure "$exposure")
index="$out/index.md"
echo "# Time-of-day sweep: city cell 1,1 shaded from $probes probes, exposure $exposure EV, $(date -u +%F)" > "$index.tmp"
echo >> "$index.tmp"
frames=()
for h in "${hours[@]}"; do
  name=$(printf "city_%05.2f" "$h")
  render "$h" "$name" "${exposure_args[@]}"
  frames+=("$out/$name.png")
  echo "tod_sweep: $h h -> $out/$name.png"
  echo "**$h h** ![]($name.png)" >> "$index.tmp"
  echo >> "$index.tmp"
done
# Only a real ImageMagick (this machine's /usr/local/bin/convert is a stand-in that cannot write GIFs).
if command -v convert > /dev/null 2>&1 && convert -version 2>/dev/null | grep -q ImageMagick; then
  if convert -delay 50 -loop 0 "${frames[@]}" "$out/sweep.tmp.gif"; then
    mv "$out/sweep.tmp.gif" "$out/sweep.gif"
    echo "![sweep](sweep.gif)" >> "$index.tmp"
    echo "tod_sweep: $out/sweep.gif"
  fi
else
  echo "tod_sweep: no ImageMagick convert: PNG sequence only"
fi
mv "$index.tmp" "$index"
echo "tod_sweep: $index"
