#!/usr/bin/env python3
"""Cost of the bench's CDR path for one StateEstimate of 6 states (bench_engine.cdr): microseconds to build its
light message with the codec and serialise it, to deserialise it, and to deserialise and decode it.

    .venv/bin/python scripts/bench_cdr.py
    .venv/bin/python scripts/bench_cdr.py --repeat 50000
"""

from __future__ import annotations

import argparse
import timeit

import numpy as np

from bench_engine.cdr import deserialize, lite_class, serialize
from bench_engine.stage import ESTIMATE_CODEC, Estimate

TYPE = "bench_msgs/msg/StateEstimate"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeat", type=int, default=20000, help="calls per timing (the best of 7 is printed)")
    repeat = parser.parse_args().repeat
    item = Estimate(
        3,
        1_500_000_000,
        "eci",
        "ukf",
        ["x", "y", "z", "vx", "vy", "vz"],
        np.arange(6.0),
        np.eye(6),
        1.5,
        {"n_eff": 3.0},
    )
    lite = lite_class(TYPE)
    data = serialize(TYPE, ESTIMATE_CODEC.encode(item, lite))
    for label, stmt in (
        ("encode + serialize", lambda: serialize(TYPE, ESTIMATE_CODEC.encode(item, lite))),
        ("deserialize", lambda: deserialize(TYPE, data)),
        ("deserialize + decode", lambda: ESTIMATE_CODEC.decode(deserialize(TYPE, data))),
    ):
        best = min(timeit.repeat(stmt, number=repeat, repeat=7)) / repeat * 1e6
        print(f"{label:24s} {best:6.2f} us")


if __name__ == "__main__":
    main()
