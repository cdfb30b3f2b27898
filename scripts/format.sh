#!/usr/bin/env bash
# Formats the C++ files (shaders/shared headers included; GLSL stages are not formatted) with the repository's .clang-format.
# Usage: scripts/format.sh [--check] [BASE]
#   without BASE: the files changed against HEAD (staged, unstaged and untracked);
#   with BASE (a commit): the files changed since BASE; --all: every tracked file.
#   --check changes nothing and exits 1, listing the files that differ from the format.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
check=0
base=""
all=0
for a in "$@"; do
  case "$a" in
    --check) check=1 ;;
    --all) all=1 ;;
    *) base="$a" ;;
  esac
done
command -v clang-format >/dev/null || { echo "format: clang-format is not installed (scripts/setup.sh)" >&2; exit 1; }
pattern='\.(cpp|h|hpp)$'
if (( all )); then
  mapfile -t files < <(git ls-files | grep -E "$pattern" || true)
elif [[ -n "$base" ]]; then
  mapfile -t files < <(git diff --name-only --diff-filter=d "$base" -- | grep -E "$pattern" || true)
else
  mapfile -t files < <({ git diff --name-only --diff-filter=d HEAD --; git ls-files --others --exclude-standard; } |
                       sort -u | grep -E "$pattern" || true)
fi
if [[ ${#files[@]} -eq 0 ]]; then
  echo "format: no C++/GLSL files to look at"
  exit 0
fi
if (( check )); then
  bad=()
  for f in "${files[@]}"; do
    clang-format --style=file "$f" | cmp -s - "$f" || bad+=("$f")
  done
  if [[ ${#bad[@]} -gt 0 ]]; then
    echo "format: ${#bad[@]} of ${#files[@]} files differ from .clang-format (run scripts/format.sh):" >&2
    printf '  %s\n' "${bad[@]}" >&2
    exit 1
  fi
  echo "format: ${#files[@]} files match .clang-format"
else
  clang-format --style=file -i "${files[@]}"
  echo "format: formatted ${#files[@]} files"
fi
