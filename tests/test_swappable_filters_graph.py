"""Swappable means swappable: the leo_radar EKF and UKF run unchanged on both formation scenarios, and the
formation CQKF runs on leo_radar, all paired on the same measurements in one graph."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from graph_helpers import read_bag, script


def _final_position_errors(bag: dict, filters: list[str]) -> dict[str, float]:
    truth = {m.step: np.array(m.state) for _, m in bag["/truth/state"]}
    errors = {}
    for name in filters:
        est = [m for _, m in bag[f"/{name}/estimate"]]
        assert est, f"{name} published nothing"
        assert all(np.all(np.isfinite(m.state)) for m in est)
        last = est[-1]
        errors[name] = float(np.linalg.norm(np.array(last.state[:3]) - truth[last.step][:3]))
    return errors


@pytest.mark.parametrize(
    "scenario, filters, extra, bound_m",
    [
        (
            "formation_pf",
            ["ekf", "ukf", "pf"],
            ["--set", "time.duration=120", "--set", "filters.pf.params.n_particles=2000"],
            1.0,
        ),
        # formation_cqkf gives each filter its own dynamics model: the extra filters say which one they use
        (
            "formation_cqkf",
            ["ekf", "ukf", "cw"],
            [
                "--set",
                "time.duration=600",
                "--set",
                "filters.ekf.dynamics.model=ss",
                "--set",
                "filters.ukf.dynamics.model=ss",
            ],
            5.0,
        ),
        ("leo_radar", ["ukf", "cqkf"], ["--set", "time.duration=120"], 20_000.0),
    ],
)
def test_filters_run_unchanged_on_other_scenarios(
    tmp_path: Path, scenario: str, filters: list[str], extra: list[str], bound_m: float
) -> None:
    out = tmp_path / scenario
    res = script(
        "launch.py",
        scenario,
        "--estimators",
        ",".join(filters),
        "--out",
        str(out),
        "--single-process",
        "--no-score",
        *extra,
    )
    assert res.returncode == 0, res.stderr[-3000:]
    bag = read_bag(out / "bag")
    errors = _final_position_errors(bag, filters)
    assert all(e < bound_m for e in errors.values()), errors
    steps = {name: [m.step for _, m in bag[f"/{name}/estimate"]] for name in filters}
    assert all(s == steps[filters[0]] for s in steps.values())  # paired: same measurements, same steps
