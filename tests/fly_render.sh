#!/usr/bin/env bash
# `lfgi fly --render` (app/fly_render.h) over the baked tiny world:
#   1. a scripted flight (inline loads: deterministic) renders the expected number of PNG frames, a strip and
#      render_frames.csv, with every surface pixel lit (pixels_missing_gi 0) and GPU times in summary.json;
#   2. the same flight again gives the same frames, bit for bit (frames_hash);
#   3. one frame is compared with a path-traced reference of the same view: a finite relative RMS, the
#      reference and error PNGs;
#   4. --render without a baked world and a bad size are errors that say why.
# Usage: fly_render.sh LFGI BAKED_WORLD_DIR TMP_DIR
set -euo pipefail
lfgi="$1"
world="$2"
tmp="$3"
rm -rf "$tmp"
mkdir -p "$tmp"
die() {
  echo "fly_render: FAIL: $*" >&2
  exit 1
}
value() { grep -o "\"$2\": [^,]*" "$1/summary.json" | head -1 | sed 's/^[^:]*: //; s/"//g'; }

args=(fly --world "$world" --seconds 2 --fps 30 --speed 20 --io-threads 0 --render 96x54 --render-every 10
  --render-reference 1 --render-reference-spp 4)
for run in a b; do
  "$lfgi" "${args[@]}" --out "$tmp/$run" >"$tmp/$run.log" 2>&1 || { cat "$tmp/$run.log"; die "run $run failed"; }
done
grep -E "^render: 6 frames 96x54 on .*, 0 pixels missing GI" "$tmp/a.log" >/dev/null ||
  { cat "$tmp/a.log"; die "the render line does not say 6 frames with 0 pixels missing GI"; }
frames=$(find "$tmp/a/frames" -name 'frame_?????.png' | wc -l)
[[ "$frames" -eq 6 ]] || die "$frames PNG frames, expected 6 (60 flight frames, every 10th)"
[[ -s "$tmp/a/strip.png" ]] || die "no strip.png"
[[ $(wc -l <"$tmp/a/render_frames.csv") -eq 7 ]] || die "render_frames.csv does not hold 6 frames"
[[ "$(value "$tmp/a" pixels_missing_gi)" == "0" ]] || die "pixels missing GI: $(value "$tmp/a" pixels_missing_gi)"
surface=$(value "$tmp/a" surface_pixels)
[[ "$surface" -gt 0 ]] || die "no surface pixel rendered"
shade=$(value "$tmp/a" gpu_shade_ms_p50)
awk -v s="$shade" 'BEGIN { exit !(s > 0) }' || die "gpu_shade_ms_p50 = $shade"
ha=$(value "$tmp/a" frames_hash)
hb=$(value "$tmp/b" frames_hash)
[[ -n "$ha" && "$ha" == "$hb" ]] || die "the same flight rendered different frames: $ha vs $hb"
line=$(grep -E "^render: frame 3 \(flight frame 30\) vs a 4 spp path-traced reference: relative RMS total [0-9.]+, indirect [0-9.]+$" "$tmp/a.log") ||
  { cat "$tmp/a.log"; die "no reference comparison of frame 3 (the middle one)"; }
[[ -s "$tmp/a/frames/frame_00003_reference.png" && -s "$tmp/a/frames/frame_00003_error.png" ]] ||
  die "no reference / error PNG of frame 3"
echo "fly_render: $line"
echo "fly_render: 6 frames, $surface surface pixels, 0 missing GI, GPU shade p50 $shade ms, frames_hash $ha twice"

out=$("$lfgi" fly --seconds 1 --render 96x54 --out "$tmp/synthetic" 2>&1) && die "--render without a baked world succeeded"
echo "$out" | grep -q "needs a baked --world" || die "no reason for the refused --render: $out"
out=$("$lfgi" fly --world "$world" --seconds 1 --render 96 --out "$tmp/bad" 2>&1) && die "--render 96 succeeded"
echo "$out" | grep -q "expected WIDTHxHEIGHT" || die "no reason for a bad --render size: $out"
echo "fly_render: PASS"
