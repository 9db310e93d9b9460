#!/usr/bin/env python3
"""Checks an installed pickplan wheel is self-contained; run by tools/wheel_smoke.sh with the fresh venv's python.

    # ldd of the extension and pickplan-bench; writes the Debian copies of the bundled libraries (to hide) into
    # HIDE_LIST
    python wheel_check.py libs HIDE_LIST
    python wheel_check.py run OUT [HIDE_LIST]   # `pickplan demo --out OUT` in this process, then checks
                                           # every native library it mapped (/proc/self/maps)

Allowed outside the wheel: what manylinux lets a wheel take from the system (auditwheel's
manylinux_2_35 policy: the glibc family, libstdc++, libgcc_s, libz, libexpat, ...). Standard library only.
"""

from __future__ import annotations

import importlib.util
import os
import pathlib
import re
import subprocess
import sys

from third_party_notices import LIBRARY_DIRS, original_name

# auditwheel's manylinux policy lib_whitelist (identical for manylinux_2_17 ... manylinux_2_35, plus
# libmvec), and the loader itself.
MANYLINUX_SYSTEM = {
    "libatomic.so.1",
    "libgcc_s.so.1",
    "libstdc++.so.6",
    "libm.so.6",
    "libmvec.so.1",
    "libanl.so.1",
    "libdl.so.2",
    "librt.so.1",
    "libc.so.6",
    "libnsl.so.1",
    "libutil.so.1",
    "libpthread.so.0",
    "libX11.so.6",
    "libXext.so.6",
    "libXrender.so.1",
    "libICE.so.6",
    "libSM.so.6",
    "libGL.so.1",
    "libgobject-2.0.so.0",
    "libgthread-2.0.so.0",
    "libglib-2.0.so.0",
    "libresolv.so.2",
    "libexpat.so.1",
    "libz.so.1",
    "ld-linux-x86-64.so.2",
    "linux-vdso.so.1",
}


def installed() -> tuple[pathlib.Path, pathlib.Path, list[pathlib.Path]]:
    """The installed package folder, its pickplan.libs/ and the native programs to check."""
    spec = importlib.util.find_spec("pickplan")
    if spec is None or not spec.submodule_search_locations:
        sys.exit("pickplan is not installed in this interpreter")
    package = pathlib.Path(spec.submodule_search_locations[0]).resolve()
    if not package.is_relative_to(pathlib.Path(sys.prefix).resolve()):
        sys.exit(f"pickplan comes from {package}, not from this venv ({sys.prefix}): run outside the source tree")
    site = package.parent
    # auditwheel moves native programs from the scripts folder to pickplan.scripts/ (bin/ keeps a wrapper).
    candidates = (site / "pickplan.scripts" / "pickplan-bench", pathlib.Path(sys.prefix) / "bin" / "pickplan-bench")
    benches = [p for p in candidates if p.is_file() and p.read_bytes()[:4] == b"\x7fELF"]
    programs = sorted(package.glob("_core*.so")) + benches[:1]
    if len(programs) != 2:
        sys.exit(f"the wheel lacks the extension or the pickplan-bench program (found {programs})")
    return package, site / "pickplan.libs", programs


def ldd(program: pathlib.Path) -> list[tuple[str, str]]:
    """(needed name, resolved path or 'not found') for every dependency, transitively."""
    out = subprocess.run(["ldd", str(program)], capture_output=True, text=True, check=True).stdout
    print(f"$ ldd {program}\n{out}", end="")
    deps = []
    for line in out.splitlines():
        m = re.match(r"\s*(\S+)\s+=>\s+(not found|\S+)", line) or re.match(r"\s*((\S+))\s+\(0x", line)
        if m:
            deps.append((pathlib.Path(m.group(1)).name, m.group(2)))
    return deps


def outside_wheel(deps: list[tuple[str, str]], libs: pathlib.Path) -> list[str]:
    bad = []
    for name, path in deps:
        if path == "not found":
            bad.append(f"{name}: not found")
        elif not pathlib.Path(path).resolve().is_relative_to(libs.resolve()) and name not in MANYLINUX_SYSTEM:
            bad.append(f"{name} => {path}")
    return bad


def interpreter_libraries() -> set[str]:
    """System libraries the Python interpreter and its standard library link (not pickplan's to hide)."""
    stdlib = pathlib.Path(sys.base_prefix) / "lib" / f"python{sys.version_info.major}.{sys.version_info.minor}"
    objects = [pathlib.Path(sys.executable).resolve(), *(stdlib / "lib-dynload").glob("*.so")]
    out = subprocess.run(["ldd", *map(str, objects)], capture_output=True, text=True).stdout
    return {os.path.realpath(p) for p in re.findall(r"=>\s+(/\S+)", out)}


def debian_copies(libs: pathlib.Path) -> tuple[list[str], list[str]]:
    """The system files the bundled libraries were copied from: (to hide, kept for the interpreter)."""
    keep, hide = interpreter_libraries(), set()
    for bundled in libs.iterdir():
        for folder in LIBRARY_DIRS:
            path = pathlib.Path(folder) / original_name(bundled.name)
            if path.exists():
                hide.add(os.path.realpath(path))
    return sorted(hide - keep), sorted(hide & keep)


def check_libs(hide_list: pathlib.Path) -> None:
    package, libs, programs = installed()
    bad = [f"{p.name}: {b}" for p in programs for b in outside_wheel(ldd(p), libs)]
    if bad:
        sys.exit("dependencies outside the wheel (and outside manylinux's system set):\n  " + "\n  ".join(bad))
    bundled = sorted(p.name for p in libs.iterdir())
    print(
        f"ldd: every dependency of {len(programs)} programs resolves into {libs} ({len(bundled)} libraries) "
        "or manylinux's system set"
    )
    hide, kept = debian_copies(libs)
    hide_list.write_text("".join(p + "\n" for p in hide))
    print(
        f"Debian copies of the bundled libraries on this machine: {len(hide)} to hide"
        + (f"; kept visible because the Python interpreter itself links them: {', '.join(kept)}" if kept else "")
    )


def mapped_libraries() -> set[str]:
    with open("/proc/self/maps") as maps:
        return {line.split(None, 5)[5].strip() for line in maps if ".so" in line and len(line.split(None, 5)) == 6}


def check_run(out: pathlib.Path, hide_list: pathlib.Path | None) -> None:
    package, libs, _ = installed()
    from pickplan.cli.main import main as pickplan_main

    status = pickplan_main(["demo", "--out", str(out)])
    metrics = (out / "metrics.md").read_text()
    if status != 0 or "Status: success" not in metrics or not (out / "demo.png").stat().st_size:
        sys.exit(f"pickplan demo failed (exit {status}):\n{metrics}")
    mapped = mapped_libraries()
    from_wheel = {p for p in mapped if pathlib.Path(p).is_relative_to(libs)}
    core = [p for p in mapped if pathlib.Path(p).is_relative_to(package) and "_core" in p]
    hidden = set(hide_list.read_text().split()) if hide_list else set()
    debian = sorted(p for p in mapped if os.path.realpath(p) in hidden)
    if not core or debian or len(from_wheel) != len(list(libs.iterdir())):
        sys.exit(
            f"native libraries: extension {core}, {len(from_wheel)} of {len(list(libs.iterdir()))} from "
            f"pickplan.libs, Debian copies loaded: {debian}"
        )
    print(
        f"demo planned and executed; the process mapped pickplan._core and all {len(from_wheel)} libraries "
        f"from {libs}, none of the {len(hidden)} Debian copies"
    )


def main() -> None:
    if len(sys.argv) >= 3 and sys.argv[1] == "libs":
        check_libs(pathlib.Path(sys.argv[2]))
    elif len(sys.argv) >= 3 and sys.argv[1] == "run":
        check_run(pathlib.Path(sys.argv[2]).resolve(), pathlib.Path(sys.argv[3]) if len(sys.argv) > 3 else None)
    else:
        sys.exit(__doc__)


if __name__ == "__main__":
    main()
