"""Validation of meta-model files at the door: the parsed JSON is checked field by field (types,
finite values, ranges) before any model is built from it, so a NaN ``sigma_r`` or a string where a
number belongs is an ``InputError`` naming the file and field, never a run computed on it."""

from __future__ import annotations

import math
from typing import Any, Optional

import numpy as np

from pickplan.core.fields import FieldReader, shown

FORMAT = "pickplan.pickup.metamodel"  # the same string as model.FORMAT (kept here: model imports heavy parts)
READABLE_VERSIONS = (2, 3, 4, 5)


def _level(r: FieldReader, lv, f: str) -> None:
    r.table(lv, f)
    r.get(lv, "name", f, r.text)
    for name in ("sigma_r", "sigma_phi"):
        r.get(lv, name, f, r.number, lo=0.0, low_open=True)
    r.get(lv, "rho_grid", f, r.array, ndim=2, lo=0.0, hi=1.0)
    surface = r.table(r.key(lv, "surface", f), f"{f}.surface")
    r.get(surface, "coeffs", f"{f}.surface", r.array, ndim=2)
    for name in ("sg_range", "sc_range"):
        v = r.get(surface, name, f"{f}.surface", r.array, ndim=1)
        if v is not None and (v.shape != (2,) or not v[0] < v[1]):
            r.note(f"{f}.surface.{name}", f"expected [low, high] with low < high, got {v.tolist()}")


def _boundary(r: FieldReader, b, f: str) -> None:
    r.table(b, f)
    for name in ("i", "j"):
        r.get(b, name, f, r.integer, lo=0)
    for name in ("s_g", "s_c"):
        r.get(b, name, f, r.number, lo=0.0)
    for name in ("svm_c", "svm_gamma"):
        r.get(b, name, f, r.number, lo=0.0, low_open=True)
    X = r.array(r.key(b, "X", f), f"{f}.X", ndim=2)
    if X.shape[1:] != (3,):
        r.fail(f"{f}.X", f"expected (N, 3) normalized poses, got shape {X.shape}")
    for name in ("y", "simulated"):
        v = r.get(b, name, f, r.array, ndim=1, lo=0.0, hi=1.0)
        if v is not None and (v.shape != (len(X),) or np.any(v != np.round(v))):
            r.note(f"{f}.{name}", f"expected {len(X)} labels of 0 or 1")
    if b.get("svm_metric") is not None:
        m = r.array(b["svm_metric"], f"{f}.svm_metric", ndim=2)
        if m.shape != (3, 3):
            r.fail(f"{f}.svm_metric", "expected a 3 x 3 matrix")


def validate_metamodel(d: Any, path: Optional[str] = None) -> dict:
    """``d`` (a parsed meta-model JSON) unchanged when every field a reader uses is well formed;
    InputError naming ``path`` and every field at fault otherwise."""
    r = FieldReader(path)
    with r:
        r.table(d, "")
        if d.get("format") != FORMAT:
            r.fail("format", f"not a pickplan meta-model (format={shown(d.get('format'))})")
        if d.get("version") not in READABLE_VERSIONS:
            r.fail("version", f"unsupported meta-model version {shown(d.get('version'))}")
        r.get(d, "part", "", r.text)
        for name in ("sg_grid", "sc_grid"):
            grid = r.get(d, name, "", r.array, ndim=1, lo=0.0)
            if grid is not None and (len(grid) < 2 or np.any(np.diff(grid) <= 0)):
                r.note(name, "expected at least 2 increasing speeds")
        domain = r.get(d, "domain", "", r.table, default={})
        for name in ("r_max", "phi_max"):
            r.get(domain, name, "domain", r.number, required=False, lo=0.0, low_open=True)
        r.get(d, "n_queries", "", r.integer, lo=1)
        with r.part():
            degree = r.key(d, "surface_degree")
            if not isinstance(degree, list) or len(degree) != 2:
                r.fail("surface_degree", f"expected [degree_sg, degree_sc], got {shown(degree)}")
            for k, v in enumerate(degree):
                r.attempt(r.integer, v, f"surface_degree[{k}]", lo=1)
        for name, low, high in (("conservative_z", 0.0, math.inf), ("lapse", 0.0, 1.0)):
            if d.get(name) is not None:
                r.attempt(r.number, d[name], name, lo=low, hi=high)
        for f, lv in r.get(d, "levels", "", r.items, default=[]):
            r.attempt(_level, r, lv, f)
        for f, b in r.get(d, "boundaries", "", r.items, default=[]):
            r.attempt(_boundary, r, b, f)
    return d
