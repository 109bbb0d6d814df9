"""What every benchmark script shares: the machine line and the report's destination.

Scripts print their tables; with ``--record`` they also write them into RESULTS.md, where each
benchmark keeps one section (its latest run, found by the title before the date).
"""

import datetime
import os
import pathlib
import platform
import re

import numpy as np

RESULTS = pathlib.Path(__file__).resolve().parent / "RESULTS.md"


def machine() -> str:
    cpu = "unknown CPU"
    try:
        cpu = next(l.split(":", 1)[1].strip() for l in open("/proc/cpuinfo") if l.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}, numpy {np.__version__}"


def heading(title: str, note: str, columns) -> list:
    """The opening lines of a RESULTS.md section: title with today's date, the machine, and the
    header of its first table."""
    return [f"## {title}, {datetime.date.today()}", "", f"Machine: {machine()}. {note}", "",
            "| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]


def section_title(heading_line: str):
    """The title of a RESULTS.md section heading ``## Title, YYYY-MM-DD`` (the part before the
    date; a heading without a date is all title), or None for a line that is no section heading."""
    if not heading_line.startswith("## "):
        return None
    text = heading_line[3:].strip()
    m = re.fullmatch(r"(.*?),\s*\d{4}-\d{2}-\d{2}", text)
    return m.group(1).strip() if m else text


def record_section(text: str, path: pathlib.Path = RESULTS) -> None:
    """Write a section (``## Title, date`` heading first) into the results file: it replaces the
    section(s) of the same title (in place of the first), or is appended when the title is new.
    RESULTS.md keeps the latest run of each benchmark; earlier runs are in git history."""
    new_lines = text.rstrip("\n").split("\n")
    title = section_title(new_lines[0])
    if title is None:
        raise ValueError(f"a recorded section must start with a '## Title, date' heading, got {new_lines[0]!r}")
    old = path.read_text().split("\n") if path.exists() else ["# Benchmark results", ""]
    # Split into the preamble and sections, each from its '## ' heading to the next one.
    starts = [i for i, line in enumerate(old) if section_title(line) is not None]
    preamble = old[:starts[0]] if starts else old
    sections = [old[a:b] for a, b in zip(starts, starts[1:] + [len(old)])]
    out, placed = [], False
    for sec in sections:
        if section_title(sec[0]) == title:
            if not placed:
                out.append(new_lines)
                placed = True
            continue
        out.append(sec)
    if not placed:
        out.append(new_lines)
    parts = ["\n".join(preamble).strip("\n")] + ["\n".join(sec).strip("\n") for sec in out]
    path.write_text("\n\n".join(parts) + "\n")


def report(lines, record: bool) -> None:
    """Print the report; with `record` (a script's --record) also write it into RESULTS.md,
    replacing the previous section of the same title."""
    text = "\n".join(lines).rstrip("\n") + "\n"
    print(text)
    if record:
        record_section(text, RESULTS)
        print(f"recorded in {RESULTS}")
