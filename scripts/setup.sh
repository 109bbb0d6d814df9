#!/usr/bin/env bash
# Installs what is missing, and only that: Debian packages (as root, or through sudo), a Python
# virtual environment (.venv, or $PROBSLAM_VENV), the PyPI dependencies, and probslam itself.
# Safe to run again: every step is skipped or incremental when already done.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

APT_PACKAGES=(cmake g++ make git libeigen3-dev libsuitesparse-dev liboctomap-dev libgtest-dev
              python3 python3-venv python3-dev)
PIP_PACKAGES=("scikit-build-core>=0.10" "pybind11>=2.12" "ninja" "numpy>=1.23" "tqdm>=4.60"
              "pytest>=7" "scipy>=1.10" "matplotlib>=3.6" "hypothesis>=6.100")
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
if ! "$py" -c "import scikit_build_core, pybind11, ninja, numpy, tqdm, pytest, scipy, matplotlib, hypothesis" 2>/dev/null; then
  echo "setup: installing Python packages into $venv"
  "$py" -m pip install -q --disable-pip-version-check "${PIP_PACKAGES[@]}"
fi
if ! "$py" -c "import atheris" 2>/dev/null; then
  "$py" -m pip install -q --disable-pip-version-check --only-binary=:all: "$FUZZ_PACKAGE" ||
    echo "setup: atheris has no wheel here; scripts/fuzz.sh will skip"
fi
echo "setup: building and installing probslam into $venv"
PATH="$(cd "$venv/bin" && pwd):$PATH" "$py" -m pip install -q --disable-pip-version-check --no-build-isolation .
