#!/usr/bin/env bash
# The GPU check of bench/vir, run on a lent device machine (docs/device.md) from the bundle that
# scripts/device_bundle.sh made here: scripts/device_bench.sh [--smoke | STEP...] (default: all three)
#   1. lfgi_bench_ceilings --quick   the device's 64-bit atomicMin ceiling (bench/vir's atomics are read
#                                    against it)
#   2. lfgi_bench_vir --quick        probe counts <= 1024, every method (3 repeats)
#   3. lfgi_bench_vir (full)         probe counts up to 4096, vir_lod / vir_lod_relight / cubemap
# Each step has its own time limit and writes results.csv + summary.json under $OUT/{ceilings,quick,full};
# the whole log goes to $OUT/device_bench.log. A step that fails or runs out of time is reported and the
# next one still runs; the exit status is the number of failed steps. --smoke: step 2 only, one repeat
# (a local check of the bundle on lavapipe). Charts are drawn afterwards on the development machine:
#   gnuplot -e "dir='DIR'; device='NAME'" bench/vir.gp
set -uo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
smoke=0
steps=(ceilings quick full)
if [[ "${1:-}" == "--smoke" ]]; then
  smoke=1
elif [[ $# -gt 0 ]]; then
  steps=("$@")
fi
bundle="${LFGI_DEVICE_BUNDLE:-$root/.device/lfgi-device.tgz}"
out="${OUT:-$root/out/device}"
[[ -f "$bundle" ]] || { echo "device_bench: $bundle missing: run scripts/device_bundle.sh first" >&2; exit 1; }
mkdir -p "$out"
exec > >(tee "$out/device_bench.log") 2>&1

d="$(mktemp -d)"
trap 'rm -rf "$d"' EXIT
tar -C "$d" -xzf "$bundle" || { echo "device_bench: cannot unpack $bundle" >&2; exit 1; }
export LFGI_SHADER_DIR="$d/shaders" LFGI_COMMIT="$(cat "$d/COMMIT")"
# The machine's GPU driver: its ICD manifest, unless the caller chose one.
if [[ -z "${VK_DRIVER_FILES:-}${VK_ICD_FILENAMES:-}" ]]; then
  for f in /usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json /usr/share/vulkan/icd.d/nvidia_icd.json \
           /etc/vulkan/icd.d/nvidia_icd.json; do
    if [[ -f "$f" ]]; then export VK_DRIVER_FILES="$f"; break; fi
  done
fi
echo "device_bench: commit $LFGI_COMMIT, driver manifest ${VK_DRIVER_FILES:-${VK_ICD_FILENAMES:-(loader default)}}"
command -v nvidia-smi >/dev/null && nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv
# Through the bundled loader and libraries; the driver's own directories last.
libpath="$d/lib:/usr/local/nvidia/lib64:/usr/local/nvidia/lib:/usr/lib64"
run() { "$d/lib/ld-linux-x86-64.so.2" --library-path "$libpath" "$d/bin/$1" "${@:2}"; }

failed=0
step() {  # step NAME LIMIT_S BINARY ARGS...
  local name="$1" limit="$2"
  shift 2
  echo "== device_bench: $name ($*), limit ${limit} s, $(date -u +%H:%M:%S) UTC"
  local t0=$SECONDS
  timeout --signal=INT --kill-after=10 "$limit" bash -c "$(declare -f run); d='$d' libpath='$libpath' run \"\$@\"" \
    _ "$@" --out "$out/$name"
  local rc=$?
  echo "== device_bench: $name rc $rc after $((SECONDS - t0)) s"
  [[ $rc -eq 0 ]] || failed=$((failed + 1))
}
if [[ $smoke -eq 1 ]]; then
  step quick 600 lfgi_bench_vir --quick --methods vir_lod,cubemap --repeat 1
else
  for s in "${steps[@]}"; do
    case "$s" in
      ceilings) step ceilings 60 lfgi_bench_ceilings --quick ;;
      quick) step quick 150 lfgi_bench_vir --quick --repeat 3 ;;
      full) step full 300 lfgi_bench_vir --methods vir_lod,vir_lod_relight,cubemap --repeat 2 --budget-s 20 ;;
      *) echo "device_bench: unknown step '$s' (ceilings, quick, full)"; failed=$((failed + 1)) ;;
    esac
  done
fi
for f in "$out"/*/summary.json; do [[ -f "$f" ]] && { echo "-- $f"; cat "$f"; echo; }; done
exit $failed
