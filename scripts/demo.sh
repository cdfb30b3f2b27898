#!/usr/bin/env bash
# One command from a fresh machine to a result: installs what is missing, builds, runs the main job and
# writes its report and pictures under out/ (see out/demo/report.md).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
source "$root/scripts/env.sh"
"$root/scripts/setup.sh"
"$root/scripts/build.sh" "$root/build"
"$root/build/bin/lfgi" device
"$root/build/bin/lfgi" demo --out "$root/out/demo" "$@"
echo "demo: report at out/demo/report.md"
