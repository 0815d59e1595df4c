"""Monte Carlo of one scenario: N seeded runs through the graph (bench_engine.batch), scored together (RMSE
per time step over the runs, paper 000 eq. 35), with score.json and a report.

Runs go to the local executor or a Dask cluster (``scheduler``); with ``resume`` the complete runs already in
OUT (same configuration and seed) are kept and only the others are made."""

from __future__ import annotations

import json
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from bench_engine import phases
from bench_engine.batch import RunSpec, reusable_run, run_batch
from bench_engine.cli.options import names
from bench_engine.launcher import prepare_run
from bench_eval.report import write_report
from bench_eval.scoring import load_bag, score_bags


@dataclass
class MonteCarlo:
    scenario: str
    out: Path
    runs: int
    seed0: int = 1
    estimators: str | None = None
    """Comma-separated estimator names (None: the scenario's)."""
    variant: str | None = None
    overrides: list[str] = field(default_factory=list)
    multiprocess: bool = False

    def specs(self) -> list[RunSpec]:
        return [
            RunSpec(
                self.scenario,
                self.out / f"run_{i:03d}",
                self.seed0 + i,
                self.estimators,
                self.variant,
                list(self.overrides),
                self.multiprocess,
            )
            for i in range(self.runs)
        ]

    def validate(self) -> dict:
        """Resolve and check the scenario once before N runs start (ScenarioError naming the bad key); returns
        the resolved scenario of run 0."""
        return prepare_run(
            self.scenario,
            self.out / "validate",
            names(self.estimators),
            self.seed0,
            self.overrides,
            self.variant,
            record=False,
        ).run["scenario"]

    def pending(self, resolved: dict, resume: bool = False) -> list[RunSpec]:
        """The runs still to make: all of them, or with ``resume`` those without a complete bag of the same
        configuration and seed in OUT (bench_engine.batch.reusable_run; raises ScenarioError if a run
        directory exists without ``resume``, or holds another configuration)."""
        return [s for s in self.specs() if not reusable_run(s.out, {**resolved, "seed": s.seed}, resume)]

    def bags(self) -> list[Path]:
        return [s.bag for s in self.specs() if (s.bag / "metadata.yaml").is_file()]


def run_montecarlo(
    mc: MonteCarlo,
    jobs: int = 2,
    domains: list[int] | None = None,
    scheduler: str | None = None,
    resume: bool = False,
    retries: int = 2,
) -> tuple[dict, list[str]]:
    """Run, score and report a Monte Carlo; returns (scores with runs_per_minute, failure messages). Writes
    OUT/score.json and OUT/report/. Raises ScenarioError before any run for a bad scenario or override, or
    for run directories already in OUT (unless ``resume``). ``scheduler``: a Dask scheduler address or
    ``"local"`` (bench_engine.executors) instead of the local executor, each run retried ``retries`` times. The
    runs are then scored ``jobs`` at a time, or on the same cluster (bench_eval.scoring.prepare_runs)."""
    mc.out.mkdir(parents=True, exist_ok=True)
    pending = mc.pending(mc.validate(), resume)
    phases.mark("validated", "montecarlo", mc.out.resolve())
    if len(pending) < mc.runs:
        print(
            f"[montecarlo] resuming: {mc.runs - len(pending)} complete runs kept, {len(pending)} to run",
            file=sys.stderr,
        )
    loaded = {}

    def load(result) -> None:  # decoded as each run ends, while the others still run
        if result.ok:
            try:
                loaded[result.spec.bag.resolve()] = load_bag(result.spec.bag)
            except Exception:  # noqa: BLE001 - score_bags reads this bag again and reports what is wrong
                pass

    started = time.monotonic()
    results = (
        run_batch(
            pending, jobs, domains, desc=Path(mc.scenario).stem, on_done=load, scheduler=scheduler, retries=retries
        )
        if pending
        else []
    )
    wall = time.monotonic() - started
    phases.mark("runs_done", "montecarlo", mc.out.resolve())
    failures = [
        f"{r.spec.out} (exit {r.code}{', ' + r.error if r.error else ''}, log {r.spec.log})"
        for r in results
        if not r.ok
    ]
    for r in results:
        for note in r.reruns:
            print(f"[montecarlo] {note}", file=sys.stderr)
    if results:
        retried = [r for r in results if r.killed]
        print(
            f"[montecarlo] {len(results)} runs in {wall:.0f} s ({60 * len(results) / wall:.1f} runs/min)"
            + (
                f"; {len(retried)} run(s) retried after a killed node ({sum(len(r.killed) for r in retried)} retries)"
                if retried
                else ""
            ),
            file=sys.stderr,
        )
    bags = mc.bags()
    if not bags:
        raise RuntimeError("no run produced a bag")
    scored, series = score_bags(
        [loaded.get(b.resolve(), b) for b in bags], with_series=True, jobs=jobs, scheduler=scheduler
    )
    if results:
        scored["runs_per_minute"] = round(60 * len(results) / wall, 2)
    (mc.out / "score.json").write_text(json.dumps(scored, indent=1))
    phases.mark("scored", "montecarlo", mc.out.resolve())
    write_report(
        mc.out / "report", {scored["scenario"]: scored["estimators"]}, {scored["scenario"]: series} if series else {}
    )
    phases.mark("reported", "montecarlo", mc.out.resolve())
    return scored, failures
