"""Command-line options every bench command spells the same way.

``--estimators NAMES``: the estimators a run starts, comma-separated, of any kind (filters, trackers,
smoothers, star trackers: bench_engine.graph.resolve_estimators). ``--filters`` is its old name: still
accepted, with a one-line notice.
"""

from __future__ import annotations

import argparse

from bench_engine.settings import notice


class _OldName(argparse.Action):
    """An option's deprecated name: stores into the new option's destination, with a one-line notice."""

    def __init__(self, *args, new: str, **kwargs) -> None:
        self.new = new
        super().__init__(*args, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        notice(f"{option_string} is deprecated: use {self.new} (the same comma-separated names)")
        setattr(namespace, self.dest, values)


def add_estimators_option(
    p: argparse.ArgumentParser, required: bool = False, default_text: str = "the scenario's 'estimators'"
) -> None:
    """``--estimators`` (and its deprecated name ``--filters``) into ``args.estimators`` (text; see
    :func:`names`)."""
    group = p.add_mutually_exclusive_group(required=required)
    text = "comma-separated estimators to run, of any kind: filters, trackers, smoothers, star trackers"
    group.add_argument("--estimators", metavar="NAMES", help=text if required else f"{text} (default: {default_text})")
    group.add_argument(
        "--filters",
        dest="estimators",
        metavar="NAMES",
        action=_OldName,
        new="--estimators",
        help="deprecated name of --estimators",
    )


def names(text: str | None) -> list[str] | None:
    """``a,b`` -> ["a", "b"]; None (or nothing but commas) -> None."""
    found = [n.strip() for n in (text or "").split(",") if n.strip()]
    return found or None
