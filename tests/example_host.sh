#!/usr/bin/env bash
# The example host (examples/host) built from the installed package and run on a baked world, against
# `lfgi render` of the same view (docs/embedding.md):
#   1. cmake --install BUILD into a temporary prefix; configure and build examples/host against it only;
#   2. a 2 x 2-cell world (32 m cells) generated and baked with the shipped codec at small settings;
#   3. the host flies 300 frames, settles at the view and writes its shaded indirect diffuse (every surface
#      pixel lit, else it exits 1);
#   4. `lfgi render --probes codec` of the same view; the host's image matches its indirect_diffuse layer
#      within MAX_REL_RMS (the same probes, visibility from the same VIR step, the same shading pass).
# usage: example_host.sh LFGI_BIN BUILD_DIR SOURCE_DIR WORK_DIR
set -euo pipefail
lfgi=$1 build=$2 src=$3 work=$4
max_rel_rms=0.02
rm -rf "$work"
mkdir -p "$work"
cmake --install "$build" --prefix "$work/prefix" > "$work/install.log"
cmake -S "$src/examples/host" -B "$work/host-build" -G Ninja -DCMAKE_PREFIX_PATH="$work/prefix" \
  -DCMAKE_BUILD_TYPE=Release > "$work/host-configure.log"
cmake --build "$work/host-build" > "$work/host-build.log"
world=$work/world
"$lfgi" world generate --size 64 --cell 32 --seed 3 --out "$world" --all --threads 2 > "$work/world.log" 2>&1
"$lfgi" bake --world "$world" --resolution 8 --spp 2 --bounces 1 --threads 2 > "$work/bake.log" 2>&1
view=(--camera 20,25,-5,40,0,20 --size 48x32 --time 12)
# --resolution 8: the maps the streamed decode gives SH cells (CellFileSourceOptions::shOnlyResolution)
LFGI_LOG_LEVEL=warn "$work/host-build/lfgi_example_host" "$world" "$work/host" --frames 300 "${view[@]}"
"$lfgi" render --world "$world" --cell 1,0 "${view[@]}" --fov 60 --resolution 8 --probes codec --out "$work/render.exr" \
  > "$work/render.log" 2>&1
"$build/bin/lfgi_image_compare" "$work/render.exr" indirect_diffuse "$work/host.pfm" "$max_rel_rms"
