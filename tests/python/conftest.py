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
