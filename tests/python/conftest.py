import os
import pathlib
import sys

import pytest

sys.path.insert(0, os.path.dirname(__file__))  # for reference.py

SHARED_DATA = pathlib.Path(os.environ.get("PROBSLAM_SHARED_DATA",
                                          pathlib.Path(__file__).resolve().parents[2].parent / "shared" / "data"))


@pytest.fixture
def shared_data():
    if not SHARED_DATA.is_dir():
        pytest.skip(f"shared datasets not present at {SHARED_DATA}")
    return SHARED_DATA


def pytest_collection_modifyitems(config, items):
    """Under the sanitizers (scripts/sanitize.sh) the slow tests (whole datasets, Monte Carlo
    runs, the examples) are left to the uninstrumented run of scripts/test.sh: they call the same
    C++ code as the fast tests, at six times the cost, and held CI at 60 of its 90 minutes. The
    reliability files keep theirs: threads sharing objects and odd inputs are what the sanitizers
    are for."""
    if not os.environ.get("PROBSLAM_SANITIZED"):
        return
    skip = pytest.mark.skip(reason="slow: run uninstrumented by scripts/test.sh")
    for item in items:
        if item.get_closest_marker("slow") and not item.path.name.startswith("test_reliability"):
            item.add_marker(skip)
