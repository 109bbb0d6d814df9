#!/usr/bin/env bash
# Fuzzes every parser entry point with atheris (fuzz/targets.py) for SECONDS_PER_TARGET seconds
# each (default 6: about 110 s for the eighteen targets on 2 cores), then prints a table of executions,
# crashes and hangs. Exits 1 on any finding; the inputs are kept in $FUZZ_OUT (default
# fuzz/findings/) as crash-*, timeout-* or oom-* files. Skips (exit 0) if atheris is missing.
#   usage: scripts/fuzz.sh [SECONDS_PER_TARGET] [TARGET ...]
#   env:   PYTHON (default .venv/bin/python, else python3), FUZZ_TIMEOUT (seconds per input,
#          default 10), FUZZ_RSS_MB (default 2048), FUZZ_OUT, PROBSLAM_SHARED_DATA
set -uo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

seconds="${1:-6}"
shift || true
py="${PYTHON:-}"
[ -n "$py" ] || { [ -x .venv/bin/python ] && py=.venv/bin/python || py=python3; }
if ! "$py" -c "import atheris" 2>/dev/null; then
  echo "fuzz: atheris is not importable by $py (pip install atheris); skipping the fuzz run"
  exit 0
fi
targets=("$@")
((${#targets[@]})) || mapfile -t targets < <("$py" -c "import sys; sys.path.insert(0, 'fuzz'); import targets; print('\n'.join(targets.TARGETS))")

out="${FUZZ_OUT:-fuzz/findings}"
mkdir -p "$out"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
"$py" fuzz/make_seeds.py shared "$work/shared" >/dev/null

status=0
printf '%-14s %12s %8s %6s %5s\n' target executions crashes hangs ooms
for t in "${targets[@]}"; do
  mkdir -p "$work/corpus/$t" "$work/shared/$t"
  log="$work/$t.log"
  "$py" fuzz/fuzz_one.py "$t" -max_total_time="$seconds" -timeout="${FUZZ_TIMEOUT:-10}" \
    -rss_limit_mb="${FUZZ_RSS_MB:-2048}" -print_final_stats=1 -artifact_prefix="$out/$t-" \
    "$work/corpus/$t" "fuzz/seeds/$t" "$work/shared/$t" >"$log" 2>&1
  rc=$?
  execs=$(grep -o 'stat::number_of_executed_units: [0-9]*' "$log" | grep -o '[0-9]*$' | tail -1)
  crashes=$(grep -c -E 'Uncaught Python exception|deadly signal|ERROR: AddressSanitizer' "$log")
  hangs=$(grep -c 'ERROR: libFuzzer: timeout' "$log")
  ooms=$(grep -c 'ERROR: libFuzzer: out-of-memory' "$log")
  if ((rc != 0)) && ((crashes + hangs + ooms == 0)); then crashes=1; fi  # died some other way
  printf '%-14s %12s %8s %6s %5s\n' "$t" "${execs:-?}" "$crashes" "$hangs" "$ooms"
  if ((crashes + hangs + ooms)); then
    status=1
    cp "$log" "$out/$t.log"
    echo "  finding: see $out/$t.log and $out/$t-*" >&2
  fi
done
exit $status
