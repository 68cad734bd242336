#!/usr/bin/env bash
# Fails when a source file of the library, the tools or the Python module is over 600 lines (the
# limit the code is split by: one responsibility a file). Tests are not held to it.
# Usage: bash scripts/check_file_sizes.sh   (run by ctest as source_files_under_600_lines)
set -euo pipefail
cd "$(dirname "$0")/.."
status=0
while IFS= read -r f; do
  n=$(wc -l < "$f")
  if [ "$n" -gt 600 ]; then
    echo "$f: $n lines, over 600: split it by responsibility" >&2
    status=1
  fi
done < <(find src include tools python/src -type f \( -name '*.cpp' -o -name '*.h' -o -name '*.hpp' \) | sort)
exit $status
