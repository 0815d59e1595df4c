"""The star tracker's per-frame core: lost-in-space identification, recursive tracking, attitude.

Per frame (centroids uv, magnitudes, time t, known body rate ω in the camera frame):

1. Not locked: Pyramid lost-in-space identification (pyramid.py). On success the identified stars start tracks
   (SNA or JPDAF, tracking.py) at their centroids, with the image velocity the body rate gives, and the
   frame's attitude is solved from them; on failure the frame has no attitude and the reason is reported.
2. Locked: the tracker follows its stars to this frame (SNA: prediction with ω and the 3√2σ gate; JPDAF:
   the motion model and the clustered joint association). How the JPDAF uses the known rate (``aid``):
   - ``"rate"`` (default): the image motion the body rate causes is a control input of the prediction and
     the velocity states hold only what the rate does not explain (JPDAFTracker.predict);
   - ``"jitter"``: the paper's — the motion model (constant velocity, or the coordinated turn at the image's
     rotation rate −(ω_z − j)) carries the stars on image velocities and only the measured boresight jitter
     rate j is compensated: the tracks' positions, velocities and covariances are turned with the image by
     −j·Δt about its centre (eq. 18; JPDAFTracker.turn_image) before the prediction;
   - ``"none"``: the motion model alone, on image velocities (the coordinated turn at −ω_z).
   The rate ω (and j) passed with a frame is the body rate over the interval since the previous frame (what
   a gyro integrates). The stars it updated this frame (SNA: a measurement in the gate; JPDAF: the
   most probable hypothesis is a detection) give the attitude from their positions (SNA: the measurement;
   JPDAF: the filtered position) and their catalogue vectors.
3. Verification, before anything is reported: a least-squares fit over those stars; a star whose residual
   exceeds the verification radius (its track took a false star or a neighbour) is dropped from the fit and
   from the tracker, and the fit is repeated. With fewer than ``min_stars`` stars left the lock is lost and
   the same frame goes back to step 1: a wrong attitude is never reported as valid. For the JPDAF the
   attitude from the filtered positions must also agree with the attitude from the measurements its tracks
   took this frame (within the latter's uncertainty), in that frame and on average over the last
   ``BIAS_WINDOW`` frames: a motion model that lags the true motion shifts all its stars together, which no
   residual shows; then the tracks restart at the measurements and the frame's attitude is taken from those
   (``filter_resets`` counts it).
4. New stars: centroids no track took are matched to the catalogue with the frame's attitude
   (PyramidIdentifier.match) and handed to the tracker — no new lost-in-space solve.

A frame whose time is not after the previous one's (out of order, repeated) is solved lost-in-space.

The reported attitude is the chosen solver's — ``"wahba"`` (SVD over all the stars, attitude.wahba) or
``"triad"`` (two stars, as in the paper, attitude.triad: anchored on the first star of the list, i.e. the
brightest star identified at acquisition while it is tracked, and paired with the star farthest from it) —
over the same stars; each star's direction is weighted by its standard deviation: the centroid noise σ
for measured positions, the filter's √(tr(H P Hᵀ)/2) (at most σ) for the JPDAF's filtered ones, so the
covariance reflects the filtering (the filtered errors of one star are correlated from frame to frame; between
stars they are independent as long as the known rate is exact).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from star_tracker.attitude import AttitudeSolution, error_vector, residuals, triad, wahba, wahba_matrix
from star_tracker.camera import Camera
from star_tracker.catalogue import ARCSEC, StarCatalogue
from star_tracker.motion import ConstantVelocity, CoordinatedTurn, MotionModel
from star_tracker.options import AIDS, MOTIONS, SOLVERS, TRACKERS
from star_tracker.pyramid import UNIDENTIFIED, PyramidIdentifier
from star_tracker.star_camera import camera_of, catalogue_of, pair_table
from star_tracker.tracking import JPDAFTracker, SNATracker, image_velocity, member, predict_centroids

BIAS_WINDOW = 10
"""Frames over which the JPDAF's filtered-versus-measured agreement is averaged (JPDAFTracking.unbiased)."""
BIAS_MEAN = 6.0
"""Largest mean of that statistic over the window (an unbiased filter's mean is at most 3)."""
BIAS_SUSPECT = 11.34
"""χ²₃ at 0.99: above it a frame's filtered attitude is kept with its disagreement added to its covariance."""


def jpdaf_motion(motion: str, aid: str, sigma_a: float, omega_z: float, jitter_rate: float = 0.0) -> MotionModel:
    """The JPDAF's motion model (``motion`` of MOTIONS, ``aid`` of AIDS) for a boresight body rate ``omega_z``
    and its measured jitter part: constant velocity, or the turn at the image's rotation rate less what ``aid``
    compensates (JPDAFTracking.motion_for)."""
    if motion == "coordinated_turn" and aid != "rate":
        compensated = jitter_rate if aid == "jitter" else 0.0
        return CoordinatedTurn(-(omega_z - compensated), sigma_a)
    return ConstantVelocity(sigma_a)


@dataclass
class FrameResult:
    """One frame's outcome."""

    ok: bool
    reason: str
    """Why there is no attitude ('' when there is one)."""
    mode: str
    """'lost_in_space' or 'tracking': how the frame's stars were identified."""
    attitude: AttitudeSolution | None
    index: np.ndarray
    """(N,) catalogue index of each centroid (−1: not identified, or a false star)."""
    star_ids: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=np.int64))
    """Catalogue indices of the stars the attitude was solved from."""
    star_uv: np.ndarray = field(default_factory=lambda: np.empty((0, 2)))
    """Their image positions (measured for SNA and lost-in-space, filtered for the JPDAF)."""
    star_rows: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=np.int64))
    """The centroid (index into the frame's positions) of each of those stars."""


class StarTrackerPipeline:
    """Identification, tracking and attitude, frame after frame (module docstring).

    ``sigma_px``: centroid noise (px per axis) assumed by the identifier, the SNA gate and the JPDAF's R;
    ``sigma_a``: the JPDAF motion model's process noise (constant velocity: acceleration σ in px/s², the
    paper's discrete form; coordinated turn: √q of its white acceleration); ``p_detect``, ``clutter_density``
    (per px², None: non-parametric) and ``gate`` (δ on d²): the JPDA's (jpdaf.py); ``verify_sigmas``: the
    verification radius in σ; ``max_misses``: frames a track may coast before it is dropped. What differs
    between the trackers (starting tracks, a frame's step, the check after verification) is the strategy
    ``tracking`` (SNATracking, JPDAFTracking), chosen once from ``tracker``."""

    def __init__(
        self,
        catalogue: StarCatalogue,
        camera: Camera,
        sigma_px: float,
        tracker: str = "jpdaf",
        solver: str = "wahba",
        motion: str = "constant_velocity",
        sigma_a: float = 0.5,
        p_detect: float = 0.95,
        clutter_density: float | None = None,
        gate: float | None = None,
        min_stars: int = 3,
        verify_sigmas: float = 6.0,
        max_misses: int = 3,
        aid: str = "rate",
        identifier: PyramidIdentifier | None = None,
    ) -> None:
        if tracker not in TRACKERS:
            raise ValueError(f"tracker must be one of {TRACKERS}, got {tracker!r}")
        if solver not in SOLVERS:
            raise ValueError(f"solver must be one of {SOLVERS}, got {solver!r}")
        if motion not in MOTIONS:
            raise ValueError(f"motion must be one of {MOTIONS}, got {motion!r}")
        if aid not in AIDS:
            raise ValueError(f"aid must be one of {AIDS}, got {aid!r}")
        if min_stars < 3:
            raise ValueError(f"min_stars must be >= 3 (a fit that can be checked), got {min_stars}")
        self.catalogue, self.camera = catalogue, camera
        self.sigma_px = float(sigma_px)
        self.sigma = camera.pixel_sigma_to_angle(sigma_px)
        self.solver, self.motion_kind = solver, motion
        self.sigma_a = float(sigma_a)
        self.p_detect, self.clutter_density, self.gate = p_detect, clutter_density, gate
        self.min_stars = int(min_stars)
        self.verify_radius = verify_sigmas * self.sigma + 2.0 * ARCSEC
        self.max_misses = int(max_misses)
        self.aid = aid
        self._jitter = 0.0
        """The boresight jitter rate of the frame being processed (rad/s)."""
        self.identifier = identifier if identifier is not None else PyramidIdentifier(catalogue, camera, sigma_px)
        self.tracking: SNATracking | JPDAFTracking = TRACKING[tracker](self)
        """How the identified stars are tracked (SNATracking, JPDAFTracking); it owns the tracker."""
        self.reset()

    @property
    def tracker(self) -> SNATracker | JPDAFTracker:
        """The current tracker (a new one after each reset)."""
        return self.tracking.tracker

    @property
    def filter_resets(self) -> int:
        """JPDAF frames whose filtered stars disagreed with their measurements (step 3) and were restarted."""
        return self.tracking.resets

    def reset(self) -> None:
        """Forget the lock: the next frame is a lost-in-space one."""
        self.locked = False
        self.t_prev: float | None = None
        self.tracking.reset()

    def motion_for(self, omega_body: np.ndarray, jitter_rate: float = 0.0) -> MotionModel:
        """The JPDAF's motion model for a body rate: constant velocity, or the turn at the image's rotation
        rate (the sky turns opposite to the camera) less what ``aid`` compensates: −(ω_z − j) with
        ``"jitter"``, −ω_z with ``"none"``; rate-aided, the velocity states hold the motion the rate does not
        explain, which does not turn."""
        return jpdaf_motion(self.motion_kind, self.aid, self.sigma_a, float(omega_body[2]), jitter_rate)

    # ------------------------------------------------------------------------------------------------ frame
    def process(
        self, uv: np.ndarray, magnitudes: np.ndarray | None, t: float, omega_body: np.ndarray, jitter_rate: float = 0.0
    ) -> FrameResult:
        """One frame (module docstring): ``omega_body`` the body rate (rad/s, camera frame) and ``jitter_rate``
        its measured boresight jitter part (rad/s; used by ``aid="jitter"`` only). Never raises on a frame's
        content."""
        uv = np.asarray(uv, dtype=float).reshape(-1, 2)
        finite = np.all(np.isfinite(uv), axis=1)
        if not finite.all():  # a centroid that is not a number is no measurement
            result = self.process(
                uv[finite], None if magnitudes is None else np.asarray(magnitudes)[finite], t, omega_body, jitter_rate
            )
            index = np.full(len(uv), UNIDENTIFIED, dtype=np.int64)
            index[finite] = result.index
            result.index = index
            result.star_rows = np.flatnonzero(finite)[result.star_rows]
            return result
        omega_body = np.asarray(omega_body, dtype=float)
        self._jitter = float(jitter_rate)
        reason = ""
        if self.locked and self.t_prev is not None and t > self.t_prev:
            result = self._track(uv, t - self.t_prev, omega_body)
            if result.ok:
                self.t_prev = t
                return result
            reason = f"lock lost ({result.reason}); "
        self.reset()
        result = self._acquire(uv, magnitudes, omega_body)
        if result.ok:
            self.locked, self.t_prev = True, t
        else:
            result.reason = reason + result.reason
        return result

    def _acquire(self, uv: np.ndarray, magnitudes: np.ndarray | None, omega_body: np.ndarray) -> FrameResult:
        ident = self.identifier.identify(uv, magnitudes)
        if not ident.ok:
            return FrameResult(False, f"lost-in-space: {ident.reason}", "lost_in_space", None, ident.index)
        rows = np.flatnonzero(ident.index >= 0)
        ids = ident.index[rows]
        self.tracking.start(ids, uv[rows], omega_body, self._jitter)
        solution = self._solve(self.camera.unproject(uv[rows]), self.catalogue.vectors[ids])
        return FrameResult(True, "", "lost_in_space", solution, ident.index, ids, uv[rows], rows)

    def _track(self, uv: np.ndarray, dt: float, omega_body: np.ndarray) -> FrameResult:
        index = np.full(len(uv), UNIDENTIFIED, dtype=np.int64)
        ids, rows, pos, sig = self.tracking.step(uv, dt, omega_body, self._jitter)
        # verification: drop the stars the fit rejects, one at a time (worst first); each star's direction b
        # and catalogue vector r are computed once, the fit that passes is kept (A_fit)
        b, r = self.camera.unproject(pos), self.catalogue.vectors[ids]
        keep = np.ones(len(ids), dtype=bool)
        while keep.sum() >= self.min_stars:
            A_fit = wahba_matrix(b[keep], r[keep])
            res = residuals(A_fit, b[keep], r[keep])
            if res.max() <= self.verify_radius:
                break
            keep[np.flatnonzero(keep)[int(np.argmax(res))]] = False
        if keep.sum() < self.min_stars:
            return FrameResult(
                False, f"{int(keep.sum())} verified tracked stars, fewer than {self.min_stars}", "tracking", None, index
            )
        if not keep.all():
            self._forget(ids[~keep])
            ids, rows, pos, sig, b, r = ids[keep], rows[keep], pos[keep], sig[keep], b[keep], r[keep]
        index[rows] = ids
        pos, sig, b, A_fit, all_star, inflation = self.tracking.verified(ids, rows, uv, pos, sig, b, r, A_fit)
        if all_star is not None and self.solver == "wahba":
            solution = all_star
        else:
            solution = self._solve(b, r, sig)
        if inflation is not None:
            solution.covariance = solution.covariance + inflation
        # new stars: the centroids no track took, identified from the attitude of the verified fit
        free = np.flatnonzero(index == UNIDENTIFIED)
        if len(free):
            new, _ = self.identifier.match(self.camera.unproject(uv[free]), A_fit, self.verify_radius)
            fresh = (new >= 0) & ~member(new, self.tracker.ids) & ~member(new, ids)
            if fresh.any():
                self.tracking.start(new[fresh], uv[free[fresh]], omega_body, self._jitter)
                index[free[fresh]] = new[fresh]
        return FrameResult(True, "", "tracking", solution, index, ids, pos, rows)

    def _forget(self, ids: np.ndarray) -> None:
        self.tracker.drop(~member(self.tracker.ids, ids))

    def _solve(self, b: np.ndarray, r: np.ndarray, sigma_px: np.ndarray | None = None) -> AttitudeSolution:
        """The chosen solver over the stars seen along b (camera frame) with catalogue vectors r; each star's
        direction has the standard deviation ``sigma_px`` (px per axis; default the centroid noise) times the
        ifov."""
        px = np.full(len(r), self.sigma_px) if sigma_px is None else np.asarray(sigma_px, dtype=float)
        sigma = np.maximum(px * self.camera.ifov, 1e-3 * ARCSEC)
        return triad(b, r, sigma) if self.solver == "triad" else wahba(b, r, sigma)


# ------------------------------------------------------------------------------------------ tracking strategies
class Verified(NamedTuple):
    """A tracked frame's verified stars as the tracking strategy hands them to the attitude solver."""

    pos: np.ndarray
    """(n, 2) their image positions."""
    sig: np.ndarray
    """(n,) their position σ (px)."""
    b: np.ndarray
    """(n, 3) their directions in the camera frame."""
    A_fit: np.ndarray
    """The verified fit's attitude matrix (the new stars are matched with it)."""
    all_star: AttitudeSolution | None = None
    """The all-star (Wahba) attitude over these stars when the strategy has solved it already."""
    inflation: np.ndarray | None = None
    """(3, 3) added to the reported attitude covariance (None: nothing)."""


class SNATracking:
    """The paper's SNA (tracking.SNATracker): the measured centroid of each star the gate took, at the centroid
    noise; nothing to check after verification. ``pipe``: the StarTrackerPipeline whose settings it reads."""

    def __init__(self, pipe: StarTrackerPipeline) -> None:
        self.pipe = pipe
        self.resets = 0
        """Always 0: the SNA keeps no filtered state to restart."""
        self.tracker: SNATracker = self._new_tracker()

    def _new_tracker(self) -> SNATracker:
        return SNATracker(self.pipe.camera, self.pipe.sigma_px, max_misses=self.pipe.max_misses)

    def reset(self) -> None:
        """A new, empty tracker."""
        self.tracker = self._new_tracker()

    def start(self, ids: np.ndarray, uv: np.ndarray, omega_body: np.ndarray, jitter_rate: float) -> None:
        """Start tracks for the stars ``ids`` identified at the centroids uv."""
        self.tracker.start(ids, uv)

    def step(
        self, uv: np.ndarray, dt: float, omega_body: np.ndarray, jitter_rate: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Follow the stars to the frame's centroids uv: the (ids, rows into uv, positions, σ px) of the stars
        updated this frame."""
        ids = self.tracker.ids.copy()
        taken = self.tracker.step(uv, dt, omega_body)
        hit = taken >= 0
        ids, rows, pos = ids[hit], taken[hit], uv[taken[hit]]
        return ids, rows, pos, np.full(len(ids), self.pipe.sigma_px)

    def verified(
        self,
        ids: np.ndarray,
        rows: np.ndarray,
        uv: np.ndarray,
        pos: np.ndarray,
        sig: np.ndarray,
        b: np.ndarray,
        r: np.ndarray,
        A_fit: np.ndarray,
    ) -> Verified:
        """The verified stars (ids, their rows into the frame's centroids uv, positions, σ, directions b,
        catalogue vectors r, the fit A_fit) as they are: the SNA's positions are the measurements."""
        return Verified(pos, sig, b, A_fit)


class JPDAFTracking:
    """The JPDAF (tracking.JPDAFTracker) with the pipeline's motion model and rate aiding (module docstring,
    step 2): the filtered position of each star whose most probable hypothesis is a detection; after
    verification the agreement of its filtered and measured attitudes (step 3), which restarts the tracks at
    the measurements (``resets`` counts it) or inflates the reported covariance. ``pipe``: the
    StarTrackerPipeline whose settings it reads."""

    def __init__(self, pipe: StarTrackerPipeline) -> None:
        self.pipe = pipe
        self.resets = 0
        """Frames whose filtered stars disagreed with their measurements and were restarted."""
        self._bias: list[float] = []
        """The agreement statistic d of the last ``BIAS_WINDOW`` frames (unbiased)."""
        self.tracker: JPDAFTracker = self._new_tracker()

    def _new_tracker(self) -> JPDAFTracker:
        pipe = self.pipe
        return JPDAFTracker(
            ConstantVelocity(pipe.sigma_a),
            pipe.sigma_px,
            p_detect=pipe.p_detect,
            clutter_density=pipe.clutter_density,
            gate=pipe.gate,
            max_misses=pipe.max_misses,
            camera=pipe.camera,
        )

    def reset(self) -> None:
        """A new, empty tracker and no agreement history."""
        self._bias = []
        self.tracker = self._new_tracker()

    def _model_rate(self, omega_body: np.ndarray, jitter_rate: float) -> np.ndarray:
        """The part of the body rate the motion model carries (image velocities), the rest being compensated."""
        if self.pipe.aid == "jitter":
            return omega_body - np.array([0.0, 0.0, jitter_rate])
        return omega_body

    def start(self, ids: np.ndarray, uv: np.ndarray, omega_body: np.ndarray, jitter_rate: float) -> None:
        """Start tracks for the stars ``ids`` identified at the centroids uv: rate-aided with zero velocity
        states (known to σ px/s), otherwise with the image velocity the motion model carries (to 1 px/s)."""
        pipe = self.pipe
        if pipe.aid == "rate":
            self.tracker.start(ids, uv, None, velocity_sigma=pipe.sigma_px)
        else:
            velocity = image_velocity(pipe.camera, uv, self._model_rate(omega_body, jitter_rate))
            self.tracker.start(ids, uv, velocity, velocity_sigma=1.0)

    def step(
        self, uv: np.ndarray, dt: float, omega_body: np.ndarray, jitter_rate: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Follow the stars to the frame's centroids uv: the (ids, rows into uv, filtered positions, σ px) of
        the stars whose most probable hypothesis is a detection (σ: the filter's, at most the centroid's)."""
        pipe, shift = self.pipe, None
        if pipe.aid == "rate":
            p = self.tracker.positions
            shift = predict_centroids(pipe.camera, p, omega_body, dt) - p
        elif pipe.aid == "jitter":  # the image turns by −j dt about the boresight's pixel (eq. 18)
            self.tracker.turn_image(-jitter_rate * dt, pipe.camera.centre)
        step = self.tracker.step(uv, dt, pipe.motion_for(omega_body, jitter_rate), shift)
        hit = step.detection >= 0
        ids, rows, pos = step.ids[hit], step.detection[hit], step.positions[hit]
        return ids, rows, pos, np.minimum(step.position_sigma[hit], pipe.sigma_px)

    def verified(
        self,
        ids: np.ndarray,
        rows: np.ndarray,
        uv: np.ndarray,
        pos: np.ndarray,
        sig: np.ndarray,
        b: np.ndarray,
        r: np.ndarray,
        A_fit: np.ndarray,
    ) -> Verified:
        """The verified stars (ids, their rows into the frame's centroids uv, filtered positions, σ, directions
        b, catalogue vectors r, the fit A_fit) after the agreement check: the filtered stars with their
        all-star attitude (and the disagreement as a covariance inflation when suspect), or, when they
        disagree with this frame's own measurements (a lagging model), the tracks restarted at the
        measurements and the stars taken from those."""
        measured = uv[rows]
        b_measured = self.pipe.camera.unproject(measured)
        agree, delta, filtered, own = self.unbiased(b, sig, b_measured, r)
        if agree:
            return Verified(pos, sig, b, A_fit, filtered, None if delta is None else np.outer(delta, delta))
        self.tracker.reseed(ids, measured)
        self.resets += 1
        return Verified(measured, np.full(len(ids), self.pipe.sigma_px), b_measured, wahba_matrix(b_measured, r), own)

    def unbiased(
        self, b: np.ndarray, sig: np.ndarray, b_measured: np.ndarray, r: np.ndarray
    ) -> tuple[bool, np.ndarray | None, AttitudeSolution, AttitudeSolution]:
        """Whether the filtered stars (directions b, σ ``sig`` px) agree with the measurements their tracks
        took (directions ``b_measured``; catalogue vectors r) (module docstring, step 3), the disagreement δθ
        to add to the reported covariance (as δθ δθᵀ) when it is suspect, and the two all-star attitudes
        (filtered, measured).

        With δθ the rotation between the attitude from the filtered positions and the attitude from the
        measurements, and P_m the latter's covariance, d = δθᵀ P_m⁻¹ δθ has a mean of at most 3 for an
        unbiased filter (cov(δθ) ≈ P_m − P_f). A frame fails with d > 30 (χ²₃ at 1 − 10⁻⁶), and a run of
        ``BIAS_WINDOW`` frames fails when the mean of d exceeds ``BIAS_MEAN`` — a lag smaller than one frame's
        noise, but the same frame after frame. A filter whose model lags the true motion moves all its stars
        the same way, which no residual of a fit shows. Between, a frame with d above ``BIAS_SUSPECT`` (χ²₃ at
        0.99) or a window mean above 3 keeps its filtered attitude but reports the covariance P_f + δθ δθᵀ,
        so that a lag too small to reject is not hidden behind the filter's small P_f."""
        filtered = wahba(b, r, np.maximum(sig * self.pipe.camera.ifov, 1e-3 * ARCSEC))
        own = wahba(b_measured, r, max(self.pipe.sigma, 1e-3 * ARCSEC))
        delta = error_vector(filtered.matrix, own.matrix)
        d = float(delta @ np.linalg.solve(own.covariance, delta))
        self._bias.append(d)
        del self._bias[:-BIAS_WINDOW]
        mean = float(np.mean(self._bias))
        if d > 30.0 or (len(self._bias) == BIAS_WINDOW and mean > BIAS_MEAN):
            self._bias.clear()
            return False, None, filtered, own
        suspect = d > BIAS_SUSPECT or (len(self._bias) == BIAS_WINDOW and mean > 3.0)
        return True, (delta if suspect else None), filtered, own


TRACKING = {"sna": SNATracking, "jpdaf": JPDAFTracking}
"""The tracking strategy of each ``tracker`` (TRACKERS)."""
assert tuple(TRACKING) == TRACKERS


def pipeline_for(conf, cam) -> StarTrackerPipeline:
    """The pipeline of a star tracker's settings ``conf`` (tracker_stage.TrackerConfig) on its camera's ``cam``
    (camera_stage.CameraConfig): the camera's catalogue and geometry; σ, P_D and the clutter density as the
    settings give them or the camera's."""
    camera, catalogue = camera_of(cam), catalogue_of(cam)
    sigma_px = conf.sigma_px or cam.sigma_px
    clutter = conf.clutter_per_frame
    if clutter is None:
        clutter = max(cam.false_stars + cam.false_rate, 0.1)
    identifier = PyramidIdentifier(catalogue, camera, sigma_px, pair_table=pair_table(cam))
    return StarTrackerPipeline(
        catalogue,
        camera,
        sigma_px,
        tracker=conf.tracker,
        solver=conf.solver,
        motion=conf.motion,
        sigma_a=conf.sigma_a,
        p_detect=conf.p_detect,
        clutter_density=clutter / (camera.width * camera.height),
        gate=conf.gate,
        min_stars=conf.min_stars,
        verify_sigmas=conf.verify_sigmas,
        max_misses=conf.max_misses,
        aid=conf.aid,
        identifier=identifier,
    )
