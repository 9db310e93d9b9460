"""Validation of meta-model files at the door: the parsed JSON is checked field by field (types,
finite values, ranges) before any model is built from it, so a NaN ``sigma_r`` or a string where a
number belongs is an ``InputError`` naming the file and field, never a run computed on it."""
from __future__ import annotations

import math
from typing import Any, Optional

import numpy as np

from pickplan.core.errors import InputError

FORMAT = "pickplan.pickup.metamodel"  # the same string as model.FORMAT (kept here: model imports heavy parts)
READABLE_VERSIONS = (2, 3, 4, 5)


class _Checker:
    def __init__(self, path: Optional[str]):
        self.path = path

    def fail(self, field: str, message: str):
        raise InputError(message, path=self.path, field=field)

    def obj(self, value, field: str) -> dict:
        if not isinstance(value, dict):
            self.fail(field, f"expected a JSON object, got {type(value).__name__}")
        return value

    def key(self, d: dict, name: str, field: str):
        if name not in d:
            self.fail(field, f"missing key {name!r}")
        return d[name]

    def objects(self, d: dict, name: str):
        """(field name, object) for each entry of the list ``d[name]``."""
        value = self.key(d, name, name)
        if not isinstance(value, list):
            self.fail(name, f"expected a list, got {type(value).__name__}")
        return [(f"{name}[{i}]", self.obj(v, f"{name}[{i}]")) for i, v in enumerate(value)]

    def number(self, value, field: str, low: float = -math.inf, high: float = math.inf,
               low_open: bool = False) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            self.fail(field, f"expected a number, got {type(value).__name__} {value!r:.40}")
        v = float(value)
        if not math.isfinite(v):
            self.fail(field, f"expected a finite number, got {v}")
        if v < low or v > high or (low_open and v == low):
            self.fail(field, f"{v} is outside {'(' if low_open else '['}{low}, {high}]")
        return v

    def integer(self, value, field: str, low: int = 0) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            self.fail(field, f"expected an integer, got {type(value).__name__} {value!r:.40}")
        if value < low:
            self.fail(field, f"expected an integer >= {low}, got {value}")
        return value

    def array(self, value, field: str, ndim: int, low: float = -math.inf, high: float = math.inf) -> np.ndarray:
        stack = [value]
        while stack:  # iterative: nested lists must not exhaust the stack
            v = stack.pop()
            if isinstance(v, list):
                stack.extend(v)
            elif isinstance(v, bool) or not isinstance(v, (int, float)):
                self.fail(field, f"expected numbers, got {type(v).__name__} {v!r:.40}")
        try:
            arr = np.asarray(value, dtype=float)
        except ValueError:
            self.fail(field, "expected a rectangular array of numbers (rows of one length)")
        if arr.ndim != ndim:
            self.fail(field, f"expected a {ndim}-D array, got shape {arr.shape}")
        if not np.all(np.isfinite(arr)):
            self.fail(field, "contains NaN or infinity")
        if arr.size and (arr.min() < low or arr.max() > high):
            self.fail(field, f"values must lie in [{low}, {high}], got {arr.min()}..{arr.max()}")
        return arr


def validate_metamodel(d: Any, path: Optional[str] = None) -> dict:
    """``d`` (a parsed meta-model JSON) unchanged when every field a reader uses is well formed;
    InputError naming ``path`` and the field otherwise."""
    c = _Checker(path)
    c.obj(d, "(top level)")
    if d.get("format") != FORMAT:
        c.fail("format", f"not a pickplan meta-model (format={d.get('format')!r:.60})")
    if d.get("version") not in READABLE_VERSIONS:
        c.fail("version", f"unsupported meta-model version {d.get('version')!r:.40}")
    if not isinstance(c.key(d, "part", "part"), str):
        c.fail("part", "expected a part name (string)")
    for name in ("sg_grid", "sc_grid"):
        grid = c.array(c.key(d, name, name), name, 1, low=0.0)
        if len(grid) < 2 or np.any(np.diff(grid) <= 0):
            c.fail(name, "expected at least 2 increasing speeds")
    domain = c.obj(c.key(d, "domain", "domain"), "domain")
    for name in ("r_max", "phi_max"):
        if name in domain:
            c.number(domain[name], f"domain.{name}", low=0.0, low_open=True)
    c.integer(c.key(d, "n_queries", "n_queries"), "n_queries", low=1)
    degree = c.key(d, "surface_degree", "surface_degree")
    if not isinstance(degree, list) or len(degree) != 2:
        c.fail("surface_degree", f"expected [degree_sg, degree_sc], got {degree!r:.40}")
    for k, v in enumerate(degree):
        c.integer(v, f"surface_degree[{k}]", low=1)
    for name, low, high in (("conservative_z", 0.0, math.inf), ("lapse", 0.0, 1.0)):
        if d.get(name) is not None:
            c.number(d[name], name, low, high)
    for f, lv in c.objects(d, "levels"):
        if not isinstance(c.key(lv, "name", f"{f}.name"), str):
            c.fail(f"{f}.name", "expected a string")
        for name in ("sigma_r", "sigma_phi"):
            c.number(c.key(lv, name, f"{f}.{name}"), f"{f}.{name}", low=0.0, low_open=True)
        c.array(c.key(lv, "rho_grid", f"{f}.rho_grid"), f"{f}.rho_grid", 2, 0.0, 1.0)
        surface = c.obj(c.key(lv, "surface", f"{f}.surface"), f"{f}.surface")
        c.array(c.key(surface, "coeffs", f"{f}.surface.coeffs"), f"{f}.surface.coeffs", 2)
        for name in ("sg_range", "sc_range"):
            r = c.array(c.key(surface, name, f"{f}.surface.{name}"), f"{f}.surface.{name}", 1)
            if r.shape != (2,) or not r[0] < r[1]:
                c.fail(f"{f}.surface.{name}", f"expected [low, high] with low < high, got {r.tolist()}")
    for f, b in c.objects(d, "boundaries"):
        for name in ("i", "j"):
            c.integer(c.key(b, name, f"{f}.{name}"), f"{f}.{name}")
        for name in ("s_g", "s_c"):
            c.number(c.key(b, name, f"{f}.{name}"), f"{f}.{name}", low=0.0)
        for name in ("svm_c", "svm_gamma"):
            c.number(c.key(b, name, f"{f}.{name}"), f"{f}.{name}", low=0.0, low_open=True)
        X = c.array(c.key(b, "X", f"{f}.X"), f"{f}.X", 2)
        if X.shape[1:] != (3,):
            c.fail(f"{f}.X", f"expected (N, 3) normalized poses, got shape {X.shape}")
        for name in ("y", "simulated"):
            v = c.array(c.key(b, name, f"{f}.{name}"), f"{f}.{name}", 1, 0.0, 1.0)
            if v.shape != (len(X),) or np.any(v != np.round(v)):
                c.fail(f"{f}.{name}", f"expected {len(X)} labels of 0 or 1")
        if b.get("svm_metric") is not None and c.array(b["svm_metric"], f"{f}.svm_metric", 2).shape != (3, 3):
            c.fail(f"{f}.svm_metric", "expected a 3 x 3 matrix")
    return d
