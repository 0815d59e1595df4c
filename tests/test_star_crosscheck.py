"""Lost-in-space identification agrees with an independent solver, tetra3rs (PyPI), on identical frames."""

from __future__ import annotations

import numpy as np
import pytest

from star_tracker.attitude import error_angle
from star_tracker.camera import DEFAULT_CAMERA
from star_tracker.catalogue import ARCSEC, load_catalogue
from star_tracker.crosscheck import GAIA_BINARY, Tetra3Solver, write_tetra3_catalogue
from star_tracker.frames import random_attitude, simulate_frame
from star_tracker.pyramid import PyramidIdentifier


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    cache = tmp_path_factory.mktemp("cache")
    catalogue = load_catalogue(6.0, cache_dir=cache)
    return (
        catalogue,
        PyramidIdentifier(catalogue, DEFAULT_CAMERA, sigma_px=0.2),
        Tetra3Solver(catalogue, DEFAULT_CAMERA, cache_dir=cache),
    )


def test_the_catalogue_is_written_in_tetra3rs_binary_layout(setup, tmp_path):
    catalogue = setup[0]
    path = tmp_path / "c.bin"
    write_tetra3_catalogue(catalogue, path)
    raw = path.read_bytes()
    assert raw[:4] == b"GDR3" and int.from_bytes(raw[4:8], "little") == 1
    assert int.from_bytes(raw[8:16], "little") == len(catalogue) and GAIA_BINARY.itemsize == 36
    rec = np.frombuffer(raw[16:], dtype=GAIA_BINARY)
    np.testing.assert_array_equal(rec["source_id"], catalogue.ids)


def test_pyramid_and_tetra3rs_agree_on_identical_frames(setup):
    catalogue, pyramid, tetra3 = setup
    rng = np.random.default_rng(2024)
    for _ in range(12):
        A = random_attitude(rng)
        frame = simulate_frame(catalogue, DEFAULT_CAMERA, A, rng, sigma_px=0.2, n_false=2)
        ours = pyramid.identify(frame.uv, frame.magnitudes)
        theirs = tetra3.solve(frame.uv, frame.magnitudes)
        assert ours.ok and theirs.ok, (ours.reason, theirs.status)
        both = (ours.index >= 0) & (theirs.index >= 0)
        assert both.sum() >= 10
        np.testing.assert_array_equal(ours.index[both], theirs.index[both])  # the same identities
        assert np.all(theirs.index[frame.truth < 0] == -1)  # neither takes a false star
        assert error_angle(ours.attitude.matrix, theirs.attitude) < 60 * ARCSEC
        assert error_angle(theirs.attitude, A) < 100 * ARCSEC  # same camera convention


def test_the_tetra3rs_database_is_cached(setup, tmp_path):
    catalogue = setup[0]
    Tetra3Solver(catalogue, DEFAULT_CAMERA, cache_dir=tmp_path)
    files = sorted(p.name for p in tmp_path.iterdir())
    assert len(files) == 1 and files[0].startswith("tetra3_")
    solver = Tetra3Solver(catalogue, DEFAULT_CAMERA, cache_dir=tmp_path)  # loads it
    assert solver.db.num_stars == len(catalogue)
