"""The scorer's parallel path and the offline results' cache beside the bag (bench_eval.scoring.prepare_runs,
bench_eval.offline_cache), on real bags: formation_cqkf's variant ``smoothed`` (three RTS smoothers, offline,
and the posterior CRB bound).

Parallel scoring gives the serial scores: the same code over the same arrays in other processes, compared to
rtol 1e-12 (worker processes may be given other BLAS kernels than the parent, which changes last bits only). A
second scoring reads every offline result (estimates and bounds) back instead of computing it, exactly; a change of the
parameters or of the code is a miss; a damaged, truncated or hostile cache file is ignored with a warning naming
it, and replaced."""

from __future__ import annotations

import io
import math
import shutil
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from graph_helpers import script

from bench_engine import plugins
from bench_engine.settings import replaced
from bench_eval import offline_cache, scoring
from bench_eval.offline_cache import CacheWarning
from bench_eval.scoring import OfflineRun, load_bag, run_offline, score_bags, scoring_options

OFFLINE = ("ss_rts", "cw_rts", "cwb_rts")


@pytest.fixture(scope="module")
def recorded(tmp_path_factory) -> list[Path]:
    root = tmp_path_factory.mktemp("cqkf")
    bags = []
    for seed in (1, 2, 3):
        out = root / f"run_{seed}"
        res = script(
            "launch.py",
            "formation_cqkf",
            "--variant",
            "smoothed",
            "--seed",
            str(seed),
            "--set",
            "time.duration=120",
            "--out",
            str(out),
            "--no-score",
            "--single-process",
            timeout=300,
        )
        assert res.returncode == 0, res.stderr[-2000:]
        bags.append(out / "bag")
    return bags


@pytest.fixture
def bags(recorded, tmp_path) -> list[Path]:
    """Fresh copies of the recorded bags (each test writes its own cache files)."""
    return [Path(shutil.copytree(b, tmp_path / b.parent.name / "bag")) for b in recorded]


@pytest.fixture
def calls(monkeypatch) -> list[str]:
    """The sources the RTS estimator was run on, and "pcrb" for each bound computed, in this process (the
    scorer's own process: jobs=1)."""
    rts, pcrb, seen = plugins.load("offline", "rts"), plugins.load("bounds", "pcrb"), []

    def counting_rts(data, source, params):
        seen.append(source)
        return rts.run(data, source, params)

    def counting_pcrb(data, params):
        seen.append("pcrb")
        return pcrb.run(data, params)

    original = plugins.load
    wrapped = {
        ("offline", "rts"): type(rts)(counting_rts, rts.check, rts.params),
        ("bounds", "pcrb"): type(pcrb)(counting_pcrb, pcrb.check, pcrb.params),
    }
    monkeypatch.setattr(plugins, "load", lambda group, name: wrapped.get((group, name)) or original(group, name))
    return seen


def mapped(a: np.ndarray) -> bool:
    """Whether ``a`` lies in a file's map (an np.memmap somewhere down its bases), not in a copy."""
    while a is not None:
        if isinstance(a, np.memmap):
            return True
        a = getattr(a, "base", None)
    return False


def assert_same_scores(a, b, path="") -> None:
    """Equal score trees, numbers to rtol 1e-12."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and sorted(a) == sorted(b), path
        for k in a:
            assert_same_scores(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b)):
            assert_same_scores(x, y, f"{path}[{i}]")
    elif isinstance(a, float) and not isinstance(a, bool):
        assert (math.isnan(a) and math.isnan(b)) or a == pytest.approx(b, rel=1e-12, abs=0.0), path
    else:
        assert a == b, path


@pytest.mark.parametrize("scheduler", [None, "local"], ids=["process pool", "dask local cluster"])
def test_scoring_on_two_processes_gives_the_serial_scores(bags, scheduler):
    serial = score_bags(bags, with_series=True, jobs=1, cache=False)
    parallel = score_bags(bags, with_series=True, jobs=2, scheduler=scheduler, cache=False)
    assert serial[0]["runs"] == 3 and set(OFFLINE) <= set(serial[0]["estimators"])
    assert_same_scores(serial[0], parallel[0])
    for name in serial[1]:
        for key, value in serial[1][name].items():
            if isinstance(value, np.ndarray):
                np.testing.assert_allclose(parallel[1][name][key], value, rtol=1e-12, atol=0, equal_nan=True)
    assert not any((b / offline_cache.DIRECTORY).exists() for b in bags)  # cache=False writes nothing


def test_a_second_scoring_reads_the_offline_results_back(bags, calls):
    first = score_bags(bags, jobs=1)
    assert sorted(calls) == sorted(["ss", "cw", "cwb", "pcrb"] * 3)
    for b in bags:
        kept = sorted(p.name.rsplit("-", 1)[0] for p in (b / offline_cache.DIRECTORY).glob("*.npz"))
        assert kept == sorted([*(f"offline-{n}" for n in OFFLINE), "bounds-pcrb"])
    calls.clear()
    again = score_bags(bags, jobs=1)
    assert calls == []
    assert again == first  # read back exactly


def test_pool_workers_hand_cached_results_over_by_file(bags, tmp_path):
    """Workers of a process pool leave out the arrays a cache file holds; the scorer maps them from the file: the
    same scores as in one process, exactly (the same files), filling the cache and reading it back."""
    serial = score_bags(bags, jobs=1)
    assert score_bags(bags, jobs=2) == serial
    data = scoring.prepared(bags[0])
    assert sorted(data.kept) == sorted([*(("offline", n) for n in OFFLINE), ("bounds", "pcrb")])
    hand_over = tmp_path / "hand_over"
    hand_over.mkdir()
    handed = scoring._handed_over(data, hand_over)
    assert list(hand_over.iterdir()) == []  # every result is in the cache already
    assert [handed.estimates[n] for n in OFFLINE] == [None] * 3 and handed.bounds["pcrb"] is None
    assert handed.estimates[data.run["estimators"][0]] is data.estimates[data.run["estimators"][0]]
    back = scoring._taken_back(handed, cache=True)
    for name in OFFLINE:
        assert mapped(back.estimates[name].P)
        np.testing.assert_array_equal(back.estimates[name].P, data.estimates[name].P)
    assert list(back.estimates) == list(data.estimates)


def test_without_the_cache_workers_hand_results_over_by_file_too(bags, tmp_path):
    """With the cache off, a worker writes its results to the hand-over directory and the scorer maps them from
    there: the same arrays, the same scores as in one process."""
    assert score_bags(bags, jobs=2, cache=False) == score_bags(bags, jobs=1, cache=False)
    data = scoring.prepared(bags[0], cache=False)
    assert data.kept == {}
    hand_over = tmp_path / "hand_over"
    hand_over.mkdir()
    handed = scoring._handed_over(data, hand_over)
    assert len(list(hand_over.glob("*.npz"))) == len(OFFLINE) + 1
    assert [handed.estimates[n] for n in OFFLINE] == [None] * 3 and handed.bounds["pcrb"] is None
    back = scoring._taken_back(handed, cache=False)
    for name in OFFLINE:
        assert mapped(back.estimates[name].P)
        np.testing.assert_array_equal(back.estimates[name].x, data.estimates[name].x)
    np.testing.assert_array_equal(back.bounds["pcrb"].P, data.bounds["pcrb"].P)


def test_a_cache_file_gone_before_it_is_taken_back_is_computed_again(bags, calls, tmp_path):
    data = scoring.prepared(bags[0])
    handed = scoring._handed_over(data, tmp_path)
    data.kept["offline", "ss_rts"].unlink()
    calls.clear()
    back = scoring._taken_back(handed, cache=True)
    assert calls == ["ss"]
    np.testing.assert_array_equal(back.estimates["ss_rts"].x, data.estimates["ss_rts"].x)


def test_changed_parameters_or_code_miss_the_cache(bags, calls, monkeypatch):
    data = load_bag(bags[0])
    opts = scoring_options(data.scenario)
    run_offline(data, opts)
    kept = data.estimates["ss_rts"]
    assert sorted(calls) == ["cw", "cwb", "ss"]
    calls.clear()
    run_offline(load_bag(bags[0]), opts)
    assert calls == []
    other = replaced(opts, offline={"ss_rts": OfflineRun(estimator="rts", source="ss", params={"changed": 1})})
    again = load_bag(bags[0])
    run_offline(again, other)
    assert calls == ["ss"]
    np.testing.assert_array_equal(again.estimates["ss_rts"].x, kept.x)  # (rts ignores its params)
    calls.clear()
    monkeypatch.setattr(offline_cache, "code_version", lambda module: "another version of the code")
    run_offline(load_bag(bags[0]), opts)
    assert sorted(calls) == ["cw", "cwb", "ss"]


def test_the_code_version_follows_every_module_the_estimator_imports(tmp_path, monkeypatch):
    """Imports inside functions count (the bench imports lazily); a module nothing imports does not."""
    pkg = tmp_path / "cache_probe"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "estimator.py").write_text("def run(data):\n    from cache_probe import fit\n    return fit.go(data)\n")
    (pkg / "fit.py").write_text("from .maths import twice\n\ndef go(x):\n    return twice(x)\n")
    (pkg / "maths.py").write_text("def twice(x):\n    return 2 * x\n")
    (pkg / "unrelated.py").write_text("X = 1\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(offline_cache, "_own_packages", lambda: {"cache_probe"})

    def version() -> str:
        offline_cache.code_version.cache_clear()
        return offline_cache.code_version("cache_probe.estimator")

    before = version()
    (pkg / "unrelated.py").write_text("X = 2\n")
    assert version() == before
    (pkg / "maths.py").write_text("def twice(x):\n    return x + x\n")
    assert version() != before
    offline_cache.code_version.cache_clear()
    sys.modules.pop("cache_probe", None)


def _hostile_npz(path: Path, member: str, payload: bytes) -> None:
    """A cache file with every expected member, one of them replaced by ``payload``."""
    with zipfile.ZipFile(path, "w") as z:
        for m in offline_cache.MEMBERS["offline"]:
            if m == member:
                z.writestr(f"{m}.npy", payload)
            else:
                with z.open(f"{m}.npy", "w") as f:
                    np.lib.format.write_array(f, np.zeros(1))


def _pickled_array() -> bytes:
    buf = io.BytesIO()
    np.save(buf, np.array([{"a": 1}], dtype=object), allow_pickle=True)
    return buf.getvalue()


def _huge_header() -> bytes:
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": "<f8", "fortran_order": False, "shape": (10**12,)})
    return buf.getvalue() + bytes(64)


@pytest.mark.parametrize(
    "damage", ["garbage", "truncated", "empty", "pickle", "huge shape", "extra member", "compressed", "moved header"]
)
def test_a_damaged_or_hostile_cache_file_is_ignored_with_a_warning(bags, calls, damage):
    data = load_bag(bags[0])
    opts = scoring_options(data.scenario)
    only = replaced(opts, offline={"ss_rts": opts.offline["ss_rts"]})
    run_offline(data, only)
    expected = data.estimates["ss_rts"]
    (file,) = (bags[0] / offline_cache.DIRECTORY).glob("offline-ss_rts-*.npz")
    good = file.read_bytes()
    if damage == "garbage":
        file.write_bytes(b"PK\x03\x04 this is not a cache file" * 10)
    elif damage == "truncated":
        file.write_bytes(good[: len(good) // 2])
    elif damage == "empty":
        file.write_bytes(b"")
    elif damage == "pickle":
        _hostile_npz(file, "x", _pickled_array())
    elif damage == "huge shape":
        _hostile_npz(file, "P", _huge_header())
    elif damage == "extra member":
        with zipfile.ZipFile(file, "a") as z:
            z.writestr("payload.npy", b"x")
    elif damage == "compressed":  # its arrays cannot be mapped from the file
        with zipfile.ZipFile(io.BytesIO(good)) as z, zipfile.ZipFile(file, "w", zipfile.ZIP_DEFLATED) as out:
            for info in z.infolist():
                out.writestr(info.filename, z.read(info))
    else:  # the central directory points the first member at bytes that are not its local header
        end = good.rindex(b"PK\x05\x06")
        directory = int.from_bytes(good[end + 16 : end + 20], "little")
        file.write_bytes(good[: directory + 42] + (7).to_bytes(4, "little") + good[directory + 46 :])
    calls.clear()
    again = load_bag(bags[0])
    with pytest.warns(CacheWarning, match=file.name):
        run_offline(again, only)
    assert calls == ["ss"]
    np.testing.assert_array_equal(again.estimates["ss_rts"].x, expected.x)
    np.testing.assert_array_equal(again.estimates["ss_rts"].P, expected.P)
    assert offline_cache.load(file, "offline") is not None  # replaced by a good one


def test_a_run_made_in_process_has_no_cache(bags):
    data = load_bag(bags[0])
    data.path = None
    scoring.run_offline(data, scoring_options(data.scenario))
    assert not (bags[0] / offline_cache.DIRECTORY).exists()
