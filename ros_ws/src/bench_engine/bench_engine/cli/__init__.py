"""The engine's user-facing command: ``recover_bag`` (console script ``bench_recover_bag``, and
``scripts/recover_bag.py`` in the repository), ``main(argv) -> int`` with the entry point ``command()``."""
