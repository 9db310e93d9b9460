#!/usr/bin/env bash
# Proves a pickplan wheel self-contained (`make wheel-smoke`, and CI after `make test`):
#   1. the bundled libraries' notices are listed and shipped (tools/third_party_notices.py --check);
#   2. the wheel installs into a fresh venv outside the source tree (its Python deps from PyPI);
#   3. the shipped cache entries (assets/cache) are in the wheel and match their SHA-256;
#   4. ldd: every dependency of pickplan._core and pickplan-bench resolves into pickplan.libs/
#      or to what manylinux takes from the system (glibc family, libstdc++, libgcc_s, libz, libexpat);
#   5. in a private mount namespace where an empty file covers every Debian copy of a bundled library,
#      `pickplan demo` plans and executes a scene (the process maps all of pickplan.libs/ and none of
#      the Debian copies) and pickplan-bench runs.
# Usage: tools/wheel_smoke.sh dist/pickplan-VERSION-TAG.whl
set -euo pipefail
tools=$(cd "$(dirname "$0")" && pwd)
wheel=$(realpath "${1:?usage: tools/wheel_smoke.sh dist/pickplan-*.whl}")
start=$SECONDS

python3 "$tools/third_party_notices.py" "$wheel" --check

work=$(mktemp -d "${TMPDIR:-/tmp}/pickplan-wheel-smoke.XXXXXX")
trap 'rm -rf "$work"' EXIT
python3 -m venv "$work/venv"
"$work/venv/bin/python" -m pip install -q --disable-pip-version-check "$wheel"
echo "installed $(basename "$wheel") ($(du -k "$wheel" | cut -f1) KiB) into a fresh venv: $work/venv"

cd "$work"  # nothing from the source tree on sys.path: pickplan comes from the venv
venv/bin/python "$tools/wheel_check.py" libs "$work/hide.txt"
# The built-in objects' shipped cache entries are in the wheel, each matching its SHA-256.
venv/bin/python -c '
import os
from pickplan.core.io import file_sha256, read_manifest, shipped_dir
folder = shipped_dir()
entries = read_manifest(folder)
assert entries, "no shipped cache entries in the wheel"
bad = [n for n, e in entries.items() if file_sha256(os.path.join(folder, n)) != e["sha256"]]
assert not bad, f"shipped cache entries failing their SHA-256: {bad}"
print(f"{len(entries)} shipped cache entries verified in {folder}")
'

# The mount namespace is private to this command: the machine's libraries stay as they are.
# Unprivileged users get one through a user namespace (needs kernel.unprivileged_userns_clone).
ns=(unshare --mount --propagation private)
[ "$(id -u)" = 0 ] || ns=(unshare --user --map-root-user --mount --propagation private)
: > "$work/empty.so"
"${ns[@]}" bash -euo pipefail -c '
  while read -r lib; do mount --bind "$1/empty.so" "$lib"; done < "$1/hide.txt"
  echo "hidden $(wc -l < "$1/hide.txt") Debian libraries, e.g. $(head -1 "$1/hide.txt") is now $(stat -c %s "$(head -1 "$1/hide.txt")") bytes"
  venv/bin/python "$2/wheel_check.py" run "$1/demo" "$1/hide.txt"
  venv/bin/pickplan-bench --only kinematics --samples 50
' hidden "$work" "$tools"
echo "wheel smoke test passed in $((SECONDS - start)) s"
