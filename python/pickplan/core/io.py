"""Files: atomic output (a result file is either complete or absent, never half-written), the
cache folder, and derived files named by their content.

- ``atomic_open`` / ``write_json`` / ``write_text`` / ``write_bytes``: results and cache entries;
- ``cache_dir``: ``$PICKPLAN_CACHE_DIR`` or ``~/.cache/pickplan`` (SDF grids, simulated grasps,
  meta-models);
- ``content_file``: a file made from text (a URDF cut from another, an OBJ of collision parts) in
  the per-user temp folder, named by the hash of its content and written once;
- ``cache_entry``: where to read a cache entry from: the user's cache folder, else the copy shipped
  with pickplan (``assets/cache``: what depends only on the built-in objects and robots, made by
  ``make builtin-cache``), whose SHA-256 in ``assets/cache/manifest.json`` is checked on every read.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import tempfile
import warnings
from typing import Any, Iterator, Optional

from pickplan.core.errors import InputError
from pickplan.core.paths import assets_dir


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


CACHE_ENV = "PICKPLAN_CACHE_DIR"


def cache_dir(*parts: str) -> str:
    """``$PICKPLAN_CACHE_DIR`` (default ``~/.cache/pickplan``), joined with ``parts``."""
    root = os.environ.get(CACHE_ENV) or os.path.join(os.path.expanduser("~"), ".cache", "pickplan")
    return os.path.join(root, *parts)


SHIPPED_MANIFEST = "manifest.json"
SHIPPED_FORMAT = 1


def shipped_dir() -> str:
    """The cache entries shipped with pickplan (``assets/cache``), laid out as the cache folder."""
    return os.path.join(assets_dir(), "cache")


def file_sha256(path: str) -> str:
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def read_manifest(folder: str) -> dict:
    """The shipped entries listed in ``folder/manifest.json``: relative path -> {"sha256", "label"};
    empty when there is no manifest (a source tree before ``make builtin-cache``)."""
    path = os.path.join(folder, SHIPPED_MANIFEST)
    if not os.path.isfile(path):
        return {}
    data = read_json(path, "shipped cache manifest")
    if not isinstance(data, dict) or data.get("format") != SHIPPED_FORMAT or not isinstance(data.get("entries"), dict):
        raise InputError(f"expected format {SHIPPED_FORMAT} with an 'entries' table", path=path, field="format")
    return data["entries"]


def cache_entry(*parts: str, label: str = "", shipped: Optional[str] = None) -> Optional[str]:
    """The file to read the cache entry ``cache_dir(*parts)`` from: that file when the user's cache
    holds it, else the copy shipped with pickplan (``shipped``, default ``shipped_dir()``) when its
    manifest lists it and its SHA-256 matches; else None: the caller computes the entry and writes it
    to ``cache_dir(*parts)``. Never trusted silently: a shipped copy that fails its checksum is not
    used (a warning says so), nor is a shipped entry of the same ``label`` (an object's name) under
    another name: it was made by another version of the generator (a warning says so)."""
    own = cache_dir(*parts)
    if os.path.isfile(own):
        return own
    folder = shipped_dir() if shipped is None else shipped
    entries = read_manifest(folder)
    name = "/".join(parts)
    entry = entries.get(name)
    if entry is None:
        stale = [
            n
            for n, e in entries.items()
            if label and e.get("label") == label and os.path.dirname(n) == os.path.dirname(name)
        ]
        if stale:
            warnings.warn(
                f"the shipped {os.path.dirname(name) or 'cache'} data of {label} was made by another "
                f"version of its generator ({stale[0]}, this version asks for {name}): computing it",
                stacklevel=2,
            )
        return None
    path = os.path.join(folder, *parts)
    if not os.path.isfile(path) or file_sha256(path) != entry.get("sha256"):
        warnings.warn(f"shipped cache entry {path}: missing or checksum mismatch (corrupt): computing it", stacklevel=2)
        return None
    return path


def content_file(text: str, folder: str, suffix: str, stem: str = "", header: str = "") -> str:
    """The path of a file holding ``header + text`` in the per-user temp folder
    ``pickplan-UID/folder``, named ``STEM-HASH.SUFFIX`` (``HASH``: 16 hex digits of the SHA-1 of
    ``text``); written atomically when it is not there yet, so equal content is written once."""
    digest = hashlib.sha1(text.encode()).hexdigest()[:16]
    user = os.getuid() if hasattr(os, "getuid") else 0
    path = os.path.join(
        tempfile.gettempdir(), f"pickplan-{user}", folder, f"{stem}-{digest}{suffix}" if stem else f"{digest}{suffix}"
    )
    if not os.path.isfile(path):
        with atomic_open(path, "w") as f:
            f.write(header + text)
    return path


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
