"""grace_velocity's truth models ``pair_j2`` and ``pair_hifi`` as the graph and the settings reference see them:
their keys of the ``truth`` section and the state they publish, registered in tracking_bench.truth_models. Cheap
to import (every node reads the truth's labels to build the graph); the integration is in pair_truth.py.

    truth:
      model: pair_hifi
      leader: {a: 6858137.0, e: 0.001, i_deg: 89.0, raan_deg: 0.0, argp_deg: 0.0, M_deg: 0.0}
      separation_m: 220000.0      # the follower trails on the same orbit, M lower by separation / a
      ballistic: [0.0045, 0.0047] # C_d A / m of leader and follower [m^2/kg] (pair_hifi)
      zonal_degree: 6             # J2 .. J6 (pair_hifi)
"""

from __future__ import annotations

from dataclasses import dataclass

from bench_engine.config import ScenarioError
from bench_engine.labels import ORBIT
from bench_engine.settings import POSITIVE, Settings, between, setting
from orbit_sim.geopotential import ZONALS
from orbit_sim.truth import OrbitElements, TruthModel

LABELS = tuple(f"{c}{s}" for s in ("1", "2") for c in ORBIT) + ("bx", "by", "bz", "bvx", "bvy", "bvz")
"""The published state (frame "eci"): leader ``x1 .. vz1``, follower ``x2 .. vz2`` and their baseline
``bx .. bvz`` = follower - leader, so sensors of either satellite and of the baseline read the components they
need (bench_models.labelled)."""


@dataclass(frozen=True, kw_only=True)
class Pair(Settings):
    """``pair_j2`` / ``pair_hifi``: a leader and a follower on the same orbit, in ECI."""

    leader: OrbitElements = setting(doc="the leader's orbit")
    separation_m: float = setting(
        unit="m", doc="the follower trails on the same orbit, its mean anomaly lower by separation / a", check=POSITIVE
    )
    ballistic: list[float] = setting(
        [0.0, 0.0], unit="m^2/kg", doc="C_d A / m of leader and follower (pair_hifi; 0: no drag)"
    )
    zonal_degree: int = setting(
        6, doc="zonal harmonics J2 .. Jn of the gravity field (pair_hifi)", check=between(2, max(ZONALS), what="in")
    )

    def validate(self, path: str) -> None:
        if len(self.ballistic) != 2 or any(b < 0 for b in self.ballistic):
            raise ScenarioError(
                f"'{path}.ballistic' must be two values >= 0 (C_d A / m of leader and follower, "
                f"m^2/kg), got {self.ballistic!r}"
            )


PAIR = TruthModel(Pair, "bench_studies.grace_velocity.pair_truth:pair_truth", LABELS, "eci")
