"""benchmarks/common.py: --record writes a benchmark's run into its script's section of RESULTS.md,
replacing the run of the same title; RESULTS.md has one section per benchmark script."""

import importlib.util
import pathlib
import re

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
    assert c.section_title("### a record, 2026-11-21", 3) == "a record"
    assert c.section_title("## a section, 2026-11-21", 3) is None
    assert c.section_title("| a | b |") is None


def test_record_replaces_the_run_of_the_same_title_in_the_scripts_section(tmp_path):
    c = _common()
    path = tmp_path / "RESULTS.md"
    path.write_text("# Benchmark results\n\nPreamble.\n\n## bench_a.py\n\nWhat A measures.\n\n"
                    "### A, 2026-01-01\n\nold A\n\n### A, 2026-01-02\n\nolder duplicate\n\n"
                    "### A small, 2026-01-01\n\nsmall A\n\n## bench_b.py\n\n### B, 2026-01-01\n\nB table\n")
    c.record_section("## A, 2026-02-01\n\nnew A\n", "bench_a.py", path)
    text = path.read_text()
    assert text == ("# Benchmark results\n\nPreamble.\n\n## bench_a.py\n\nWhat A measures.\n\n"
                    "### A, 2026-02-01\n\nnew A\n\n### A small, 2026-01-01\n\nsmall A\n\n"
                    "## bench_b.py\n\n### B, 2026-01-01\n\nB table\n")
    # A new title of a known script is appended to that script's section.
    c.record_section("## B large, 2026-02-02\n\nlarge B\n", "bench_b.py", path)
    assert path.read_text() == text + "\n### B large, 2026-02-02\n\nlarge B\n"
    # A script without a section gets one at the end.
    c.record_section("## C, 2026-02-03\n\nC table\n", "bench_c.py", path)
    assert path.read_text().endswith("large B\n\n## bench_c.py\n\n### C, 2026-02-03\n\nC table\n")
    # The same title under another script is another record.
    c.record_section("## A, 2026-02-04\n\nA by C\n", "bench_c.py", path)
    assert "### A, 2026-02-01\n\nnew A" in path.read_text()


def test_report_prints_only_unless_recording(tmp_path, monkeypatch, capsys):
    c = _common()
    path = tmp_path / "RESULTS.md"
    monkeypatch.setattr(c, "RESULTS", path)
    c.report(["## A, 2026-01-01", "", "table"], record=False, script="bench_a.py")
    assert "table" in capsys.readouterr().out and not path.exists()
    c.report(["## A, 2026-01-01", "", "table"], record=True, script="bench_a.py")
    assert path.read_text() == "# Benchmark results\n\n## bench_a.py\n\n### A, 2026-01-01\n\ntable\n"


def test_scripts_record_only_when_asked():
    for script in (ROOT / "benchmarks").glob("*.py"):
        text = script.read_text()
        assert "--no-record" not in text, script.name
        if "report(lines" in text and script.name != "common.py":
            assert '"--record"' in text and "args.record" in text, script.name


def test_studies_only_print():
    """The studies print their tables; their last runs are written up in studies/README.md."""
    studies = sorted((ROOT / "studies").glob("*.py"))
    assert len(studies) == 7
    readme = (ROOT / "studies" / "README.md").read_text()
    for script in studies:
        text = script.read_text()
        assert '"--record"' not in text and "record=args" not in text, script.name
        assert f"## {script.name}" in readme, script.name
        assert f"studies/{script.name}" in text, script.name  # its usage line names where it lives


def test_results_has_one_section_per_benchmark_script():
    """RESULTS.md: a `## script.py` section for each recording benchmark (or `## sweeps/NAME.toml`
    for a sweep file that exists), in which every record is `### Title, date` followed by the
    machine line; nothing else at those levels."""
    text = (ROOT / "benchmarks" / "RESULTS.md").read_text()
    sections = re.findall(r"^## (.*)$", text, flags=re.M)
    recording = [p.name for p in (ROOT / "benchmarks").glob("bench_*.py") if '"--record"' in p.read_text()]
    # A sweep's section holds tables made by `probslam batch` on that file of benchmarks/sweeps/.
    sweeps = [s for s in sections if s.startswith("sweeps/")]
    assert all((ROOT / "benchmarks" / s).is_file() for s in sweeps), sweeps
    assert sorted(sections) == sorted(recording + sweeps)
    for block in re.split(r"^## ", text, flags=re.M)[1:]:
        records = re.findall(r"^### (.*)\n\n(.*)$", block, flags=re.M)
        assert records, block.split("\n")[0]
        for title, first in records:
            assert re.search(r", \d{4}-\d{2}-\d{2}$", title), title
            assert first.startswith("Machine:"), title


def test_recording_a_run_again_leaves_results_unchanged(tmp_path):
    """What --record writes matches RESULTS.md's layout: each record, printed again as a script
    prints it (`## Title, date`) and recorded into its script's section, gives the same file."""
    c = _common()
    original = (ROOT / "benchmarks" / "RESULTS.md").read_text()
    path = tmp_path / "RESULTS.md"
    path.write_text(original)
    for block in re.split(r"^## ", original, flags=re.M)[1:]:
        script = block.split("\n")[0]
        for record in re.split(r"^### ", block, flags=re.M)[1:]:
            c.record_section("## " + record, script, path)
    assert path.read_text() == original
