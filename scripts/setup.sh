#!/usr/bin/env bash
# Installs what is missing, and only that: Debian packages (as root, or through sudo), a Python
# virtual environment (.venv, or $PROBSLAM_VENV), the PyPI dependencies, and probslam itself.
# Safe to run again: every step is skipped or incremental when already done.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

APT_PACKAGES=(cmake g++ make git libeigen3-dev libsuitesparse-dev liboctomap-dev libgtest-dev
              python3 python3-venv python3-dev)
PIP_PACKAGES=("scikit-build-core>=0.10" "pybind11>=2.12" "ninja" "numpy>=1.23" "tqdm>=4.60"
              "pytest>=7" "pytest-xdist>=3.5" "scipy>=1.10" "matplotlib>=3.6" "hypothesis>=6.100" "rosbags>=0.10" "evo>=1.38"
              "dask>=2024.1" "distributed>=2024.1" "pyarrow>=14")
# The fuzzer of scripts/fuzz.sh: optional (wheels exist for common CPython/Linux pairs only;
# fuzz.sh skips with a message without it), so its failure to install stops nothing.
FUZZ_PACKAGE="atheris>=2.3"

missing=()
for pkg in "${APT_PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || missing+=("$pkg")
done
if ((${#missing[@]})); then
  echo "setup: installing Debian packages: ${missing[*]}"
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

venv="${PROBSLAM_VENV:-.venv}"
if [ ! -x "$venv/bin/python" ]; then
  echo "setup: creating virtual environment $venv"
  "${PYTHON:-python3}" -m venv "$venv"
fi
py="$venv/bin/python"
if ! "$py" -c "import scikit_build_core, pybind11, ninja, numpy, tqdm, pytest, xdist, scipy, matplotlib, hypothesis, rosbags, evo, dask, distributed, pyarrow" 2>/dev/null; then
  echo "setup: installing Python packages into $venv"
  "$py" -m pip install -q --disable-pip-version-check "${PIP_PACKAGES[@]}"
fi
if ! "$py" -c "import atheris" 2>/dev/null; then
  "$py" -m pip install -q --disable-pip-version-check --only-binary=:all: "$FUZZ_PACKAGE" ||
    echo "setup: atheris has no wheel here; scripts/fuzz.sh will skip"
fi
# One CMake build directory per environment (scripts/build_root.sh says why).
source scripts/build_root.sh
venv_abs="$(cd "$venv" && pwd)"
root="$(build_root "$venv")"
build_dir="$root/{wheel_tag}"
mkdir -p "$root"
build_log="$root/pip-install.log"  # the last build's full output
# PROBSLAM_BUILD_TESTS=1 (scripts/test.sh sets it): the same CMake tree also builds the C++ tests,
# which ctest then runs there, so the library is compiled once for the wheel and the tests.
tests_define=()
if [ "${PROBSLAM_BUILD_TESTS:-0}" = 1 ]; then
  tests_define=(--config-settings=cmake.define.PROBSLAM_BUILD_TESTS=ON)
fi
# The first build compiles everything (docs/install.md#build-time: 3.3 min of a 3.8 min setup on 2
# idle cores); a rebuild in the kept CMake tree compiles only what changed.
if compgen -G "$root/*/build.ninja" >/dev/null; then
  build_kind="a rebuild: incremental, only what changed compiles"
else
  build_kind="a first build: 3.3 min of compiling on 2 idle cores, docs/install.md#build-time"
fi
echo "setup: building and installing probslam into $venv (CMake build directory $build_dir;"
echo "setup: $build_kind; progress below, the full log in $build_log)"
# Progress: ninja's "[n/N] ..." lines as they come (paths shortened), or a line after every 30 s
# of silence. A foreground pipeline, so that Ctrl-C stops the build too.
progress() {
  local line status start=$SECONDS
  while :; do
    if IFS= read -r -t 30 line; then
      if [[ "$line" =~ ^\ *\[[0-9]+/[0-9]+\]\  ]]; then
        echo "setup:   $(sed -E 's/^ *//; s# [^ ]*/([^/ ]+\.(cpp|o))# \1#g' <<<"$line" | cut -c1-100)"
      fi
    else
      status=$?
      ((status > 128)) || break  # end of the build's output
      echo "setup:   still building ($((SECONDS - start)) s)"
    fi
  done
}
start=$SECONDS
if ! PATH="$venv_abs/bin:$PATH" "$py" -m pip install -v --disable-pip-version-check --no-build-isolation \
    --config-settings=build-dir="$build_dir" ${tests_define[@]+"${tests_define[@]}"} . 2>&1 | tee "$build_log" | progress; then
  tail -n 40 "$build_log" >&2
  echo "setup: building probslam failed after $((SECONDS - start)) s; full log: $build_log" >&2
  exit 1
fi
echo "setup: probslam installed into $venv in $((SECONDS - start)) s (log: $build_log)"
