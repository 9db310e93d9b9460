"""The native code keeps the package's layering: each folder of cpp/include/pickplan, cpp/src and
bindings is a layer with a namespace of its own, and every include points down (or sideways within
the layer). Ranks: core 0, geometry 1, then perception, omg and pickup side by side at 2 (none
includes another: perception builds fields from depth images, omg and pickup are two planners)."""

import os
import re

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
NATIVE_LAYERS = {"core": 0, "geometry": 1, "perception": 2, "omg": 2, "pickup": 2}
# folders whose direct sub-folders are layers (bindings/common.hpp and module.cpp sit above them)
LAYERED_DIRS = ("cpp/include/pickplan", "cpp/src", "bindings")
INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.M)
NAMESPACE = re.compile(r"^namespace (pickplan(?:::\w+)*) \{", re.M)


def _layered_files(root: str):
    """(path, layer) for every C++ file in a layer folder under root."""
    for top in LAYERED_DIRS:
        base = os.path.join(root, top)
        if not os.path.isdir(base):
            continue
        for layer in sorted(os.listdir(base)):
            folder = os.path.join(base, layer)
            if not os.path.isdir(folder):
                continue
            for dirpath, _, files in os.walk(folder):
                for f in sorted(files):
                    if f.endswith((".hpp", ".cpp", ".h")):
                        yield os.path.join(dirpath, f), layer


def _included_layer(root: str, path: str, target: str):
    """The layer an include names: "pickplan/<layer>/..." or a path relative to the file."""
    if target.startswith("pickplan/"):
        return target.split("/")[1]
    resolved = os.path.relpath(os.path.normpath(os.path.join(os.path.dirname(path), target)), root)
    for top in LAYERED_DIRS:
        rest = os.path.relpath(resolved, top)
        if not rest.startswith("..") and os.sep in rest:
            return rest.split(os.sep)[0]
    return None  # a helper above the layers (bindings/common.hpp) or a third-party header


def include_violations(root: str) -> list:
    wrong = []
    for path, layer in _layered_files(root):
        if layer not in NATIVE_LAYERS:
            wrong.append(f"{os.path.relpath(path, root)}: folder {layer!r} is not a native layer")
            continue
        for target in INCLUDE.findall(open(path).read()):
            there = _included_layer(root, path, target)
            if there is None or there == layer:
                continue
            if there not in NATIVE_LAYERS or NATIVE_LAYERS[there] >= NATIVE_LAYERS[layer]:
                wrong.append(f"{os.path.relpath(path, root)} ({layer}) includes {target}")
    return wrong


def namespace_violations(root: str) -> list:
    """Library code (cpp/) opens only its folder's namespace, pickplan::<layer>."""
    wrong = []
    for path, layer in _layered_files(root):
        rel = os.path.relpath(path, root)
        if not rel.startswith("cpp" + os.sep):
            continue  # the bindings live in pickplan::bind
        opened = NAMESPACE.findall(open(path).read())
        if path.endswith(".hpp") and not opened:
            wrong.append(f"{rel}: declares no pickplan namespace")
        wrong.extend(
            f"{rel}: namespace {ns}, expected pickplan::{layer}" for ns in opened if ns != f"pickplan::{layer}"
        )
    return wrong


def test_every_native_include_points_down_the_layers():
    files = list(_layered_files(ROOT))
    assert len(files) > 60, "the native tree was not found"  # guards against checking nothing
    assert not include_violations(ROOT)


def test_every_native_file_is_in_its_layers_namespace():
    assert not namespace_violations(ROOT)


def _write(root, rel, text):
    path = os.path.join(root, rel)
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w") as f:
        f.write(text)


@pytest.mark.parametrize(
    "rel, include",
    [
        ("cpp/include/pickplan/core/a.hpp", '#include "pickplan/geometry/b.hpp"'),  # upward
        ("cpp/src/omg/a.cpp", '#include "pickplan/pickup/b.hpp"'),  # sideways between applications
        ("cpp/src/geometry/a.cpp", '#include "../omg/b.hpp"'),  # upward, relative
        ("bindings/core/a.cpp", '#include "pickplan/omg/b.hpp"'),
    ],
)
def test_the_checks_catch_a_planted_violation(tmp_path, rel, include):
    root = str(tmp_path)
    layer = rel.split("/")[-2]
    _write(root, "cpp/include/pickplan/core/ok.hpp", "#pragma once\nnamespace pickplan::core {\n}\n")
    _write(
        root,
        "cpp/src/omg/ok.cpp",
        '#include "pickplan/core/ok.hpp"\n#include "pickplan/geometry/b.hpp"\nnamespace pickplan::omg {\n}\n',
    )
    assert include_violations(root) == [] and namespace_violations(root) == []
    _write(root, rel, f"{include}\nnamespace pickplan::{layer} {{\n}}\n")
    assert len(include_violations(root)) == 1
    _write(root, "cpp/include/pickplan/core/ok.hpp", "#pragma once\nnamespace pickplan {\n}\n")
    assert namespace_violations(root) == [
        "cpp/include/pickplan/core/ok.hpp: namespace pickplan, expected pickplan::core"
    ]
