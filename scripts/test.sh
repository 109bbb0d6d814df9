#!/usr/bin/env bash
# Installs what is missing, then runs every test: the C++ suite and the consumer-project test
# through ctest, then pytest. Exits non-zero on any failure.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
# One compile: setup.sh builds the wheel and the C++ tests in one CMake tree (its build
# directory, build/<venv>-<hash>/<wheel tag>), and ctest runs there.
PROBSLAM_BUILD_TESTS=1 bash scripts/setup.sh
venv="$(cd "${PROBSLAM_VENV:-.venv}" && pwd)"
export PATH="$venv/bin:$PATH"
jobs="${PROBSLAM_JOBS:-2}"
source scripts/build_root.sh
root="$(build_root "$venv")"
caches=("$root"/*/CMakeCache.txt)
if [ ! -f "${caches[0]}" ] || [ "${#caches[@]}" -ne 1 ]; then
  echo "test: expected one CMake tree under $root, found: ${caches[*]}" >&2
  exit 1
fi
ctest --test-dir "$(dirname "${caches[0]}")" --output-on-failure -j "$jobs"
# pytest on every core (pytest-xdist): a test file's tests stay together in one worker (module
# fixtures such as test_batch's cluster are made once), files are shared out as workers free up.
"$venv/bin/python" -m pytest tests/python -q -p no:cacheprovider -n "$jobs" --dist loadfile
