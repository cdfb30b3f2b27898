#!/usr/bin/env bash
# Installs the Debian packages in scripts/apt-packages.txt that are not installed yet (non-interactive).
# Does nothing, and needs no root, when everything is already present.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
# The commit-msg hook (subject <= 72 characters; CONTRIBUTING.md), when this is a git checkout.
if hooks=$(git -C "$here/.." rev-parse --git-path hooks 2>/dev/null); then
  [[ "$hooks" = /* ]] || hooks="$here/../$hooks"
  if [[ ! -e "$hooks/commit-msg" ]]; then
    mkdir -p "$hooks" && cp "$here/hooks/commit-msg" "$hooks/commit-msg" && echo "setup: installed the commit-msg hook" || true
  fi
fi
mapfile -t wanted < <(sed -e 's/#.*//' -e 's/[[:space:]]//g' "$here/apt-packages.txt" | grep -v '^$')
missing=()
for pkg in "${wanted[@]}"; do
  status=$(dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null || true)
  [[ "$status" == "install ok installed" ]] || missing+=("$pkg")
done
if [[ ${#missing[@]} -eq 0 ]]; then
  echo "setup: all ${#wanted[@]} packages present"
  exit 0
fi
echo "setup: installing ${#missing[@]} missing package(s): ${missing[*]}"
sudo=""
if [[ $(id -u) -ne 0 ]]; then
  command -v sudo >/dev/null || { echo "setup: need root (or sudo) to install: ${missing[*]}" >&2; exit 1; }
  sudo="sudo"
fi
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq
$sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
echo "setup: done"
