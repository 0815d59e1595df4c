"""Sphinx configuration of the bench's documentation site (``make docs``).

MyST Markdown pages; warnings are errors and every cross-reference is checked (``make docs`` runs
``sphinx -n -W``). Three local extensions (``docs/_ext``): ``api_pages`` writes the API reference of the
rclpy-free modules from their docstrings, ``settings_page`` the settings reference from the code that reads the
settings, and ``run_blocks`` runs the tutorials' shell and Python steps on shortened runs while the site is
built, so that a step that stops working fails the build.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import yaml

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(DOCS / "_ext"))

project = "Spacecraft tracking bench"
author = "The tracking bench contributors"
copyright = "the tracking bench contributors; Apache-2.0"
release = (
    subprocess.run(
        ["git", "-C", str(ROOT), "describe", "--always", "--dirty"], capture_output=True, text=True
    ).stdout.strip()
    or "unknown"
)

extensions = ["myst_parser", "sphinx.ext.autodoc", "sphinx.ext.mathjax", "api_pages", "settings_page", "run_blocks"]
source_suffix = {".md": "markdown", ".rst": "restructuredtext"}  # .rst: the generated API pages
root_doc = "index"
exclude_patterns = ["_build", "tables"]
myst_enable_extensions = ["colon_fence", "deflist", "dollarmath"]
myst_heading_anchors = 3

html_theme = "furo"
html_title = project
html_static_path: list[str] = []

# api_pages: one page per package, every module that imports no ROS client library at its top level.
api_packages = yaml.safe_load((ROOT / "ros_ws" / "packages.yaml").read_text())["layers"]  # lowest layer first

# Every reference is checked (nitpicky), except to what lies outside the bench: the standard library, numpy,
# scipy and the other libraries its signatures name have no inventory here (the site is built offline).
nitpicky = True
BENCH = "(" + "|".join(api_packages) + ")"
nitpick_ignore_regex = [(r"py:.*", rf"(?!{BENCH}\b).*")]

autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": True}
autodoc_member_order = "bysource"
autodoc_typehints = "none"
autodoc_preserve_defaults = True

api_source = str(ROOT / "ros_ws" / "src")

# run_blocks: the steps run in a scratch copy of the repository's layout (links to .venv, scripts, foxglove,
# tests), never in the checkout's own runs/. RUN_BLOCKS=0 builds the pages without running them.
run_blocks_root = str(ROOT)
run_blocks_execute = os.environ.get("RUN_BLOCKS", "1") != "0"
run_blocks_timeout_s = 300
toc_object_entries = False  # the API pages list their modules in the navigation, not every object
