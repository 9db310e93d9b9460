"""Atomic file output: a result file is either complete or absent, never half-written."""
from __future__ import annotations

import contextlib
import json
import os
import tempfile
from typing import Any, Iterator

from pickplan.core.errors import InputError


@contextlib.contextmanager
def atomic_open(path: str, mode: str = "w", **kwargs) -> Iterator[Any]:
    """Write to a temporary file in the target folder, then rename it over ``path``."""
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    os.makedirs(folder, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".tmp-", suffix=os.path.basename(path), dir=folder)
    try:
        # mkstemp makes owner-only files; a result keeps the mode of the file it replaces, else rw-r--r--.
        os.chmod(tmp, os.stat(path).st_mode & 0o777 if os.path.exists(path) else 0o644)
        with os.fdopen(fd, mode, **kwargs) as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def write_json(path: str, data: Any) -> None:
    """Indented, key-sorted JSON (results people read and diff)."""
    with atomic_open(path, "w", encoding="utf-8") as f:
        json.dump(data, f, indent=2, sort_keys=True)


def write_text(path: str, text: str) -> None:
    with atomic_open(path, "w", encoding="utf-8") as f:
        f.write(text)


def write_bytes(path: str, data: bytes) -> None:
    with atomic_open(path, "wb") as f:
        f.write(data)


def read_json(path: str, what: str = "JSON file") -> Any:
    """The parsed JSON at ``path``; InputError naming the file for a missing file, a folder, bytes
    that are not UTF-8, malformed JSON, an integer too long to convert or nesting too deep for the
    decoder."""
    path = os.fspath(path)
    if os.path.isdir(path):
        raise InputError(f"expected a {what}, got a folder", path=path)
    if not os.path.isfile(path):
        raise FileNotFoundError(f"{what} not found: {path}")
    try:
        with open(path, "r", encoding="utf-8") as f:
            return json.load(f)
    except UnicodeDecodeError as exc:
        raise InputError(f"not UTF-8 text ({exc.reason} at byte {exc.start})", path=path) from None
    except ValueError as exc:  # JSONDecodeError, or an integer of more digits than Python converts
        raise InputError(f"malformed JSON: {exc}", path=path) from None
    except RecursionError:  # the decoder recurses once per level of nesting
        raise InputError("malformed JSON: nested too deeply", path=path) from None
