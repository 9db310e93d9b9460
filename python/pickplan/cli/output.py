"""What the command line shows. Results (tables, "wrote ...") go to stdout; the library's progress
and notes go to the ``pickplan`` logger, which the command line shows on stderr:

=================  ==========================================================================
option             shows
=================  ==========================================================================
(default)          progress and notes (INFO), warnings, progress bars on a terminal
``-q/--quiet``     warnings and errors only; no progress bars
``-v/--verbose``   also the library's details (DEBUG)
=================  ==========================================================================

The options are accepted before and after the command (``pickplan -q demo``, ``pickplan demo -q``).
"""

from __future__ import annotations

import argparse
import logging
import sys

LOGGER = "pickplan"


class _CurrentStderr(logging.Handler):
    """Writes to whatever ``sys.stderr`` is when a record arrives (a test may have replaced it)."""

    def emit(self, record: logging.LogRecord) -> None:
        try:
            sys.stderr.write(self.format(record) + "\n")
        except Exception:  # noqa: BLE001 - logging never raises into the caller
            self.handleError(record)


def add_verbosity_options(parser: argparse.ArgumentParser, top: bool = True) -> None:
    """``-v/--verbose`` and ``-q/--quiet`` on ``parser`` and on every subcommand below it; below the
    top they default to "not given", so the flag may stand before or after the command."""
    default = {} if top else {"default": argparse.SUPPRESS}
    group = parser.add_mutually_exclusive_group()
    group.add_argument(
        "-v", "--verbose", action="count", help="show the library's details", **({"default": 0} if top else default)
    )
    group.add_argument(
        "-q",
        "--quiet",
        action="store_true",
        help="show only warnings and errors",
        **({"default": False} if top else default),
    )
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in dict.fromkeys(action.choices.values()):  # aliases map to one parser
                add_verbosity_options(sub, top=False)


def level_of(args: argparse.Namespace) -> int:
    if getattr(args, "quiet", False):
        return logging.WARNING
    return logging.DEBUG if getattr(args, "verbose", 0) else logging.INFO


def configure_logging(level: int) -> None:
    """The ``pickplan`` logger at ``level``, shown on stderr by one handler (a second call replaces
    the level, not the handler)."""
    logger = logging.getLogger(LOGGER)
    logger.setLevel(level)
    if not any(isinstance(h, _CurrentStderr) for h in logger.handlers):
        handler = _CurrentStderr()
        handler.setFormatter(logging.Formatter("%(message)s"))
        logger.addHandler(handler)
