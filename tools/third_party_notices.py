#!/usr/bin/env python3
"""The notices of the native libraries auditwheel bundles into the wheel (LICENSES/).

    python3 tools/third_party_notices.py dist/pickplan-*.whl --write   # regenerate LICENSES/ (Debian only)
    python3 tools/third_party_notices.py dist/pickplan-*.whl --check   # CI: every bundled library has one

--write maps each file in the wheel's pickplan.libs/ back to the Debian package it was copied from
(dpkg), copies that package's /usr/share/doc/PKG/copyright to LICENSES/SOURCE.copyright and writes
LICENSES/THIRD_PARTY.md. --check needs no dpkg: it fails when a bundled library is missing from
THIRD_PARTY.md, a listed notice file is missing, or the wheel's .dist-info does not carry them.
Standard library only.
"""

from __future__ import annotations

import argparse
import pathlib
import re
import shutil
import subprocess
import sys
import zipfile

ROOT = pathlib.Path(__file__).resolve().parent.parent
LICENSES = ROOT / "LICENSES"
TABLE = LICENSES / "THIRD_PARTY.md"
# BLAS and LAPACK sit in subfolders behind Debian's alternatives symlinks.
LIBRARY_DIRS = (
    "/usr/lib/x86_64-linux-gnu",
    "/usr/lib/x86_64-linux-gnu/blas",
    "/usr/lib/x86_64-linux-gnu/lapack",
    "/usr/lib/x86_64-linux-gnu/openblas-serial",
    "/usr/lib",
    "/lib/x86_64-linux-gnu",
    "/lib",
)

# The licence of the bundled library itself (the Debian copyright files also list the licences of
# files that do not end up in the shared library, e.g. build scripts and documentation).
LICENCES_BY_PACKAGE = {
    "coinor-libipopt1v5": "CPL-1.0 (Common Public License, as Debian's copyright file states)",
    "libblas3": "BSD-3-Clause",
    "libbz2-1.0": "bzip2-1.0.6 (BSD-style)",
    "libccd2": "BSD-3-Clause",
    "libconsole-bridge1.0": "BSD-3-Clause",
    "libfcl0.7": "BSD-3-Clause",
    "libgfortran5": "GPL-3.0-or-later WITH GCC-exception-3.1",
    "liblapack3": "BSD-3-Clause",
    "liblzma5": "public domain",
    "libmumps-seq-5.5": "CeCILL-C",
    "liboctomap1.9": "BSD-3-Clause",
    "libopenblas0-serial": "BSD-3-Clause",
    "libquadmath0": "LGPL-2.1-or-later",
    "libscotch-7.0": "CeCILL-C",
    "libtinyxml2.6.2v5": "Zlib",
    "liburdfdom-model3.0": "BSD-3-Clause",
}


def original_name(bundled: str) -> str:
    """auditwheel's grafted name without its hash: libfcl-f3038bac.so.0.7.0 -> libfcl.so.0.7.0."""
    return re.sub(r"-[0-9a-f]{8}\.", ".", bundled, count=1)


def bundled_libraries(wheel: pathlib.Path) -> list[str]:
    with zipfile.ZipFile(wheel) as zf:
        names = [n.split("/", 1)[1] for n in zf.namelist() if n.startswith("pickplan.libs/") and not n.endswith("/")]
    return sorted(original_name(n) for n in names)


def debian_package(library: str) -> str:
    for folder in LIBRARY_DIRS:
        path = pathlib.Path(folder) / library
        if not path.exists():
            continue
        # Debian 12 merges /lib into /usr/lib, but dpkg records whichever path the package ships.
        for candidate in {str(path), str(path.resolve()), str(path.resolve()).removeprefix("/usr")}:
            found = subprocess.run(["dpkg", "-S", candidate], capture_output=True, text=True)
            if found.returncode == 0:
                return found.stdout.split(":", 1)[0]
    raise SystemExit(f"no Debian package ships {library}; is this the machine that built the wheel?")


def query(package: str, field: str) -> str:
    return subprocess.run(
        ["dpkg-query", "-W", "-f", field, package], capture_output=True, text=True, check=True
    ).stdout.strip()


def write(wheel: pathlib.Path) -> None:
    rows, sources = [], {}
    for library in bundled_libraries(wheel):
        package = debian_package(library)
        source = query(package, "${source:Package}")
        sources.setdefault(source, package)
        licence = LICENCES_BY_PACKAGE.get(package, "see the notice file")
        rows.append(
            f"| `{library}` | {package} {query(package, '${Version}')} | {licence} | "
            f"[{source}.copyright]({source}.copyright) |"
        )
    for old in LICENSES.glob("*.copyright"):
        old.unlink()
    for source, package in sources.items():
        shutil.copyfile(f"/usr/share/doc/{package}/copyright", LICENSES / f"{source}.copyright")
    TABLE.write_text(
        "# Third-party libraries in the pickplan wheel\n\n"
        "The wheel (`make wheel`) bundles these shared libraries in `pickplan.libs/`, copied by auditwheel\n"
        "from the Debian 12 packages named here; each `.copyright` file beside this one is that package's\n"
        "`/usr/share/doc/PACKAGE/copyright`. Their sources: `apt-get source PACKAGE` on Debian 12.\n"
        "pickplan itself is BSD-3-Clause (`LICENSE`). Regenerate with\n"
        "`python3 tools/third_party_notices.py dist/pickplan-*.whl --write`.\n\n"
        "| library | Debian package | licence | notice |\n|---|---|---|---|\n" + "\n".join(rows) + "\n"
    )
    print(f"wrote {TABLE.relative_to(ROOT)}: {len(rows)} libraries from {len(sources)} source packages")


def check(wheel: pathlib.Path) -> None:
    table = TABLE.read_text()
    listed = dict(re.findall(r"^\| `([^`]+)` \|.*\[([^\]]+)\]", table, flags=re.M))
    problems = [
        f"{lib} is bundled but not listed in LICENSES/THIRD_PARTY.md (run --write)"
        for lib in bundled_libraries(wheel)
        if lib not in listed
    ]
    problems += [
        f"LICENSES/{notice} is missing" for notice in set(listed.values()) if not (LICENSES / notice).is_file()
    ]
    with zipfile.ZipFile(wheel) as zf:
        shipped = {pathlib.PurePosixPath(n).name for n in zf.namelist() if ".dist-info/licenses/" in n}
    problems += [
        f"the wheel's .dist-info/licenses/ lacks {name}"
        for name in ["LICENSE", "THIRD_PARTY.md", *sorted(set(listed.values()))]
        if name not in shipped
    ]
    if problems:
        sys.exit("third-party notices:\n  " + "\n  ".join(problems))
    print(f"third-party notices: {len(listed)} bundled libraries listed, notices shipped in the wheel")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("wheel", type=pathlib.Path)
    mode = parser.add_mutually_exclusive_group(required=True)
    mode.add_argument("--write", action="store_true", help="regenerate LICENSES/ from dpkg")
    mode.add_argument("--check", action="store_true", help="fail unless every bundled library has a notice")
    args = parser.parse_args()
    if not args.wheel.is_file():
        sys.exit(f"wheel not found: {args.wheel}")
    write(args.wheel) if args.write else check(args.wheel)


if __name__ == "__main__":
    main()
