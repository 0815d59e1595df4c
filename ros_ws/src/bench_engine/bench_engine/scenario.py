"""The engine's own scenario keys (the top level) and the scenario as a whole: its registered sections.

A scenario's top-level keys are the engine's (:class:`EngineKeys`: ``scenario``, ``description``, ``seed``,
``time``, ``estimators``, ``standard_views``, ``variants``, ``sweeps``) and the sections the packages register
(entry-point group ``tracking_bench.sections``: a bench_engine.settings.SectionReader each, named after its
key). :func:`check_top_level` reads them all strictly; :func:`coerce_scenario` gives every declared value its
type (a node's ROS parameters); bench_engine.settings_reference documents them from the same declarations.

Vocabulary: an *estimator* is any node that publishes estimates (``/NAME/estimate``): a filter, a tracker, a
smoother, a star identifier. ``estimators`` selects the ones a run starts, of any kind. The ``filters`` section
configures the filter-type estimators only (beside ``trackers``, ``star_trackers``, …).
"""

from __future__ import annotations

from dataclasses import dataclass

from bench_engine import plugins
from bench_engine.settings import NON_NEGATIVE, Check, SectionReader, Settings, coerce, read, read_key, setting
from bench_engine.timegrid import Time

NAME = Check(
    lambda names: len(set(names)) == len(names) and all(n.replace("_", "").isalnum() for n in names),
    "a list of distinct names (letters, digits and underscores)",
)


@dataclass(frozen=True, kw_only=True)
class EngineKeys(Settings):
    """The top-level keys the engine reads itself."""

    scenario: str = setting(
        "", doc="the scenario's name, in reports and run directories", default_text="the file's name without .yaml"
    )
    description: str = setting("", doc="what the scenario is, for people (not read by any node)")
    seed: int = setting(
        0,
        doc="the run's random seed: sensors, random filters and seeded truth models draw from "
        "it (--seed overrides it; Monte Carlo runs take seed, seed + 1, …)",
        check=NON_NEGATIVE,
    )
    time: Time = setting(doc="the lock-step time grid")
    estimators: list[str] | None = setting(
        None,
        old=("default_filters",),
        check=NAME,
        doc="the estimators a run starts when the command line selects none (--estimators): names of any "
        "estimator kind (a filter, a tracker, a star tracker, …; bench_engine.graph.resolve_estimators)",
        default_text="every estimator the scenario's sections define",
    )
    standard_views: bool = setting(
        True,
        doc="publish and record the standard ROS views of every estimate and "
        "truth (Odometry, pose, markers, diagnostics: bench_engine.views); "
        "Monte Carlo batches turn them off",
    )
    variants: dict = setting(
        {},
        doc="named sets of overrides ({key.path: value} each) that --variant applies "
        "on top of the file, in the order given",
    )
    sweeps: dict = setting(
        {}, doc="named grids of runs over variants and overrides (bench_eval.sweep; scripts/sweep.py --grid NAME)"
    )


def section_readers() -> dict[str, object]:
    """Every registered section reader by key (a SectionReader, or a plain function cfg -> typed section)."""
    return plugins.registered("sections")


def check_top_level(cfg: dict) -> EngineKeys:
    """The engine's keys, read strictly; a top-level key that is neither one of them nor a registered section
    raises ScenarioError naming it."""
    return read(EngineKeys, cfg, "", others=section_readers())


def scenario_seed(cfg: dict) -> int:
    """The scenario's ``seed`` (an integer >= 0, default 0), read strictly."""
    return read_key(EngineKeys, cfg, "seed")


def default_estimators(cfg: dict) -> list[str] | None:
    """The scenario's ``estimators`` (or its deprecated name ``default_filters``, with a notice); None if unset."""
    return read_key(EngineKeys, cfg, "estimators")


def coerce_scenario(cfg: dict) -> dict:
    """A copy of ``cfg`` with every declared value of its declared type (bench_engine.settings.coerce) and
    deprecated keys under their names of today; nothing is checked."""
    out = coerce(EngineKeys, cfg)
    for key, reader in section_readers().items():
        if key in out and isinstance(reader, SectionReader):
            out[key] = reader.coerce(out[key])
    return out


def upgrade_run_config(run: dict) -> dict:
    """A run config (``run_config.yaml``: bench_engine.launcher.prepare_run) of any version with its selected
    estimators under ``estimators`` (bags recorded before this name say ``filters``). The scenario in it is
    left as recorded: its readers take the old key names (``default_filters``) with a notice. Anything that is
    no run config is returned as it is (its reader reports it)."""
    if not isinstance(run, dict) or "filters" not in run or "estimators" in run:
        return run
    return {("estimators" if k == "filters" else k): v for k, v in run.items()}
