"""What every benchmark script shares: the machine line and the report's destination."""

import datetime
import os
import pathlib
import platform

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


def report(lines, record: bool) -> None:
    """Print the report; append it to RESULTS.md when `record` (not for --quick smoke runs)."""
    text = "\n".join(lines).rstrip("\n") + "\n"
    print(text)
    if record:
        with open(RESULTS, "a") as f:
            f.write(text + "\n")
