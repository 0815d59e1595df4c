"""The bench's user-facing commands. Each module holds one command's logic as ``main(argv) -> int`` and the
console script's entry point ``command()`` (setup.py): ``bench_launch``, ``bench_score``, ``bench_montecarlo``,
``bench_replay``, ``bench_sweep``, ``bench_demo`` and ``bench_reproduce``; ``scripts/NAME.py`` runs the same
``main`` from the repository. ``bench_recover_bag`` is ``bench_engine.cli.recover_bag``."""
