"""Monte Carlo of one scenario: N seeded runs through the graph (bench_engine.batch), scored together (RMSE
per time step over the runs, paper 000 eq. 35), with score.json and a report."""
from __future__ import annotations

import json
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from bench_engine.batch import RunSpec, run_batch
from bench_engine.launcher import prepare_run


@dataclass
class MonteCarlo:
    scenario: str
    out: Path
    runs: int
    seed0: int = 1
    filters: str | None = None
    variant: str | None = None
    overrides: list[str] = field(default_factory=list)
    multiprocess: bool = False

    def specs(self) -> list[RunSpec]:
        return [RunSpec(self.scenario, self.out / f"run_{i:03d}", self.seed0 + i, self.filters, self.variant,
                        list(self.overrides), self.multiprocess) for i in range(self.runs)]

    def validate(self) -> None:
        """Resolve and check the scenario once before N runs start (ScenarioError naming the bad key)."""
        filters = self.filters.split(",") if self.filters else None
        prepare_run(self.scenario, self.out / "validate", filters, self.seed0, self.overrides, self.variant,
                    record=False)

    def bags(self) -> list[Path]:
        return [s.bag for s in self.specs() if (s.bag / "metadata.yaml").is_file()]


def run_montecarlo(mc: MonteCarlo, jobs: int = 2, domains: list[int] | None = None) -> tuple[dict, list[str]]:
    """Run, score and report a Monte Carlo; returns (scores with runs_per_minute, failure messages). Writes
    OUT/score.json and OUT/report/. Raises ScenarioError before any run for a bad scenario or override."""
    from bench_eval.report import write_report
    from bench_eval.scoring import score_bags
    mc.out.mkdir(parents=True, exist_ok=True)
    mc.validate()
    started = time.monotonic()
    results = run_batch(mc.specs(), jobs, domains, desc=Path(mc.scenario).stem)
    wall = time.monotonic() - started
    failures = [f"{r.spec.out} (exit {r.code}, log {r.spec.log})" for r in results if not r.ok]
    print(f"[montecarlo] {mc.runs} runs in {wall:.0f} s ({60 * mc.runs / wall:.1f} runs/min)", file=sys.stderr)
    bags = mc.bags()
    if not bags:
        raise RuntimeError("no run produced a bag")
    scored, series = score_bags(bags, with_series=True)
    scored["runs_per_minute"] = round(60 * mc.runs / wall, 2)
    (mc.out / "score.json").write_text(json.dumps(scored, indent=1))
    write_report(mc.out / "report", {scored["scenario"]: scored["filters"]},
                 {scored["scenario"]: series} if series else {})
    return scored, failures
