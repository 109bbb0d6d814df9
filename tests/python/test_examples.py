"""Every examples/*.py runs as written on the installed package and its bundled data, and every
fenced Python block of the README is one of them (so the README's code runs too)."""

import os
import pathlib
import re
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
EXAMPLES = sorted((ROOT / "examples").glob("*.py"))


def test_there_are_examples():
    assert len(EXAMPLES) >= 4


@pytest.mark.parametrize("example", EXAMPLES, ids=lambda p: p.name)
@pytest.mark.slow
def test_example_runs(example, tmp_path):
    env = dict(os.environ, MPLBACKEND="Agg")
    run = subprocess.run([sys.executable, str(example)], cwd=tmp_path, env=env, capture_output=True, text=True,
                         timeout=300)
    assert run.returncode == 0, run.stderr
    assert "Traceback" not in run.stderr


@pytest.mark.parametrize("page", ["README.md"] + sorted(p.name for p in (ROOT / "docs").glob("*.md")))
def test_every_python_block_is_an_example_file(page):
    """Each block of the README and of the docs/ pages is the text of an examples/ file (its
    lines after the leading comment) and the page names that file just above the block."""
    path = ROOT / page if page == "README.md" else ROOT / "docs" / page
    text = path.read_text(encoding="utf-8")
    bodies = {p.name: p.read_text(encoding="utf-8") for p in EXAMPLES}
    blocks = re.findall(r"^```python\n(.*?)^```", text, flags=re.S | re.M)
    if page == "README.md":
        assert blocks
    for block in blocks:
        owners = [name for name, body in bodies.items() if block.strip() in body]
        assert owners, f"{page}: block not in any examples/*.py:\n{block}"
        before = text[:text.index(block)]
        assert f"examples/{owners[0]}" in before[-400:], f"{page} does not name examples/{owners[0]}"
