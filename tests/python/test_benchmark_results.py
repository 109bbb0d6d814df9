"""benchmarks/common.py: --record replaces a benchmark's section in RESULTS.md by title."""

import importlib.util
import pathlib

ROOT = pathlib.Path(__file__).resolve().parents[2]


def _common():
    spec = importlib.util.spec_from_file_location("bench_common", ROOT / "benchmarks" / "common.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_section_title_is_the_part_before_the_date():
    c = _common()
    assert c.section_title("## EKF SLAM, Victoria Park full run vs dense numpy, 2026-11-21") == \
        "EKF SLAM, Victoria Park full run vs dense numpy"
    assert c.section_title("## Notes by hand") == "Notes by hand"
    assert c.section_title("### not a section, 2026-11-21") is None
    assert c.section_title("| a | b |") is None


def test_record_replaces_the_section_of_the_same_title(tmp_path):
    c = _common()
    path = tmp_path / "RESULTS.md"
    path.write_text("# Benchmark results\n\nPreamble.\n\n## A, 2026-01-01\n\nold A\n\n"
                    "## A, 2026-01-02\n\nolder duplicate\n\n## B, 2026-01-01\n\nB table\n")
    c.record_section("## A, 2026-02-01\n\nnew A\n", path)
    text = path.read_text()
    assert text == "# Benchmark results\n\nPreamble.\n\n## A, 2026-02-01\n\nnew A\n\n## B, 2026-01-01\n\nB table\n"
    c.record_section("## C, 2026-02-02\n\nC table\n", path)  # a new title is appended
    assert path.read_text() == text + "\n## C, 2026-02-02\n\nC table\n"


def test_report_prints_only_unless_recording(tmp_path, monkeypatch, capsys):
    c = _common()
    path = tmp_path / "RESULTS.md"
    monkeypatch.setattr(c, "RESULTS", path)
    c.report(["## A, 2026-01-01", "", "table"], record=False)
    assert "table" in capsys.readouterr().out and not path.exists()
    c.report(["## A, 2026-01-01", "", "table"], record=True)
    assert path.read_text().endswith("## A, 2026-01-01\n\ntable\n")


def test_scripts_record_only_when_asked():
    for script in (ROOT / "benchmarks").glob("*.py"):
        text = script.read_text()
        assert "--no-record" not in text, script.name
        if "report(lines" in text and script.name != "common.py":
            assert '"--record"' in text and "args.record" in text, script.name
