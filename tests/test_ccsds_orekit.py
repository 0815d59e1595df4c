"""Orekit, a real CCSDS client, reads every message the bench exports, and what it reads is the bag's.

Two bags recorded through the graph: leo_radar's ``iss`` variant (a real element set on its UTC epoch) and the
paper's leo_radar (no calendar epoch: placed at the nominal epoch, bench_ccsds.epochs), each exported by
``bench_ccsds.export.export_bag``. Orekit 13 (orekit-jpype, Apache-2.0, on the system's Java) parses every OEM
and TDM; every epoch, state, covariance entry and observation it reads equals the bag's as read by rosbags (an
independent reader): epochs to the nanosecond, values to 1e-15 relative (17 significant digits written, then
one unit conversion on each side: km -> m, deg -> rad). Orekit's TEME -> GTOD rotation (IERS 1996 conventions,
no EOP data) is also the external check of the bench's GMST (orbit_sim.frames).

Orekit's data: the leap-second table ``tests/data/orekit/tai-utc.dat`` in the USNO ``tai-utc.dat`` format (public
data: TAI - UTC from 1972 on, the values of IERS Bulletin C as tzdata's leap-seconds.list carries them; the
pre-1972 rate lines are left out, no bench date is before 1972). Orekit needs it even to read a message's UTC
dates ("no IERS UTC-TAI history data loaded" otherwise). CENTER_NAME EARTH makes the parser build the Earth as a
celestial body, which Orekit loads from JPL ephemerides the bench does not ship; the parser only stores it, so
the test registers a stand-in Earth (name and GM) in place of the ephemerides. One JVM for the module (about 4 s
to start; a JVM cannot be restarted in a process). The JVM starts on pytest's main thread, which it then treats
as a Java thread of ``-Xss`` stack: :func:`vm_args` gives it the stack the process's limit grants (see there).
"""

from __future__ import annotations

import datetime as dt_
import os
import resource
import subprocess
import sys
from pathlib import Path

import jpype
import numpy as np
import orekit_jpype
import pytest
from graph_helpers import read_bag, script, stamp
from jpype import JImplements, JOverride

from bench_ccsds.epochs import run_time
from bench_ccsds.export import export_bag
from bench_ccsds.kvn import epoch_text
from bench_eval.cli.replay import recorded_run
from orbit_sim.frames import gmst82, julian_date

DATA = Path(__file__).parent / "data" / "orekit"
RTOL = 1e-15
JVM_MAX_XSS = 1 << 30
"""The largest -Xss HotSpot accepts (1 GiB)."""


def stack_limit() -> int:
    """The stack the process's limit (RLIMIT_STACK) grants its main thread, in bytes, at most JVM_MAX_XSS."""
    soft, _hard = resource.getrlimit(resource.RLIMIT_STACK)
    return JVM_MAX_XSS if soft == resource.RLIM_INFINITY else min(soft, JVM_MAX_XSS)


def vm_args() -> str:
    """The JVM's options. -Xrs: the JVM leaves SIGINT, SIGTERM and SIGHUP to Python (pytest's Ctrl-C, the graph's
    signals). TieredStopAtLevel=1 (the quick C1 compiler only): less CPU than the optimising compiler for parsing
    a few thousand lines once (``/usr/bin/time -f '%U' .venv/bin/python -m pytest tests/test_ccsds_orekit.py``).
    -Xss: the stack limit of the process (:func:`stack_limit`). Started on the process's main thread, HotSpot
    caps that thread's stack at -Xss with guard pages (1 MiB by default) for the life of the process: any later
    test of the same pytest process, e.g. OpenBLAS's multithreaded LU (dgetrf_parallel, half a MiB of stack a
    level) under np.linalg.inv, would overflow into them and die of SIGSEGV."""
    return f"-Xrs,-XX:TieredStopAtLevel=1,-Xss{stack_limit() // 1024}k"


def java(name: str):
    """A Java class by its full name (on the started JVM: JPype's imports of Java packages need it running, so
    the module cannot import them at its top)."""
    return jpype.JClass(name)


@JImplements("org.orekit.bodies.CelestialBody", deferred=True)
class StandInEarth:
    """The Earth as the CCSDS parsers store it for CENTER_NAME EARTH: a name and GM, no ephemeris."""

    @JOverride
    def getName(self):
        return "Earth"

    @JOverride
    def getGM(self):
        return 3.986004418e14

    @JOverride
    def getInertiallyOrientedFrame(self):
        return java("org.orekit.frames.FramesFactory").getGCRF()

    @JOverride
    def getBodyOrientedFrame(self):
        return java("org.orekit.frames.FramesFactory").getGCRF()

    @JOverride
    def getPVCoordinates(self, date, frame):
        pv = java("org.orekit.utils.PVCoordinates")
        return java("org.orekit.utils.TimeStampedPVCoordinates")(date, pv.ZERO)

    @JOverride
    def getPosition(self, date, frame):
        return java("org.orekit.utils.PVCoordinates").ZERO.getPosition()


@JImplements("org.orekit.bodies.CelestialBodyLoader", deferred=True)
class StandInLoader:
    @JOverride
    def loadCelestialBody(self, name):
        return StandInEarth()


@pytest.fixture(scope="module")
def orekit():
    """The Orekit classes the tests use, on a JVM started once, with the leap seconds and a stand-in Earth."""
    if not jpype.isJVMStarted():
        orekit_jpype.initVM(vmargs=vm_args())
    file, frames = java("java.io.File"), java("org.orekit.frames.FramesFactory")
    context = java("org.orekit.data.DataContext").getDefault()
    context.getDataProvidersManager().addProvider(java("org.orekit.data.DirectoryCrawler")(file(str(DATA))))
    context.getCelestialBodies().addCelestialBodyLoader(
        java("org.orekit.bodies.CelestialBodyFactory").EARTH, StandInLoader()
    )
    utc = java("org.orekit.time.TimeScalesFactory").getUTC()
    parsers, source = java("org.orekit.files.ccsds.ndm.ParserBuilder"), java("org.orekit.data.DataSource")

    class Orekit:
        @staticmethod
        def oem(path: Path):
            return parsers().buildOemParser().parseMessage(source(file(str(path))))

        @staticmethod
        def tdm(path: Path):
            return parsers().buildTdmParser().parseMessage(source(file(str(path))))

        @staticmethod
        def date(utc_ns: int):
            return java("org.orekit.time.AbsoluteDate")(epoch_text(utc_ns), utc)

        teme = frames.getTEME()
        gtod = frames.getGTOD(java("org.orekit.utils.IERSConventions").IERS_1996, True)
        x_axis = java("org.hipparchus.geometry.euclidean.threed.Vector3D").PLUS_I
        z_axis = java("org.hipparchus.geometry.euclidean.threed.Vector3D").PLUS_K

    return Orekit


STACK_PROBE = """
import numpy as np, orekit_jpype
from test_ccsds_orekit import vm_args
orekit_jpype.initVM(vmargs=vm_args())
maps = [line.split() for line in open("/proc/self/maps")]
spans = [[int(a, 16) for a in m[0].split("-")] for m in maps]
top = next(k for k, m in enumerate(maps) if m[-1] == "[stack]")
room = spans[top][1] - max(hi for lo, hi in spans if hi <= spans[top][0])
a = np.random.default_rng(0).normal(size=(200, 200)) + 200 * np.eye(200)
print(room, np.abs(np.linalg.inv(a) @ a - np.eye(200)).max())
"""
"""Starts the JVM as the fixture does, then prints the room the main thread's stack has below its top (to the next
mapping: the JVM's guard pages if it put any) and the error of an inverse by OpenBLAS's threaded LU (a deep stack)."""


def test_the_jvm_leaves_the_main_thread_the_stack_of_the_process_limit():
    """In a child process (a JVM and a crash are the process's): after the JVM starts on the main thread, that
    thread can still grow its stack to the limit (within 64 KiB: the pages HotSpot keeps), and a 200 x 200 inverse
    by two OpenBLAS threads (dgetrf_parallel: half a MiB of stack a level) runs instead of dying of SIGSEGV."""
    env = dict(os.environ, OPENBLAS_NUM_THREADS="2")
    cwd = Path(__file__).parent
    res = subprocess.run(
        [sys.executable, "-c", STACK_PROBE], capture_output=True, text=True, timeout=120, env=env, cwd=cwd
    )
    assert res.returncode == 0, (res.returncode, res.stdout, res.stderr[-2000:])
    room, residual = (float(x) for x in res.stdout.split()[-2:])
    assert stack_limit() - 64 * 1024 <= room and residual < 1e-12


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """(bag, ccsds directory, run time) of a short run of each scenario, recorded through the graph."""
    out = {}
    for name, args in (
        ("iss", ["--variant", "iss", "--set", "time.duration=8"]),
        ("nominal", ["--set", "time.duration=4"]),
    ):
        run = tmp_path_factory.mktemp(f"ccsds-{name}")
        result = script("launch.py", "leo_radar", *args, "--out", str(run), "--no-score", timeout=240)
        assert result.returncode == 0, result.stderr[-2000:]
        export = export_bag(run / "bag", run / "ccsds")
        assert sorted(p.name for p in export.written) == ["ekf.oem", "radar.tdm", "truth.oem", "ukf.oem"]
        out[name] = (run / "bag", run / "ccsds", run_time(recorded_run(run / "bag")["scenario"]))
    return out


def _seconds_from(orekit, date, epoch_ns: int) -> float:
    return float(date.durationFrom(orekit.date(epoch_ns)))


@pytest.mark.parametrize("bag_name", ["iss", "nominal"])
def test_orekit_reads_every_oem_value_as_the_bag_has_it(orekit, exported, bag_name):
    bag, ccsds, clock = exported[bag_name]
    topics = read_bag(bag)
    for source in ("truth", "ekf", "ukf"):
        messages = [m for _t, m in topics["/truth/state" if source == "truth" else f"/{source}/estimate"]]
        messages.sort(key=stamp)
        segments = orekit.oem(ccsds / f"{source}.oem").getSegments()
        assert segments.size() == 1
        seg = segments.get(0)
        meta = seg.getMetadata()
        assert str(meta.getReferenceFrame().getName()) == "TEME" and str(meta.getTimeSystem()) == "UTC"
        assert str(meta.getCenter().getName()) == "EARTH"
        if bag_name == "iss":
            assert str(meta.getObjectName()).upper() == "ISS (ZARYA)" and str(meta.getObjectID()) == "1998-067A"
        lines = list(seg.getData().getEphemeridesDataLines())
        assert len(lines) == len(messages)
        for line, msg in zip(lines, messages):
            t_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
            assert _seconds_from(orekit, line.getDate(), clock.epoch_ns) == pytest.approx(t_ns * 1e-9, abs=1e-9)
            got = [
                line.getPosition().getX(),
                line.getPosition().getY(),
                line.getPosition().getZ(),
                line.getVelocity().getX(),
                line.getVelocity().getY(),
                line.getVelocity().getZ(),
            ]
            np.testing.assert_allclose(got, msg.state[:6], rtol=RTOL, atol=0)
        covariances = list(seg.getData().getCovarianceMatrices())
        if source == "truth":
            assert not covariances
            continue
        assert len(covariances) == len(messages)
        for cov, msg in zip(covariances, messages):
            matrix = cov.getCovarianceMatrix()
            got = np.array([[matrix.getEntry(i, j) for j in range(6)] for i in range(6)])
            lower = np.tril(np.reshape(msg.covariance, (6, 6)))  # an OEM holds the lower triangle (a filter's P
            np.testing.assert_allclose(got, lower + np.tril(lower, -1).T, rtol=RTOL, atol=0)  # is symmetric to ~1e-14)
            assert str(cov.getReferenceFrame().getName()) == "TEME"


@pytest.mark.parametrize("bag_name", ["iss", "nominal"])
def test_orekit_reads_every_tdm_observation_as_the_bag_has_it(orekit, exported, bag_name):
    bag, ccsds, clock = exported[bag_name]
    scans = sorted((m for _t, m in read_bag(bag)["/radar/measurement"]), key=stamp)
    seg = orekit.tdm(ccsds / "radar.tdm").getSegments().get(0)
    meta = seg.getMetadata()
    assert str(meta.getAngleType()) == "AZEL" and str(meta.getTimeSystem()) == "UTC"
    assert str(meta.getParticipants().get(jpype.JInt(1))) == "radar"
    observations = list(seg.getData().getObservations())
    assert len(observations) == 3 * len(scans)
    for k, scan in enumerate(scans):
        t_ns = scan.header.stamp.sec * 1_000_000_000 + scan.header.stamp.nanosec
        for obs, (kind, value) in zip(
            observations[3 * k : 3 * k + 3],
            (("RANGE", scan.range), ("ANGLE_1", scan.azimuth), ("ANGLE_2", scan.elevation)),
        ):
            assert str(obs.getType()) == kind
            assert _seconds_from(orekit, obs.getEpoch(), clock.epoch_ns) == pytest.approx(t_ns * 1e-9, abs=1e-9)
            assert obs.getMeasurement() == pytest.approx(value, rel=RTOL, abs=0)


def test_orekit_teme_to_gtod_is_the_bench_gmst_rotation(orekit):
    """Orekit's TEME -> GTOD (IERS 1996 conventions, no EOP data: UT1 = UTC) against R3(GMST82) of the bench
    from 1992 to 2031: the angle about z and the pole within 1e-7 rad each (Orekit's frames differ by a small
    offset that does not change over the years, under a metre at 7000 km; a GMST error of 1 ms of UT1 is
    7e-8 rad, a wrong formula far more)."""
    for epoch in (
        dt_.datetime(1992, 8, 20, 12, 14),
        dt_.datetime(2000, 6, 28, 0, 50, 19, 733568),
        dt_.datetime(2019, 12, 9, 16, 38, 29, 363424),
        dt_.datetime(2031, 3, 1, 5),
    ):
        epoch = epoch.replace(tzinfo=dt_.UTC)
        jd, fraction = julian_date(epoch)
        ns = round((jd - 2440587.5) * 86400e9) + round(fraction * 86400e9)
        transform = orekit.teme.getTransformTo(orekit.gtod, orekit.date(ns))
        x, z = transform.transformVector(orekit.x_axis), transform.transformVector(orekit.z_axis)
        angle = -np.arctan2(x.getY(), x.getX())
        assert abs(np.angle(np.exp(1j * (angle - gmst82(jd, fraction))))) < 1e-7
        assert np.hypot(z.getX(), z.getY()) < 1e-7


def test_the_nominal_epoch_puts_theta0_at_greenwich(orekit, exported):
    """A run without a calendar epoch is exported at the first instant from 2000-01-01T12:00 UTC whose GMST is
    its theta0 (leo_radar: 40 deg), so its TEME and Orekit's agree with the bench's ECEF at t = 0."""
    _bag, _ccsds, clock = exported["nominal"]
    assert clock.nominal and epoch_text(clock.epoch_ns).startswith("2000-01-0")
    x = orekit.teme.getTransformTo(orekit.gtod, orekit.date(clock.epoch_ns)).transformVector(orekit.x_axis)
    assert abs(np.degrees(-np.arctan2(x.getY(), x.getX())) - 40.0) < 1e-5
