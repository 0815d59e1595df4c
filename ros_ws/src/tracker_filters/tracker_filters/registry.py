"""Filters by name, for scenario files and the filter node: ``make_filter("ukf", dynamics, alpha=1.0)``.

Filters are registered in the entry-point group ``tracking_bench.estimators`` (name = class). A filter
class takes the dynamics model first and its tuning parameters as keyword arguments, and raises ValueError
for an invalid parameter value.
"""

from __future__ import annotations

import inspect

from bench_engine import plugins
from bench_models.models import DynamicsModel
from tracker_filters.filter_base import Filter


def filter_parameters(name: str) -> list[str]:
    """Names of the keyword parameters filter ``name`` accepts (beyond the dynamics model)."""
    params = list(inspect.signature(_filter_class(name).__init__).parameters.values())[2:]
    return [p.name for p in params if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)]


def make_filter(name: str, dynamics: DynamicsModel, **params) -> Filter:
    """Build filter ``name`` over ``dynamics`` with tuning ``params``.

    Raises ValueError naming the unknown filter and the registered names, an unknown parameter and the
    accepted ones, or an invalid parameter value (e.g. "ukf: alpha must be in (0, 1], got -1").
    """
    cls = _filter_class(name)
    allowed = filter_parameters(name)
    unknown = sorted(set(params) - set(allowed))
    if unknown:
        raise ValueError(f"{name}: unknown parameter(s) {', '.join(unknown)}; allowed: {', '.join(allowed) or 'none'}")
    _check_types(name, cls, params)
    try:
        return cls(dynamics, **params)
    except ValueError as err:
        message = str(err)
        raise ValueError(message if message.startswith(f"{name}:") else f"{name}: {message}") from err


def _check_types(name: str, cls: type, params: dict) -> None:
    """A parameter whose default is a number must be given a number (ValueError naming it otherwise)."""
    defaults = {p.name: p.default for p in inspect.signature(cls.__init__).parameters.values()}
    for key, value in params.items():
        default = defaults.get(key)
        numeric = isinstance(default, (int, float)) and not isinstance(default, bool)
        if numeric and (isinstance(value, bool) or not isinstance(value, (int, float))):
            raise ValueError(f"{name}: parameter {key} must be a number, got {value!r}")


def filter_names() -> list[str]:
    """Every registered filter type."""
    return plugins.names("estimators")


def _filter_class(name: str) -> type:
    if name not in filter_names():
        raise ValueError(f"unknown filter {name!r}; allowed: {', '.join(filter_names())}")
    return plugins.load("estimators", name)
