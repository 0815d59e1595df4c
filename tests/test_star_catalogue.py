"""The star catalogue: Hipparcos read, proper motion, close pairs merged, the disk cache (keyed, rebuilt when
corrupt or when its inputs change)."""

from __future__ import annotations

import logging
import shutil

import numpy as np
import pytest

from star_tracker import catalogue as cat_mod
from star_tracker.catalogue import (
    ARCSEC,
    MAS,
    StarCatalogue,
    angle_between,
    build_catalogue,
    chord,
    load_catalogue,
    merge_close,
    propagate,
    radec_to_unit,
    read_hipparcos,
    unit_to_radec,
)


@pytest.fixture(scope="module")
def hip():
    return read_hipparcos()


def test_hipparcos_columns_are_the_documented_ones(hip):
    assert len(hip["hip"]) == 117955
    sirius = np.flatnonzero(hip["hip"] == 32349)[0]
    # Sirius: RA 06h45m09s, Dec -16°43', Hp -1.09, pm (-546, -1223) mas/yr
    assert np.degrees(hip["ra"][sirius]) == pytest.approx(101.287, abs=0.01)
    assert np.degrees(hip["dec"][sirius]) == pytest.approx(-16.716, abs=0.01)
    assert hip["mag"][sirius] == pytest.approx(-1.09, abs=0.01)
    assert hip["pm_ra"][sirius] == pytest.approx(-546.0, abs=2.0)
    assert hip["pm_dec"][sirius] == pytest.approx(-1223.1, abs=2.0)


def test_proper_motion_moves_a_star_by_its_rate_times_the_interval():
    ra, dec = np.array([1.0, 4.0]), np.array([0.3, -1.2])
    pm_ra, pm_dec = np.array([300.0, -1000.0]), np.array([-400.0, 50.0])
    u0 = radec_to_unit(ra, dec)
    u = propagate(ra, dec, pm_ra, pm_dec, 30.0)
    moved = angle_between(u0, u)
    np.testing.assert_allclose(moved, 30.0 * MAS * np.hypot(pm_ra, pm_dec), rtol=1e-6)
    ra1, dec1 = unit_to_radec(u)
    # the declination moves by pm_dec, the right ascension by pm_ra / cos(dec)
    # (to first order: near the pole a large pm_ra bends the path, hence the tolerance)
    np.testing.assert_allclose((dec1 - dec) / MAS / 30.0, pm_dec, atol=0.5)
    np.testing.assert_allclose((ra1 - ra) * np.cos(dec) / MAS / 30.0, pm_ra, rtol=1e-3)


def test_close_stars_merge_into_one_photocentre_with_the_summed_flux():
    base = radec_to_unit(np.array([0.5]), np.array([0.2]))[0]
    east = np.array([-np.sin(0.5), np.cos(0.5), 0.0])
    v = np.array([base, base + 60 * ARCSEC * east, base + 3000 * ARCSEC * east])
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    ids, vec, mags, members = merge_close(np.array([7, 8, 9]), v, np.array([5.0, 6.0, 5.5]), 100 * ARCSEC)
    assert len(ids) == 2
    pair = int(np.flatnonzero(members == 2)[0])
    assert ids[pair] == 7  # named after its brightest member
    assert mags[pair] == pytest.approx(5.0 - 2.5 * np.log10(1.0 + 10**-0.4))
    w = 10**-0.4  # flux of the 6.0 star relative to the 5.0
    assert angle_between(vec[pair], v[0]) / ARCSEC == pytest.approx(60 * w / (1 + w), rel=1e-3)
    single = 1 - pair
    assert ids[single] == 9 and mags[single] == 5.5 and np.allclose(vec[single], v[2])


def test_two_stars_below_the_limit_can_merge_into_one_above_it():
    v = radec_to_unit(np.array([1.0, 1.0 + 50 * ARCSEC, 2.0]), np.array([0.0, 0.0, 0.0]))
    src = {
        "hip": np.array([1, 2, 3]),
        "ra": np.array([1.0, 1.0 + 50 * ARCSEC, 2.0]),
        "dec": np.zeros(3),
        "pm_ra": np.zeros(3),
        "pm_dec": np.zeros(3),
        "mag": np.array([6.4, 6.4, 6.4]),
    }
    c = build_catalogue(6.0, cat_mod.HIPPARCOS_EPOCH, 100.0, merge_margin=1.0, source=src)
    assert len(c) == 1 and c.ids[0] == 1 and c.members[0] == 2
    assert c.magnitudes[0] == pytest.approx(6.4 - 2.5 * np.log10(2))
    assert angle_between(c.vectors[0], (v[0] + v[1]) / np.linalg.norm(v[0] + v[1])) < 1e-3 * ARCSEC


def test_the_real_catalogue_is_magnitude_limited_sorted_and_at_its_epoch(tmp_path, hip):
    c = load_catalogue(6.0, epoch=2025.0, merge_arcsec=140.0, cache_dir=tmp_path)
    assert 4000 < len(c) < 5000
    assert np.all(np.diff(c.magnitudes) >= 0) and c.magnitudes[-1] <= 6.0
    np.testing.assert_allclose(np.linalg.norm(c.vectors, axis=1), 1.0)
    assert c.ids[0] == 32349 and c.epoch == 2025.0  # Sirius first
    sirius = np.flatnonzero(hip["hip"] == 32349)[0]
    at_1991 = radec_to_unit(hip["ra"][sirius], hip["dec"][sirius])
    moved = angle_between(c.vectors[0], at_1991) / ARCSEC
    assert moved == pytest.approx(33.75 * np.hypot(546.0, 1223.1) / 1000.0, rel=0.01)  # ≈ 45"
    assert np.any(c.members > 1)  # some unresolved pairs were merged
    # no two entries closer than the merge separation
    d, _ = c.tree.query(c.vectors, k=2)
    assert np.min(2 * np.arcsin(d[:, 1] / 2)) >= 140.0 * ARCSEC
    assert c.index_of(c.ids[[5, 17]]).tolist() == [5, 17] and c.index_of([-3]).tolist() == [-1]


def test_the_cache_is_used_and_keyed_by_its_inputs(tmp_path, monkeypatch):
    first = load_catalogue(5.0, cache_dir=tmp_path)
    files = sorted(tmp_path.glob("*.npz"))
    assert len(files) == 1

    def fail(*_a, **_k):
        raise AssertionError("the source was read although a valid cache exists")

    monkeypatch.setattr(cat_mod, "read_hipparcos", fail)
    again = load_catalogue(5.0, cache_dir=tmp_path)
    np.testing.assert_array_equal(again.ids, first.ids)
    np.testing.assert_array_equal(again.vectors, first.vectors)
    monkeypatch.undo()
    other = load_catalogue(5.0, epoch=2000.0, cache_dir=tmp_path)  # another input: another cache file
    assert len(sorted(tmp_path.glob("*.npz"))) == 2
    assert angle_between(other.vectors[0], first.vectors[0]) > 1 * ARCSEC


def test_a_changed_source_file_changes_the_key(tmp_path):
    copy = tmp_path / "hip2.dat"
    shutil.copy(cat_mod.hipparcos_path(), copy)
    key = cat_mod.cache_key(6.0, 2025.0, 140.0, 1.0, copy)
    assert key == cat_mod.cache_key(6.0, 2025.0, 140.0, 1.0, copy)
    with open(copy, "a") as f:
        f.write("\n")
    assert cat_mod.cache_key(6.0, 2025.0, 140.0, 1.0, copy) != key
    assert cat_mod.cache_key(6.5, 2025.0, 140.0, 1.0, copy) != cat_mod.cache_key(6.0, 2025.0, 140.0, 1.0, copy)


@pytest.mark.parametrize("damage", ["garbage", "truncated", "wrong_arrays"])
def test_a_corrupt_cache_is_rebuilt_with_a_logged_message(tmp_path, caplog, damage):
    good = load_catalogue(4.0, cache_dir=tmp_path)
    (path,) = tmp_path.glob("*.npz")
    if damage == "garbage":
        path.write_bytes(b"not a numpy archive")
    elif damage == "truncated":
        path.write_bytes(path.read_bytes()[:200])
    else:
        np.savez(
            path, ids=np.arange(3), vectors=np.ones((2, 3)), magnitudes=np.zeros(3), members=np.ones(3), epoch=2025.0
        )
    with caplog.at_level(logging.WARNING, logger="star_tracker.catalogue"):
        rebuilt = load_catalogue(4.0, cache_dir=tmp_path)
    assert "rebuilding" in caplog.text
    np.testing.assert_array_equal(rebuilt.ids, good.ids)
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="star_tracker.catalogue"):
        load_catalogue(4.0, cache_dir=tmp_path)  # the rewritten cache is valid again
    assert "rebuilding" not in caplog.text


def test_an_unwritable_cache_directory_still_gives_the_catalogue(tmp_path, caplog):
    blocker = tmp_path / "file"
    blocker.write_text("a file where the cache directory should be")
    with caplog.at_level(logging.WARNING, logger="star_tracker.catalogue"):
        c = load_catalogue(4.0, cache_dir=blocker / "cache")
    assert len(c) > 100 and "uncached" in caplog.text


def test_a_cone_search_returns_exactly_the_stars_within_the_radius(tmp_path):
    c = load_catalogue(6.0, cache_dir=tmp_path)
    rng = np.random.default_rng(3)
    for axis in rng.normal(size=(5, 3)):
        axis /= np.linalg.norm(axis)
        got = c.cone(axis, np.radians(12.0))
        want = np.flatnonzero(angle_between(c.vectors, axis[None]) <= np.radians(12.0))
        np.testing.assert_array_equal(got, want)


def test_neighbourhoods_hold_exactly_the_stars_within_the_radius_each_star_last_built_once(tmp_path):
    c = load_catalogue(4.0, cache_dir=tmp_path)
    radius = np.radians(15.0)
    start, stars = c.neighbourhoods(radius)
    assert start.shape == (len(c) + 1,) and start[-1] == len(stars)
    chords = np.linalg.norm(c.vectors[:, None] - c.vectors[None], axis=-1)
    for a in range(len(c)):
        near = stars[start[a] : start[a + 1]]
        assert near[-1] == a  # the star itself last
        np.testing.assert_array_equal(
            np.sort(near[:-1]), np.flatnonzero((chords[a] <= chord(radius)) & (np.arange(len(c)) != a))
        )
    again = c.neighbourhoods(radius)
    assert again[0] is start and again[1] is stars  # shared by every identifier of the catalogue
    assert not (start.flags.writeable or stars.flags.writeable)
    assert len(c.neighbourhoods(radius / 2)[1]) < len(stars)  # another radius, another index


def test_catalogue_sorts_its_entries_brightest_first():
    c = StarCatalogue(np.array([3, 1, 2]), np.eye(3) * 2.0, np.array([5.0, 1.0, 3.0]), np.ones(3))
    assert c.ids.tolist() == [1, 2, 3]
    np.testing.assert_allclose(np.linalg.norm(c.vectors, axis=1), 1.0)
