#!/usr/bin/env bash
# The whole C++ suite, then pytest through the extension module, built with AddressSanitizer and
# UndefinedBehaviorSanitizer (-DPROBSLAM_SANITIZE=ON). Any sanitizer report aborts the run, so a
# green run is a clean one. Run scripts/setup.sh first (scripts/test.sh does).
#   bash scripts/sanitize.sh            # ctest, then pytest
#   bash scripts/sanitize.sh --cpp      # ctest only
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
venv="$(cd "${PROBSLAM_VENV:-.venv}" && pwd)"
export PATH="$venv/bin:$PATH"
jobs="${PROBSLAM_JOBS:-2}"
build=build/asan

# -O1 keeps the instrumented suite quick while leaving stack traces readable.
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Debug -DCMAKE_CXX_FLAGS_DEBUG="-O1 -g" \
  -DPROBSLAM_SANITIZE=ON -DPROBSLAM_BUILD_TESTS=ON -DPROBSLAM_BUILD_PYTHON=ON \
  -DPython_EXECUTABLE="$venv/bin/python" -Dpybind11_DIR="$("$venv/bin/python" -m pybind11 --cmakedir)" >/dev/null
cmake --build "$build" -j "$jobs"

# Leak checking stays off: CPython and numpy keep allocations alive until exit by design.
export ASAN_OPTIONS="detect_leaks=0:abort_on_error=1:strict_init_order=1:detect_stack_use_after_return=1"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
# The installed-package consumer and C++ example tests link without the sanitizer runtime: they
# are covered by scripts/test.sh.
ctest --test-dir "$build" --output-on-failure -j "$jobs" -E "consumer_project|cpp_example"

[ "${1:-}" = "--cpp" ] && exit 0

# pytest against the instrumented module: a package tree of links to python/probslam plus the
# sanitized _core, put first on the path; CPython itself is not instrumented, so the ASan
# runtime is preloaded. --capture=sys leaves file descriptor 2 alone, so a sanitizer report that
# aborts the run is printed rather than lost with pytest's captured output.
pkg="$build/pkg/probslam"
rm -rf "$build/pkg" && mkdir -p "$pkg"
for f in python/probslam/*; do ln -s "$PWD/$f" "$pkg/"; done
ln -s "$PWD/$(ls "$build"/bindings/_core*.so)" "$pkg/"
LD_PRELOAD="$(g++ -print-file-name=libasan.so):$(g++ -print-file-name=libubsan.so)" \
  PYTHONPATH="$PWD/$build/pkg" PROBSLAM_SANITIZED=1 \
  "$venv/bin/python" -m pytest tests/python -q -p no:cacheprovider -x --capture=sys -n "$jobs" --dist loadfile
