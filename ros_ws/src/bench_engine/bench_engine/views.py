"""The standard ROS views of the bench's estimates and truth: what RViz, Foxglove or any ROS tool can show.

Longer than 500 lines: one short builder per standard message (Odometry, poses, attitude, diagnostics, markers)
and the publishers that attach them to a node; the state layout they read is in bench_engine.view_state.

Every node that publishes estimates (``/NAME/estimate``, bench_msgs/StateEstimate) or the truth (``/NAME/state``,
bench_msgs/TruthState) also publishes, on topics beside it, the standard messages that view each item, where the
item's state holds what they need (selected by label, never by position). The topic suffixes are a contract
(the constants below); :func:`add_standard_views` adds the topics to the graph (bench_engine.graph.build_graph),
so the recorder records them and the pacing counts them, and :func:`item_publishers` is the node shells' one
call that publishes them. A node advertises only the views its state supports: each kind says the labels of the
states it publishes (``NodeSpec.labels``: a leo_radar UKF's orbit state has no pose, no attitude). A view topic
whose message an item cannot fill (a kind that says no labels) gets nothing: pacing and the recorder count what
was published, zero included. The scorer reads only ``/NAME/measurement``, ``/NAME/estimate`` and
``/truth/state``.

Everything here is a pure conversion (item -> light message, bench_engine.cdr) except :func:`item_publishers`,
which only calls the shell's own publisher methods; nothing imports rclpy. tests/test_views.py checks the
conversions, tests/test_standard_outputs_graph.py a bag.

Conventions:

* frames: ``header.frame_id`` is the item's frame (``eci``, ``lvlh``, ``icrs``); an Odometry's
  ``child_frame_id`` is the body as the publishing node sees it, named after the node (``ukf``, ``truth``): the
  bench's states have no body names, and one child frame per estimator keeps a TF tree unambiguous;
* Odometry (REP-103, nav_msgs): position x y z, velocity vx vy vz; the orientation is the identity, so the
  child frame's axes are the header frame's and the twist (nav_msgs: in the child frame) is the state's
  velocity as it is; orientation and angular velocity are unknown: their variances are :data:`UNKNOWN_VARIANCE`
  (a large value rather than −1, which tools that draw covariance ellipsoids or take square roots mishandle).
  pose.covariance and twist.covariance are 6 × 6 row-major over (x, y, z, rotation about x, y, z) and
  (vx, vy, vz, wx, wy, wz): the position and velocity blocks of the estimate's covariance (their cross terms
  have no place in Odometry); the truth's known blocks are zero (exact);
* attitude (labels qw qx qy qz, scalar first, A = R(q) the body(camera)-from-reference rotation, star_tracker's
  convention): geometry_msgs/PoseWithCovarianceStamped, the pose of the body in the reference frame, i.e. the
  orientation is q's conjugate (R(q)ᵀ rotates body coordinates into reference ones); its rotation covariance is
  the estimate's attitude-error covariance (rx ry rz, body frame: bench_models.states) rotated into the
  reference frame, Aᵀ P A; position x y z if the state has them, else zero and unknown. And
  bench_msgs/AttitudeEstimate, the bench's own compact attitude: q as the estimate gives it (reference -> body),
  the error covariance in the body frame, and the stars used (the diagnostic ``stars``);
* diagnostic_msgs/DiagnosticArray: at most one per :data:`DIAGNOSTICS_PERIOD_S` of sim time per estimator (ROS's
  diagnostic_updater: about 1 Hz), the status of the estimates since the previous one, this one included: named
  after the estimator, level OK when each had a measurement update, WARN when one had none (NIS NaN: coasting, a
  gated or rejected measurement); values ``step``, ``nis`` and every diagnostic (``n_eff``, ``gated``, …) of the
  latest estimate with ``repr`` (float() reads them back exactly), ``window_estimates``, ``window_without_update``
  (the first estimate gets one; each estimate's own NIS and diagnostics are on ``/NAME/estimate``);
* visualization_msgs/Marker: the trajectory as line-strip segments, one marker per segment (the previous drawn
  position to this one), at most one per :data:`MARKER_PERIOD_S` of sim time, each with its own id in the
  namespace of the node and no lifetime: a viewer accumulates them, and every message is the same few bytes. A
  Marker rather than a MarkerArray: it opens with its header, so the recorder logs it at its sim time
  (bench_engine.sim_clock.SimClock), as every other view.
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Callable
from typing import Any

import numpy as np

from bench_engine import cdr
from bench_engine.labels import POSITION, QUATERNION, VELOCITY
from bench_engine.msg_schema import message_class
from bench_engine.scenario import EngineKeys
from bench_engine.settings import read_key
from bench_engine.stage import Estimate, Item
from bench_engine.topics import ESTIMATE, ESTIMATE_TYPE, TRUTH_TYPE, NodeSpec, topic_owner
from bench_engine.view_state import State, attitude_matrix, block, state_of

ODOMETRY = "odometry"
"""``/NAME/odometry`` (nav_msgs/Odometry): position and velocity with their covariance, for a state with
x y z vx vy vz (orbit and relative-navigation states)."""
POSE = "pose"
"""``/NAME/pose`` (geometry_msgs/PoseWithCovarianceStamped): the attitude of a state with qw qx qy qz, as the
pose of the body in the item's frame."""
ATTITUDE = "attitude"
"""``/NAME/attitude`` (bench_msgs/AttitudeEstimate): an estimate's attitude in the bench's own convention
(estimates only)."""
DIAGNOSTICS = "diagnostics"
"""``/NAME/diagnostics`` (diagnostic_msgs/DiagnosticArray): an estimate's NIS and diagnostics (estimates only)."""
MARKERS = "markers"
"""``/NAME/markers`` (visualization_msgs/Marker): the trajectory of a state with x y z."""
SUFFIXES = (ODOMETRY, POSE, ATTITUDE, DIAGNOSTICS, MARKERS)

ODOMETRY_TYPE = "nav_msgs/msg/Odometry"
POSE_TYPE = "geometry_msgs/msg/PoseWithCovarianceStamped"
ATTITUDE_TYPE = "bench_msgs/msg/AttitudeEstimate"
DIAGNOSTICS_TYPE = "diagnostic_msgs/msg/DiagnosticArray"
MARKERS_TYPE = "visualization_msgs/msg/Marker"
ESTIMATE_VIEWS = {
    ODOMETRY: ODOMETRY_TYPE,
    POSE: POSE_TYPE,
    ATTITUDE: ATTITUDE_TYPE,
    DIAGNOSTICS: DIAGNOSTICS_TYPE,
    MARKERS: MARKERS_TYPE,
}
"""The views of every ``/NAME/estimate`` topic."""
TRUTH_VIEWS = {ODOMETRY: ODOMETRY_TYPE, POSE: POSE_TYPE, MARKERS: MARKERS_TYPE}
"""The views of every topic of TruthState (``/truth/state``)."""

UNKNOWN_VARIANCE = 1.0e16
"""The variance of a component a view does not know (an Odometry's orientation and angular velocity, an
attitude pose's position): far above any variance a bench state has in SI units (a position across the Earth,
~1e14 m²; a rotation, ~10 rad²)."""
DIAGNOSTICS_PERIOD_S = 1.0
"""Sim time between two diagnostics of one estimator (module docstring: ROS's convention of about 1 Hz)."""
MARKER_PERIOD_S = 1.0
"""Sim time between two trajectory markers of one node (at 10 Hz: 1 marker in 10 estimates)."""
MARKER_WIDTH = 2.0e-3
"""A trajectory line's width as a fraction of the first drawn position's distance from the frame's origin (a low
orbit in ECI: about 13 km), at least 1 m."""
TRUTH_COLOR = (0.1, 0.8, 0.1)
PALETTE = ((0.9, 0.3, 0.1), (0.1, 0.5, 0.95), (0.85, 0.1, 0.75), (0.95, 0.75, 0.1), (0.1, 0.8, 0.8), (0.55, 0.35, 0.9))
"""Estimators' trajectory colours, picked by a stable hash of the node name."""


# --- the graph --------------------------------------------------------------------------------------------

NEEDS = {ODOMETRY: POSITION + VELOCITY, POSE: QUATERNION, ATTITUDE: QUATERNION, MARKERS: POSITION, DIAGNOSTICS: ()}
"""The state labels each view needs (an item without them gets none of that view: the functions below)."""


def supported(labels: tuple[str, ...] | None) -> set[str]:
    """The views a state with ``labels`` supports (None: unknown, every view)."""
    return set(NEEDS) if labels is None else {view for view, need in NEEDS.items() if set(need) <= set(labels)}


def view_topics(topic: str, type_name: str, labels: tuple[str, ...] | None = None) -> dict[str, str]:
    """The view topics (with their types) of a data topic: ``/NAME/estimate`` of StateEstimate gives
    ESTIMATE_VIEWS, a TruthState topic ``/NAME/state`` TRUTH_VIEWS, anything else none; of those, the ones a
    state with ``labels`` supports (None: unknown, all of them)."""
    parts = topic.split("/")
    if len(parts) != 3 or parts[0] or not parts[1]:
        return {}
    if type_name == ESTIMATE_TYPE and topic_owner(topic, ESTIMATE) is not None:
        views = ESTIMATE_VIEWS
    elif type_name == TRUTH_TYPE and parts[2] == "state":
        views = TRUTH_VIEWS
    else:
        return {}
    keep = supported(labels)
    return {f"/{parts[1]}/{suffix}": view_type for suffix, view_type in views.items() if suffix in keep}


SWITCH = "standard_views"
"""The scenario key that turns the views on (default) or off: ``--set standard_views=false``. Monte Carlo batches
(bench_engine.batch) turn them off: they add an Odometry (or a pose and an attitude) to every estimate and truth
sample, with a diagnostics status and a marker per second of sim time (``scripts/bench_graph.py --set
standard_views=false`` measures the difference), and the scorer does not read them."""


def standard_views(cfg: dict) -> bool:
    """The scenario's ``standard_views`` (bench_engine.scenario.EngineKeys: a bool, default true)."""
    return read_key(EngineKeys, cfg, SWITCH)


def add_standard_views(nodes: list[NodeSpec], cfg: dict) -> None:
    """Add to each node's published topics the views of its estimate and truth topics that their state supports
    (``NodeSpec.labels``), unless the scenario turns them off (build_graph's one call): the recorder then records
    them, the readiness barrier waits for their subscribers and the pacing counts them, like any data topic. A
    bag player (role ``replay``) replays the recorded truth and measurements only, so a replayed run's bag has
    no truth views."""
    if not standard_views(cfg):
        return
    for node in nodes:
        if node.role == "replay":
            continue
        for topic, type_name in list(node.publishes.items()):
            for view, view_type in view_topics(topic, type_name, node.labels.get(topic)).items():
                node.publishes.setdefault(view, view_type)


# --- the views --------------------------------------------------------------------------------------------

_lite = cdr.lite_class
"""Light classes by type (cached): the typestore is built when one is first needed, or by :func:`warm`."""
STATUS_TYPE = "diagnostic_msgs/msg/DiagnosticStatus"
KEY_VALUE_TYPE = "diagnostic_msgs/msg/KeyValue"
POINT_TYPE = "geometry_msgs/msg/Point"


def warm() -> None:
    """Compile now the CDR code of the bench's messages and of their views (bench_engine.cdr.warm: rosbags
    generates code for each). The node shells call it when they are imported: the launcher and the
    Monte Carlo fork server import them before they fork nodes and runs, which inherit the compiled code.
    Importing this module builds nothing (the graph and the scorer import it)."""
    cdr.warm([*cdr.bench_types(), *ESTIMATE_VIEWS.values()])


_UNKNOWN_BLOCK = np.diag([0.0, 0.0, 0.0, UNKNOWN_VARIANCE, UNKNOWN_VARIANCE, UNKNOWN_VARIANCE])
"""A 6 × 6 covariance whose first three components are exact and last three unknown."""


def _header(msg: Any, item: Item) -> None:
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(int(item.t_ns), 1_000_000_000)
    msg.header.frame_id = item.frame_id


_ODOMETRY_BASE = np.concatenate(
    [np.zeros(3), [0.0, 0.0, 0.0, 1.0], _UNKNOWN_BLOCK.ravel(), np.zeros(6), _UNKNOWN_BLOCK.ravel()]
)
"""An Odometry's 85 numbers after its frame names, in wire order: position x y z, orientation x y z w (the
identity), pose covariance (36), linear and angular velocity, twist covariance (36); here with nothing known."""
_POSE_COV, _LINEAR, _TWIST_COV = slice(7, 43), slice(43, 46), slice(49, 85)


def _odometry_numbers(st: State) -> np.ndarray | None:
    """The 85 numbers of the Odometry of a state with x y z vx vy vz (``_ODOMETRY_BASE``'s order); None without."""
    x, P, lay = st.x, st.P, st.layout
    if lay.position is None or lay.velocity is None:
        return None
    out = _ODOMETRY_BASE.copy()
    out[:3] = x[list(lay.position)]
    out[_LINEAR] = x[list(lay.velocity)]
    if P is not None:
        pose, twist = out[_POSE_COV].reshape(6, 6), out[_TWIST_COV].reshape(6, 6)
        if lay.cov_position is not None:
            pose[:3, :3] = block(P, lay.cov_position, lay.cov_position)
        else:
            pose[0, 0] = pose[1, 1] = pose[2, 2] = UNKNOWN_VARIANCE
        if lay.cov_velocity is not None:
            twist[:3, :3] = block(P, lay.cov_velocity, lay.cov_velocity)
        else:
            twist[0, 0] = twist[1, 1] = twist[2, 2] = UNKNOWN_VARIANCE
    return out


def odometry(item: Item, child_frame_id: str, state: State | None = None) -> Any | None:
    """nav_msgs/Odometry of an estimate or truth sample with x y z vx vy vz; None without them. (``state``:
    the item's, if already read.)"""
    numbers = _odometry_numbers(state or state_of(item))
    if numbers is None:
        return None
    msg = _lite(ODOMETRY_TYPE)(child_frame_id=child_frame_id)
    _header(msg, item)
    p, o, v = msg.pose.pose.position, msg.pose.pose.orientation, msg.twist.twist.linear
    p.x, p.y, p.z, o.x, o.y, o.z, o.w = numbers[:7].tolist()
    v.x, v.y, v.z = numbers[_LINEAR].tolist()
    msg.pose.covariance = numbers[_POSE_COV].copy()
    msg.twist.covariance = numbers[_TWIST_COV].copy()
    return msg


class OdometryEncoder:
    """:func:`odometry` straight to its CDR bytes (bench_engine.cdr's, byte for byte: tests/test_views.py): an
    Odometry is its stamp, its two frame names, then 85 float64 (``_ODOMETRY_BASE``), so its bytes are rosbags'
    serialisation of a message with the same frame names (kept per frame name, the stamp written in place), then
    one array's bytes: no message objects built and serialised field by field with every estimate and sample."""

    TAIL = 8 * len(_ODOMETRY_BASE)

    def __init__(self, child_frame_id: str) -> None:
        self.child_frame_id = child_frame_id
        self._prefixes: dict[str, bytes] = {}

    def _prefix(self, frame_id: str) -> bytes:
        prefix = self._prefixes.get(frame_id)
        if prefix is None:
            template = _lite(ODOMETRY_TYPE)(child_frame_id=self.child_frame_id)
            template.header.frame_id = frame_id
            data = cdr.serialize(ODOMETRY_TYPE, template)
            prefix = data[: -self.TAIL]
            # the contract above, checked on the template: zero stamp first, the numbers 8-aligned at the end
            if (
                data[-self.TAIL :] != _ODOMETRY_BASE_DEFAULT
                or data[cdr.HEADER : cdr.HEADER + 8] != bytes(8)
                or (len(prefix) - cdr.HEADER) % 8
            ):
                raise RuntimeError("nav_msgs/Odometry is not laid out as bench_engine.views.OdometryEncoder assumes")
            self._prefixes[frame_id] = prefix
        return prefix

    def __call__(self, item: Item, state: State | None = None) -> bytes | None:
        numbers = _odometry_numbers(state or state_of(item))
        if numbers is None:
            return None
        prefix = self._prefix(item.frame_id)
        sec, nanosec = divmod(int(item.t_ns), 1_000_000_000)
        return b"".join((prefix[: cdr.HEADER], _STAMP.pack(sec, nanosec), prefix[cdr.HEADER + 8 :], numbers.tobytes()))


_STAMP = struct.Struct("<iI")
_ODOMETRY_BASE_DEFAULT = np.concatenate([np.zeros(6), [1.0], np.zeros(78)]).astype("<f8").tobytes()
"""The numbers of a default Odometry (identity orientation, zero covariances) as rosbags writes them."""


def pose(item: Item, state: State | None = None) -> Any | None:
    """geometry_msgs/PoseWithCovarianceStamped of an estimate or truth sample with qw qx qy qz; None without."""
    st = state or state_of(item)
    x, P, lay = st.x, st.P, st.layout
    if lay.quaternion is None:
        return None
    q = x[list(lay.quaternion)]
    q = q / np.linalg.norm(q)
    A = attitude_matrix(q)
    msg = _lite(POSE_TYPE)()
    _header(msg, item)
    o = msg.pose.pose.orientation
    o.w, o.x, o.y, o.z = float(q[0]), -float(q[1]), -float(q[2]), -float(q[3])  # the conjugate: R(q)ᵀ
    cov = np.zeros((6, 6))
    if lay.position is not None:
        p = msg.pose.pose.position
        p.x, p.y, p.z = (float(x[i]) for i in lay.position)
    if P is None:  # the truth: exact, where the state holds it
        if lay.position is None:
            cov[0, 0] = cov[1, 1] = cov[2, 2] = UNKNOWN_VARIANCE
    else:
        if lay.cov_position is not None:
            cov[:3, :3] = block(P, lay.cov_position, lay.cov_position)
        else:
            cov[0, 0] = cov[1, 1] = cov[2, 2] = UNKNOWN_VARIANCE
        if lay.cov_rotation is not None:
            cov[3:, 3:] = A.T @ block(P, lay.cov_rotation, lay.cov_rotation) @ A
            if lay.cov_position is not None:
                cov[:3, 3:] = block(P, lay.cov_position, lay.cov_rotation) @ A
                cov[3:, :3] = cov[:3, 3:].T
        else:
            cov[3, 3] = cov[4, 4] = cov[5, 5] = UNKNOWN_VARIANCE
    msg.pose.covariance = cov.reshape(36)
    return msg


def attitude(item: Item, state: State | None = None) -> Any | None:
    """bench_msgs/AttitudeEstimate of an estimate with qw qx qy qz (the estimate's convention and body-frame
    error covariance, NaN if it has none); None for anything else."""
    if not isinstance(item, Estimate):
        return None
    st = state or state_of(item)
    x, P, lay = st.x, st.P, st.layout
    if lay.quaternion is None:
        return None
    stars = float(item.diagnostics.get("stars", 0.0))
    msg = _lite(ATTITUDE_TYPE)(
        step=int(item.step), estimator_name=item.source, stars_used=int(stars) if 0.0 <= stars < 2.0**32 else 0
    )
    _header(msg, item)
    o = msg.orientation
    o.w, o.x, o.y, o.z = (float(x[i]) for i in lay.quaternion)
    msg.covariance = (
        np.ascontiguousarray(block(P, lay.cov_rotation, lay.cov_rotation)).reshape(9)
        if lay.cov_rotation is not None
        else np.full(9, np.nan)
    )
    return msg


def diagnostics(
    item: Item, state: State | None = None, estimates: int = 1, without_update: int | None = None
) -> Any | None:
    """diagnostic_msgs/DiagnosticArray of an estimate: its NIS and diagnostics, as the status of the ``estimates``
    estimates up to it of which ``without_update`` had no measurement update (default: this one alone); None for
    anything else."""
    if not isinstance(item, Estimate):
        return None
    nis = float(item.nis)
    if without_update is None:
        without_update = int(nis != nis)
    key_value, status_class = _lite(KEY_VALUE_TYPE), _lite(STATUS_TYPE)
    values = [key_value(key="step", value=str(int(item.step))), key_value(key="nis", value=repr(nis))]
    values += [key_value(key=str(k), value=repr(float(v))) for k, v in item.diagnostics.items()]
    values += [
        key_value(key="window_estimates", value=str(int(estimates))),
        key_value(key="window_without_update", value=str(int(without_update))),
    ]
    if not without_update:
        level, message = status_class.OK, ""
    elif estimates == 1:
        level, message = status_class.WARN, "no measurement update (NIS NaN)"
    else:
        level, message = (
            status_class.WARN,
            (
                f"{without_update} of the {estimates} estimates since the last status "
                "had no measurement update (NIS NaN)"
            ),
        )
    status = status_class(level=level, name=item.source, message=message, values=values)
    msg = _lite(DIAGNOSTICS_TYPE)(status=[status])
    _header(msg, item)
    return msg


class PeriodicDiagnostics:
    """One estimator's diagnostics at most once per ``period_s`` of sim time (module docstring): call it with
    each estimate; it returns the DiagnosticArray of the estimates since the last one it returned (this one
    included) once ``period_s`` has passed since that one (the first estimate gets one), else None."""

    def __init__(self, period_s: float = DIAGNOSTICS_PERIOD_S) -> None:
        self.period_ns = int(round(period_s * 1e9))
        self.last_t_ns: int | None = None
        self.estimates = 0
        self.without_update = 0

    def __call__(self, item: Item, state: State | None = None) -> Any | None:
        if not isinstance(item, Estimate):
            return None
        nis = float(item.nis)
        self.estimates += 1
        self.without_update += nis != nis
        if self.last_t_ns is not None and item.t_ns - self.last_t_ns < self.period_ns:
            return None
        msg = diagnostics(item, state, self.estimates, self.without_update)
        self.last_t_ns, self.estimates, self.without_update = int(item.t_ns), 0, 0
        return msg


def color(name: str) -> tuple[float, float, float]:
    """A node's trajectory colour: the truth's green, an estimator's from PALETTE by a stable hash."""
    return TRUTH_COLOR if name == "truth" else PALETTE[zlib.crc32(name.encode()) % len(PALETTE)]


class TrajectoryMarkers:
    """The trajectory of one node's items as line-strip segments (module docstring): call it with each item;
    it returns a Marker for a segment, or None (no position, or less than MARKER_PERIOD_S since the last)."""

    def __init__(self, name: str, period_s: float = MARKER_PERIOD_S) -> None:
        self.name = name
        self.period_ns = int(round(period_s * 1e9))
        self.color = color(name)
        self.count = 0
        self.last: tuple[float, float, float] | None = None
        self.last_t_ns = 0
        self.width = 0.0

    def __call__(self, item: Item, state: State | None = None) -> Any | None:
        st = state or state_of(item)
        x, lay = st.x, st.layout
        if lay.position is None:
            return None
        if self.last is not None and item.t_ns - self.last_t_ns < self.period_ns:
            return None
        here = tuple(float(x[i]) for i in lay.position)
        if self.last is None:
            self.width = max(1.0, MARKER_WIDTH * float(np.linalg.norm(here)))
        marker_class, point = _lite(MARKERS_TYPE), _lite(POINT_TYPE)
        marker = marker_class(
            ns=self.name,
            id=self.count,
            type=marker_class.LINE_STRIP,
            action=marker_class.ADD,
            points=[point(x=a, y=b, z=c) for a, b, c in (self.last or here, here)],
        )
        _header(marker, item)
        marker.scale.x = self.width
        c = marker.color
        c.r, c.g, c.b, c.a = (*self.color, 1.0)
        self.count += 1
        self.last, self.last_t_ns = here, int(item.t_ns)
        return marker


class StandardViews:
    """The views of one data topic's items, for the view topics the graph gave the node (``topics``: suffix ->
    topic). ``encoded(item)`` -> [(view topic, type, CDR bytes)], in a fixed order."""

    def __init__(self, node: str, topics: dict[str, str]) -> None:
        self.topics = topics
        serialized = _serialized
        encoders: list[tuple[str, str, Callable[[Item, State], bytes | None]]] = []
        for suffix, encode in (
            (ODOMETRY, OdometryEncoder(node)),
            (POSE, serialized(POSE_TYPE, pose)),
            (ATTITUDE, serialized(ATTITUDE_TYPE, attitude)),
            (DIAGNOSTICS, serialized(DIAGNOSTICS_TYPE, PeriodicDiagnostics())),
            (MARKERS, serialized(MARKERS_TYPE, TrajectoryMarkers(node))),
        ):
            if suffix in topics:
                encoders.append((topics[suffix], (ESTIMATE_VIEWS | TRUTH_VIEWS)[suffix], encode))
        self.encoders = encoders

    def encoded(self, item: Item) -> list[tuple[str, str, bytes]]:
        st = state_of(item)
        out = []
        for topic, type_name, encode in self.encoders:
            data = encode(item, st)
            if data is not None:
                out.append((topic, type_name, data))
        return out


def _serialized(type_name: str, make: Callable[[Item, State], Any | None]) -> Callable[[Item, State], bytes | None]:
    """``make``'s light message as CDR bytes (bench_engine.cdr), None when it makes none."""
    serialize = cdr.serialize

    def encode(item: Item, st: State) -> bytes | None:
        msg = make(item, st)
        return None if msg is None else serialize(type_name, msg)

    return encode


# --- the shells' call -------------------------------------------------------------------------------------


def item_publishers(node: Any, publishes: dict[str, str]) -> dict[str, Callable[[Item], None]]:
    """A node shell's publishers (bench_engine.bench_node.BenchNode: ``item_publisher``, ``data_publisher``,
    ``publish_data``), by data topic: for each topic of ``publishes`` that is not a view, the shell's item
    publisher; an item published on a topic with views in ``publishes`` then goes out on each of them, as CDR
    bytes (bench_engine.cdr). The node's name names its Odometry child frame and its markers."""
    owner = {
        view: topic
        for topic, type_name in publishes.items()
        for view in view_topics(topic, type_name)
        if view in publishes
    }
    out: dict[str, Callable[[Item], None]] = {}
    for topic, type_name in publishes.items():
        if topic in owner:
            continue
        publish = node.item_publisher(topic, type_name)
        mine = {view.rsplit("/", 1)[1]: view for view, base in owner.items() if base == topic}
        if mine:
            for view in mine.values():
                node.data_publisher(message_class(publishes[view]), view)
            publish = _with_views(
                publish,
                StandardViews(node.get_name(), mine),
                node.publish_data,
                lambda text: node.get_logger().warning(text),
            )
        out[topic] = publish
    return out


def _with_views(
    publish: Callable[[Item], None],
    views: StandardViews,
    publish_data: Callable[[str, bytes], None],
    warn: Callable[[str], None],
) -> Callable[[Item], None]:
    """``publish``, then the item's views; a view that fails is logged (once) and skipped: it never stops the
    node or holds back its estimates."""
    warned = []

    def publish_with_views(item: Item) -> None:
        publish(item)
        try:
            for topic, _, data in views.encoded(item):
                publish_data(topic, data)
        except Exception as err:  # noqa: BLE001 - a view is a by-product: report it, keep the node running
            if not warned:
                warned.append(err)
                warn(
                    f"standard views of step {item.step} not published ({type(err).__name__}: {err}); "
                    "later failures are not logged"
                )

    return publish_with_views
