"""Error types for bad input. ``InputError`` is a ``ValueError`` (existing ``except ValueError``
code keeps working) that names the file and the field at fault."""
from __future__ import annotations

from typing import Optional


class InputError(ValueError):
    """A file or value pickplan was given is wrong: the message names the file (when there is one)
    and the field, e.g. ``scenes/s.json: objects[2].pose: not a rigid transform``."""

    def __init__(self, message: str, path: Optional[str] = None, field: Optional[str] = None):
        self.path, self.field, self.detail = path, field, message
        where = ": ".join(str(p) for p in (path, field) if p)
        super().__init__(f"{where}: {message}" if where else message)
