"""Stone Soup (PyPI ``stonesoup``), an independent tracking library, as a peer of the bench's filters and
associators: the same problems posed to both, for tests/test_stonesoup_crosscheck.py and
scripts/bench_stonesoup.py.

Only the model functions are shared: :class:`BenchTransition` hands Stone Soup a bench ``DynamicsModel`` (f,
its Jacobian F and Q) and :class:`BenchMeasurement` a bench ``MeasurementModel`` (h and its Jacobian H at the
measurement's time, with the noise R). Everything else (the EKF and UKF predict and update, sigma points and
weights, the Kalman algebra, hypotheses, gating, assignment, joint events, mixture reduction) is Stone Soup's
own code: :func:`stonesoup_filter` runs its ExtendedKalman/UnscentedKalman predictor and updater over a list of
measurements.

Conventions. Stone Soup's time is a ``datetime``: bench times t (s) map to EPOCH + t, which keeps microseconds,
so a step's dt differs from the bench's float difference by < 1e-12 s. The angle components of a bench model
(``angle_indices``) are returned as Stone Soup ``Bearing`` values, so its innovations wrap to [-pi, pi) (the
bench's ``residual``: (-pi, pi], the same except at exactly pi), and its unscented mean of an angle is the
weighted circular mean atan2(sum w sin, sum w cos) (``Angle.average``) where the bench averages offsets from the
central point, Y0 + sum w (Y_i - Y0) (tracker_filters/sigma_points.py): the two differ at third order in the
sigma points' angular spread. With ``angles_as_bearings=False`` the angles are plain floats: no wrapping (the
data must not cross +-pi) and the same linear mean as the bench.

Stone Soup is imported with this module: import it only where Stone Soup is installed (the test suite and the
benchmark; requirements.txt installs it as a test dependency).
"""

from __future__ import annotations

from collections.abc import Sequence
from datetime import datetime, timedelta

import numpy as np
from stonesoup.base import Property
from stonesoup.dataassociator.neighbour import GNNWith2DAssignment
from stonesoup.dataassociator.probability import JPDA
from stonesoup.functions import gm_reduce_single
from stonesoup.gater.distance import DistanceGater
from stonesoup.hypothesiser.distance import DistanceHypothesiser
from stonesoup.hypothesiser.probability import PDAHypothesiser
from stonesoup.measures import SquaredMahalanobis
from stonesoup.models.measurement.nonlinear import NonLinearGaussianMeasurement
from stonesoup.models.transition.nonlinear import GaussianTransitionModel
from stonesoup.predictor.base import Predictor
from stonesoup.predictor.kalman import ExtendedKalmanPredictor, UnscentedKalmanPredictor
from stonesoup.types.angle import Bearing
from stonesoup.types.array import CovarianceMatrix, StateVector, StateVectors
from stonesoup.types.detection import Detection
from stonesoup.types.hypothesis import SingleHypothesis
from stonesoup.types.state import GaussianState
from stonesoup.types.track import Track
from stonesoup.updater.base import Updater
from stonesoup.updater.kalman import ExtendedKalmanUpdater, UnscentedKalmanUpdater

from bench_engine.stage import Measurement
from bench_models.models import DynamicsModel, MeasurementModel
from tracker_filters.filter_base import gate_threshold

EPOCH = datetime(2000, 1, 1)
"""Stone Soup time of bench time 0."""


def timestamp(t: float) -> datetime:
    """The Stone Soup time of bench time t (s)."""
    return EPOCH + timedelta(seconds=float(t))


class BenchTransition(GaussianTransitionModel):
    """A bench DynamicsModel as a Stone Soup transition model: function = ``propagate`` (a batch of sigma points
    in one call), jacobian = ``transition_matrix``, covar = ``process_noise``."""

    dynamics: DynamicsModel = Property(doc="The bench's dynamics model")

    @property
    def ndim_state(self) -> int:
        return len(self.dynamics.labels)

    def function(self, state, noise=False, time_interval: timedelta | None = None, **kwargs):
        X = np.asarray(state.state_vector, dtype=float)
        moved = self.dynamics.propagate(X.T, time_interval.total_seconds()).T
        return StateVectors(moved) if moved.shape[1] > 1 else StateVector(moved)

    def jacobian(self, state, time_interval: timedelta | None = None, **kwargs) -> np.ndarray:
        x = np.asarray(state.state_vector, dtype=float)[:, 0]
        return self.dynamics.transition_matrix(x, time_interval.total_seconds())

    def covar(self, time_interval: timedelta | None = None, **kwargs) -> CovarianceMatrix:
        zero = np.zeros(self.ndim_state)
        return CovarianceMatrix(self.dynamics.process_noise(zero, time_interval.total_seconds()))


class BenchMeasurement(NonLinearGaussianMeasurement):
    """A bench MeasurementModel at one measurement time as a Stone Soup measurement model: function = ``h``
    (a batch of sigma points in one call; angle components as ``Bearing`` unless ``angles_as_bearings`` is
    False), jacobian = ``jacobian``, covar = the measurement's R (module docstring)."""

    model: MeasurementModel = Property(doc="The bench's measurement model")
    time: float = Property(doc="Bench time of the measurement (s): h of a ground radar depends on it")
    angles_as_bearings: bool = Property(default=True, doc="Angle components as Bearing (wrapped) or floats")

    @property
    def ndim_meas(self) -> int:
        return len(self.model.labels)

    def function(self, state, noise=False, **kwargs):
        X = np.asarray(state.state_vector, dtype=float)
        Y = np.atleast_2d(self.model.h(X.T if X.shape[1] > 1 else X[:, 0], self.time)).T
        out = StateVectors(Y) if Y.shape[1] > 1 else StateVector(Y)
        if self.angles_as_bearings and self.model.angle_indices:
            out = out.astype(object)
            for i in self.model.angle_indices:
                out[i, :] = [Bearing(v) for v in Y[i]]
        return out

    def jacobian(self, state, **kwargs) -> np.ndarray:
        return self.model.jacobian(np.asarray(state.state_vector, dtype=float)[:, 0], self.time)


def detection(
    model: MeasurementModel, t: float, z: np.ndarray, R: np.ndarray, ndim_state: int, angles_as_bearings: bool = True
) -> Detection:
    """A Stone Soup Detection of the bench measurement z of an ``ndim_state``-dimensional state (angles typed
    like :class:`BenchMeasurement`'s h)."""
    sm = BenchMeasurement(
        ndim_state=ndim_state,
        mapping=tuple(range(ndim_state)),
        noise_covar=CovarianceMatrix(np.asarray(R, dtype=float)),
        model=model,
        time=float(t),
        angles_as_bearings=angles_as_bearings,
    )
    vector = StateVector(np.asarray(z, dtype=float))
    if angles_as_bearings and model.angle_indices:
        vector = vector.astype(object)
        for i in model.angle_indices:
            vector[i, 0] = Bearing(float(z[i]))
    return Detection(vector, timestamp=timestamp(t), measurement_model=sm)


class StoneSoupFilter:
    """Stone Soup's EKF (``kind="ekf"``: ExtendedKalmanPredictor, ExtendedKalmanUpdater with the Joseph-form
    covariance, the bench's) or UKF (``"ukf"``: UnscentedKalmanPredictor and Updater with scaled sigma points
    alpha, beta, kappa) over a bench DynamicsModel, one Stone Soup detection at a time."""

    def __init__(
        self, kind: str, dynamics: DynamicsModel, alpha: float = 1.0, beta: float = 2.0, kappa: float = 0.0
    ) -> None:
        transition = BenchTransition(dynamics=dynamics)
        self.ndim_state = transition.ndim_state
        if kind == "ekf":
            self.predictor = ExtendedKalmanPredictor(transition)
            self.updater = ExtendedKalmanUpdater(None, use_joseph_cov=True)
        elif kind == "ukf":
            self.predictor = UnscentedKalmanPredictor(transition, alpha=alpha, beta=beta, kappa=kappa)
            self.updater = UnscentedKalmanUpdater(None, alpha=alpha, beta=beta, kappa=kappa)
        else:
            raise ValueError(f"kind must be 'ekf' or 'ukf', got {kind!r}")
        self.state: GaussianState | None = None

    def initialise(self, x0: np.ndarray, P0: np.ndarray, t0: float) -> None:
        self.state = GaussianState(
            StateVector(np.asarray(x0, dtype=float)),
            CovarianceMatrix(np.asarray(P0, dtype=float)),
            timestamp=timestamp(t0),
        )

    def process(self, det: Detection) -> GaussianState:
        """Predict to the detection's time and update with it; returns the posterior."""
        prediction = self.predictor.predict(self.state, timestamp=det.timestamp)
        self.state = self.updater.update(SingleHypothesis(prediction, det))
        return self.state


def stonesoup_filter(
    kind: str,
    dynamics: DynamicsModel,
    model: MeasurementModel,
    x0: np.ndarray,
    P0: np.ndarray,
    t0: float,
    measurements: Sequence[Measurement],
    alpha: float = 1.0,
    beta: float = 2.0,
    kappa: float = 0.0,
    angles_as_bearings: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """:class:`StoneSoupFilter` from N(x0, P0) at t0 over the bench's measurement items (their t, z, R): the
    posterior means (m, n) and covariances (m, n, n) after each."""
    flt = StoneSoupFilter(kind, dynamics, alpha, beta, kappa)
    flt.initialise(x0, P0, t0)
    means, covars = [], []
    for m in measurements:
        state = flt.process(detection(model, m.t, m.z, m.R, flt.ndim_state, angles_as_bearings))
        means.append(np.asarray(state.state_vector, dtype=float)[:, 0])
        covars.append(np.asarray(state.covar, dtype=float))
    return np.array(means), np.array(covars)


# ---- association ----------------------------------------------------------------------------------------------


def gaussian_track(x: np.ndarray, P: np.ndarray, t: float) -> Track:
    """A Stone Soup track holding one Gaussian state N(x, P) at bench time t."""
    return Track(
        [
            GaussianState(
                StateVector(np.asarray(x, dtype=float)),
                CovarianceMatrix(np.asarray(P, dtype=float)),
                timestamp=timestamp(t),
            )
        ]
    )


class StoneSoupGNN:
    """Stone Soup's global nearest neighbour (GNNWith2DAssignment) with the bench's gate and assignment rule
    (tracker_filters.association.GlobalNearestNeighbour), over an EKF predictor and Joseph-form updater.

    The cost of a pair is Stone Soup's squared Mahalanobis distance between the detection and the track's
    predicted measurement (innovation covariance H P H' + R), the bench's d2. Gating is Stone Soup's
    DistanceGater at the chi-square quantile of ``gate_probability``. Stone Soup charges a missed track its
    hypothesiser's ``missed_distance``; the bench assigns as many tracks as possible and only then minimises
    the total d2. The two rules agree when a miss costs more than any set of gated pairs, (T + 1) x gate for T
    tracks, which :meth:`associator` sets unless ``miss_cost`` is given. With a miss costing the gate (Stone
    Soup's DistanceHypothesiser gates and charges a miss with the same missed_distance) Stone Soup may leave a
    track missed to give its detection to a track whose other gated detection costs more than the gate:
    tests/test_stonesoup_crosscheck.py shows such a case; 5 of its 60 random cases of four tracks contesting
    six detections are assigned differently that way.
    """

    def __init__(self, dynamics: DynamicsModel, gate_probability: float, miss_cost: float | None = None) -> None:
        self.predictor = ExtendedKalmanPredictor(BenchTransition(dynamics=dynamics))
        self.updater = ExtendedKalmanUpdater(None, use_joseph_cov=True)
        self.gate_probability = float(gate_probability)
        self.miss_cost = miss_cost
        self._associators: dict[tuple[int, float], GNNWith2DAssignment] = {}

    def associator(self, n_tracks: int, gate: float) -> GNNWith2DAssignment:
        """The associator for n_tracks tracks and this gate (built once)."""
        key = (n_tracks, gate)
        if key not in self._associators:
            miss = (n_tracks + 1) * gate if self.miss_cost is None else self.miss_cost
            hypothesiser = DistanceHypothesiser(
                self.predictor, self.updater, SquaredMahalanobis(), missed_distance=miss, include_all=True
            )
            self._associators[key] = GNNWith2DAssignment(
                DistanceGater(hypothesiser, SquaredMahalanobis(), gate_threshold=gate)
            )
        return self._associators[key]

    def step(self, tracks: Sequence[Track], detections: Sequence[Detection], t: float) -> list[int]:
        """Associate the detections of time t and update each track with its detection, or append its
        prediction on a miss; returns the detection index of each track (-1: missed)."""
        if not detections:
            for track in tracks:
                track.append(self.predictor.predict(track, timestamp=timestamp(t)))
            return [-1] * len(tracks)
        gate = gate_threshold(self.gate_probability, detections[0].measurement_model.ndim_meas)
        chosen = self.associator(len(tracks), gate).associate(set(tracks), set(detections), timestamp(t))
        index = {id(d): j for j, d in enumerate(detections)}
        out = []
        for track in tracks:
            hypothesis = chosen[track]
            if hypothesis:
                track.append(self.updater.update(hypothesis))
                out.append(index[id(hypothesis.measurement)])
            else:
                track.append(hypothesis.prediction)
                out.append(-1)
        return out


class StoneSoupJPDA:
    """Stone Soup's JPDA (PDAHypothesiser, JPDA associator) over linear-Gaussian tracks, each track's posterior
    the moment-matched mixture of its hypotheses' updates (gm_reduce_single), as in Stone Soup's JPDA tutorial.

    Parametric clutter (density ``clutter_density`` per unit measurement volume): a detection hypothesis weighs
    P_D N(nu; 0, S) / lambda, a miss 1 - P_D P_G, and the joint events are every feasible combination over all
    tracks, normalised; the bench's JointProbabilisticAssociator (star_tracker/jpdaf.py) gives the same
    weights, enumerated per cluster of tracks sharing gated detections (Stone Soup's product over all tracks
    grows as the product of their hypothesis counts). Without a clutter density the two differ where tracks
    share detections: Stone Soup weighs each track's detections by its own gate volume over its number of
    gated detections, the bench a cluster's events by phi!/V^phi with V the cluster's summed gate volumes;
    they agree for a track alone in its cluster.
    """

    def __init__(
        self, predictor: Predictor, updater: Updater, p_detect: float, clutter_density: float, gate_probability: float
    ) -> None:
        self.updater = updater
        self.associator = JPDA(
            PDAHypothesiser(
                predictor,
                updater,
                clutter_spatial_density=clutter_density,
                prob_detect=p_detect,
                prob_gate=gate_probability,
            )
        )

    def step(self, tracks: Sequence[Track], detections: Sequence[Detection], t: float) -> np.ndarray:
        """Associate and update every track with the detections of time t; returns the weights (T, N + 1):
        [missed, detection 0, ..., detection N - 1] of each track (zero outside its gate)."""
        hypotheses = self.associator.associate(set(tracks), set(detections), timestamp(t))
        weights = np.zeros((len(tracks), len(detections) + 1))
        index = {id(d): j for j, d in enumerate(detections)}
        for r, track in enumerate(tracks):
            means, covars, w = [], [], []
            for hypothesis in hypotheses[track]:
                if hypothesis:
                    j, state = index[id(hypothesis.measurement)], self.updater.update(hypothesis)
                else:
                    j, state = -1, hypothesis.prediction
                weights[r, j + 1] = float(hypothesis.probability)
                means.append(state.state_vector)
                covars.append(state.covar)
                w.append(hypothesis.probability)
            mean, covar = gm_reduce_single(StateVectors(np.hstack(means)), np.stack(covars, axis=2), np.asarray(w))
            track.append(GaussianState(mean, covar, timestamp=timestamp(t)))
        return weights
