"""The ``probslam`` command line: each command parses its flags (``parser``), calls one pipeline
and prints what the pipeline's run says, writes and draws (``commands``). The flags that set an
options field are made from the field's description; the library checks the values and its
messages, which name the field, are told as the flag that gave it (``messages``)."""

from __future__ import annotations

import contextlib
import os
import sys
import warnings
from typing import List, Optional

from ..pipelines.inputs import one_line
from . import commands, messages, parser
from .commands import (BUNDLED_GRAPH, BUNDLED_LANDMARKS, BUNDLED_LOCALIZATION_MAP, BUNDLED_LOG, BUNDLED_RAW_LOG,
                       BUNDLED_SLAM_LOG, COMMANDS)
from .messages import (EPILOG, EXIT_BROKEN_PIPE, EXIT_INTERRUPTED, EXIT_NOT_CONVERGED, EXIT_USER_ERROR, UserError,
                       check_output)
from .parser import SLAM_FLAGS, build_parser, given_options, long_options, output_prefix


def main(argv: Optional[List[str]] = None) -> int:
    """Runs the command line; the exit status (EPILOG). PROBSLAM_DEBUG=1 shows an unexpected error's
    traceback."""
    try:
        status = _run(argv)
        sys.stdout.flush()  # a pipe closed under buffered output shows here, not at exit
        return status
    except BrokenPipeError:
        # The reader stopped (probslam ... | head -1): quiet, the status of a tool killed by SIGPIPE;
        # the output left is dropped, not flushed into the closed pipe at exit.
        with contextlib.suppress(OSError, ValueError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_BROKEN_PIPE


def _run(argv: Optional[List[str]]) -> int:
    command_line = build_parser()
    args = command_line.parse_args(argv)
    command = command_line.command_parser(args)
    args.given, args.flags = given_options(argv), long_options(command)
    format_warning = warnings.formatwarning
    # A reader's warning (a few malformed lines skipped) as one line, without the source line.
    warnings.formatwarning = lambda message, category, *rest, **kw: f"probslam: warning: {message}\n"
    try:
        if getattr(args, "output", None) is not None:
            args.output = output_prefix(args.output, command.get_default("output"))
            check_output(args.output)  # before any data is read: a run may take minutes
        return COMMANDS[args.command](args)
    except KeyboardInterrupt:
        print("probslam: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        raise
    except (UserError, ValueError, TypeError, OSError, ImportError) as exc:
        # Bad options (the library names the argument), unreadable or unwritable files.
        print(f"probslam: error: {one_line(exc)}", file=sys.stderr)
        return EXIT_USER_ERROR
    except Exception as exc:  # noqa: BLE001 - the last resort: one line, not a traceback
        if os.environ.get("PROBSLAM_DEBUG"):
            raise
        print(f"probslam: unexpected error: {type(exc).__name__}: {one_line(exc)} "
              "(a bug: please report it; PROBSLAM_DEBUG=1 shows the traceback)", file=sys.stderr)
        return 1
    finally:
        warnings.formatwarning = format_warning


__all__ = ["BUNDLED_GRAPH", "BUNDLED_LANDMARKS", "BUNDLED_LOCALIZATION_MAP", "BUNDLED_LOG", "BUNDLED_RAW_LOG",
           "BUNDLED_SLAM_LOG", "COMMANDS", "EPILOG", "EXIT_BROKEN_PIPE", "EXIT_INTERRUPTED", "EXIT_NOT_CONVERGED",
           "EXIT_USER_ERROR", "SLAM_FLAGS", "UserError", "build_parser", "commands", "main", "messages", "parser"]
