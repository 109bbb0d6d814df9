"""What every benchmark script shares: the machine line and the report's destination.

Scripts print their tables; with ``--record`` they also write them into RESULTS.md, where each
benchmark script keeps one section (``## bench_x.py``) holding its latest run of each workload
(``### Title, date``, found by the title before the date).
"""

import datetime
import os
import pathlib
import platform
import re
import sys

import numpy as np

RESULTS = pathlib.Path(__file__).resolve().parent / "RESULTS.md"


def machine() -> str:
    cpu = "unknown CPU"
    try:
        cpu = next(l.split(":", 1)[1].strip() for l in open("/proc/cpuinfo") if l.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}, numpy {np.__version__}"


def commit() -> str:
    """The short hash of the checkout's HEAD ("unknown" outside git)."""
    import subprocess
    try:
        out = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                             cwd=pathlib.Path(__file__).parent).stdout.strip()
    except OSError:
        out = ""
    return out or "unknown"


def heading(title: str, note: str, columns) -> list:
    """The opening lines of a RESULTS.md section: title with today's date, the machine, and the
    header of its first table."""
    return [f"## {title}, {datetime.date.today()}", "", f"Machine: {machine()}. {note}", "",
            "| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]


def section_title(heading_line: str, level: int = 2):
    """The title of a heading ``## Title, YYYY-MM-DD`` (``###`` with level 3): the part before the
    date (a heading without a date is all title), or None for a line that is no such heading."""
    marker = "#" * level + " "
    if not heading_line.startswith(marker):
        return None
    text = heading_line[len(marker):].strip()
    m = re.fullmatch(r"(.*?),\s*\d{4}-\d{2}-\d{2}", text)
    return m.group(1).strip() if m else text


def _split(lines, level):
    """Lines cut at each heading of `level`: (the lines before the first, [each heading's lines])."""
    starts = [i for i, line in enumerate(lines) if section_title(line, level) is not None]
    head = lines[:starts[0]] if starts else lines
    return head, [lines[a:b] for a, b in zip(starts, starts[1:] + [len(lines)])]


def _join(blocks) -> str:
    return "\n\n".join(s for s in ("\n".join(b).strip("\n") for b in blocks) if s)


def record_section(text: str, script: str, path: pathlib.Path = RESULTS) -> None:
    """Write a record (``## Title, date`` heading first, as the scripts print it) into the results
    file, in the section of its script (``## bench_x.py``) as ``### Title, date``. It replaces the
    record(s) of the same title in that section (in place of the first) or is appended to it; a
    script without a section gets one at the end. RESULTS.md so keeps one section per benchmark
    script holding the latest run of each of its workloads; earlier runs are in git history."""
    new_lines = text.rstrip("\n").split("\n")
    if new_lines and new_lines[0].startswith("## "):
        new_lines[0] = "#" + new_lines[0]
    title = section_title(new_lines[0], 3)
    if title is None:
        raise ValueError(f"a recorded section must start with a '## Title, date' heading, got {new_lines[0]!r}")
    old = path.read_text().split("\n") if path.exists() else ["# Benchmark results", ""]
    preamble, sections = _split(old, 2)
    for i, sec in enumerate(sections):
        if section_title(sec[0]) == script:
            intro, records = _split(sec, 3)
            kept, placed = [], False
            for rec in records:
                if section_title(rec[0], 3) == title:
                    if not placed:
                        kept.append(new_lines)
                        placed = True
                    continue
                kept.append(rec)
            if not placed:
                kept.append(new_lines)
            sections[i] = _join([intro] + kept).split("\n")
            break
    else:
        sections.append([f"## {script}", ""] + new_lines)
    path.write_text(_join([preamble] + sections) + "\n")


def report(lines, record: bool, script: str = None) -> None:
    """Print the report; with `record` (a script's --record) also write it into RESULTS.md, in the
    section of `script` (default: the running script's file name), replacing its previous run."""
    text = "\n".join(lines).rstrip("\n") + "\n"
    print(text)
    if record:
        record_section(text, script or pathlib.Path(sys.argv[0]).name, RESULTS)
        print(f"recorded in {RESULTS}")
