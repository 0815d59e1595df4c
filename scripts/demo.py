#!/usr/bin/env python3
"""The main job (`make demo`): run the studies through the ROS 2 graph, score the bags, write a report.

For each study: the graph runs with its filters side by side (one process per node), the recorder writes a
rosbag2-style MCAP bag, the scorer reads it back, and OUT/report.md gathers the tables (bench next to the
paper) and plots. With --runs N > 1 each study is a Monte Carlo of N seeded runs (2 in parallel).

Example:
  .venv/bin/python scripts/demo.py --out runs/demo
  .venv/bin/python scripts/demo.py --out runs/demo --runs 20
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy loads: see bench_engine.launcher
SCRIPTS = Path(__file__).resolve().parent
STUDIES = {
    "leo_radar": ["--filters", "ekf,ukf"],
    "formation_pf": ["--filters", "pf,sir"],
    "formation_cqkf": ["--filters", "ss,cw,cwb"],
}


def run_study(name: str, args: list[str], out: Path, runs: int, domain: int) -> Path:
    """Run one study; returns the list of bag directories' parent (the study's output directory)."""
    study = out / name
    shutil.rmtree(study, ignore_errors=True)
    if runs == 1:
        cmd = [sys.executable, str(SCRIPTS / "launch.py"), name, "--out", str(study), "--domain-id", str(domain),
               "--no-score", *args]
    else:
        cmd = [sys.executable, str(SCRIPTS / "montecarlo.py"), name, "--runs", str(runs), "--jobs", "2",
               "--out", str(study), "--domain-base", str(domain), *args]
    print(f"[demo] {name}: {' '.join(cmd[1:])}", file=sys.stderr)
    subprocess.run(cmd, check=True)
    return study


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", type=Path, default=Path("runs/demo"), help="output directory (default runs/demo)")
    p.add_argument("--runs", type=int, default=1, help="Monte Carlo runs per study (default 1)")
    p.add_argument("--studies", default=",".join(STUDIES), help=f"comma-separated subset of {list(STUDIES)}")
    args = p.parse_args(argv)
    from bench_eval.report import write_report
    from bench_eval.scoring import print_summary, score_bags
    scored_all, series_all = {}, {}
    for i, name in enumerate(args.studies.split(",")):
        if name not in STUDIES:
            p.error(f"unknown study {name!r}; allowed: {list(STUDIES)}")
        study = run_study(name, STUDIES[name], args.out, args.runs, domain=30 + 3 * i)
        bags = sorted(b.parent for b in study.glob("**/bag/metadata.yaml"))
        scored, series = score_bags(bags, with_series=True)
        (study / "score.json").write_text(json.dumps(scored, indent=1))
        print(print_summary(scored))
        scored_all[name] = scored["filters"]
        if series:
            series_all[name] = series
    report = write_report(args.out, scored_all, series_all)
    print(f"[demo] report: {report}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
