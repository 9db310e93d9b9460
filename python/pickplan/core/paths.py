"""Where pickplan's own files live (pure Python: no native module needed)."""

from __future__ import annotations

import os


def assets_dir() -> str:
    """Folder of the files pickplan authors: installed inside the package, or the source tree's."""
    package = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))  # pickplan/
    for cand in (os.path.join(package, "assets"), os.path.join(package, "..", "..", "assets")):
        if os.path.isdir(cand):
            return os.path.abspath(cand)
    raise FileNotFoundError(f"pickplan assets folder not found next to {package}")
