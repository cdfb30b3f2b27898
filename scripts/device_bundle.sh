#!/usr/bin/env bash
# Packs the GPU benchmarks for a lent device machine (docs/device.md): scripts/device_bundle.sh [BUILD_DIR]
# writes .device/lfgi-device.tgz (~34 MB, under the device tool's 64 MiB working-tree limit): the stripped
# lfgi_bench_vir and lfgi_bench_ceilings, the compiled shaders, and every shared library they load,
# glibc and its dynamic loader included, so that they run on a bare machine whatever its distribution
# (scripts/device_bench.sh starts them through the bundled loader). The GPU driver is the machine's own.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${1:-$root/build}"
bins=(lfgi_bench_vir lfgi_bench_ceilings)
for b in "${bins[@]}"; do
  [[ -x "$build/bin/$b" ]] || { echo "device_bundle: $build/bin/$b missing: build it first (scripts/build.sh)" >&2; exit 1; }
done
out="$root/.device"
stage="$(mktemp -d)"
trap 'rm -rf "$stage"' EXIT
mkdir -p "$stage/bin" "$stage/lib" "$stage/shaders" "$out"
for b in "${bins[@]}"; do
  cp "$build/bin/$b" "$stage/bin/"
  strip "$stage/bin/$b"
done
cp "$build"/shaders/*.spv "$stage/shaders/"
# Every library the binaries load, plus what a GPU driver may load beside them: glibc's stub libraries (a
# host copy of another glibc version would not link against the bundled libc) and glvnd's libGLdispatch.
{
  for b in "${bins[@]}"; do ldd "$build/bin/$b" | awk '/=>/ {print $3} /ld-linux/ {print $1}'; done
  for l in libdl.so.2 libpthread.so.0 librt.so.1 libresolv.so.2 libGLdispatch.so.0; do
    ldconfig -p | awk -v l="$l" '$1 == l && /x86-64/ {print $NF; exit}'
  done
} | sort -u | while read -r lib; do
  [[ -n "$lib" && -e "$lib" ]] && cp -L "$lib" "$stage/lib/$(basename "$lib")"
done
git -C "$root" rev-parse --short HEAD >"$stage/COMMIT" 2>/dev/null || echo unknown >"$stage/COMMIT"
tar -C "$stage" -czf "$out/lfgi-device.tgz.tmp" .
mv "$out/lfgi-device.tgz.tmp" "$out/lfgi-device.tgz"
echo "device_bundle: $out/lfgi-device.tgz ($(du -h "$out/lfgi-device.tgz" | cut -f1), commit $(cat "$stage/COMMIT"))"
