"""The k-vector range search equals brute force, and so does the catalogue's pair table."""

from __future__ import annotations

import numpy as np
import pytest

from star_tracker.camera import DEFAULT_CAMERA
from star_tracker.catalogue import angle_between, load_catalogue
from star_tracker.kvector import KVector, PairTable


def brute(values, ya, yb):
    return np.flatnonzero((values >= ya) & (values <= yb))


@pytest.mark.parametrize("kind", ["uniform", "clustered", "duplicates", "two"])
def test_kvector_queries_equal_brute_force(kind):
    rng = np.random.default_rng(5)
    values = {
        "uniform": rng.uniform(-3, 7, 2000),
        "clustered": np.concatenate([rng.normal(0, 0.01, 1500), rng.exponential(5.0, 500)]),
        "duplicates": rng.integers(0, 30, 1000).astype(float),
        "two": np.array([1.0, 2.0]),
    }[kind]
    kv = KVector(values)
    lo, hi = values.min(), values.max()
    queries = [(a, a + w) for a, w in zip(rng.uniform(lo - 1, hi + 1, 400), rng.exponential(0.2 * (hi - lo), 400))]
    queries += [
        (lo, hi),
        (lo - 5, lo - 1),
        (hi + 1, hi + 5),
        (lo, lo),
        (hi, hi),
        (hi, hi + 1),
        (lo - 1, lo),
        (3.0, 2.0),
        (np.nan, 1.0),
    ]
    queries += [(v, v) for v in values[:50]] + [(v, values[(i + 7) % len(values)]) for i, v in enumerate(values[:50])]
    for ya, yb in queries:
        got = np.sort(kv.query(ya, yb))
        np.testing.assert_array_equal(got, brute(values, ya, yb), err_msg=f"[{ya}, {yb}]")


def test_kvector_refuses_too_few_or_non_finite_values():
    with pytest.raises(ValueError):
        KVector(np.array([1.0]))
    with pytest.raises(ValueError):
        KVector(np.array([1.0, np.nan, 2.0]))


def test_the_pair_table_holds_every_close_pair_and_its_lookups_equal_brute_force(tmp_path):
    cat = load_catalogue(5.0, cache_dir=tmp_path)
    table = PairTable(cat, DEFAULT_CAMERA.max_separation)
    all_angles = angle_between(cat.vectors[:, None, :], cat.vectors[None, :, :])
    iu = np.triu_indices(len(cat), 1)
    close = all_angles[iu] <= DEFAULT_CAMERA.max_separation
    assert len(table) == int(close.sum())
    np.testing.assert_allclose(table.angles, angle_between(cat.vectors[table.first], cat.vectors[table.second]))
    rng = np.random.default_rng(6)
    for theta in rng.uniform(0.0, DEFAULT_CAMERA.max_separation, 30):
        f, s = table.lookup(theta, 4e-4)
        got = {(min(a, b), max(a, b)) for a, b in zip(f.tolist(), s.tolist())}
        want_mask = close & (np.abs(all_angles[iu] - theta) <= 4e-4)
        want = set(zip(iu[0][want_mask].tolist(), iu[1][want_mask].tolist()))
        assert got == want and len(got) > 0
