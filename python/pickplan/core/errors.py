"""Error types for bad input. ``InputError`` is a ``ValueError`` (existing ``except ValueError``
code keeps working) that names the file and the field at fault, and carries every problem found
(``problems``) when a reader collected more than one (``core.fields.FieldReader``)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable, Optional, Tuple


@dataclass(frozen=True)
class Problem:
    """One thing wrong with an input: the file (when there is one), the field and what is wrong."""

    field: str
    message: str
    path: Optional[str] = None

    def __str__(self) -> str:  # without the file: a list of one file's problems names it once
        return f"{self.field}: {self.message}" if self.field else self.message


class InputError(ValueError):
    """A file or value pickplan was given is wrong: the message names the file (when there is one)
    and the field, e.g. ``scenes/s.json: objects[2].pose: not a rigid transform``; several
    problems of one file read ``FILE: FIELD: MESSAGE; FIELD: MESSAGE``."""

    def __init__(
        self,
        message: str = "",
        path: Optional[str] = None,
        field: Optional[str] = None,
        problems: Iterable[Problem] = (),
    ):
        problems = tuple(problems) or (Problem(field or "", message, None if path is None else str(path)),)
        self.problems: Tuple[Problem, ...] = problems
        first = problems[0]
        self.path, self.field, self.detail = first.path, first.field or None, first.message
        super().__init__(_text(problems))


def _text(problems: Tuple[Problem, ...]) -> str:
    groups: dict = {}
    for p in problems:
        groups.setdefault(p.path, []).append(str(p))
    return "; ".join(f"{path}: " + "; ".join(items) if path else "; ".join(items) for path, items in groups.items())
