"""CCSDS in, through the graph: a simulated run's TDM exported, imported and replayed into the same estimators
gives the original run's estimates; without a reference the run is scored by what needs no truth, with the
truth's OEM as the reference it scores as the original did.

Precision: the TDM holds 17 significant digits in km and degrees, so each imported measurement equals the bag's
to one unit in the last place (the degree conversion; ranges exactly). The estimators amplify those last-place
differences (the batch re-solves are ill-conditioned where the range is 1000 times finer than the cross-range),
so the test allows 1e-5 of each estimate's own standard deviation in the state and 1e-7 of sigma_i sigma_j in
its covariance: far below any difference of substance, far above the noise of the last place.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from graph_helpers import read_bag, script, stamp

from bench_ccsds.export import export_bag

DURATION = ["--set", "time.duration=20"]  # 201 steps: the first scan, the first re-solve (100 scans) and after


@pytest.fixture(scope="module")
def original(tmp_path_factory):
    run = tmp_path_factory.mktemp("ccsds-original")
    result = script("launch.py", "leo_radar", "--variant", "iss", *DURATION, "--out", str(run), timeout=240)
    assert result.returncode == 0, result.stderr[-2000:]
    export_bag(run / "bag", run / "ccsds")
    return run


def _import(original, tmp_path, *extra: str, as_json: bool = True):
    """Import the original run's TDM; the score as JSON, or (``as_json`` off) as the summary a user reads, with
    the score taken from the run directory's score.json."""
    out = tmp_path / "import"
    result = script(
        "import_tdm.py",
        str(original / "ccsds" / "radar.tdm"),
        "--scenario",
        "leo_radar",
        "--variant",
        "iss",
        *DURATION,
        "--out",
        str(out),
        *(["--json"] if as_json else []),
        *extra,
        timeout=240,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    if as_json:
        return out, json.loads(result.stdout)
    assert all(f"  {name}: NIS " in result.stdout for name in ("ekf", "ukf")), result.stdout
    return out, json.loads((out / "score.json").read_text())


def _estimates(bag, name):
    return sorted((m for _t, m in read_bag(bag)[f"/{name}/estimate"]), key=stamp)


def test_an_imported_tdm_gives_the_original_runs_estimates(original, tmp_path):
    out, score = _import(original, tmp_path, as_json=False)
    topics = read_bag(out / "bag")
    assert "/truth/state" not in topics and topics["/clock"], "no truth: the clock follows the measurements"
    for name in ("ekf", "ukf"):
        before, after = _estimates(original / "bag", name), _estimates(out / "bag", name)
        assert [m.step for m in before] == [m.step for m in after] and len(before) > 150
        assert [stamp(m) for m in before] == [stamp(m) for m in after]
        for a, b in zip(before, after):
            P = np.reshape(a.covariance, (6, 6))
            sd = np.sqrt(np.diag(P))
            assert np.all(np.abs(np.asarray(a.state) - b.state) <= 1e-5 * sd)
            assert np.all(np.abs(P - np.reshape(b.covariance, (6, 6))) <= 1e-7 * np.outer(sd, sd))
    scans = {m.step: m for _t, m in read_bag(original / "bag")["/radar/measurement"]}
    for _t, m in topics["/radar/measurement"]:
        ref = scans[m.step]
        assert m.range == ref.range and stamp(m) == stamp(ref)
        assert m.azimuth == pytest.approx(ref.azimuth, rel=2.3e-16, abs=0)
        assert m.elevation == pytest.approx(ref.elevation, rel=2.3e-16, abs=0)
        np.testing.assert_array_equal(m.covariance, ref.covariance)
    for name in ("ekf", "ukf"):  # scored by what needs no truth
        block = score["estimators"][name]["innovations"]
        assert score["metric"] == "innovations (no truth)" and block["updates"] == len(scans) - 1
        assert block["nis_dof"] == 3 and block["nis_band"][0] < 3.0 < block["nis_band"][1]
        assert 0.5 * block["nis_band"][0] < block["nis_mean"] < 2 * block["nis_band"][1]
        residuals = block["residuals"]["radar"]["rms_normalised"]
        # The 1 deg angles are noise-bound (a post-fit residual near the noise). The range's post-fit residuals
        # exceed its noise in these first 20 s: the pass's start is where no Gaussian filter is consistent
        # (README, leo_radar), which needs no truth to see.
        assert 0.8 < residuals["azimuth"] < 1.2 and 0.8 < residuals["elevation"] < 1.2
        assert 1.0 < residuals["range"] < 5.0
        assert block["sigma_position"]["peak_m"] > 5 * block["sigma_position"]["converged_m"] > 0


def test_with_the_truths_oem_as_reference_it_scores_as_the_original(original, tmp_path):
    out, score = _import(original, tmp_path, "--reference", str(original / "ccsds" / "truth.oem"))
    first = json.loads((original / "score.json").read_text())
    for name in ("ekf", "ukf"):
        for key in ("rmse_converged_m", "rmse_peak_m", "nees_mean"):
            assert score["estimators"][name][key] == pytest.approx(first["estimators"][name][key], rel=1e-6)
        assert "innovations" in score["estimators"][name]
    truth = sorted((m for _t, m in read_bag(out / "bag")["/truth/state"]), key=stamp)
    reference = {m.step: m for _t, m in read_bag(original / "bag")["/truth/state"]}
    assert len(truth) == len(read_bag(original / "bag")["/radar/measurement"])
    for m in truth:  # the OEM's lines at the measurement epochs: the truth itself, to its written digits
        np.testing.assert_allclose(m.state, reference[m.step].state, rtol=3e-16, atol=0)
