"""What the command line says when a run cannot go on: a user's error (one line on stderr, exit
status 2), the exit statuses, and the library's messages, which name an option's field or a
reader's parameter, told as the flag that set it (the CLI does not check values again)."""

from __future__ import annotations

import argparse
import contextlib
import os
from typing import Iterable, Iterator, Mapping, Optional

from ..pipelines.inputs import READ_ERRORS, InputError, name_pattern, one_line, renamed

EPILOG = """exit status:
  0  success
  1  an unexpected error (a bug: please report it)
  2  a user or input error: a bad option, a missing, empty or unreadable file, an output folder
     that does not exist or cannot be written (one line on stderr)
  3  optimize did not converge within --max-iterations, or localize's estimate never converged
     (the result is written all the same)
  130  interrupted (Ctrl-C); optimize writes the graph of its last completed iteration first
  141  the output's reader stopped (probslam ... | head -1), nothing said, as other tools

Without a dataset argument every command runs on small excerpts of public datasets bundled with
the package (probslam.data.path(NAME) gives their paths). Plots need matplotlib (optional: pip
install 'probslam[plot]'); without it they are skipped with a notice."""
#: Exit status: a user or input error; a run that finished but did not converge; Ctrl-C (128 +
#: SIGINT, as shells report it); the reader of the output pipe stopped (128 + SIGPIPE, as a tool
#: killed by it has).
EXIT_USER_ERROR, EXIT_NOT_CONVERGED, EXIT_INTERRUPTED, EXIT_BROKEN_PIPE = 2, 3, 130, 141


class UserError(Exception):
    """An input or usage error: printed as one line on stderr, exit status 2."""


@contextlib.contextmanager
def told(names: Mapping[str, str], args: Optional[argparse.Namespace] = None,
         path: Optional[str] = None) -> Iterator[None]:
    """The library's errors about a parameter of ``names`` (an option's field or a reader's
    parameter -> the flag or file that gave it) as a UserError that says the flag
    (``inputs.renamed``), with the value ``args`` has for it, naming ``path`` when given; other
    errors, and a file's (InputError, which names it), raised as they are."""
    try:
        yield
    except InputError:
        raise
    except (TypeError,) + READ_ERRORS as exc:
        message = one_line(exc)
        subject = name_pattern(names).match(message) if names and args is not None else None
        # The value given: the flag's dest, named as the field (min_particles) or as the flag (--resolution).
        given = subject and getattr(args, subject.group(1),
                                    getattr(args, names[subject.group(1)].lstrip("-").replace("-", "_"), None))
        text, named = renamed(message, names, given)
        if not named:
            raise
        raise UserError(text if path is None or path in text else f"{path}: {text}") from None


def refuse_given(args: argparse.Namespace, dests: Iterable[str], why: str) -> None:
    """UserError naming the first of ``dests`` given: it does not apply to this run (``why``)."""
    for dest in dests:
        if dest in args.given:
            raise UserError(f"{args.given[dest]} {why}")


def check_output(prefix: str) -> None:
    """UserError naming -o when its folder is missing or not writable: before a run of minutes."""
    folder = os.path.dirname(prefix) or "."
    if not os.path.isdir(folder):
        raise UserError(f"-o {prefix}: folder {folder} does not exist")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise UserError(f"-o {prefix}: folder {folder} is not writable")
