#!/usr/bin/env bash
# Installs what is missing, then runs every test: the C++ suite and the consumer-project test
# through ctest, then pytest. Exits non-zero on any failure.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
bash scripts/setup.sh
venv="$(cd "${PROBSLAM_VENV:-.venv}" && pwd)"
export PATH="$venv/bin:$PATH"
jobs="${PROBSLAM_JOBS:-2}"

cmake -S . -B build/ctest -G Ninja -DCMAKE_BUILD_TYPE=Release -DPROBSLAM_BUILD_TESTS=ON >/dev/null
cmake --build build/ctest -j "$jobs"
ctest --test-dir build/ctest --output-on-failure -j "$jobs"
"$venv/bin/python" -m pytest tests/python -q -p no:cacheprovider
