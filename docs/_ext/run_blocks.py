"""Sphinx extension: tutorial steps that are run while the site is built.

A ``run`` directive shows a shell or Python block to the reader and, when ``run_blocks_execute`` is on, runs it:

````markdown
```{run} bash
:shorten: --set time.duration=60
.venv/bin/python scripts/launch.py leo_radar --out runs/tutorial/leo
```
````

- ``bash`` blocks run in ``bash -euo pipefail``; ``python`` blocks in the Python that builds the site (the
  bench's venv). A non-zero exit is a build warning naming the page and line with the output's tail, so under
  ``-W`` a step that stops working fails the build.
- ``:shorten: ARGS`` appends ARGS to every command line of the block that runs a bench script
  (``scripts/NAME.py``), e.g. a shorter ``time.duration`` or fewer ``--runs`` (argparse keeps an option's last
  value). The page says so under the block, so the reader knows what the build ran.
- ``:output:`` shows the block's standard output under it.
- Every block of every page runs in one scratch directory (``_build/run``), which holds links to the
  repository's ``.venv``, ``scripts``, ``foxglove``, ``tests`` and ``ros_ws`` and a fresh ``runs/``: relative paths
  work as in a checkout and the checkout's own ``runs/`` is never touched. The blocks of a page run in order, so
  a step may read what an earlier step of its page wrote; pages may be read in parallel (``sphinx -j``), so a
  page never relies on another page's steps.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

from docutils import nodes
from docutils.parsers.rst import directives
from sphinx.util import logging
from sphinx.util.docutils import SphinxDirective

LOG = logging.getLogger(__name__)
LINKED = (".venv", "scripts", "foxglove", "tests", "ros_ws")
"""What the scratch directory links from the repository."""
BENCH_SCRIPT = re.compile(r"\bscripts/\w+\.py\b")
TAIL = 3000
"""Characters of a failed step's output that its warning quotes."""


def logical_lines(text: str) -> list[str]:
    """A shell block's lines with backslash continuations joined."""
    lines, current = [], ""
    for raw in text.splitlines():
        if raw.rstrip().endswith("\\"):
            current += raw.rstrip()[:-1] + " "
        else:
            lines.append(current + raw)
            current = ""
    if current:
        lines.append(current)
    return lines


def shortened(text: str, extra: str) -> str:
    """A shell block with ``extra`` appended to every command line that runs a bench script (before a trailing
    comment, a closing ``&`` or a pipe)."""
    if not extra:
        return text
    out = []
    for line in logical_lines(text):
        if BENCH_SCRIPT.search(line) and not line.lstrip().startswith("#"):
            code, hash_, comment = line.partition(" #")
            match = re.search(r"\s*(&|\|.*)\s*$", code)
            head, end = (code[: match.start()], code[match.start() :]) if match else (code.rstrip(), "")
            line = f"{head} {extra}{end}" + (f" #{comment}" if hash_ else "")
        out.append(line)
    return "\n".join(out)


def scratch(app) -> Path:
    """The scratch directory of this build (made at builder-inited)."""
    return Path(app.outdir).parent / "run"


def make_scratch(app) -> None:
    """builder-inited: a fresh scratch directory with links into the repository."""
    if not app.config.run_blocks_execute:
        return
    work, root = scratch(app), Path(app.config.run_blocks_root)
    shutil.rmtree(work, ignore_errors=True)
    (work / "runs").mkdir(parents=True)
    for name in LINKED:
        if (root / name).exists():
            (work / name).symlink_to(root / name)


class Run(SphinxDirective):
    """``{run} bash|python``: show the block; run it when the build executes steps (see the module)."""

    required_arguments = 1
    has_content = True
    option_spec = {"shorten": directives.unchanged, "output": directives.flag}

    def run(self) -> list[nodes.Node]:
        language = self.arguments[0]
        if language not in ("bash", "python"):
            raise self.error(f"run: the language is bash or python, not {language!r}")
        text = "\n".join(self.content)
        shown = nodes.literal_block(text, text, language=language)
        self.set_source_info(shown)
        result: list[nodes.Node] = [shown]
        extra = self.options.get("shorten", "")
        if extra:
            note = nodes.paragraph()
            note += nodes.emphasis(text="The documentation's build runs this step with ")
            note += nodes.literal(text=extra)
            note += nodes.emphasis(text=" appended to each bench command, to keep it short.")
            result.append(note)
        if not self.config.run_blocks_execute:
            return result
        output = self.execute(language, shortened(text, extra) if language == "bash" else text)
        if "output" in self.options and output is not None:
            result.append(nodes.literal_block(output, output, language="text"))
        return result

    def execute(self, language: str, code: str) -> str | None:
        """Run one step in the scratch directory; a warning naming this block if it fails. Returns its stdout."""
        work = scratch(self.env.app)
        command = ["bash", "-euo", "pipefail", "-c", code] if language == "bash" else [sys.executable, "-c", code]
        env = {
            **os.environ,
            "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
            "OPENBLAS_NUM_THREADS": "1",
            "PYTHONUNBUFFERED": "1",
        }
        start = time.perf_counter()
        try:
            done = subprocess.run(
                command,
                cwd=work,
                env=env,
                capture_output=True,
                text=True,
                timeout=self.config.run_blocks_timeout_s,
                stdin=subprocess.DEVNULL,
            )
        except subprocess.TimeoutExpired:
            LOG.warning(
                "run: step timed out after %s s", self.config.run_blocks_timeout_s, location=self.get_location()
            )
            return None
        LOG.info("run: %s step of %s in %.1f s", language, self.env.docname, time.perf_counter() - start)
        if done.returncode != 0:
            tail = (done.stdout + done.stderr)[-TAIL:]
            LOG.warning("run: step failed (exit %s):\n%s", done.returncode, tail, location=self.get_location())
            return None
        return done.stdout


def setup(app):
    app.add_config_value("run_blocks_root", "", "env")
    app.add_config_value("run_blocks_execute", True, "env")
    app.add_config_value("run_blocks_timeout_s", 300, "env")
    app.add_directive("run", Run)
    app.connect("builder-inited", make_scratch)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
