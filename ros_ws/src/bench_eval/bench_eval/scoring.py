"""Offline scoring from bags only: bag -> offline estimators -> aligned tracks -> the scenario's metric family.

A bag directory written by the recorder carries the run config (``run_config.yaml``: the resolved scenario),
so the scorer rebuilds the same sensor models the run used (a metric maps estimates into a sensor's coordinates).
Estimates are matched to truth and measurements by lock-step index (``step``), never by arrival order.
"""

from __future__ import annotations

import dataclasses
import multiprocessing
import os
import tempfile
import uuid
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import numpy as np
import yaml
from tqdm import tqdm

from bench_engine import plugins, yamlio
from bench_engine.config import ScenarioError
from bench_engine.settings import SectionReader, Settings, read, setting, variant
from bench_eval import metrics, offline_cache
from bench_eval.bag_data import BagData, Estimates, load_bag, load_bags  # noqa: F401 - the scorer's inputs, importable from here
from bench_eval.bounds import BoundRun, BoundSeries, score_bounds
from bench_eval.consistency import innovation_scores, score_without_truth
from bench_eval.errors import NothingToScore  # noqa: F401 - raised here, importable from here
from bench_eval.window import EDGES, ScoringWindow, check_window
from bench_models.states import error_labels


@dataclass(frozen=True, kw_only=True)
class OfflineRun(Settings):
    """One entry of ``scoring.offline``: the offline ``estimator`` (registered in tracking_bench.offline) run over
    the recorded estimates or measurements of ``source`` with its ``params``; scored under its own name."""

    estimator: str = setting(
        doc="a registered offline estimator (entry-point group tracking_bench.offline)",
        choices=lambda: plugins.names("offline"),
    )
    source: str = setting(doc="the estimator or measurement of the run it runs over")
    params: Settings = variant(
        "estimator",
        lambda: plugins.names("offline"),
        lambda name: plugins.load("offline", name).params,
        inline=False,
        doc="the offline estimator's parameters",
    )


@dataclass(frozen=True, kw_only=True)
class ScoringOptions(Settings):
    """The scenario's ``scoring`` section: the metric family with its options, offline estimators and bounds."""

    metric: str = setting(
        doc="a registered metric family (entry-point group tracking_bench.metrics)",
        choices=lambda: plugins.names("metrics"),
    )
    offline: dict[str, OfflineRun] = setting(
        {}, doc="offline estimators run over every bag and scored under their names (bench_eval.offline)"
    )
    bounds: dict[str, BoundRun] = setting({}, doc="lower bounds to score the estimators against (bench_eval.bounds)")
    window: ScoringWindow | None = setting(
        None,
        doc="the part of each run every estimator is scored over (bench_eval.window; null: each over all of its steps)",
    )
    options: Settings = variant(
        "metric", lambda: plugins.names("metrics"), lambda name: plugins.load("metrics", name).options
    )


def scoring_options(cfg: dict) -> ScoringOptions:
    """The scenario's ``scoring`` section, read strictly; each offline estimator and bound then checks its
    source and parameters against the scenario."""
    opts = read(ScoringOptions, cfg.get("scoring"), "scoring")
    for job in opts.offline.values():
        plugins.load("offline", job.estimator).check(cfg, job.source, job.params)
    for run in opts.bounds.values():
        plugins.load("bounds", run.bound).check(cfg, run.params)
    check_window(opts.window, cfg)
    return opts


SCORING = SectionReader(
    "scoring",
    ScoringOptions,
    "how the bags are scored: the metric family, offline "
    "estimators, bounds and the scoring window (bench_eval.scoring)",
    scoring_options,
)


def prepared(run: Path | str | BagData, cache: bool = True) -> BagData:
    """One run made ready to score: its bag read (unless it is a BagData already), its offline estimators run
    or read from the cache beside the bag (bench_eval.offline_cache), its bounds computed. The scorer's task,
    in a worker process or on a Dask worker."""
    data = run if isinstance(run, BagData) else load_bag(run)
    opts = scoring_options(data.scenario)
    data.offline = run_offline(data, opts, cache)
    for name, b in opts.bounds.items() if data.truth else ():  # a run without truth: no bound (score_bags)
        if name not in data.bounds:
            data.bounds[name] = _cached(
                data,
                cache,
                "bounds",
                name,
                b.bound,
                b.params,
                None,
                lambda b=b: plugins.load("bounds", b.bound).run(data, b.params),
            )
    return data


_IN_WORKER = False


def in_scoring_worker() -> bool:
    """True in a process that :func:`prepare_runs` gave bags to prepare (a pool worker or a Dask worker): the
    bags share the CPUs there, so a task should start no processes of its own."""
    return _IN_WORKER


def _prepared_in_worker(run: Path | str | BagData, cache: bool = True, hand_over: Path | None = None) -> BagData:
    """:func:`prepared` in a scoring worker (:func:`in_scoring_worker`); with ``hand_over`` (a worker on this
    host, which sees the same files: a directory) its results handed over by file (:func:`_handed_over`)."""
    global _IN_WORKER
    _IN_WORKER = True
    data = prepared(run, cache)
    return data if hand_over is None else _handed_over(data, hand_over)


def _handed_over(data: BagData, directory: Path) -> BagData:
    """``data`` without the arrays of its offline results and bounds (each left as None in its place), which go
    by file: those the cache keeps stay where they are (``data.kept``), the others are first written to
    ``directory`` (bench_eval.offline_cache.store; a result that cannot be written stays in ``data``). The process
    it goes to maps them from the files (:func:`_taken_back`) instead of receiving them pickled through a pipe
    (a grace_velocity day's orbit fits are ~100 MB a run)."""
    results = [("offline", n, data.estimates[n]) for n in data.offline] + [("bounds", *b) for b in data.bounds.items()]
    for group, name, result in results:
        if (group, name) not in data.kept:
            file = directory / f"{group}-{name}-{uuid.uuid4().hex}.npz"
            if offline_cache.store(file, result, "sent through the pipe"):
                data.kept[group, name] = file
    estimates = {n: None if ("offline", n) in data.kept else e for n, e in data.estimates.items()}
    bounds = {n: None if ("bounds", n) in data.kept else b for n, b in data.bounds.items()}
    return dataclasses.replace(data, estimates=estimates, bounds=bounds)


def _taken_back(data: BagData, cache: bool) -> BagData:
    """A run from :func:`_handed_over` with its results mapped from their files; prepared again here if a file
    cannot be read any more (removed or replaced since)."""
    for (group, name), file in data.kept.items():
        arrays = offline_cache.load(file, group)
        if arrays is None:
            return prepared(data.path, cache)
        getattr(data, "estimates" if group == "offline" else group)[name] = _from_arrays(group, arrays)
    return data


def prepare_runs(
    runs: list[Path | str | BagData], jobs: int | None = None, scheduler: str | None = None, cache: bool = True
) -> list[BagData]:
    """:func:`prepared` of every run, in order: ``jobs`` at a time in worker processes (default: every CPU this
    process may use), or on the Dask cluster at ``scheduler`` (an address, or ``"local"``:
    bench_engine.executors), with a progress bar; in this process when there is one run or one job. ``cache``:
    offline estimates and bounds kept beside each bag and read back (bench_eval.offline_cache)."""
    jobs = len(os.sched_getaffinity(0)) if jobs is None else max(1, int(jobs))  # the CPUs it may use
    if scheduler is not None:
        from bench_engine.executors import map_dask  # dask: imported only when a cluster scores

        task = partial(_prepared_in_worker, cache=cache)  # whole: a cluster's workers may not share our files
        return map_dask(task, runs, scheduler, jobs, desc="scoring")
    if jobs == 1 or len(runs) == 1:
        return [prepared(r, cache) for r in tqdm(runs, unit="run", desc="scoring", disable=len(runs) == 1)]
    # forkserver, not fork: a process forked from a threaded one (a test runner, a node) may inherit a held lock
    with (
        tempfile.TemporaryDirectory(prefix="scoring-") as hand_over,
        ProcessPoolExecutor(min(jobs, len(runs)), mp_context=multiprocessing.get_context("forkserver")) as pool,
    ):
        task = partial(_prepared_in_worker, cache=cache, hand_over=Path(hand_over))  # a worker here: the same files
        done = tqdm(pool.map(task, runs), total=len(runs), unit="run", desc="scoring")
        return [_taken_back(data, cache) for data in done]  # mapped: the files may go (POSIX keeps mapped data)


def track_of(data: BagData, filter_name: str) -> metrics.Track:
    """Estimates of one filter aligned with the truth of the same steps: the estimate's components that the
    truth has, matched by label wherever they sit in either state (e.g. a bias block first), with the
    covariance of their errors (bench_models.states.error_labels). Steps without a truth sample (an imported
    TDM whose reference covers part of it: bench_ccsds.ingest) are left out."""
    est = data.estimates[filter_name]
    covered, _, truth = data.truth_at(est.steps)
    if not covered.all():
        est = Estimates(
            est.steps[covered],
            est.t[covered],
            est.x[covered],
            est.P[covered],
            est.labels,
            {k: v[covered] for k, v in est.diagnostics.items()},
            None if est.nis is None else est.nis[covered],
        )
    for labels, whose in ((est.labels, f"estimator '{filter_name}'"), (data.truth_labels, "the truth")):
        if len(set(labels)) != len(labels):
            raise ValueError(f"{whose} repeats state labels {labels}: components are matched by label")
    scored = [i for i, lab in enumerate(est.labels) if lab in data.truth_labels]
    labels = [est.labels[i] for i in scored]
    all_errors, errors = error_labels(est.labels), error_labels(labels)
    cov = [all_errors.index(lab) for lab in errors]
    truth_index = [data.truth_labels.index(lab) for lab in labels]
    return metrics.Track(est.t, est.x[:, scored], metrics.covariance_block(est.P, cov), truth[:, truth_index], labels)


def _scenario_name(runs: list[BagData]) -> str:
    return _one_scenario({d.scenario.get("scenario") for d in runs})


def _one_scenario(names: set) -> str:
    if len(names) != 1:
        raise ScenarioError(
            f"bags of different scenarios cannot be scored together: {sorted(map(str, names))}; "
            "score each scenario's bags separately"
        )
    return names.pop()


def _recorded_scenario(bag: Path | str | BagData) -> str | None:
    """The scenario name in a bag's run config, None where it cannot be read (load_bag then says why)."""
    if isinstance(bag, BagData):
        return bag.scenario.get("scenario")
    try:
        return yamlio.load((Path(bag) / "run_config.yaml").read_text())["scenario"]["scenario"]
    except (OSError, yaml.YAMLError, UnicodeDecodeError, LookupError, TypeError):
        return None


def run_offline(data: BagData, opts: ScoringOptions, cache: bool = True) -> list[str]:
    """Run the scoring section's offline estimators over one run's recorded estimates or measurements
    (bench_eval.offline); their estimates join ``data.estimates``. A run read from a bag keeps each result
    beside it and reads it back next time (bench_eval.offline_cache; ``cache=False``: neither). Returns the
    names of the estimators that ran (or were read back)."""
    ran = []
    for name, job in opts.offline.items():
        if job.source in data.estimates or job.source in data.measurements:
            data.estimates[name] = _cached(
                data,
                cache,
                "offline",
                name,
                job.estimator,
                job.params,
                job.source,
                lambda job=job: plugins.load("offline", job.estimator).run(data, job.source, job.params),
            )
            ran.append(name)
    return ran


def _cached(
    data: BagData, cache: bool, group: str, name: str, component: str, params: dict, source: str | None, compute
):
    """``compute()``, or its result kept beside the run's bag (bench_eval.offline_cache), which it then keeps;
    computed without a cache for a run made in process or with ``cache`` off."""
    if not cache or data.path is None:
        return compute()
    file = offline_cache.path(
        data.path, group, name, offline_cache.key(data.path, group, name, component, params, source)
    )
    arrays = offline_cache.load(file, group)
    if arrays is not None:
        data.kept[group, name] = file
        return _from_arrays(group, arrays)
    result = compute()
    if offline_cache.store(file, result):
        data.kept[group, name] = file
    return result


def _from_arrays(group: str, a: dict[str, np.ndarray]):
    """The Estimates (group ``offline``) or BoundSeries (``bounds``) of a cache file's arrays."""
    steps, t, P, labels = (
        a["steps"].astype(np.int64, copy=False),
        a["t"].astype(float, copy=False),
        a["P"].astype(float, copy=False),
        a["labels"],
    )
    if group == "bounds":
        return BoundSeries(steps, t, [str(s) for s in labels], P)
    return Estimates(
        steps,
        t,
        a["x"].astype(float, copy=False),
        P,
        [str(s) for s in labels],
        {str(n): v.astype(float, copy=False) for n, v in zip(a["diagnostic_names"], a["diagnostic_values"])},
    )


def scored_estimators(data: BagData, offline: list[str]) -> list[str]:
    """The estimators of a run that are scored against the truth: the run's selected ones, the offline estimators,
    then any other estimator of the bag (a tracker, a smoother, a pipeline stage) that estimates truth
    components (e.g. a 9-state kinematic smoother whose positions and velocities are in the truth)."""
    names = [n for n in data.run["estimators"] + offline if n in data.estimates]
    return names + sorted(
        n for n, e in data.estimates.items() if n not in names and e.labels and set(e.labels) & set(data.truth_labels)
    )


def collect(
    bag_dirs: list[Path | str | BagData], jobs: int | None = None, scheduler: str | None = None, cache: bool = True
) -> tuple[str, ScoringOptions, list[BagData], list[list[str]]]:
    """Load the bags and run the offline estimators over each whole run, and the bounds (:func:`prepare_runs`: in
    parallel, offline results cached beside the bags): (scenario, scoring options, runs, the scored estimators of
    each run)."""
    _one_scenario({_recorded_scenario(b) for b in bag_dirs} - {None} or {None})  # before any bag is prepared
    runs = prepare_runs(bag_dirs, jobs, scheduler, cache)
    scenario = _scenario_name(runs)
    opts = scoring_options(runs[0].scenario)
    return scenario, opts, runs, [scored_estimators(data, data.offline) for data in runs]


def _tracks(runs: list[BagData], scored: list[list[str]]) -> dict[str, list[metrics.Track]]:
    """Every scored estimator's estimates aligned with the truth, one Track per run that has it."""
    tracks: dict[str, list[metrics.Track]] = {}
    for data, names in zip(runs, scored):
        for name in names:
            if data.truth and any(int(k) in data.truth for k in data.estimates[name].steps):
                tracks.setdefault(name, []).append(track_of(data, name))
    return tracks


def _part(
    runs: list[BagData], scored: list[list[str]], window: ScoringWindow | None, part: str = "window"
) -> tuple[list[BagData], list[list[str]]]:
    """The runs cut to ``part`` of the scoring window (bench_eval.window), with the estimators scored there."""
    if window is None:
        return runs, scored
    cut = [window.cut(data, names, part) for data, names in zip(runs, scored)]
    return [c[0] for c in cut], [c[1] for c in cut]


def _score_edges(blocks: dict, family, runs: list[BagData], scored: list[list[str]], opts: ScoringOptions) -> None:
    """Add to each scored estimator's block ``edges: {head, tail}``, the metric family's scores over each edge of
    the runs (bench_eval.window: each estimator over its own steps there)."""
    for edge in EDGES:
        part, there = _part(runs, scored, opts.window, edge)
        tracks = _tracks(part, there)
        if tracks:
            for name, block in family.score(tracks, part, opts.options).items():
                if name in blocks:
                    blocks[name].setdefault("edges", {})[edge] = block


def score_bags(
    bag_dirs: list[Path | str | BagData],
    with_series: bool = False,
    jobs: int | None = None,
    scheduler: str | None = None,
    cache: bool = True,
):
    """Score one or more bags of the same scenario (several bags = Monte Carlo runs, paper 000 eq. 35) with
    the metric family the scenario's ``scoring.metric`` names, over the scenario's scoring window
    (bench_eval.window: every estimator over the same steps; with ``edges``, the head and tail apart); the runs are
    prepared ``jobs`` at a time (default every CPU) or on a Dask cluster (``scheduler``), each offline estimator's
    result kept beside its bag (``cache``; :func:`prepare_runs`).

    Returns {"scenario", "runs", "metric", "estimators": {name: scores}} (and the plot series when
    ``with_series``), plus ``window`` {head_s, tail_s, steps: scored steps per run} when the scenario has one.
    """
    scenario, opts, whole, everyone = collect(bag_dirs, jobs, scheduler, cache)
    if not any(data.truth for data in whole) and any(data.estimates for data in whole):
        return score_without_truth(scenario, whole, with_series)
    runs, scored = _part(whole, everyone, opts.window)
    tracks = _tracks(runs, scored)
    if not tracks:
        found = [b.run.get("bag_dir", "a loaded bag") if isinstance(b, BagData) else str(b) for b in bag_dirs]
        raise NothingToScore(
            f"no estimates in {', '.join(found)}"
            f"{' (in the scoring window)' if opts.window else ''}: the run's filters published "
            "nothing (did the sensors ever see the target?)"
        )
    family = plugins.load("metrics", opts.metric)
    result = {
        "scenario": scenario,
        "runs": len(runs),
        "metric": opts.metric,
        "estimators": family.score(tracks, runs, opts.options),
    }
    bound_scores, bound_series = score_bounds(tracks, runs, opts.bounds)
    for name, block in bound_scores.items():
        result["estimators"].setdefault(name, {})["bounds"] = block
    if any("ccsds_import" in data.run for data in runs):  # real data scored against a reference: what needs none too
        for name, block in innovation_scores(runs).items():
            result["estimators"].setdefault(name, {}).update(block)
    if opts.window is not None:
        result["window"] = {
            "head_s": opts.window.head_s,
            "tail_s": opts.window.tail_s,
            "steps": [len(data.estimates[names[0]].steps) if names else 0 for data, names in zip(runs, scored)],
        }
        if opts.window.edges:
            _score_edges(result["estimators"], family, whole, everyone, opts)
    if not with_series:
        return result
    series = family.series(tracks, runs, opts.options)
    for name, block in bound_series.items():
        if name in series:
            series[name]["bounds"] = block
    return result, series
