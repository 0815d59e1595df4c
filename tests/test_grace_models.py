"""GRACE study building blocks: labelled measurement models, GNSS and KBR sensors, derived measurements
(difference, Newton velocities) and the range-rate metric (paper 002, eqs. 27-29)."""

from __future__ import annotations

import numpy as np
import pytest

from bench_engine.config import ScenarioError
from bench_engine.settings import read
from bench_engine.stage import Measurement
from bench_models.labelled import ComponentModel, RangeRateModel, UnboundModel
from bench_studies.grace_velocity.metrics import range_rate
from radar_sensor.sensor import build_sensor
from tracker_filters.derived import DerivedConfig, DifferenceStage, DifferentiatedStage
from tracker_filters.differentiation import newton_weights

PAIR = (
    "x1",
    "y1",
    "z1",
    "vx1",
    "vy1",
    "vz1",
    "x2",
    "y2",
    "z2",
    "vx2",
    "vy2",
    "vz2",
    "bx",
    "by",
    "bz",
    "bvx",
    "bvy",
    "bvz",
)
BASELINE = ("bx", "by", "bz", "bvx", "bvy", "bvz", "bax", "bay", "baz")


def test_a_component_model_binds_to_any_layout_that_has_its_components() -> None:
    model = ComponentModel(("bx", "by", "bz"))
    with pytest.raises(UnboundModel):
        model.h(np.zeros(18))
    truth, filt = model.for_state(PAIR), model.for_state(BASELINE)
    x = np.arange(18.0)
    np.testing.assert_array_equal(truth.h(x), [12.0, 13.0, 14.0])
    np.testing.assert_array_equal(filt.h(np.arange(9.0)), [0.0, 1.0, 2.0])
    np.testing.assert_array_equal(filt.jacobian(np.zeros(9)), np.hstack([np.eye(3), np.zeros((3, 6))]))
    np.testing.assert_array_equal(truth.h(np.tile(x, (4, 1))), np.tile([12.0, 13.0, 14.0], (4, 1)))
    with pytest.raises(ValueError, match=r"\['bx', 'by', 'bz'\]"):
        model.for_state(("x1", "y1", "z1"))


def test_range_rate_model_and_its_jacobian_against_finite_differences() -> None:
    model = RangeRateModel(("bx", "by", "bz"), ("bvx", "bvy", "bvz")).for_state(BASELINE)
    rng = np.random.default_rng(4)
    x = np.concatenate([rng.normal(0, 1e5, 3), rng.normal(0, 10.0, 3), rng.normal(0, 0.1, 3)])
    b, w = x[:3], x[3:6]
    np.testing.assert_allclose(model.h(x), [np.linalg.norm(b), b @ w / np.linalg.norm(b)], rtol=1e-14)
    H = model.jacobian(x)
    steps = np.concatenate([np.full(3, 1.0), np.full(3, 1e-4), np.full(3, 1e-4)])
    fd = np.array([(model.h(x + e) - model.h(x - e)) / (2 * s) for e, s in zip(np.diag(steps), steps)]).T
    np.testing.assert_allclose(H, fd, rtol=1e-6, atol=1e-12)
    assert H[:, 6:].tolist() == [[0.0] * 3] * 2


def test_range_rate_is_the_derivative_of_the_range() -> None:
    t = np.linspace(0.0, 10.0, 11)
    b = np.stack([2.2e5 + 3.0 * t + 0.01 * t**2, -40.0 * t, 5.0 + 0 * t], axis=1)
    w = np.stack([3.0 + 0.02 * t, -40.0 + 0 * t, 0 * t], axis=1)
    rho = np.linalg.norm(b, axis=1)
    np.testing.assert_allclose(range_rate(b, w)[1:-1], (rho[2:] - rho[:-2]) / 2.0, rtol=1e-6)


def _gnss_cfg(**extra) -> dict:
    return {
        "time": {"start": 0.0, "duration": 100.0, "dt": 10.0},
        "sensors": {
            "g": {"type": "gnss", "position": ["x1", "y1", "z1"], "interval": 10.0, "sigma_position": 0.02, **extra}
        },
    }


@pytest.mark.parametrize("tau", [0.0, 300.0])
def test_gnss_noise_has_its_std_and_correlation(tau: float) -> None:
    sensor = build_sensor(_gnss_cfg(correlation_time=tau), "g")
    sensor.bind(list(PAIR))
    rng = np.random.default_rng(7)
    x = np.zeros(18)
    e = np.array([sensor.observe(x, 10.0 * k, k, rng) for k in range(20000)])
    assert np.std(e) == pytest.approx(0.02, rel=0.05)
    lag1 = np.mean([np.corrcoef(e[:-1, i], e[1:, i])[0, 1] for i in range(3)])
    assert lag1 == pytest.approx(np.exp(-10.0 / tau) if tau else 0.0, abs=0.03)


def test_gnss_and_kbr_sections_are_read_strictly() -> None:
    with pytest.raises(ScenarioError, match="position"):
        build_sensor(_gnss_cfg(position=["x1", "y1"]), "g")
    with pytest.raises(ScenarioError, match="correlation_time"):
        build_sensor(_gnss_cfg(correlation_time=-1.0), "g")
    cfg = _gnss_cfg()
    cfg["sensors"]["k"] = {
        "type": "kbr",
        "position": ["bx", "by", "bz"],
        "velocity": ["bvx", "bvy", "bvz"],
        "interval": 10.0,
        "sigma_range_rate": 1e-6,
        "sigma_range": 1e-3,
    }
    with pytest.raises(ScenarioError, match="sigma_range"):  # range is not measured: its sigma is a mistake
        build_sensor(cfg, "k")


def _m(step: int, z, source: str = "a", R=None) -> Measurement:
    z = np.asarray(z, dtype=float)
    return Measurement(step, int(step * 10e9), "eci", source, z, np.eye(len(z)) if R is None else R, ["x", "y", "z"])


def test_difference_pairs_steps_in_any_arrival_order() -> None:
    stage = DifferenceStage(
        "b",
        read(
            DerivedConfig,
            {"type": "difference", "of": ["a", "c"], "labels": ["bx", "by", "bz"]},
            "derived_measurements.b",
        ),
    )
    assert stage.on_input("/a/measurement", _m(0, [5, 5, 5])) == []
    assert stage.on_input("/c/measurement", _m(1, [1, 1, 1], "c")) == []  # a missed step 1
    assert stage.on_input("/c/measurement", _m(2, [1, 2, 3], "c", 2 * np.eye(3))) == []
    ((topic, out),) = stage.on_input("/a/measurement", _m(2, [4, 4, 4]))
    assert topic == "/b/measurement" and out.step == 2 and out.labels == ["bx", "by", "bz"]
    np.testing.assert_array_equal(out.z, [3, 2, 1])
    np.testing.assert_array_equal(out.R, 3 * np.eye(3))
    assert all(not buffer for buffer in stage.pending.values())  # steps 0 and 1 can never pair


def test_newton_velocity_is_exact_on_a_polynomial_and_lags_half_a_window() -> None:
    labels = ("bx", "by", "bz", "bvx", "bvy", "bvz")
    stage = DifferentiatedStage(
        "pv",
        read(
            DerivedConfig,
            {"type": "differentiated", "of": "b", "labels": list(labels), "order": 4, "max_gap": 300.0},
            "derived_measurements.pv",
        ),
    )

    def p(t):
        return np.array([1e5 + 3 * t - 0.02 * t**2 + 1e-4 * t**3, 2 * t, 1e-6 * t**4])

    def v(t):
        return np.array([3 - 0.04 * t + 3e-4 * t**2, 2.0, 4e-6 * t**3])

    outs = [stage.on_input("/b/measurement", _m(k, p(10.0 * k), "b", 4e-4 * np.eye(3))) for k in range(8)]
    assert [len(o) for o in outs] == [0, 0, 0, 0, 1, 1, 1, 1]
    for k, ((_, out),) in enumerate(outs[4:]):
        assert out.step == k + 2 and out.labels == list(labels)  # the centre sample, 2 steps back
        np.testing.assert_allclose(out.z, np.concatenate([p(10.0 * (k + 2)), v(10.0 * (k + 2))]), rtol=1e-9)
    w = newton_weights(np.arange(5) * 10.0, 20.0)
    R = outs[4][0][1].R
    np.testing.assert_allclose(R[3:, 3:], 4e-4 * np.sum(w * w) * np.eye(3))
    np.testing.assert_allclose(R[:3, 3:], 4e-4 * w[2] * np.eye(3), atol=1e-18)
