"""One reader of input fields for every file kind pickplan reads (robot descriptions, scenes,
observations, pick-up problems, meta-models): typed reads with physical ranges, every problem
recorded as a ``Problem`` (file, field, message) and raised together as one ``InputError``.

A failed read records its problem and skips the rest of the enclosing ``part`` (what depends on
the value cannot be checked), then reading goes on with the next part, so a file's independent
mistakes are all named at once::

    r = FieldReader(path)
    with r:                                   # raises InputError with every problem at the end
        d = r.table(data, "", known=("gamma", "limits"))
        with r.part():
            gamma = r.number(r.key(d, "gamma"), "gamma", lo=0.0, hi=1.0, low_open=True)
        limits = r.get(d, "limits", "", r.table, default={}, required=False)
"""

from __future__ import annotations

import contextlib
import math
from typing import Any, Callable, Iterable, Iterator, List, Optional

import numpy as np

from pickplan.core.errors import InputError, Problem

MAX_SHOWN = 40  # characters of a bad value quoted in a message


class _Skip(Exception):
    """Internal: a read failed; the enclosing part is abandoned (never leaves a ``FieldReader``)."""


def shown(value: Any, limit: int = MAX_SHOWN) -> str:
    """``value`` for a message: its type and a short repr; never the whole of a huge value (a
    5,000-digit integer has no repr in Python 3.11, a 1 MB string would flood the terminal)."""
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 64:
        return f"an integer of about {int(value.bit_length() * math.log10(2)) + 1} digits"
    if isinstance(value, np.ndarray):
        return f"an array of shape {value.shape} ({value.dtype})"
    text = repr(value)
    text = text if len(text) <= limit else text[:limit] + "..."
    return f"{type(value).__name__} {text}"


def join(where: str, key) -> str:
    """The dotted field name of ``key`` in the table at ``where``."""
    if isinstance(key, int):
        return f"{where}[{key}]"
    return f"{where}.{key}" if where else str(key)


def _is_number(v) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_))


class FieldReader:
    """Reads the fields of one input (``path``: the file, None for values given in memory)."""

    def __init__(self, path: Optional[str] = None):
        self.path = None if path is None else str(path)
        self.problems: List[Problem] = []

    # --- problems ---------------------------------------------------------------------------------
    def note(self, field: str, message: str) -> None:
        """Record a problem and go on (the value is still usable for the checks that follow)."""
        problem = Problem(field, message, self.path)
        if problem not in self.problems:
            self.problems.append(problem)

    def fail(self, field: str, message: str):
        """Record a problem and abandon the enclosing part."""
        self.note(field, message)
        raise _Skip()

    @staticmethod
    def skip():
        """Abandon the enclosing part (its problems are recorded already)."""
        raise _Skip()

    @contextlib.contextmanager
    def part(self) -> Iterator[None]:
        """A block whose failed read does not stop the reads after it."""
        try:
            yield
        except _Skip:
            pass

    def attempt(self, read: Callable, *args, default=None, **kwargs):
        """``read(*args, **kwargs)``, or ``default`` when it failed (its problem is recorded)."""
        try:
            return read(*args, **kwargs)
        except _Skip:
            return default

    def check(self) -> None:
        """Raise every problem recorded so far (before work that needs all the values)."""
        if self.problems:
            raise InputError(problems=self.problems)

    def __enter__(self) -> "FieldReader":
        return self

    def __exit__(self, kind, exc, tb) -> bool:
        if kind is None or kind is _Skip:
            self.check()
            return kind is _Skip
        return False

    # --- structure --------------------------------------------------------------------------------
    def table(self, value, where: str, known: Optional[Iterable[str]] = None) -> dict:
        """A mapping (JSON object, TOML table); unknown keys are named (each one)."""
        if not isinstance(value, dict):
            self.fail(where or "(top level)", f"expected an object (a table of keys), got {shown(value)}")
        if known is not None:
            known = sorted(known)
            for key in sorted(set(value) - set(known), key=str):
                self.note(join(where, key), f"unknown key (expected one of {known})")
        return value

    def key(self, table: dict, name: str, where: str = ""):
        """``table[name]``; the field is named missing when it is not there."""
        if name not in table:
            self.fail(join(where, name), "missing")
        return table[name]

    def get(self, table: dict, name: str, where: str, read: Callable, default=None, required: bool = True, **kwargs):
        """``read(table[name], field, **kwargs)``; ``default`` when the key is absent (named missing
        when ``required``) or its value is wrong (named)."""
        if name not in table:
            if required:
                self.note(join(where, name), "missing")
            return default
        return self.attempt(read, table[name], join(where, name), default=default, **kwargs)

    def items(self, value, where: str) -> list:
        """(field, item) for each entry of a list."""
        if not isinstance(value, list):
            self.fail(where, f"expected a list, got {shown(value)}")
        return [(f"{where}[{i}]", v) for i, v in enumerate(value)]

    # --- values -----------------------------------------------------------------------------------
    def number(
        self,
        value,
        where: str,
        lo: float = -math.inf,
        hi: float = math.inf,
        positive: bool = False,
        low_open: bool = False,
        unit: str = "",
    ) -> float:
        """A finite real number in [lo, hi] (``low_open``: lo excluded; ``positive``: > 0)."""
        if not _is_number(value):
            self.fail(where, f"expected a number, got {shown(value)}")
        try:
            v = float(value)
        except OverflowError:
            self.fail(where, f"expected a number, got {shown(value)}: too large")
        if not math.isfinite(v):
            self.fail(where, f"expected a finite number, got {v}")
        if positive and not v > 0:
            self.fail(where, f"expected a positive number, got {v}")
        if v < lo or v > hi or (low_open and v == lo):
            unit = f" {unit}" if unit else ""
            self.fail(where, f"{v}{unit} is outside {'(' if low_open else '['}{float(lo)}, {float(hi)}]{unit}")
        return v

    def integer(self, value, where: str, lo: Optional[int] = None, hi: Optional[int] = None) -> int:
        """An integer (not a bool, not a float) in [lo, hi]."""
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
            self.fail(where, f"expected an integer, got {shown(value)}")
        value = int(value)
        if (lo is not None and value < lo) or (hi is not None and value > hi):
            bounds = f"[{'-inf' if lo is None else lo}, {'inf' if hi is None else hi}]"
            self.fail(where, f"expected an integer in {bounds}, got {shown(value) if abs(value) > 1e18 else value}")
        return value

    def text(self, value, where: str, allow_empty: bool = False) -> str:
        if not isinstance(value, str) or (not value and not allow_empty) or "\x00" in value:
            self.fail(where, f"expected a non-empty string, got {shown(value)}")
        return value

    def choice(self, value, where: str, options: Iterable[str]) -> str:
        options = list(options)
        if not isinstance(value, str) or value not in options:
            spelled = (
                ", ".join(repr(o) for o in options[:-1]) + f" or {options[-1]!r}"
                if len(options) > 1
                else repr(options[0])
            )
            self.fail(where, f"expected {spelled}, got {shown(value)}")
        return value

    def vector(self, value, where: str, n: Optional[int] = None, **bounds) -> tuple:
        """A list of ``n`` numbers (each checked as ``number`` with ``bounds``)."""
        if not isinstance(value, (list, tuple)) or (n is not None and len(value) != n):
            got = f"{len(value)} values" if isinstance(value, (list, tuple)) else shown(value)
            self.fail(where, f"expected a list of {n if n is not None else 'some'} numbers, got {got}")
        out = [self.attempt(self.number, v, f"{where}[{i}]", **bounds) for i, v in enumerate(value)]
        if any(v is None for v in out):
            self.skip()
        return tuple(out)

    def array(
        self,
        value,
        where: str,
        shape: Optional[tuple] = None,
        ndim: Optional[int] = None,
        lo: float = -math.inf,
        hi: float = math.inf,
        finite: bool = True,
    ) -> np.ndarray:
        """A float array from nested lists of numbers or a numeric numpy array (no strings, bools or
        complex values, which numpy would convert silently); ``shape`` entries of -1 are free."""
        if isinstance(value, np.ndarray):
            if value.dtype.kind not in "fiu":
                self.fail(where, f"expected numbers, got an array of {value.dtype}")
        else:
            stack = [value]
            while stack:  # iterative: a deeply nested list must not exhaust the stack
                v = stack.pop()
                if isinstance(v, (list, tuple)):
                    stack.extend(v)
                elif not _is_number(v):
                    self.fail(where, f"expected numbers, got {shown(v)}")
        try:
            arr = np.asarray(value, dtype=float)
        except (TypeError, ValueError, OverflowError):
            self.fail(where, "expected a rectangular array of numbers (rows of one length)")
        if ndim is not None and arr.ndim != ndim:
            self.fail(where, f"expected a {ndim}-D array, got shape {arr.shape}")
        if shape is not None and (arr.ndim != len(shape) or any(s not in (-1, a) for s, a in zip(shape, arr.shape))):
            want = "(" + ", ".join("N" if s == -1 else str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"
            self.fail(where, f"expected shape {want}, got {arr.shape}")
        if finite and not np.all(np.isfinite(arr)):
            self.fail(where, "contains NaN or infinity")
        if arr.size and (arr.min() < lo or arr.max() > hi):
            self.fail(where, f"values must lie in [{float(lo)}, {float(hi)}], got {arr.min()}..{arr.max()}")
        return arr
