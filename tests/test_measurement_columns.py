"""The measurement codecs' columnar read (``measurement_vectors``), which the scorer uses instead of decoding each
message of a topic: the same vectors as ``decode``, bit for bit, or None where they cannot be columns."""

from __future__ import annotations

import numpy as np
import pytest

from bench_engine import cdr
from bench_engine.columns import table
from bench_engine.stage import Measurement
from radar_sensor.messages import RANGE_AZ_EL, VECTOR_MEASUREMENT

RANGE_AZ_EL_TYPE = "bench_msgs/msg/RangeAzEl"
VECTOR_TYPE = "bench_msgs/msg/VectorMeasurement"


def _table(type_name: str, codec, items: list[Measurement]):
    lite = cdr.lite_class(type_name)
    return table(type_name, [cdr.serialize(type_name, codec.encode(item, lite)) for item in items])


def _items(rng, dims: list[int]) -> list[Measurement]:
    return [
        Measurement(k, 10**9 * k, "eci", "s", rng.normal(size=d) * 1e3, np.eye(d), [f"c{i}" for i in range(d)])
        for k, d in enumerate(dims)
    ]


@pytest.mark.parametrize(
    "type_name, codec, dims",
    [
        (RANGE_AZ_EL_TYPE, RANGE_AZ_EL, [3] * 40),
        (RANGE_AZ_EL_TYPE, RANGE_AZ_EL, [4] * 40),
        (VECTOR_TYPE, VECTOR_MEASUREMENT, [3] * 40),
        (VECTOR_TYPE, VECTOR_MEASUREMENT, [6] * 7),
    ],
)
def test_the_columns_are_the_decoded_vectors(type_name, codec, dims):
    tab = _table(type_name, codec, _items(np.random.default_rng(len(dims)), dims))
    vectors = codec.measurement_vectors(tab)
    assert vectors.shape == (len(dims), dims[0]) and vectors.dtype == float
    for i, z in enumerate(vectors):
        expected = codec.decode(tab.row(i)).z
        assert z.tobytes() == np.asarray(expected, dtype=float).tobytes()


@pytest.mark.parametrize("type_name, codec", [(RANGE_AZ_EL_TYPE, RANGE_AZ_EL), (VECTOR_TYPE, VECTOR_MEASUREMENT)])
def test_vectors_of_different_lengths_are_no_columns(type_name, codec):
    dims = [3, 4, 3] if codec is RANGE_AZ_EL else [3, 6, 3]
    assert codec.measurement_vectors(_table(type_name, codec, _items(np.random.default_rng(1), dims))) is None
