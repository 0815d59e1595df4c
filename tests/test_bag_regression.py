"""The same seed gives the same bag contents, on any machine and across refactorings: a short seeded run of each
study (``launch.py SCENARIO --seed 3 --set time.duration=30 --single-process``) is read back with rosbags and
compared, decoded, with the reference recorded in tests/data/bag_reference/SCENARIO.npz.zst (bag_values.py:
what is compared exactly, what with a tolerance, and how the reference is stored).

Exactly: the topics, their message types and counts, every step, stamp and log time, frame, label, name, array
length, NaN, every identification (star ids, -1 for none), which steps have an estimate.

Floats: within RTOL of their column's scale (bag_values.scale), on every machine. Why 1e-6:

- What moves. numpy's SIMD kernels and OpenBLAS's kernels are picked by CPU; they round differently in the last
  bit (u = 1.1e-16), and the runs amplify that. The largest amplification in these runs is a cancellation: an
  innovation of a few centimetres formed from positions of 7e6 m (grace_velocity's GNSS baseline, sigma 2 cm)
  keeps only |r| u / sigma = 6.9e6 * 1.1e-16 / 0.02 = 4e-8 of relative accuracy, and its NIS, a square, twice
  that. An adaptive truth integrator (rtol 1e-12) may take other steps when its last bits change, moving a 1 km
  formation's relative state by up to rtol |r| / 1 km = 7e-9 of its scale. Filters are stable (they forget), so
  neither grows with the run's length.
- Real changes move values by far more: another seed by the noise itself, a change of a model or of a tuning
  parameter by what it changes in the estimates.

RTOL = 1e-6 is ten times the largest rounding effect predicted above. It is also the test's resolution: a change
that moves no value by more than 1e-6 of its scale (7 m of an ECI position) goes unseen here; the physics tests
check such things against their own references. How far each study's values move on other kernels (and with
some real changes) is measured by

    .venv/bin/python tests/test_bag_regression.py --measure

A deliberate change of a model, a noise draw or a message fails this test; regenerate the reference then and
say why in the commit:

    .venv/bin/python tests/test_bag_regression.py --reason "why" [SCENARIO ...]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

import bag_values
import numpy as np
import pytest
import scipy.linalg  # noqa: F401 - loads scipy's own OpenBLAS, for threadpoolctl to see both
import threadpoolctl
from graph_helpers import script
from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__  # what np.show_runtime() reports

from bench_engine.config import load_scenario
from bench_eval.scoring import scoring_options

RTOL = 1.0e-6
"""Tolerance of every float, in units of its column's scale (module docstring)."""
REFERENCE = Path(__file__).parent / "data" / "bag_reference"
SCENARIOS = ["formation_cqkf", "formation_pf", "grace_velocity", "leo_radar", "star_tracker"]
RUN = ["--seed", "3", "--set", "time.duration=30", "--no-score", "--single-process"]
KERNEL_VARIABLES = ("NPY_DISABLE_CPU_FEATURES", "OPENBLAS_CORETYPE")
"""The environment variables that make numpy and OpenBLAS run other kernels than this CPU's best (make
test-portable sets them)."""


def run_args(scenario: str) -> list[str]:
    """RUN, and for a study with a scoring window (bench_eval.window) its margins shrunk to nothing: they do not
    fit in 30 s, and the launcher refuses a window that leaves nothing of the run. Scoring is off: the window
    changes no message."""
    if scoring_options(load_scenario(scenario)).window is None:
        return RUN
    return [*RUN, "--set", "scoring.window.head_s=0", "--set", "scoring.window.tail_s=0"]


def record(scenario: str, out: Path, *extra: str, env: dict[str, str] | None = None) -> dict[str, bag_values.Topic]:
    """The decoded bag of the seeded run of ``scenario`` (``extra``: more arguments; ``env``: more environment)."""
    res = script("launch.py", scenario, *run_args(scenario), *extra, "--out", str(out), extra_env=env)
    assert res.returncode == 0, res.stderr[-2000:]
    return bag_values.read(out / "bag")


def reference(scenario: str) -> dict[str, bag_values.Topic]:
    return bag_values.load(REFERENCE / f"{scenario}.npz.zst")[0]


def report(problems: list[str], deviations: list[bag_values.Deviation]) -> str:
    worst = "; ".join(f"{d.topic} {d.path} {d.scaled:.2g}" for d in deviations[:3])
    return "\n".join(problems[:20] + [f"({len(problems)} differences; largest float deviations: {worst})"])


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_a_seeded_run_records_the_same_messages_as_the_reference(tmp_path: Path, scenario: str) -> None:
    problems, deviations = bag_values.compare(record(scenario, tmp_path), reference(scenario), RTOL)
    assert not problems, report(problems, deviations)


def _differences(scenario: str, topic: str, change) -> list[str]:
    """What compare() finds on one topic of the reference after ``change(topic)`` changed it."""
    ref, changed = reference(scenario)[topic], reference(scenario)[topic]
    change(changed)
    return bag_values.compare({topic: changed}, {topic: ref}, RTOL)[0]


def _move(path: str, message: int, index: int, by):
    """A change: value ``index`` of ``path`` in ``message`` becomes ``by(value, its scale)``."""

    def change(topic: bag_values.Topic) -> None:
        col = topic.columns[path]
        scale = np.broadcast_to(bag_values.scale(path, col.values), np.size(col.values[message]))[index]
        value = np.array(col.values[message], dtype=float)
        value.flat[index] = by(value.flat[index], scale)
        col.values[message] = value

    return change


def test_the_comparison_tolerates_rounding_and_names_what_changed() -> None:
    """The rules of bag_values.compare on the stored reference (no run): a float moved by half the tolerance
    passes, by twice fails naming the topic, message and field; a NaN where there was a number fails; a change of
    an identification or of a count fails."""
    assert not _differences("leo_radar", "/ukf/estimate", _move("covariance", 100, 7, lambda v, s: v + 0.5 * RTOL * s))
    assert _differences("leo_radar", "/ukf/estimate", _move("covariance", 100, 7, lambda v, s: v + 2 * RTOL * s))[
        0
    ].startswith("/ukf/estimate message 100 covariance[7]:")
    assert (
        "NaN/inf at other places"
        in _differences("leo_radar", "/radar/measurement", _move("range", 3, 0, lambda v, s: np.nan))[0]
    )

    def reassign(topic: bag_values.Topic) -> None:  # the same stars, given to other centroids
        topic.columns["star_id"].values[5] = topic.columns["star_id"].values[5][::-1]

    assert _differences("star_tracker", "/sna_wahba/stars", reassign)[0].startswith(
        "/sna_wahba/stars message 5 star_id:"
    )

    def lose_one(topic: bag_values.Topic) -> None:
        topic.count -= 1

    assert _differences("star_tracker", "/clock", lose_one) == [
        "/clock: 300 rosgraph_msgs/msg/Clock messages, the reference has 301 rosgraph_msgs/msg/Clock"
    ]


@pytest.mark.parametrize(
    "change, changed",
    [
        (["--seed", "4"], None),  # another noise draw: every message but the truth's and /clock
        (["--set", "filters.ukf.params.beta=2.02"], "/ukf/"),  # 1 % of one UKF parameter: the UKF's messages only
    ],
)
def test_a_real_change_is_caught(tmp_path: Path, change: list[str], changed: str | None) -> None:
    """The test above can fail: another seed, or a small change of one filter's model, is reported (and, for the
    filter, only on that filter's topics)."""
    problems, _ = bag_values.compare(record("leo_radar", tmp_path, *change), reference("leo_radar"), RTOL)
    assert problems
    if changed is not None:
        assert all(p.startswith(changed) for p in problems), problems


@pytest.mark.skipif(
    not any(os.environ.get(k) for k in KERNEL_VARIABLES),
    reason="runs on this CPU's own kernels (make test-portable narrows them)",
)
def test_the_kernels_asked_for_change_the_last_bits_within_the_tolerance(tmp_path: Path, monkeypatch) -> None:
    """Under make test-portable: numpy and OpenBLAS run the kernels the environment asks for, and these change
    the last bits of a run (some value differs from the same run on this CPU's own kernels), by less than RTOL.
    Without the first, the portable run would prove nothing; without the second, the kernels made no difference
    here and the comparison above was not put to the test."""
    disabled = os.environ.get("NPY_DISABLE_CPU_FEATURES", "").replace(",", " ").split()
    assert not [f for f in disabled if __cpu_features__.get(f)], __cpu_features__
    if os.environ.get("OPENBLAS_CORETYPE"):
        found = {
            i["filepath"]: i["architecture"] for i in threadpoolctl.threadpool_info() if i["internal_api"] == "openblas"
        }
        assert found and {a.lower() for a in found.values()} == {os.environ["OPENBLAS_CORETYPE"].lower()}, found
    narrowed = record("leo_radar", tmp_path / "narrowed")
    for k in KERNEL_VARIABLES:
        monkeypatch.delenv(k, raising=False)
    problems, deviations = bag_values.compare(narrowed, record("leo_radar", tmp_path / "own"), RTOL)
    assert not problems, report(problems, deviations)
    assert deviations[0].scaled > 0, "the kernels asked for give the same bits as this CPU's own"


OTHER_KERNELS = {
    "numpy AVX2": {"NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR"},
    "OpenBLAS Haswell": {"OPENBLAS_CORETYPE": "Haswell"},
    "numpy AVX2 + OpenBLAS Haswell": {
        "NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR",
        "OPENBLAS_CORETYPE": "Haswell",
    },
    "numpy SSE4.2 + OpenBLAS Sandybridge": {
        "NPY_DISABLE_CPU_FEATURES": "X86_V3 X86_V4 AVX512_ICL AVX512_SPR",
        "OPENBLAS_CORETYPE": "Sandybridge",
    },
}
"""Kernel settings --measure runs: what an AVX2 CPU (an AMD Zen 2/3 runs OpenBLAS's Haswell kernels) and an
older one would run; make test-portable runs the last."""
REAL_CHANGES = [
    ("every study", ["--seed", "4"]),
    ("leo_radar", ["--set", "filters.ukf.params.beta=2.02"]),
    ("leo_radar", ["--set", "sensors.radar.sigma_range=32.0"]),
    ("leo_radar", ["--set", "earth.j2=1.0826377e-3"]),
    ("formation_cqkf", ["--set", "filter_defaults.dynamics.sigma_accel=3.03e-5"]),
    ("grace_velocity", ["--set", "filter_defaults.dynamics.q=1.01e-6"]),
    ("star_tracker", ["--set", "star_tracker_defaults.sigma_a=0.0505"]),
]
"""Changes --measure compares with the seeded runs: another noise draw, about 1 % of one parameter, and J2
changed by 1e-5 of itself (below this test's resolution)."""


def _largest(found: dict[str, bag_values.Topic], ref: dict[str, bag_values.Topic]) -> str:
    """The differences of two runs in one cell: other counts or discrete values, and the largest float
    deviation in units of its scale."""
    problems, deviations = bag_values.compare(found, ref, np.inf)
    worst = deviations[0].scaled if deviations else 0.0
    return (f"{len(problems)} discrete, " if problems else "") + f"{worst:.1e}"


def measure(tmp: Path) -> None:
    """Print how far each study's seeded run moves on other kernels than this CPU's own, and with real changes,
    in units of the scale (RTOL is the tolerance)."""
    own_env = {k: os.environ.pop(k) for k in KERNEL_VARIABLES if k in os.environ}  # this CPU's own kernels
    own = {scenario: record(scenario, tmp / scenario) for scenario in SCENARIOS}
    blas = sorted({i["architecture"] for i in threadpoolctl.threadpool_info() if i["internal_api"] == "openblas"})
    print(
        f"largest deviation from this CPU's own kernels (numpy {np.__version__}: "
        f"{[t for t in __cpu_dispatch__ if __cpu_features__.get(t)]}; OpenBLAS {blas}), in units of the scale; "
        f"RTOL {RTOL:g}"
    )
    print("| study | " + " | ".join(OTHER_KERNELS) + " |\n|---|" + "---|" * len(OTHER_KERNELS))
    for scenario in SCENARIOS:
        cells = [
            _largest(record(scenario, tmp / f"{scenario}-{i}", env=env), own[scenario])
            for i, env in enumerate(OTHER_KERNELS.values())
        ]
        print(f"| {scenario} | " + " | ".join(cells) + " |")
    print(
        "\nreal changes, against the seeded runs (on this CPU's own kernels):\n| change | study | differences |"
        "\n|---|---|---|"
    )
    for i, (where, change) in enumerate(REAL_CHANGES):
        for scenario in SCENARIOS if where == "every study" else [where]:
            cell = _largest(record(scenario, tmp / f"change{i}-{scenario}", *change), own[scenario])
            print(f"| {' '.join(change)} | {scenario} | {cell} |")
    os.environ.update(own_env)


def regenerate(scenarios: list[str], reason: str, tmp: Path) -> None:
    """Record the reference of each of ``scenarios`` anew, ``reason`` kept in it."""
    REFERENCE.mkdir(parents=True, exist_ok=True)
    for scenario in scenarios:
        topics = record(scenario, tmp / scenario)
        path = REFERENCE / f"{scenario}.npz.zst"
        bag_values.save(
            path,
            topics,
            {
                "command": f"launch.py {scenario} {' '.join(run_args(scenario))}",
                "reason": reason,
                "numpy": np.__version__,
            },
        )
        problems, deviations = bag_values.compare(topics, reference(scenario), RTOL / 10)
        assert not problems, report(problems, deviations)  # the stored precision never decides a comparison
        print(f"{path}: {len(topics)} topics, {path.stat().st_size // 1024} KiB", file=sys.stderr)


def main() -> None:
    p = argparse.ArgumentParser(
        description="Regenerate tests/data/bag_reference after a deliberate change "
        "(--reason), or measure how far the runs move on other kernels "
        "(--measure)."
    )
    p.add_argument("scenarios", nargs="*", default=SCENARIOS, help="studies to regenerate (default: all)")
    mode = p.add_mutually_exclusive_group(required=True)
    mode.add_argument("--reason", help="regenerate: why the reference changes (kept in the file)")
    mode.add_argument("--measure", action="store_true", help="print the deviations; changes nothing")
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        if args.measure:
            measure(Path(tmp))
        else:
            regenerate(args.scenarios, args.reason, Path(tmp))


if __name__ == "__main__":
    main()
