"""The scores as a user reads them: one line per estimator with its main numbers (``score.py``, ``launch.py``,
``montecarlo.py``, ``demo.py`` print it; ``--json`` gives the whole record instead)."""

from __future__ import annotations

import json
from pathlib import Path

from bench_engine import plugins
from bench_eval.claims import diverged
from bench_eval.consistency import TRUTHLESS
from bench_eval.scoring import score_bags


def print_summary(scored: dict) -> str:
    """A short human-readable table of the main numbers (the metric family's own parts: ``Metric.summary``)."""
    family = scored.get("metric")
    family_summary = plugins.load("metrics", family).summary if family not in (None, TRUTHLESS) else None
    lines = [f"{scored['scenario']} — {scored['runs']} run(s)"]
    for name, block in scored["estimators"].items():
        if diverged(block):
            lines.append(f"  {name}: diverged (the filter lost the target: NEES beyond any chi-square band)")
            continue
        parts = []
        for key, unit in (
            ("rmse_converged_m", "m"),
            ("rmse_peak_m", "m"),
            ("convergence_time_s", "s"),
            ("nees_mean", ""),
        ):
            if key in block:
                v = block[key]
                parts.append(f"{key}={'n/a' if v is None else f'{v:.4g}'}{unit}")
        if "band_m" in block and block["band_m"]:
            lo, hi = block["band_m"]
            parts.append(f"band=[{lo:.4g}, {hi:.4g}] m" if lo is not None else "band=n/a")
        if family_summary is not None:
            parts += family_summary(block)
        if "mae" in block:
            settle = block.get("settling_time_s")
            parts.append(f"settled after {'never' if settle is None else f'{settle:.0f} s'}")
            parts.append("MAE " + ", ".join(f"{k} {v:.3g}" for k, v in block["mae"].items()))
            inside = block.get("within_3sigma") or {}
            if inside:
                parts.append(f"within 3 sigma {min(inside.values()):.0%}..{max(inside.values()):.0%}")
        if "innovations" in block:
            parts.append(_innovations_line(block["innovations"]))
        if not parts:  # a family without the keys above: its first scalar scores
            parts = [f"{k}={v:.4g}" for k, v in _scalars(block)[:6]]
        lines.append(f"  {name}: " + "; ".join(parts))
    return "\n".join(lines)


def _innovations_line(block: dict) -> str:
    """The truthless scores (bench_eval.consistency) in one line."""
    parts = []
    if block.get("nis_mean") is not None:
        lo, hi = block["nis_band"]
        parts.append(
            f"NIS {block['nis_mean']:.3g} ({block['nis_dof']:g} dof, 95 % band [{lo:.3g}, {hi:.3g}], "
            f"{block['updates']} updates)"
        )
    for sensor, res in block.get("residuals", {}).items():
        parts.append(
            f"post-fit residual RMS/sigma {sensor}: "
            + ", ".join(f"{k} {v:.3g}" for k, v in res["rms_normalised"].items() if v is not None)
        )
    sigma = block.get("sigma_position")
    if sigma:
        when = sigma["convergence_time_s"]
        parts.append(
            f"position sigma {sigma['converged_m']:.4g} m after {when:.0f} s"
            if when is not None
            else "position sigma never settled"
        )
    return "; ".join(parts)


def _scalars(block: dict, prefix: str = "") -> list[tuple[str, float]]:
    """The numeric leaves of a score block, depth first, as (dotted key, value)."""
    out = []
    for key, value in block.items():
        if isinstance(value, dict):
            out += _scalars(value, f"{prefix}{key}.")
        elif isinstance(value, (int, float)) and not isinstance(value, bool):
            out.append((f"{prefix}{key}", float(value)))
    return out


def score_run(out_dir: Path, as_json: bool = False) -> str:
    """Score the bag of one run directory (OUT/bag), save OUT/score.json, return the text to print."""
    scored = score_bags([Path(out_dir) / "bag"])
    (Path(out_dir) / "score.json").write_text(json.dumps(scored, indent=1))
    return json.dumps(scored, indent=1) if as_json else print_summary(scored)
