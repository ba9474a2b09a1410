#!/usr/bin/env bash
# The tree's C, C++ and OpenCL sources against .clang-format (clang-format 14,
# Debian 12's).  Installs it if missing.
#   bash tools/format.sh          reformat every tracked source in place
#   bash tools/format.sh check    list what differs and fail (CI)
set -euo pipefail

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
command -v clang-format-14 >/dev/null || CAMBIUM_EXTRA_PACKAGES="clang-format-14" bash "$root/tools/setup.sh" packages
cd "$root"
mapfile -t files < <(git ls-files '*.cpp' '*.h' '*.c' '*.cl' '*.inc')
if [ "${1:-}" = check ]; then
  clang-format-14 --dry-run -Werror "${files[@]}"
  echo "format: ${#files[@]} files as .clang-format says"
else
  clang-format-14 -i "${files[@]}"
fi
