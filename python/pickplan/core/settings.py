"""Python dataclass settings -> the native settings structs with the same field names."""
from __future__ import annotations

from dataclasses import asdict


def to_native(settings, native_type, skip=(), **extra):
    """An instance of ``native_type`` with every dataclass field of ``settings`` (but those named in
    ``skip``: Python-only fields) and ``extra`` copied."""
    out = native_type()
    for name, value in {**asdict(settings), **extra}.items():
        if name not in skip:
            setattr(out, name, value)
    return out
