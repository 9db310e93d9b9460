"""Exit codes that mean one thing each, and the one place that turns exceptions into them.

=====  =====================================================================================
code   meaning
=====  =====================================================================================
0      success
1      ran, but no plan: infeasible, no goal, or the plan failed its success test
2      bad input: a file, a field or an option is wrong (the message names it); usage errors
3      internal error: a bug in pickplan (one line; ``PICKPLAN_TRACEBACK=1`` prints the traceback)
=====  =====================================================================================
"""

from __future__ import annotations

import enum
import os
import re
import socket
import sys
import tempfile
import traceback
from typing import Callable
from pickplan.core.errors import InputError
from pickplan.core.robots import check_description


class OutputKind(enum.Enum):
    """What an output option names: a folder (created when missing) or one file (``out_kind`` in a
    command's parser defaults; ``--out`` is a folder unless a command says otherwise)."""

    folder = "folder"
    file = "file"


class ExitCode(enum.IntEnum):
    OK = 0
    NO_PLAN = 1
    BAD_INPUT = 2
    INTERNAL_ERROR = 3


# Exceptions that mean the user gave something wrong (ValueError covers InputError, JSON and
# Unicode decoding; RecursionError: input nested deeper than a parser recurses).
BAD_INPUT_ERRORS = (ValueError, KeyError, OSError, RecursionError, ImportError)
RAY_CONNECT_SECONDS = 2.0


def run_command(name: str, handler: Callable, args) -> int:
    """``handler(args)`` as an exit code; a bad-input exception prints one line naming the
    problem (exit 2), any other exception one line saying it is a bug (exit 3), never a bare
    traceback."""
    try:
        check_arguments(args)
        return int(handler(args) or ExitCode.OK)
    except KeyboardInterrupt:
        print(f"pickplan {name}: interrupted", file=sys.stderr)
        return 130
    except BAD_INPUT_ERRORS as exc:
        message = str(exc) if not isinstance(exc, KeyError) else f"missing key {exc}"
        if isinstance(exc, RecursionError):
            message = f"input nested too deeply ({exc})"
        print(f"pickplan {name}: error: {message}", file=sys.stderr)
        return ExitCode.BAD_INPUT
    except Exception as exc:  # noqa: BLE001 - the last resort: one line instead of a traceback
        if os.environ.get("PICKPLAN_TRACEBACK"):
            traceback.print_exc()
        print(
            f"pickplan {name}: internal error ({type(exc).__name__}: {exc}); this is a bug in pickplan, "
            f"PICKPLAN_TRACEBACK=1 prints where",
            file=sys.stderr,
        )
        return ExitCode.INTERNAL_ERROR


def check_arguments(args) -> None:
    """Options that name files and folders (and ``--robot``: the description, as ``robots check``
    does), checked before any work starts."""

    out = getattr(args, "out", None)
    if isinstance(out, str):
        check_output(out, "out", getattr(args, "out_kind", OutputKind.folder))
    html = getattr(args, "html", None)
    if isinstance(html, str):
        check_output(html, "html", OutputKind.file)
    robot = getattr(args, "robot", None)
    if isinstance(robot, str):  # every problem `pickplan robots check` names, before a scene is made for it
        _, problems = check_description(robot)
        if problems:
            raise InputError(problems=problems)
    for option in ("scene", "metamodel"):
        value = getattr(args, option, None)
        if isinstance(value, str) and os.path.isdir(value):
            raise InputError(f"'{value}' is a folder; expected a file", field=f"--{option}")
    ray = getattr(args, "ray", None)
    if isinstance(ray, str):
        check_ray_address(ray)


def check_output(path: str, option: str, kind: OutputKind) -> None:
    """InputError naming ``--option`` unless ``path`` can be written as a ``kind``: not a dangling
    symbolic link, not a file where a folder goes (or the reverse), and the nearest folder of it
    that exists takes a new file (tried, not guessed from permission bits: root ignores those, a
    read-only file system does not)."""
    field = f"--{option}"
    if os.path.islink(path) and not os.path.exists(path):
        raise InputError(f"'{path}' is a symbolic link to '{os.readlink(path)}', which does not exist", field=field)
    if kind is OutputKind.folder and os.path.exists(path) and not os.path.isdir(path):
        raise InputError(f"'{path}' is a file; expected a folder (it is created when missing)", field=field)
    if kind is OutputKind.file and os.path.isdir(path):
        raise InputError(f"'{path}' is a folder; expected a file", field=field)
    folder = os.path.abspath(path if kind is OutputKind.folder else os.path.dirname(os.path.abspath(path)))
    while not os.path.lexists(folder):
        folder = os.path.dirname(folder)
    if not os.path.isdir(folder):
        what = "a symbolic link that leads nowhere" if not os.path.exists(folder) else "a file"
        raise InputError(f"cannot create '{path}': '{folder}' is {what}", field=field)
    try:
        fd, probe = tempfile.mkstemp(prefix=".pickplan-write-check-", dir=folder)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise InputError(
            f"cannot write '{path}': the folder '{folder}' does not take new files ({exc.strerror})", field=field
        ) from None


def check_ray_address(address: str) -> None:
    """'local', 'auto', or HOST:PORT (optionally ray://HOST:PORT) that accepts a connection within
    ``RAY_CONNECT_SECONDS``: Ray itself retries for ~21 s before it gives up."""

    if address in ("local", "auto"):
        return
    m = re.fullmatch(r"(?:ray://)?(\[[0-9a-fA-F:]+\]|[A-Za-z0-9.\-]+):(\d{1,5})", address)
    if not m or not 0 < int(m.group(2)) < 65536:
        raise InputError(f"expected 'local', 'auto' or HOST:PORT, got {address!r}", field="--ray")
    host, port = m.group(1).strip("[]"), int(m.group(2))
    try:
        socket.create_connection((host, port), timeout=RAY_CONNECT_SECONDS).close()
    except OSError as exc:
        raise InputError(f"no Ray cluster answers at {host}:{port} ({exc})", field="--ray") from None
