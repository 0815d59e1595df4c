"""The same seed gives the same bag contents, across refactorings: the messages of a short run of each study
hash to the digests recorded before the package reshape (tests/data/bag_digests.json: per topic, the SHA-256
of every message's CDR bytes in the order the recorder wrote them, and the message count); star_tracker's since
the nodes zero the CDR padding (bench_engine.cdr), which rclpy left as its reused buffer's bytes. Log times are
not hashed: they became sim time (bench_engine.sim_clock) with the bytes and their order unchanged.

A deliberate change of a model, a noise draw or a message changes these digests; regenerate the file then,
and say why in the commit.
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pytest
from mcap.reader import make_reader

from graph_helpers import script

RECORDED = json.loads((Path(__file__).parent / "data" / "bag_digests.json").read_text())


def digests(bag: Path) -> dict[str, list]:
    found: dict[str, list] = {}
    with open(next(bag.glob("*.mcap")), "rb") as f:
        for _schema, channel, message in make_reader(f).iter_messages(log_time_order=False):
            entry = found.setdefault(channel.topic, [hashlib.sha256(), 0])
            entry[0].update(message.data)
            entry[1] += 1
    return {topic: [h.hexdigest()[:16], n] for topic, (h, n) in sorted(found.items())}


@pytest.mark.parametrize("scenario", sorted(RECORDED["digests"]))
def test_a_seeded_run_records_the_same_messages_as_before(tmp_path: Path, scenario: str) -> None:
    res = script("launch.py", scenario, "--seed", "3", "--set", "time.duration=30", "--out", str(tmp_path),
                 "--no-score", "--single-process")
    assert res.returncode == 0, res.stderr[-2000:]
    assert digests(tmp_path / "bag") == RECORDED["digests"][scenario]
