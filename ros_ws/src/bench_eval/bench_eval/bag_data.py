"""What the scorer reads from a run's bag: the truth, measurements and estimates by step (:class:`BagData`, each
estimator's :class:`Estimates`), decoded as columns (bench_engine.columns). Estimates are matched to truth and
measurements by lock-step index (``step``), never by arrival order."""

from __future__ import annotations

import multiprocessing
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from bench_engine import yamlio
from bench_engine.bag_errors import BagDamaged
from bench_engine.bag_reader import BagReader
from bench_engine.columns import Table
from bench_engine.graph import ESTIMATE, ESTIMATE_TYPE, MEASUREMENT, TRUTH_TOPIC, topic_owner
from bench_engine.scenario import upgrade_run_config
from bench_engine.stage import codec
from bench_models.states import error_labels


@dataclass
class Estimates:
    """One filter's estimates of one run, in step order."""

    steps: np.ndarray  # (K,)
    t: np.ndarray  # (K,) s
    x: np.ndarray  # (K, n)
    P: np.ndarray  # (K, n, n)
    labels: list[str]
    diagnostics: dict[str, np.ndarray]  # name -> (K,), NaN where an estimate does not carry it
    nis: np.ndarray | None = None  # (K,) the NIS of each update (NaN where none); None: not recorded

    @classmethod
    def from_table(cls, tab: Table, rows: np.ndarray) -> Estimates:
        """The estimates in rows ``rows`` of a StateEstimate topic's table (bench_engine.columns)."""
        rows = rows[np.argsort(tab["step"][rows], kind="stable")]
        labels = list(tab["labels"][rows[0]])
        n = len(error_labels(labels))  # a quaternion's covariance is of its 3-component error
        names = [tab["diagnostic_names"][i] for i in rows]
        values = [tab["diagnostic_values"][i] for i in rows]
        diag = {
            k: np.array([v[list(m).index(k)] if k in m else np.nan for m, v in zip(names, values)])
            for k in sorted(set().union(*names))
        }
        return cls(
            tab["step"][rows].astype(np.int64),
            tab.seconds()[rows],
            _stack(tab["state"], rows),
            _stack(tab["covariance"], rows).reshape(len(rows), n, n),
            labels,
            diag,
            np.asarray(tab["nis"], dtype=float)[rows],
        )


def _stack(column, rows: np.ndarray) -> np.ndarray:
    """Rows of a numeric column as one float array (a list column when its vectors' lengths vary by step)."""
    if isinstance(column, np.ndarray):
        return column[rows].astype(float)
    return np.array([column[i] for i in rows], dtype=float)


@dataclass(frozen=True)
class PerStep:
    """A step -> value dict as arrays: its steps (K,) in the dict's order, its values stacked (K, ...), and for
    the truth's (time, state) values the times (K,). Only for values that are arrays of one shape and dtype."""

    steps: np.ndarray
    values: np.ndarray
    t: np.ndarray | None = None

    @staticmethod
    def packed(by_step: dict, timed: bool = False) -> PerStep | dict:
        """``by_step`` (step -> value, or step -> (time, value) when ``timed``) as a PerStep; as it is when it is
        empty or its values are not arrays of one shape and dtype (e.g. a star camera's centroids)."""
        values = [v for _, v in by_step.values()] if timed else list(by_step.values())
        if not values or any(
            not isinstance(v, np.ndarray) or v.shape != values[0].shape or v.dtype != values[0].dtype for v in values
        ):
            return by_step
        times = np.fromiter((t for t, _ in by_step.values()), float, len(values)) if timed else None
        return PerStep(np.fromiter(by_step, np.int64, len(values)), np.stack(values), times)

    @staticmethod
    def unpacked(packed: PerStep | dict) -> dict:
        """The step -> value dict of :meth:`packed` (each value a row of the stacked array)."""
        if not isinstance(packed, PerStep):
            return packed
        rows = list(packed.values)
        return dict(zip(packed.steps.tolist(), rows if packed.t is None else zip(packed.t.tolist(), rows)))


@dataclass
class BagData:
    """The decoded content of one run's bag (plain arrays: picklable, so bags load in parallel)."""

    run: dict
    truth: dict[int, tuple[float, np.ndarray]] = field(default_factory=dict)  # step -> (t, state)
    truth_labels: list[str] = field(default_factory=list)
    measurements: dict[str, dict[int, np.ndarray]] = field(default_factory=dict)  # sensor -> step -> z
    estimates: dict[str, Estimates] = field(default_factory=dict)
    bounds: dict = field(default_factory=dict)
    """Bound name -> its bench_eval.bounds.BoundSeries over this run (filled by the scorer: prepared)."""
    path: Path | None = None
    """The bag directory it was read from (None for a run made in process): where the offline estimators'
    results are kept (bench_eval.offline_cache)."""
    offline: list[str] = field(default_factory=list)
    """The offline estimators whose estimates joined ``estimates`` (run_offline)."""
    kept: dict[tuple[str, str], Path] = field(default_factory=dict)
    """(group, name) -> the file that holds that result of ``estimates`` (group ``offline``) or ``bounds``: its
    cache file (bench_eval.offline_cache), for each result read from or written to the cache, or the file a
    scoring worker handed it over in (bench_eval.scoring.prepare_runs)."""
    _truth_index: tuple = field(default=(None,), init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        self.run = upgrade_run_config(self.run)  # a bag recorded before 'estimators' says 'filters'

    def __getstate__(self) -> dict:
        """The fields as pickled (a run sent between a scoring worker and the main process), the truth's and each
        sensor's values by step packed into arrays (:class:`PerStep`), not pickled as one small array a step: both
        processes spend that time on the cores the other runs need."""
        state = dict(self.__dict__, _truth_index=(None,))
        state["truth"] = PerStep.packed(self.truth, timed=True)
        state["measurements"] = {name: PerStep.packed(z) for name, z in self.measurements.items()}
        return state

    def __setstate__(self, state: dict) -> None:
        state["truth"] = PerStep.unpacked(state["truth"])
        state["measurements"] = {name: PerStep.unpacked(z) for name, z in state["measurements"].items()}
        self.__dict__.update(state)

    @property
    def scenario(self) -> dict:
        return self.run["scenario"]

    def truth_span(self) -> tuple[float, float]:
        """The times of the first and the last truth sample, s."""
        t = self._truth_arrays()[1]
        return float(t.min()), float(t.max())

    def truth_at(self, steps: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(which of ``steps`` have a truth sample (K,) bool, their times (k,) s, their states (k, n)): the truth
        looked up for many steps at once (arrays built by ``_truth_arrays``)."""
        known, t, states = self._truth_arrays()
        steps = np.asarray(steps, dtype=np.int64)
        at = np.minimum(np.searchsorted(known, steps), max(len(known) - 1, 0))
        covered = known[at] == steps if len(known) else np.zeros(len(steps), bool)
        return covered, t[at[covered]], states[at[covered]]

    def _truth_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The truth as arrays sorted by step (steps, t, states), built again only when ``truth`` is another dict or
        another size (a value replaced in place is not seen: the bench fills a truth once)."""
        if self._truth_index[0] is not self.truth or len(self._truth_index[1]) != len(self.truth):
            known = np.fromiter(self.truth, dtype=np.int64, count=len(self.truth))
            order = np.argsort(known, kind="stable")
            t = np.fromiter((tt for tt, _ in self.truth.values()), dtype=float, count=len(known))
            states = np.array([s for _, s in self.truth.values()], dtype=float).reshape(
                len(known), -1 if known.size else 0
            )
            self._truth_index = (self.truth, known[order], t[order], states[order])
        return self._truth_index[1:]


def load_bag(bag_dir: Path | str) -> BagData:
    """Decode truth, measurements and estimates of a recorded run (as columns: bench_engine.columns)."""
    bag_dir = Path(bag_dir)
    config = bag_dir / "run_config.yaml"
    if not config.is_file():
        raise FileNotFoundError(f"{bag_dir} has no run_config.yaml: not a bag recorded by this bench")
    try:
        data = BagData(yamlio.load(config.read_text()), path=bag_dir)
        data.scenario.get("scenario")
    except (yaml.YAMLError, UnicodeDecodeError, LookupError, TypeError, AttributeError) as err:
        raise BagDamaged(f"{config} is not a run config written by this bench (damaged or edited)") from err
    reader = BagReader(bag_dir)
    types = reader.topics()
    sensors = {t: topic_owner(t, MEASUREMENT) for t in types}
    wanted = [
        t
        for t in types
        if t == TRUTH_TOPIC
        or sensors[t] is not None
        or (topic_owner(t, ESTIMATE) is not None and types[t] == ESTIMATE_TYPE)
    ]
    for topic, tab in reader.tables(wanted).items():
        steps = tab["step"].tolist()
        if topic == TRUTH_TOPIC:
            data.truth = dict(zip(steps, zip(tab.seconds().tolist(), _stack(tab["state"], np.arange(len(tab))))))
            data.truth_labels = list(tab["labels"][-1])
        elif sensors[topic] is not None:
            reader = codec(types[topic])
            vectors = reader.measurement_vectors(tab) if hasattr(reader, "measurement_vectors") else None
            data.measurements.setdefault(sensors[topic], {}).update(
                zip(steps, vectors)
                if vectors is not None
                else ((step, reader.decode(tab.row(i)).z) for i, step in enumerate(steps))
            )
        else:
            owners = np.array(tab["filter_name"], dtype=object)
            for name in dict.fromkeys(owners):
                data.estimates[name] = Estimates.from_table(tab, np.flatnonzero(owners == name))
    return data


def load_bags(bags: list[Path | str | BagData], jobs: int = 2) -> list[BagData]:
    """Load several bags, in ``jobs`` worker processes when there are many; a BagData item (a bag loaded
    already, e.g. as its run ended) is taken as it is."""
    paths = [b for b in bags if not isinstance(b, BagData)]
    if len(paths) <= 2 or jobs <= 1:
        loaded = iter([load_bag(b) for b in paths])
    else:
        with ProcessPoolExecutor(jobs, mp_context=multiprocessing.get_context("forkserver")) as pool:  # as below
            loaded = iter(list(pool.map(load_bag, paths, chunksize=4)))
    return [b if isinstance(b, BagData) else next(loaded) for b in bags]
