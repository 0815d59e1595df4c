"""A filter's settings, declared once: ``filters.NAME`` over ``filter_defaults``, its dynamics model, its
initialiser and its estimator type's parameters (bench_engine.settings).

Cheap to import (the filter node kind reads it to build the graph, and the graph reads every node kind): the
registered dynamics models and initialisers are :class:`~bench_engine.settings.Builder`s whose settings are
declared here and whose builders (tracker_filters.builders) are imported when a filter is built.

    type: ukf                 # a registered estimator (entry-point group tracking_bench.estimators)
    sensors: [radar]          # measurement topics it consumes
    dynamics: {model: orbit_j2, sigma_accel: 0.5}
    init: {method: first_scan, velocity_sigma: 8000.0}
    params: {alpha: 1.0}      # constructor parameters of the filter type
    gate_probability: 0.9999  # optional NIS gate: reject measurements beyond this chi-square quantile
    gate_reinit_after: 3      # that many consecutive gated measurements: lock lost, restart from the next one
"""

from __future__ import annotations

import inspect
from dataclasses import dataclass, make_dataclass
from functools import cache
from typing import Any

from bench_engine import plugins
from bench_engine.config import ScenarioError, merge
from bench_engine.labels import BIAS, ORBIT
from bench_engine.settings import (
    NON_NEGATIVE,
    POSITIVE,
    Builder,
    Check,
    SectionReader,
    Settings,
    at_least,
    read,
    read_key,
    setting,
    variant,
)
from orbit_sim.relative import CONVENTIONS

# --- dynamics models ------------------------------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class OrbitJ2(Settings):
    """``orbit_j2``: two-body + J2 orbit in ECI (the scenario's earth), white acceleration noise."""

    sigma_accel: float = setting(
        unit="m/s^1.5", check=NON_NEGATIVE, doc="square root of the white-acceleration spectral density"
    )

    def state_labels(self) -> tuple[str, ...]:
        return ORBIT


def _one_or_three(value: float | list[float]) -> bool:
    values = value if isinstance(value, list) else [value]
    return len(values) in (1, 3) and all(v >= 0 for v in values)


@dataclass(frozen=True, kw_only=True)
class RelativeMotion(Settings):
    """A linear relative-motion model about the chief of ``truth.chief`` (LVLH: x radial, y along, z normal)."""

    sigma_accel: float | list[float] = setting(
        unit="m/s^1.5",
        check=Check(_one_or_three, ">= 0, one value or three"),
        doc="square root of the white-acceleration spectral density: one value, or one per LVLH axis (radial, "
        "along, normal)",
    )
    reference: str = setting(
        "stated",
        choices=("stated", "mean"),
        doc="the chief's reference radius: stated (its a) or mean (its orbit-averaged |r| under the truth's gravity)",
    )

    def state_labels(self) -> tuple[str, ...]:
        return ORBIT


@dataclass(frozen=True, kw_only=True)
class Cw(RelativeMotion):
    """``cw``: Clohessy-Wiltshire."""

    discretisation: str = setting(
        "exact", choices=("exact", "euler"), doc="the transition matrix: the exact exponential or Euler's first order"
    )


@dataclass(frozen=True, kw_only=True)
class CwBias(RelativeMotion):
    """``cw_bias``: Clohessy-Wiltshire with a constant unknown acceleration bias in the state (9 states)."""

    sigma_bias: float = setting(
        unit="m/s^2.5", check=NON_NEGATIVE, doc="square root of the bias's random-walk spectral density"
    )

    def state_labels(self) -> tuple[str, ...]:
        return ORBIT + BIAS


@dataclass(frozen=True, kw_only=True)
class Ss(RelativeMotion):
    """``ss``: Schweighart-Sedwick (CW with the J2-averaged terms)."""


@dataclass(frozen=True, kw_only=True)
class WhiteJerk(Settings):
    """``white_jerk``: paper 002's kinematic model, white jerk on positions, velocities, accelerations."""

    q: float = setting(unit="m^2/s^5", check=NON_NEGATIVE, doc="the white jerk's spectral density")
    labels: list[str] = setting(
        doc="the state: 3 positions, 3 velocities, 3 accelerations, in that order",
        check=Check(
            lambda v: len(v) == 9 and len(set(v)) == 9,
            "9 distinct components (3 positions, 3 velocities, 3 accelerations)",
        ),
    )
    frame: str = setting("eci", doc="the frame of the state (header.frame_id of the estimates)")

    def state_labels(self) -> tuple[str, ...]:
        return tuple(self.labels)


ORBIT_J2 = Builder(OrbitJ2, "tracker_filters.builders:orbit_j2")
CW = Builder(Cw, "tracker_filters.builders:cw")
CW_BIAS = Builder(CwBias, "tracker_filters.builders:cw_bias")
SS = Builder(Ss, "tracker_filters.builders:ss")
WHITE_JERK = Builder(WhiteJerk, "tracker_filters.builders:white_jerk")


@dataclass(frozen=True, kw_only=True)
class DynamicsSettings(Settings):
    """A filter's ``dynamics``: a registered model (tracking_bench.dynamics) with its keys, and optionally a
    given process noise."""

    model: str = setting(
        doc="a registered dynamics model (entry-point group tracking_bench.dynamics)",
        choices=lambda: plugins.names("dynamics"),
    )
    q_diagonal: list[float] | None = setting(
        None,
        check=Check(lambda q: all(v >= 0 for v in q), "a list of values >= 0"),
        doc="the per-step discrete process noise Q's diagonal at q_reference_dt, in q_convention axes, instead of "
        "the model's own (one value per state component)",
    )
    q_convention: str = setting("radial_along_normal", choices=CONVENTIONS, doc="the axes of q_diagonal")
    q_reference_dt: float = setting(1.0, unit="s", check=POSITIVE, doc="the step q_diagonal is given for")
    options: Settings = variant(
        "model", lambda: plugins.names("dynamics"), lambda name: plugins.load("dynamics", name).settings
    )


# --- initialisers ---------------------------------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class FirstScan(Settings):
    """``first_scan``: position from the first measurement (its model's inverse), velocity unknown."""

    velocity_sigma: float = setting(unit="m/s", check=POSITIVE, doc="the initial velocity's standard deviation")


def _six(what: str, test=lambda v: True) -> Check:
    return Check(lambda v: len(v) == 6 and all(test(x) for x in v), what)


@dataclass(frozen=True, kw_only=True)
class Given(Settings):
    """``given``: the initial estimate and standard deviations the paper states."""

    convention: str = setting("radial_along_normal", choices=CONVENTIONS, doc="the axes of mean and sigma")
    mean: list[float] = setting(unit="m, m/s", check=_six("6 values"), doc="initial relative position and velocity")
    sigma: list[float] = setting(
        unit="m, m/s", check=_six("6 values > 0", lambda x: x > 0), doc="their standard deviations"
    )
    bias_mean: list[float] | None = setting(
        None, unit="m/s^2", doc="initial bias of a 9-state filter", default_text="zeros"
    )
    bias_sigma: list[float] | None = setting(
        None, unit="m/s^2", doc="its standard deviations (9-state filter)", default_text="zeros"
    )


@dataclass(frozen=True, kw_only=True)
class TruthScaled(Settings):
    """``truth_scaled``: the true initial state with a relative error (paper 004), diagonal P0."""

    error_fraction: float = setting(check=NON_NEGATIVE, doc="x0 = x_true (1 + error_fraction)")
    sigma_position: float = setting(unit="m", check=POSITIVE, doc="initial position standard deviation")
    sigma_velocity: float = setting(unit="m/s", check=POSITIVE, doc="initial velocity standard deviation")
    sigma_bias: float = setting(1e-6, unit="m/s^2", check=POSITIVE, doc="initial bias standard deviation (CW+bias)")
    bias_mean: list[float] | None = setting(
        None, unit="m/s^2", doc="initial bias of a 9-state filter", default_text="zeros"
    )


@dataclass(frozen=True, kw_only=True)
class PositionFix(Settings):
    """``position_fix``: the first measurement's components of a kinematic state (positions, velocities,
    accelerations); the others zero mean."""

    sigma_velocity: float = setting(unit="m/s", check=POSITIVE, doc="the velocities' prior standard deviation")
    sigma_acceleration: float = setting(unit="m/s^2", check=POSITIVE, doc="the accelerations' prior standard deviation")


FIRST_SCAN = Builder(FirstScan, "tracker_filters.builders:first_scan")
GIVEN = Builder(Given, "tracker_filters.builders:given")
TRUTH_SCALED = Builder(TruthScaled, "tracker_filters.builders:truth_scaled")
POSITION_FIX = Builder(PositionFix, "tracker_filters.builders:position_fix")


@dataclass(frozen=True, kw_only=True)
class InitSettings(Settings):
    """A filter's ``init``: a registered initialiser (tracking_bench.initialisers) with its keys."""

    method: str = setting(
        doc="a registered initialiser (entry-point group tracking_bench.initialisers)",
        choices=lambda: plugins.names("initialisers"),
    )
    options: Settings = variant(
        "method", lambda: plugins.names("initialisers"), lambda name: plugins.load("initialisers", name).settings
    )


# --- estimator parameters -------------------------------------------------------------------------------------


@cache
def estimator_parameters(name: str) -> type:
    """The Settings class of registered estimator type ``name``'s parameters: its constructor's keyword
    arguments after the dynamics model, with their annotations and defaults."""
    cls = plugins.load("estimators", name)
    params = list(inspect.signature(cls.__init__, eval_str=True).parameters.values())[2:]
    fields = []
    for p in params:
        if p.kind not in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY):
            continue
        hint = Any if p.annotation is p.empty else p.annotation
        default = ... if p.default is p.empty else p.default
        doc = f"argument {p.name} of {cls.__module__}.{cls.__qualname__}"
        fields.append((p.name, hint, setting(doc=doc) if default is ... else setting(default, doc=doc)))
    return make_dataclass(f"{cls.__name__}Parameters", fields, bases=(Settings,), frozen=True, kw_only=True)


# --- the filter -----------------------------------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class FilterSettings(Settings):
    """One filter: ``filters.NAME`` merged over ``filter_defaults``."""

    type: str = setting(
        doc="a registered estimator type (entry-point group tracking_bench.estimators)",
        choices=lambda: plugins.names("estimators"),
        default_text="the filter's name",
    )
    sensors: list[str] | None = setting(
        None, doc="the sensors and derived measurements it consumes", default_text="every sensor"
    )
    dynamics: DynamicsSettings = setting(doc="its dynamics model")
    init: InitSettings = setting(doc="how it starts")
    params: Settings = variant(
        "type",
        lambda: plugins.names("estimators"),
        estimator_parameters,
        inline=False,
        doc="its estimator type's parameters",
    )
    gate_probability: float = setting(
        0.0,
        check=Check(lambda v: 0.0 <= v < 1.0, "in [0, 1) (0 = no gate)"),
        doc="reject a measurement whose NIS is beyond this chi-square quantile",
    )
    gate_reinit_after: int = setting(
        3,
        check=at_least(1),
        doc="after this many consecutive gated measurements the filter has lost lock: restart from the next",
    )


def filter_config(cfg: dict, name: str) -> dict:
    """A filter's settings as written: ``filter_defaults`` merged with ``filters.NAME`` (type defaults to NAME)."""
    defaults, own = cfg.get("filter_defaults") or {}, (cfg.get("filters") or {}).get(name) or {}
    for key, value in (("filter_defaults", defaults), (f"filters.{name}", own)):
        if not isinstance(value, dict):
            raise ScenarioError(f"'{key}' must be a mapping of settings, got {value!r}")
    merged = merge(defaults, own)
    merged.setdefault("type", name)
    return merged


def filter_settings(cfg: dict, name: str) -> FilterSettings:
    """Filter ``name``'s settings, read strictly (ScenarioError naming a bad key)."""
    return read(FilterSettings, filter_config(cfg, name), f"filters.{name}")


def filter_key(cfg: dict, name: str, key: str) -> Any:
    """One key of filter ``name`` (e.g. its ``sensors`` or ``dynamics`` for the graph), read as
    :func:`filter_settings` reads it but without the rest (the estimator type's parameters load the filters)."""
    return read_key(FilterSettings, filter_config(cfg, name), key, f"filters.{name}")


def state_labels(cfg: dict, name: str) -> tuple[str, ...] | None:
    """The labels of filter ``name``'s state, from its dynamics settings (None for a registered model whose
    settings do not say them)."""
    options = filter_key(cfg, name, "dynamics").options
    return options.state_labels() if hasattr(options, "state_labels") else None


def read_filters(cfg: dict) -> dict[str, FilterSettings]:
    """The ``filters`` section (the reader of ``filters`` and ``filter_defaults``): each filter's settings."""
    filters = cfg.get("filters") or {}
    if not isinstance(filters, dict):
        raise ScenarioError(f"'filters' must be a mapping of filter names to settings, got {filters!r}")
    for name in filters:
        if not str(name).replace("_", "").isalnum():
            raise ScenarioError(f"filter name '{name}' must be letters, digits and underscores")
    return {name: filter_settings(cfg, name) for name in filters}


FILTERS = SectionReader(
    "filters",
    dict[str, FilterSettings],
    "the filters (node kind filter: estimators); a "
    "selected estimator no section defines is a filter of that type with filter_defaults",
    read_filters,
)
FILTER_DEFAULTS = SectionReader(
    "filter_defaults",
    FilterSettings,
    "defaults of every filter (and of a selected filter type without an entry): any key of filters.<name>",
    read_filters,
    defaults_of="filters",
)
