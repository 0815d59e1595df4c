"""What filters and sensors need of a measurement model is declared once and checked when they are built: the
angles among its components (bench_engine.labels) and what an initialiser requires of it."""

from __future__ import annotations

import numpy as np
import pytest

from bench_engine.config import ScenarioError, load_scenario
from bench_engine.labels import ANGLES, AZIMUTHS
from bench_models.isl import RangeAzElModel
from bench_models.models import angle_components, check_angles
from bench_models.radar import GroundRadarModel
from bench_models.states import state_error
from radar_sensor.sensor import Sensor, build_sensor
from tracker_filters.builders import build_filter_stack


def test_the_models_angles_are_the_components_their_labels_name() -> None:
    radar = GroundRadarModel(78.0, 16.0, 400.0, with_range_rate=True)
    assert tuple(radar.angle_indices) == angle_components(radar.labels) == (1, 2)
    assert RangeAzElModel.angle_indices == (1, 2)
    assert {"azimuth", "elevation"} <= ANGLES and AZIMUTHS <= ANGLES


def test_a_state_error_wraps_exactly_the_declared_angles() -> None:
    labels = ["range", "azimuth", "x"]
    _, err = state_error(labels, np.array([0.0, 3.0, 3.0]), np.array([0.0, -3.0, -3.0]))
    np.testing.assert_allclose(err, [0.0, 6.0 - 2 * np.pi, 6.0])


class _MislabelledModel:
    labels = ("range", "azimuth", "elevation")
    angle_indices = (1,)  # forgets the elevation


def test_a_sensor_whose_model_wraps_other_components_than_its_angles_is_refused() -> None:
    with pytest.raises(ValueError, match=r"wraps components \(1,\).*are \(1, 2\)"):
        check_angles(_MislabelledModel())
    with pytest.raises(ScenarioError, match="sensor 'odd'"):
        Sensor("odd", "custom", _MislabelledModel(), np.eye(3), 1.0, 1, "enu", lambda x, t: True)


def test_a_reported_azimuth_is_in_zero_to_two_pi() -> None:
    sensor = build_sensor(load_scenario("leo_radar"), "radar")
    assert sensor._azimuths == [1]


def test_first_scan_initialisation_on_a_sensor_that_gives_no_position_is_refused_at_validation() -> None:
    cfg = load_scenario("formation_cqkf")
    cfg["filter_defaults"]["init"] = {"method": "first_scan", "velocity_sigma": 1.0}
    cfg["filters"]["cw"].pop("init", None)
    with pytest.raises(ScenarioError, match=r"'filters.cw.init' .*ScanPositionModel.*measurement '\w+'"):
        build_filter_stack(cfg, "cw")


def test_first_scan_initialisation_on_a_radar_is_accepted() -> None:
    stack = build_filter_stack(load_scenario("leo_radar"), "ukf")
    assert stack.initialise.requires.__name__ == "ScanPositionModel"
