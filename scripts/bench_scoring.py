#!/usr/bin/env python3
"""What scoring a Monte Carlo costs, on one core and on every core, and re-scoring it from the cache.

Makes a Monte Carlo's bags (``montecarlo.py SCENARIO --runs N``; or takes them from ``--bags DIR``, a Monte
Carlo's output directory), then times ``score.py`` on all of them as a user runs it:

  one core         ``--jobs 1 --no-cache`` on one CPU: every bag read, every offline estimator fitted, in turn
  JOBS jobs        ``--jobs JOBS --no-cache``: the same on JOBS processes (default: every CPU)
  filling cache    ``--jobs JOBS`` after the bags' offline_cache/ folders are removed: fits and keeps them
  from cache       ``--jobs JOBS`` again: each offline estimator's result read back (bench_eval.offline_cache)

The two long JOBS rows are measured ``--rounds`` times in alternation (no cache, filling, no cache, filling, ...),
so that neither always runs first after the one-core run. It prints each row's wall time per round, their mean and
its share of the one-core time, and the CPU time the host took from this virtual machine while the row ran
(steal, /proc/stat: time its CPUs had work but the host ran something else; empty where the kernel does not count
it). Then what the machine itself allows: one bag scored alone on one CPU against JOBS copies of it scored at once,
one per CPU (twice each, alternated). JOBS copies at once taking longer than one alone (shared caches and memory
bandwidth, a host's other load on its virtual CPUs) is a slowdown no scheduling can win back: JOBS jobs then take
at least slowdown / JOBS of the one-core time.

The default is grace_velocity's dynamic variant, whose orbit fits make scoring the long part of its Monte Carlo.
Nothing is asserted: these are measurements.

Example:
  .venv/bin/python scripts/bench_scoring.py                                # grace_velocity dynamic, 20 runs
  .venv/bin/python scripts/bench_scoring.py --bags runs/mc-grace --jobs 2
  .venv/bin/python scripts/bench_scoring.py --scenario leo_radar --variant "" --runs 10
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

from bench_eval.offline_cache import DIRECTORY as CACHE_DIR

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"

SCRIPTS = Path(__file__).resolve().parent
FLOOR_REPEATS = 2
"""How many times the machine's slowdown is measured (one alone, then the copies at once)."""
STAT = Path("/proc/stat")
"""The kernel's CPU time counters; the 'cpu' line's eighth value is the time the host ran others on our CPUs."""


def steal() -> float | None:
    """The CPU time the host has taken from this (virtual) machine since it booted, s (/proc/stat's steal); None
    where the kernel does not say."""
    try:
        fields = STAT.read_text().split("\n", 1)[0].split()
        return int(fields[8]) / os.sysconf("SC_CLK_TCK") if fields[0] == "cpu" and len(fields) > 8 else None
    except (OSError, ValueError):
        return None


@dataclass
class Row:
    """A measured row: its wall times (one per round) and the host's steal over them, s (None: not counted)."""

    name: str
    walls: list[float] = field(default_factory=list)
    stolen: float | None = 0.0

    def time(self, cmd: list[str], cpus: set[int] | None = None) -> None:
        """Run ``cmd`` (:func:`run`, on ``cpus``) once more, counting the host's steal meanwhile."""
        before = steal()
        self.walls.append(run(cmd, cpus))
        after = steal()
        self.stolen = None if None in (before, after, self.stolen) else self.stolen + after - before

    @property
    def mean(self) -> float:
        return sum(self.walls) / len(self.walls)

    def line(self, one: float) -> str:
        stolen = "" if self.stolen is None else f"{self.stolen:.1f}"
        walls = ", ".join(f"{w:.1f}" for w in self.walls)
        return f"| {self.name} | {walls} | {self.mean:.1f} | {self.mean / one:.3f} | {stolen} |"


def run(cmd: list[str], cpus: set[int] | None = None) -> float:
    """Run a command of scripts/, quietly, on ``cpus`` (default: those of this process); its wall time in s. A
    failure ends the benchmark with its stderr."""
    start = time.perf_counter()
    pin = None if cpus is None else (lambda: os.sched_setaffinity(0, cpus))
    done = subprocess.run([sys.executable, *cmd], capture_output=True, text=True, preexec_fn=pin)
    if done.returncode != 0:
        sys.exit(
            f"error: {' '.join(Path(c).name if c.endswith('.py') else c for c in cmd)} failed:\n{done.stderr[-2000:]}"
        )
    return time.perf_counter() - start


def at_once(cmds: list[list[str]], cpus: list[int]) -> float:
    """Run the commands at once, each pinned to its own CPU; the wall time until the last ends, in s."""
    start = time.perf_counter()
    procs = [
        subprocess.Popen(
            [sys.executable, *cmd],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
            preexec_fn=lambda cpu=cpu: os.sched_setaffinity(0, {cpu}),
        )
        for cmd, cpu in zip(cmds, cpus)
    ]
    for proc in procs:
        _, err = proc.communicate()
        if proc.returncode != 0:
            sys.exit(f"error: score.py failed:\n{err[-2000:]}")
    return time.perf_counter() - start


def machine_slowdown(score_one: list[str], jobs: int, repeats: int = FLOOR_REPEATS) -> tuple[float, float]:
    """The mean wall time of ``score_one`` alone on one CPU and of ``jobs`` copies of it at once, one per CPU
    (alternated ``repeats`` times)."""
    cpus = sorted(os.sched_getaffinity(0))[:jobs]
    alone, together = [], []
    for _ in range(repeats):
        alone.append(run(score_one, cpus={cpus[0]}))
        together.append(at_once([score_one] * len(cpus), cpus))
    return sum(alone) / repeats, sum(together) / repeats


def make_bags(args: argparse.Namespace, out: Path) -> float:
    cmd = [str(SCRIPTS / "montecarlo.py"), args.scenario, "--runs", str(args.runs), "--out", str(out)]
    cmd += ["--jobs", str(args.jobs)] + (["--variant", args.variant] if args.variant else [])
    return run(cmd)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scenario", default="grace_velocity")
    p.add_argument("--variant", default="dynamic", help="the scenario's variants ('' for none; default dynamic)")
    p.add_argument("--runs", type=int, default=20, help="Monte Carlo runs to make (default 20)")
    p.add_argument("--bags", type=Path, help="score this Monte Carlo's bags (OUT/run_*/bag) instead of making them")
    p.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="parallel jobs (default: every CPU)")
    p.add_argument(
        "--rounds", type=int, default=2, help="times the two long JOBS rows are measured, alternated (default 2)"
    )
    args = p.parse_args(argv)
    if min(args.runs, args.jobs, args.rounds) < 1:
        p.error("--runs, --jobs and --rounds must be at least 1")
    with tempfile.TemporaryDirectory() as tmp:
        mc = args.bags or Path(tmp) / "mc"
        made = None if args.bags else make_bags(args, mc)
        bags = sorted(mc.glob("run_*/bag"))
        if not bags:
            sys.exit(f"error: {mc}: no Monte Carlo bags (run_*/bag) in it")
        score = [str(SCRIPTS / "score.py"), *map(str, bags), "--json"]
        rows = [
            Row(name)
            for name in (
                "one job on one core, no cache",
                f"{args.jobs} jobs, no cache",
                f"{args.jobs} jobs, filling the cache",
                f"{args.jobs} jobs, from the cache",
            )
        ]
        rows[0].time([*score, "--jobs", "1", "--no-cache"], cpus={min(os.sched_getaffinity(0))})
        for _ in range(args.rounds):
            rows[1].time([*score, "--jobs", str(args.jobs), "--no-cache"])
            for bag in bags:
                shutil.rmtree(bag / CACHE_DIR, ignore_errors=True)
            rows[2].time([*score, "--jobs", str(args.jobs)])
        rows[3].time([*score, "--jobs", str(args.jobs)])
        jobs = min(args.jobs, len(os.sched_getaffinity(0)))
        alone, together = machine_slowdown([str(SCRIPTS / "score.py"), str(bags[0]), "--json", "--no-cache"], jobs)
    variant = f" --variant {args.variant}" if args.variant else ""
    print(f"score.py on {len(bags)} bags of {args.scenario}{variant}; {os.cpu_count()} CPUs")
    if made is not None:
        print(f"(making them: montecarlo.py --runs {args.runs} --jobs {args.jobs}, scored once, {made:.0f} s)")
    print(f"(the two long {args.jobs}-job rows alternated, {args.rounds} rounds)")
    print("| scoring | wall per round [s] | mean [s] | of one core | taken by the host [CPU s] |")
    print("|---|---|---|---|---|")
    for row in rows:
        print(row.line(rows[0].mean))
    slowdown = together / alone
    print(
        f"\nThis machine: one bag scored alone on one CPU {alone:.1f} s, {jobs} copies at once (one per CPU) "
        f"{together:.1f} s (means of {FLOOR_REPEATS}): a slowdown of {slowdown:.3f}, so {jobs} jobs take at least "
        f"{slowdown / jobs:.3f} of the one-core time here."
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
