"""The Fast DDS profile of the bench's own processes: a reliable writer announces its history every 100 ms.

Fast DDS (rmw_fastrtps, ROS 2 Jazzy's default middleware) may drop a message on its way between processes (its
shared-memory transport under load); the reliable protocol then resends it, but only once the reader learns it
is missing: from the writer's next message, or from its next heartbeat, every 3 s by default. Under lock-step
pacing the writer sends nothing more until its readers acknowledge, so a dropped message stalled the whole run
until that heartbeat: leo_radar's stepping took 5–6 s instead of 3.5 s in about half the runs, each stall
about 2 s long with nothing received (measured by timing the truth's waits and the recorder's silences). With
a heartbeat every :data:`HEARTBEAT_PERIOD_S` a dropped message costs at most that.

ROS QoS still sets every policy it names (reliability, history, durability, depth); the heartbeat is one that ROS
leaves to the vendor. The profile applies to the processes the bench starts (:func:`use_bench_profile`, called
before rclpy is initialised); a user's own ``FASTRTPS_DEFAULT_PROFILES_FILE`` wins, and a bench node started
standalone in a user's system uses whatever that system sets.
"""

from __future__ import annotations

import os
from pathlib import Path

PROFILE_ENV = "FASTRTPS_DEFAULT_PROFILES_FILE"
"""The variable Fast DDS 2.x reads its XML profiles from when it creates the process's first participant."""
PROFILE = Path(__file__).with_name("dds") / "fastdds_profile.xml"
HEARTBEAT_PERIOD_S = 0.1
"""The writers' heartbeat period the profile sets (``heartbeatPeriod``)."""


def use_bench_profile() -> None:
    """Let this process's DDS participants use the bench's profile, unless the environment names another;
    call it before ``rclpy.init``."""
    os.environ.setdefault(PROFILE_ENV, str(PROFILE))
