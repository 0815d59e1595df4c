"""Where the standard views (bench_engine.views) find what they show in an estimate's or a truth sample's state:
the position, velocity and attitude quaternion components, selected by label (bench_engine.labels), in the
state vector and in its covariance (an attitude state's covariance has the rotation error rx ry rz in place of
the quaternion)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from bench_engine.labels import POSITION, QUATERNION, ROTATION, VELOCITY
from bench_engine.stage import Estimate, Item


@dataclass(frozen=True)
class Layout:
    """Where a state's components are: indices into the state vector and into its covariance (None: absent)."""

    position: tuple[int, ...] | None
    velocity: tuple[int, ...] | None
    quaternion: tuple[int, ...] | None
    cov_position: tuple[int, ...] | None
    cov_velocity: tuple[int, ...] | None
    cov_rotation: tuple[int, ...] | None


def covariance_labels(labels: tuple[str, ...], n: int) -> tuple[str, ...] | None:
    """The labels of an n × n covariance of a state with ``labels``: the labels themselves, or for an attitude
    state with one row fewer, its error labels (rx ry rz in place of qw qx qy qz); None if neither fits."""
    if n == len(labels):
        return labels
    if n == len(labels) - 1 and all(q in labels for q in QUATERNION):
        i = labels.index(QUATERNION[0])
        return labels[:i] + ROTATION + tuple(lab for lab in labels[i:] if lab not in QUATERNION)
    return None


@lru_cache(maxsize=256)
def layout(labels: tuple[str, ...], n_cov: int) -> Layout:
    """The :class:`Layout` of a state with ``labels`` and an ``n_cov`` × ``n_cov`` covariance (0: none)."""

    def find(names: tuple[str, ...], within: tuple[str, ...] | None) -> tuple[int, ...] | None:
        if within is None or not all(n in within for n in names):
            return None
        return tuple(within.index(n) for n in names)

    cov = covariance_labels(labels, n_cov)
    return Layout(
        find(POSITION, labels),
        find(VELOCITY, labels),
        find(QUATERNION, labels),
        find(POSITION, cov),
        find(VELOCITY, cov),
        find(ROTATION, cov),
    )


def block(P: np.ndarray, rows: tuple[int, ...], cols: tuple[int, ...]) -> np.ndarray:
    """P[rows, cols] (3 × 3), by slicing when the indices are consecutive (the usual layouts)."""
    r, c = rows[0], cols[0]
    if rows == (r, r + 1, r + 2) and cols == (c, c + 1, c + 2):
        return P[r : r + 3, c : c + 3]
    return P[np.ix_(rows, cols)]


@dataclass(frozen=True)
class State:
    """An item's state as the views read it: labels, values, covariance (None for the truth) and layout."""

    labels: tuple[str, ...]
    x: np.ndarray
    P: np.ndarray | None
    layout: Layout


def state_of(item: Item) -> State:
    """The :class:`State` of an estimate or a truth sample."""
    if isinstance(item, Estimate):
        P = np.asarray(item.P, dtype=float)
        P = P if P.size else None
        labels = tuple(item.labels)
        return State(labels, np.asarray(item.x, dtype=float), P, layout(labels, 0 if P is None else len(P)))
    labels = tuple(item.labels)
    return State(labels, np.asarray(item.state, dtype=float), None, layout(labels, 0))


def attitude_matrix(q: np.ndarray) -> np.ndarray:
    """R(q) of a scalar-first unit quaternion (normalised first): the body-from-reference matrix A."""
    w, x, y, z = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )
