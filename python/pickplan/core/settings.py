"""Settings plumbing shared by every layer: option enums with string values, Python dataclass
settings whose defaults are the native structs' (written once, in C++), and Python dataclass
settings -> the native settings structs with the same field names."""

from __future__ import annotations

import enum
import typing
from dataclasses import asdict, fields, is_dataclass

import numpy as np


class Option(str, enum.Enum):
    """An option or status with a string value: equal to, hashed and serialised (JSON) as that
    value, so old files and the CLI keep their spellings. ``parse`` converts a spelling once, at an
    API boundary. Members with a native counterpart (``py::enum_``) share its member names."""

    def __str__(self) -> str:
        return self.value

    def __format__(self, spec: str) -> str:
        return format(self.value, spec)

    def __hash__(self) -> int:  # as the value's, so a member and its spelling are one dict key
        return hash(self.value)

    @classmethod
    def parse(cls, value, what: str = ""):
        """The member spelt ``value`` (a member passes through); otherwise a ValueError naming
        the valid spellings."""
        if isinstance(value, cls):
            return value
        try:
            return cls(value)
        except ValueError:
            valid = ", ".join(repr(m.value) for m in cls)
            raise ValueError(f"unknown {what or cls.__name__} {value!r}; valid: {valid}") from None

    @classmethod
    def from_native(cls, native):
        """The member named as the native enum value ``native``."""
        return cls[native.name]


def native_defaults(native_type):
    """Class decorator, applied under ``@dataclass``: every annotated field the class leaves without a
    default takes the default of the field of that name of a default-constructed ``native_type`` (a
    native enum as the member of the field's Option of the same name, a vector or list as a tuple),
    so each default is written once, in the C++ struct. Python-only fields, and fields whose Python
    type differs (None for "derive it"), keep defaults of their own."""

    def apply(cls):
        native = native_type()
        hints = typing.get_type_hints(cls)
        for name in cls.__dict__.get("__annotations__", {}):
            if name in cls.__dict__ or typing.get_origin(hints[name]) is typing.ClassVar:
                continue
            if not hasattr(native, name):
                raise TypeError(f"{cls.__name__}.{name} has no default and {native_type.__name__} no such field")
            setattr(cls, name, _python_value(getattr(native, name), hints[name]))
        return cls

    return apply


def _python_value(value, hint):
    """A native struct's field value as the Python dataclass field typed ``hint`` holds it."""
    if isinstance(hint, type) and issubclass(hint, Option):
        return hint[value.name]
    if isinstance(value, np.ndarray):
        return tuple(value.tolist())
    if isinstance(value, (list, tuple)):
        return tuple(tuple(v) if isinstance(v, (list, tuple)) else v for v in value)
    return value


def native_value(value, native_default):
    """``value`` as the native struct field holding ``native_default`` expects it: an Option
    becomes the member of the same name of the field's ``py::enum_``."""
    if isinstance(value, Option):
        return getattr(type(native_default), value.name)
    return value


def _field_values(settings, skip=()) -> dict:
    """``asdict(settings)`` less the fields in ``skip``: without its deep copy when no other field holds a
    dataclass (50-100 us a call, paid by every plan and every success test)."""
    values = {f.name: getattr(settings, f.name) for f in fields(settings) if f.name not in skip}
    if any(
        is_dataclass(v) or isinstance(v, dict) or (isinstance(v, (list, tuple)) and any(map(is_dataclass, v)))
        for v in values.values()
    ):
        return {k: v for k, v in asdict(settings).items() if k not in skip}
    return values


def to_native(settings, native_type, skip=(), **extra):
    """An instance of ``native_type`` with every dataclass field of ``settings`` (but those named in
    ``skip``: Python-only fields) and ``extra`` copied."""
    out = native_type()
    for name, value in {**_field_values(settings, skip), **extra}.items():
        if name not in skip:
            setattr(out, name, native_value(value, getattr(out, name)))
    return out
