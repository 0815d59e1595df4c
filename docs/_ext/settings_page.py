"""Sphinx extension: the settings reference page, written at ``builder-inited`` from the code that reads the
settings (bench_engine.settings_reference.markdown: every scenario key with its type, default, unit and meaning,
from the declarations the readers read), so the page and the validation cannot disagree. It writes
``reference/settings.md`` (generated, not tracked), only when its text changes.
"""

from __future__ import annotations

from pathlib import Path

from bench_engine.settings_reference import markdown


def write_page(app) -> None:
    """builder-inited: write reference/settings.md (only where its text changed)."""
    target, text = Path(app.srcdir) / "reference" / "settings.md", markdown()
    if not target.is_file() or target.read_text(encoding="utf-8") != text:
        target.write_text(text, encoding="utf-8")


def setup(app) -> dict:
    app.connect("builder-inited", write_page)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
