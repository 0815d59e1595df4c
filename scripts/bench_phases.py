#!/usr/bin/env python3
"""Where a run's wall time goes: the phases of a single launch and of a Monte Carlo batch, end to end.

Runs, as a user would, ``launch.py SCENARIO`` (one process per node, forked from the launcher; the same with
``--fresh-nodes``, each node a fresh interpreter; and ``--single-process``) and
``montecarlo.py SCENARIO --runs N --jobs J``, with phase recording on (bench_engine.phases: every process of
the run appends its timestamps to one file), and prints each phase's wall time:

  interpreter + imports   process start of the command to its imports done
  validation              scenario resolved and every node's objects built once (launcher)
  process spawn           node processes started and imported (one process per node); nothing in one process
  node set-up             rclpy initialised, nodes built (cores, endpoints)
  discovery + readiness   last node built to the truth's first step (readiness barrier)
  stepping                first to last step (the truth's pacing loop)
  drain                   last step to the recorder closing the bag (messages in flight, the done protocol)
  bag close               the recorder writing the bag's summary and metadata.yaml
  shutdown                bag closed to every node gone (and the bag checked)
  scoring                 the bag(s) scored (and, for Monte Carlo, the report written)
  exit                    the command's interpreter exit

and the ratios of the issue: single launch wall / stepping and Monte Carlo wall / (stepping / jobs). For the
Monte Carlo the per-run phases are means over its runs, measured from the moment the batch starts a run.
Nothing is asserted: these are measurements (on a shared machine, upper bounds).

Example:
  .venv/bin/python scripts/bench_phases.py                          # leo_radar, 10-run Monte Carlo, 2 jobs
  .venv/bin/python scripts/bench_phases.py --runs 20 --modes multi-process,montecarlo
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"

from bench_engine import phases  # noqa: E402

SCRIPTS = Path(__file__).resolve().parent
PHASES = (
    "interpreter + imports",
    "validation",
    "process spawn",
    "node set-up",
    "discovery + readiness",
    "stepping",
    "drain",
    "bag close",
    "shutdown",
    "scoring",
    "exit",
)
LAUNCH_MODES = {"multi-process": [], "fresh-nodes": ["--fresh-nodes"], "single-process": ["--single-process"]}


def _first(records: list[dict], event: str, who: str | None = None) -> float | None:
    times = [r["t"] for r in records if r["event"] == event and (who is None or r["who"] == who)]
    return min(times) if times else None


def _last(records: list[dict], event: str, exclude: tuple[str, ...] = ()) -> float | None:
    times = [r["t"] for r in records if r["event"] == event and r["who"] not in exclude]
    return max(times) if times else None


def run_phases(records: list[dict], start: float, end: float | None, after_run: str | None) -> dict[str, float]:
    """Phases of one run from its records: consecutive boundaries on the critical path (a missing boundary
    merges its phase into the next one). ``start``: when the command (or the batch) started the run;
    ``after_run``: the launcher event after which scoring starts (None: no scoring in this command)."""
    launcher = [r for r in records if r["who"] == "launcher"]
    nodes = [r for r in records if r["who"] not in ("launcher", "batch", "montecarlo")]
    spawned_processes = [r for r in nodes if r["event"] == "imported"]
    bounds = [
        ("interpreter + imports", _first(launcher, "imported")),
        ("validation", _first(launcher, "validated")),
        ("process spawn", _last(nodes, "imported") if spawned_processes else _first(launcher, "spawned")),
        ("node set-up", _last(nodes, "node_created") if spawned_processes else _first(launcher, "node_created")),
        ("discovery + readiness", _first(records, "stepping_start")),
        ("stepping", _first(records, "stepping_end")),
        ("drain", _first(records, "bag_close_start")),
        ("bag close", _first(records, "bag_closed")),
        ("shutdown", _first(launcher, "run_end")),
        ("scoring", _first(launcher, after_run) if after_run else None),
        ("exit", end),
    ]
    out, previous = {}, start
    for name, t in bounds:
        if t is None:
            out[name] = 0.0
            continue
        t = max(t, previous)
        out[name] = t - previous
        previous = t
    return out


def timed(cmd: list[str], log: Path) -> tuple[list[dict], float, float]:
    """Run ``cmd`` with its phase timestamps going to ``log``: (the phase records, start, end wall time)."""
    env = dict(os.environ, **{phases.ENV: str(log)})
    start = time.time()
    res = subprocess.run(cmd, capture_output=True, text=True, env=env)
    end = time.time()
    if res.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed (exit {res.returncode}):\n{res.stderr[-2000:]}")
    return phases.read(log), start, end


def one_launch(scenario: str, mode: str, extra: list[str], tmp: Path) -> tuple[dict, float, float]:
    """(phases, wall, stepping) of one launch.py run."""
    out = tmp / mode
    cmd = [sys.executable, str(SCRIPTS / "launch.py"), scenario, "--out", str(out), *LAUNCH_MODES[mode], *extra]
    records, start, end = timed(cmd, tmp / f"{mode}.jsonl")
    stepping = json.loads((out / "timing.json").read_text())["stepping_s"]
    return run_phases(records, start, end, "scored"), end - start, stepping


def montecarlo(scenario: str, runs: int, jobs: int, extra: list[str], tmp: Path) -> dict:
    out = tmp / "mc"
    cmd = [
        sys.executable,
        str(SCRIPTS / "montecarlo.py"),
        scenario,
        "--runs",
        str(runs),
        "--jobs",
        str(jobs),
        "--out",
        str(out),
        *extra,
    ]
    records, start, end = timed(cmd, tmp / "mc.jsonl")
    mc = [r for r in records if r["who"] == "montecarlo"]
    by_run: dict[str, list[dict]] = {}
    for r in records:
        if r["who"] != "montecarlo" and r["run"]:
            by_run.setdefault(r["run"], []).append(r)
    per_run = []
    for _run, recs in sorted(by_run.items()):
        begin = _first(recs, "run_spawn", "batch")
        per_run.append(run_phases(recs, begin, _first(recs, "run_exited", "batch"), None))
    steppings = [json.loads((Path(run) / "timing.json").read_text())["stepping_s"] for run in by_run]
    return {
        "wall": end - start,
        "command": {
            "interpreter + imports": _first(mc, "imported") - start,
            "validation": _first(mc, "validated") - _first(mc, "imported"),
            "runs": _first(mc, "runs_done") - _first(mc, "validated"),
            "scoring": _first(mc, "scored") - _first(mc, "runs_done"),
            "report": _first(mc, "reported") - _first(mc, "scored"),
            "exit": end - _first(mc, "reported"),
        },
        "per_run": {p: statistics.mean(r[p] for r in per_run) for p in PHASES},
        "per_run_wall": statistics.mean(sum(r.values()) for r in per_run),
        "stepping_sum": sum(steppings),
        "stepping_mean": statistics.mean(steppings),
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scenario", default="leo_radar")
    p.add_argument(
        "--modes",
        default="multi-process,fresh-nodes,single-process,montecarlo",
        help="comma-separated subset of multi-process, fresh-nodes, single-process, montecarlo",
    )
    p.add_argument("--repeat", type=int, default=1, help="launches per mode (the median of each phase is printed)")
    p.add_argument("--runs", type=int, default=10, help="Monte Carlo runs (default 10)")
    p.add_argument("--jobs", type=int, default=2, help="Monte Carlo jobs (default 2)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    p.add_argument("--json", action="store_true", help="also print every figure as JSON")
    args = p.parse_args(argv)
    modes = [m.strip() for m in args.modes.split(",") if m.strip()]
    unknown = [m for m in modes if m not in (*LAUNCH_MODES, "montecarlo")]
    if unknown or args.repeat < 1 or args.runs < 1 or args.jobs < 1:
        p.error(f"unknown mode(s) {unknown}" if unknown else "--repeat, --runs and --jobs must be >= 1")
    extra = [a for o in args.overrides for a in ("--set", o)]
    result: dict = {"scenario": args.scenario, "cpus": os.cpu_count()}
    with tempfile.TemporaryDirectory(prefix="bench_phases_") as tmpdir:
        tmp = Path(tmpdir)
        launches = {}
        for mode in [m for m in modes if m in LAUNCH_MODES]:
            runs = []
            for i in range(args.repeat):
                (tmp / str(i)).mkdir(exist_ok=True)
                runs.append(one_launch(args.scenario, mode, extra, tmp / str(i)))
            launches[mode] = {
                "phases": {ph: statistics.median(r[0][ph] for r in runs) for ph in PHASES},
                "wall": statistics.median(r[1] for r in runs),
                "stepping": statistics.median(r[2] for r in runs),
            }
        if launches:
            print(
                f"launch.py {args.scenario} {' '.join(extra)}: wall time by phase [s] "
                f"(median of {args.repeat}; {os.cpu_count()} CPUs)"
            )
            print(f"{'phase':24s}" + "".join(f"{m:>22s}" for m in launches))
            for ph in PHASES:
                print(
                    f"{ph:24s}"
                    + "".join(
                        f"{v['phases'][ph]:14.2f} ({100 * v['phases'][ph] / v['wall']:3.0f} %)"
                        for v in launches.values()
                    )
                )
            print(f"{'wall':24s}" + "".join(f"{v['wall']:22.2f}" for v in launches.values()))
            print(f"{'wall / stepping':24s}" + "".join(f"{v['wall'] / v['stepping']:22.2f}" for v in launches.values()))
            print()
        result["launch"] = launches
        if "montecarlo" in modes:
            mc = montecarlo(args.scenario, args.runs, args.jobs, extra, tmp)
            result["montecarlo"] = mc
            print(f"montecarlo.py {args.scenario} --runs {args.runs} --jobs {args.jobs} {' '.join(extra)}")
            print("  per run, from the batch starting it to its process's exit (mean over runs) [s]:")
            for ph in PHASES:
                if ph not in ("scoring",):
                    print(f"    {ph:24s}{mc['per_run'][ph]:8.2f}")
            print(
                f"    {'run wall':24s}{mc['per_run_wall']:8.2f}   (stepping "
                f"{mc['stepping_mean']:.2f}: run wall / stepping {mc['per_run_wall'] / mc['stepping_mean']:.2f})"
            )
            print("  the command [s]:")
            for name, value in mc["command"].items():
                print(f"    {name:24s}{value:8.2f}")
            print(f"    {'wall':24s}{mc['wall']:8.2f}")
            print(
                f"  Monte Carlo wall / (stepping / jobs) = {mc['wall']:.1f} / ({mc['stepping_sum']:.1f} / "
                f"{args.jobs}) = {mc['wall'] / (mc['stepping_sum'] / args.jobs):.2f}; runs only "
                f"{mc['command']['runs'] / (mc['stepping_sum'] / args.jobs):.2f}"
            )
    if args.json:
        print(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
