"""Sphinx configuration of pickplan's documentation (``make docs``: built with warnings as errors)."""
import pickplan

project = "pickplan"
author = "the pickplan authors"
copyright = "the pickplan authors, BSD-3-Clause"
release = version = pickplan.__version__

extensions = ["myst_parser", "sphinx.ext.autodoc", "sphinx.ext.viewcode"]
source_suffix = {".md": "markdown"}
exclude_patterns = ["_build"]
# The docstrings say what each value is in prose; signatures show the types.
autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": True}
autodoc_member_order = "bysource"
autodoc_typehints = "signature"
autodoc_mock_imports = ["rclpy"]
myst_heading_anchors = 3
html_theme = "furo"
html_title = f"pickplan {release}"
