"""Runs one fuzz target under atheris: ``python fuzz/fuzz_one.py TARGET [libFuzzer options]
[CORPUS_DIR ...]`` (``-max_total_time=S``, ``-timeout=S``, ``-rss_limit_mb=N``, ...).

atheris sees the coverage of Python code only: the readers' Python layers (probslam.io,
probslam.graph) are instrumented with ``atheris.instrument_imports``; the C++ extension is not
built with clang's -fsanitize=fuzzer, so inside the C++ parsers the search is blind (mutations
of the seeds, kept when they reach new Python lines). A crash of the extension still kills the
run and is reported, as are uncaught exceptions, hangs (-timeout) and memory blow-ups
(-rss_limit_mb).
"""

import os
import sys

import atheris
import numpy  # noqa: F401  (imported uninstrumented: numpy's own code is not fuzzed)

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from targets import TARGETS, Workspace, check  # noqa: E402

with atheris.instrument_imports(include=["probslam"]):
    import probslam  # noqa: F401
    import probslam.eval  # noqa: F401
    import probslam.graph  # noqa: F401
    import probslam.inverse_learning  # noqa: F401
    import probslam.io  # noqa: F401


def main() -> None:
    if len(sys.argv) < 2 or sys.argv[1] not in TARGETS:
        sys.exit(f"usage: fuzz_one.py TARGET [libFuzzer options] [corpus dirs]; targets: {', '.join(TARGETS)}")
    target, ws = TARGETS[sys.argv[1]], Workspace()
    atheris.Setup([sys.argv[0]] + sys.argv[2:], lambda data: check(target, ws, data))
    atheris.Fuzz()


if __name__ == "__main__":
    main()
