"""Every command's expected failures are one line on stderr with a documented exit code, never a traceback
(issue 18, item 1; the commands' one way out: bench_engine.cli.guard).

The table runs each command (launch, score, montecarlo, sweep, replay, recover_bag, demo) as a user would,
through scripts/, against bad inputs: a scenario YAML with a syntax error, bags of two scenarios, a corrupt
metadata.yaml, a bag directory without its .mcap file, bags of a scenario the bench cannot score (recorded by
another tool, or needing a metric not registered here), a --set on a key nothing reads, an output directory
that is a file, one that is read-only and a full disk. Each case stops before any graph starts (only the two
bags the table reads are recorded, by short runs), and the cases run three at a time.

Read-only: the tests run as root here, and root ignores directory permissions, so a root run makes the
directory immutable (``chattr +i``: root cannot write into it either) and removes the flag afterwards; any
other user gets ``chmod 555``. Full disk: RLIMIT_FSIZE (``ulimit -f``) of FULL_DISK_BYTES in the command's
process, which then gets EFBIG on the first file larger than that, as it would get ENOSPC on a full disk; no
mount or privilege is needed. (ENOSPC itself is checked in-process: test_no_space_names_the_path_and_the_way_out.)
"""

from __future__ import annotations

import errno
import importlib
import os
import resource
import shutil
import subprocess
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import pytest
import yaml
from graph_helpers import script

from bench_engine.cli.guard import BAD_INPUT, BUG, os_error_line, run_main, writing
from bench_eval import offline_cache

FULL_DISK_BYTES = 1000
"""Less than any run configuration (launch, montecarlo, replay), a recovered bag, a report's plot, and the
64 KiB that montecarlo, sweep and demo write to check their output directory."""


@dataclass(frozen=True)
class Case:
    id: str
    command: str
    args: Callable[[Inputs], list[str]]
    code: int
    says: str
    """A fragment of the one line on stderr."""
    full_disk: bool = False


@dataclass
class Inputs:
    """The bad (and the good) inputs of the table, in one temporary directory."""

    root: Path
    leo: Path  # a leo_radar bag
    formation: Path  # a formation_pf bag
    corrupt_metadata: Path
    no_mcap: Path
    empty: Path
    foreign: Path  # a rosbag2 bag without the bench's run config: its scenario is unknown
    unregistered_metric: Path
    corrupt_run_config: Path
    bad_yaml: Path  # a scenario file with a syntax error
    grid_yaml: Path  # a valid scenario with a one-cell grid
    a_file: Path
    read_only: Path  # an existing, empty directory nobody may write into
    read_only_bag: Path  # a crashed bag (no metadata.yaml) in a directory nobody may write into, nor into it

    def out(self, name: str) -> str:
        """An output directory that does not exist yet."""
        return str(self.root / "out" / name)

    def existing_out(self, name: str) -> str:
        """An empty output directory that exists (a command checks it before validating anything)."""
        (self.root / "out" / name).mkdir()
        return self.out(name)

    def crashed_copy(self, name: str) -> str:
        """A copy of the leo_radar bag as a killed recorder leaves it (no metadata.yaml)."""
        path = self.root / "crashed" / name
        shutil.copytree(self.leo, path)
        (path / "metadata.yaml").unlink()
        return str(path)


LAUNCH_SET = ["--set", "time.duration=5"]
TABLE = [
    # --- launch
    Case(
        "launch-yaml-syntax-error",
        "launch.py",
        lambda i: [str(i.bad_yaml), "--out", i.out("l1")],
        2,
        "bad_scenario.yaml, line 3, column 11: not valid YAML",
    ),
    Case(
        "launch-unknown-scenario",
        "launch.py",
        lambda i: ["leo_radr", "--out", i.out("l2")],
        2,
        "unknown scenario 'leo_radr'; available: ",
    ),
    Case(
        "launch-set-nonexistent-key",
        "launch.py",
        lambda i: ["leo_radar", "--out", i.out("l3"), *LAUNCH_SET, "--set", "sensors.radar.no_such_key=1"],
        2,
        "unknown key(s) 'sensors.radar.no_such_key'",
    ),
    Case(
        "launch-out-is-a-file",
        "launch.py",
        lambda i: ["leo_radar", "--out", str(i.a_file), *LAUNCH_SET],
        2,
        "a_file is a file, not a directory",
    ),
    Case(
        "launch-out-read-only",
        "launch.py",
        lambda i: ["leo_radar", "--out", str(i.read_only), *LAUNCH_SET],
        2,
        "(read-only or no permission): choose a writable output directory",
    ),
    Case(
        "launch-full-disk",
        "launch.py",
        lambda i: ["leo_radar", "--out", i.out("l4"), *LAUNCH_SET],
        2,
        "(the disk is full or a file size limit is reached)",
        full_disk=True,
    ),
    Case(
        "launch-bad-option",
        "launch.py",
        lambda i: ["leo_radar", "--seed", "seven"],
        2,
        "launch.py: error: argument --seed: invalid int value: 'seven' (see launch.py --help)",
    ),
    # --- score
    Case(
        "score-two-scenarios",
        "score.py",
        lambda i: [str(i.leo), str(i.formation)],
        2,
        "bags of different scenarios cannot be scored together: ['formation_pf', 'leo_radar']",
    ),
    Case(
        "score-corrupt-metadata",
        "score.py",
        lambda i: [str(i.corrupt_metadata)],
        2,
        "metadata.yaml is not rosbag2 metadata (line",
    ),
    Case("score-no-mcap", "score.py", lambda i: [str(i.no_mcap)], 2, "names bag_0.mcap, which is not there"),
    Case("score-empty-directory", "score.py", lambda i: [str(i.empty)], 2, "not a bag directory"),
    Case("score-foreign-bag", "score.py", lambda i: [str(i.foreign)], 2, "not a bag recorded by this bench"),
    Case(
        "score-unregistered-metric",
        "score.py",
        lambda i: [str(i.unregistered_metric)],
        2,
        "'scoring.metric' must be one of",
    ),
    Case(
        "score-corrupt-run-config",
        "score.py",
        lambda i: [str(i.corrupt_run_config)],
        2,
        "is not a run config written by this bench",
    ),
    Case(
        "score-plots-is-a-file",
        "score.py",
        lambda i: [str(i.leo), "--plots", str(i.a_file)],
        2,
        "a_file is a file, not a directory",
    ),
    Case(
        "score-plots-read-only",
        "score.py",
        lambda i: [str(i.leo), "--plots", str(i.read_only)],
        2,
        "(read-only or no permission)",
    ),
    Case(
        "score-plots-full-disk",
        "score.py",
        lambda i: [str(i.leo), "--plots", i.existing_out("s1")],
        2,
        "(the disk is full or a file size limit is reached)",
        full_disk=True,
    ),
    # --- replay
    Case(
        "replay-no-mcap",
        "replay.py",
        lambda i: [str(i.no_mcap), "--estimators", "ukf", "--out", i.out("r1")],
        2,
        "names bag_0.mcap, which is not there",
    ),
    Case(
        "replay-corrupt-metadata",
        "replay.py",
        lambda i: [str(i.corrupt_metadata), "--estimators", "ukf", "--out", i.out("r2")],
        2,
        "metadata.yaml is not rosbag2 metadata",
    ),
    Case(
        "replay-foreign-bag",
        "replay.py",
        lambda i: [str(i.foreign), "--estimators", "ukf", "--out", i.out("r3")],
        2,
        "is not a bag recorded by this bench (no run_config.yaml)",
    ),
    Case(
        "replay-set-nonexistent-key",
        "replay.py",
        lambda i: [str(i.leo), "--estimators", "ukf", "--out", i.out("r4"), "--set", "filters.ukf.no_such_key=1"],
        2,
        "unknown key(s) 'filters.ukf.no_such_key'",
    ),
    Case(
        "replay-out-is-a-file",
        "replay.py",
        lambda i: [str(i.leo), "--estimators", "ukf", "--out", str(i.a_file)],
        2,
        "a_file is a file, not a directory",
    ),
    Case(
        "replay-out-read-only",
        "replay.py",
        lambda i: [str(i.leo), "--estimators", "ukf", "--out", str(i.read_only)],
        2,
        "(read-only or no permission)",
    ),
    Case(
        "replay-full-disk",
        "replay.py",
        lambda i: [str(i.leo), "--estimators", "ukf", "--out", i.existing_out("r5")],
        2,
        "(the disk is full or a file size limit is reached)",
        full_disk=True,
    ),
    # --- recover_bag
    Case("recover-no-mcap", "recover_bag.py", lambda i: [str(i.no_mcap)], 2, "no .mcap file"),
    Case("recover-not-a-directory", "recover_bag.py", lambda i: [str(i.a_file)], 2, "is not a directory"),
    Case("recover-read-only", "recover_bag.py", lambda i: [str(i.read_only_bag)], 2, "(read-only or no permission)"),
    Case(
        "recover-full-disk",
        "recover_bag.py",
        lambda i: [i.crashed_copy("full")],
        2,
        "(the disk is full or a file size limit is reached)",
        full_disk=True,
    ),
    # --- montecarlo
    Case(
        "montecarlo-yaml-syntax-error",
        "montecarlo.py",
        lambda i: [str(i.bad_yaml), "--runs", "1", "--out", i.out("m1")],
        2,
        "line 3, column 11: not valid YAML",
    ),
    Case(
        "montecarlo-set-nonexistent-key",
        "montecarlo.py",
        lambda i: ["leo_radar", "--runs", "1", "--out", i.out("m2"), *LAUNCH_SET, "--set", "no_such_section.key=1"],
        2,
        "unknown key(s) 'no_such_section'",
    ),
    Case(
        "montecarlo-out-is-a-file",
        "montecarlo.py",
        lambda i: ["leo_radar", "--runs", "1", "--out", str(i.a_file)],
        2,
        "a_file is a file, not a directory",
    ),
    Case(
        "montecarlo-out-read-only",
        "montecarlo.py",
        lambda i: ["leo_radar", "--runs", "1", "--out", str(i.read_only)],
        2,
        "(read-only or no permission)",
    ),
    Case(
        "montecarlo-full-disk",
        "montecarlo.py",
        lambda i: ["leo_radar", "--runs", "1", "--out", i.out("m3")],
        2,
        "(the disk is full or a file size limit is reached)",
        full_disk=True,
    ),
    # --- sweep
    Case(
        "sweep-yaml-syntax-error",
        "sweep.py",
        lambda i: [str(i.bad_yaml), "--grid", "g", "--out", i.out("w1")],
        2,
        "line 3, column 11: not valid YAML",
    ),
    Case(
        "sweep-set-nonexistent-key",
        "sweep.py",
        lambda i: [str(i.grid_yaml), "--grid", "one", "--out", i.out("w2"), "--set", "time.no_such_key=1"],
        2,
        "unknown key(s) 'time.no_such_key'",
    ),
    Case(
        "sweep-out-is-a-file",
        "sweep.py",
        lambda i: [str(i.grid_yaml), "--grid", "one", "--out", str(i.a_file)],
        2,
        "a_file is a file, not a directory",
    ),
    Case(
        "sweep-out-read-only",
        "sweep.py",
        lambda i: [str(i.grid_yaml), "--grid", "one", "--out", str(i.read_only)],
        2,
        "(read-only or no permission)",
    ),
    Case(
        "sweep-full-disk",
        "sweep.py",
        lambda i: [str(i.grid_yaml), "--grid", "one", "--out", i.existing_out("w3")],
        2,
        "(the disk is full or a file size limit is reached)",
        full_disk=True,
    ),
    # --- demo
    Case(
        "demo-unknown-study",
        "demo.py",
        lambda i: ["--studies", "leo_radr", "--out", i.out("d1")],
        2,
        "demo.py: error: unknown study ['leo_radr']",
    ),
    Case(
        "demo-out-is-a-file",
        "demo.py",
        lambda i: ["--studies", "leo_radar", "--out", str(i.a_file)],
        2,
        "a_file is a file, not a directory",
    ),
    Case(
        "demo-out-read-only",
        "demo.py",
        lambda i: ["--studies", "leo_radar", "--out", str(i.read_only)],
        2,
        "(read-only or no permission)",
    ),
    Case(
        "demo-full-disk",
        "demo.py",
        lambda i: ["--studies", "leo_radar", "--out", i.out("d2")],
        2,
        "(the disk is full or a file size limit is reached)",
        full_disk=True,
    ),
]


def _full_disk() -> None:
    """In the command's process (before exec): no file may grow past FULL_DISK_BYTES. Python ignores SIGXFSZ,
    so a write past it fails with EFBIG."""
    resource.setrlimit(resource.RLIMIT_FSIZE, (FULL_DISK_BYTES, FULL_DISK_BYTES))


@contextmanager
def read_only(*paths: Path) -> Iterator[None]:
    """``paths`` (directories) read-only for the commands run inside the block: immutable for root, mode 555
    for anyone else; restored afterwards."""
    if os.geteuid() != 0:
        for p in paths:
            p.chmod(0o555)
        try:
            yield
        finally:
            for p in paths:
                p.chmod(0o755)
        return
    if shutil.which("chattr") is None:
        pytest.skip("root ignores directory permissions and chattr is not installed")
    done = []
    try:
        for p in paths:
            res = subprocess.run(["chattr", "+i", str(p)], capture_output=True, text=True)
            if res.returncode != 0:
                pytest.skip(f"root ignores directory permissions and chattr +i failed here: {res.stderr.strip()}")
            done.append(p)
        yield
    finally:
        for p in done:
            subprocess.run(["chattr", "-i", str(p)], check=True)


def _record(name: str, scenario: str, out: Path, duration: str) -> Path:
    res = script(
        "launch.py", scenario, "--out", str(out), "--no-score", "--set", f"time.duration={duration}", timeout=120
    )
    assert res.returncode == 0, f"{name}: {res.stderr[-2000:]}"
    return out / "bag"


def _make_inputs(root: Path) -> Inputs:
    with ThreadPoolExecutor(2) as pool:  # the only graph runs of this module: two short ones
        leo_f = pool.submit(_record, "leo", "leo_radar", root / "leo", "5")
        formation_f = pool.submit(_record, "formation", "formation_pf", root / "formation", "10")
        leo, formation = leo_f.result(), formation_f.result()

    def copy(name: str) -> Path:
        shutil.copytree(leo, root / name)
        return root / name

    corrupt_metadata = copy("corrupt_metadata")
    with open(corrupt_metadata / "metadata.yaml", "a") as f:
        f.write("  custom: [unclosed: {\n")
    no_mcap = copy("no_mcap")
    next(no_mcap.glob("*.mcap")).unlink()
    (root / "empty").mkdir()
    foreign = copy("foreign")
    (foreign / "run_config.yaml").unlink()
    unregistered = copy("unregistered_metric")
    run = yaml.safe_load((unregistered / "run_config.yaml").read_text())
    run["scenario"]["scoring"]["metric"] = "final_error"  # the plugin example's metric: not installed here
    (unregistered / "run_config.yaml").write_text(yaml.safe_dump(run, sort_keys=False))
    corrupt_run_config = copy("corrupt_run_config")
    (corrupt_run_config / "run_config.yaml").write_text("scenario: [leo_radar\nfilters: ekf\n")
    bad_yaml = root / "bad_scenario.yaml"
    bad_yaml.write_text("scenario: bad\ntime: {dt: 1,\n  foo: bar: [1}\n")
    grid_yaml = root / "grid_scenario.yaml"
    cfg = yaml.safe_load(Path(importlib.import_module("bench_studies.formation_cqkf").SCENARIO).read_text())
    cfg["sweeps"] = {"one": {"axes": {"rho": {"1km": []}}}}
    cfg["time"]["duration"] = 60
    grid_yaml.write_text(yaml.safe_dump(cfg, sort_keys=False))
    (root / "a_file").write_text("not a directory\n")
    (root / "out").mkdir()
    (root / "read_only").mkdir()
    read_only_bag = root / "read_only_bags" / "bag"
    shutil.copytree(leo, read_only_bag)
    (read_only_bag / "metadata.yaml").unlink()
    return Inputs(
        root,
        leo,
        formation,
        corrupt_metadata,
        no_mcap,
        root / "empty",
        foreign,
        unregistered,
        corrupt_run_config,
        bad_yaml,
        grid_yaml,
        root / "a_file",
        root / "read_only",
        read_only_bag,
    )


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> Inputs:
    return _make_inputs(tmp_path_factory.mktemp("bad_inputs"))


@pytest.fixture(scope="module")
def outcomes(inputs: Inputs, request) -> dict[str, subprocess.CompletedProcess]:
    """Every selected case's command, run three at a time (they wait on imports and files more than on a
    core), with the read-only directories read-only while they run."""
    selected = {
        item.callspec.params["case"].id
        for item in request.session.items
        if getattr(item, "callspec", None) and "case" in item.callspec.params
    }
    cases = [c for c in TABLE if c.id in selected]

    def run(case: Case) -> subprocess.CompletedProcess:
        popen = {"preexec_fn": _full_disk} if case.full_disk else {}
        return script(case.command, *case.args(inputs), timeout=120, **popen)

    with read_only(inputs.read_only, inputs.read_only_bag.parent, inputs.read_only_bag):
        with ThreadPoolExecutor(3) as pool:
            return dict(zip([c.id for c in cases], pool.map(run, cases)))


@pytest.mark.parametrize("case", TABLE, ids=[c.id for c in TABLE])
def test_a_bad_input_is_one_line_and_its_exit_code(case: Case, outcomes) -> None:
    res = outcomes[case.id]
    lines = res.stderr.splitlines()
    assert "Traceback" not in res.stderr, res.stderr
    assert len(lines) == 1, f"expected one line on stderr, got {len(lines)}:\n{res.stderr}"
    assert res.returncode == case.code, res.stderr
    assert case.says in lines[0], lines[0]
    assert lines[0].startswith("error: ") or lines[0].startswith(f"{case.command}: error: ")


def test_the_read_only_and_full_cases_leave_nothing_behind(inputs: Inputs, outcomes) -> None:
    """A failed command leaves the read-only directories as they were, and a full disk leaves no bag."""
    assert not list(inputs.read_only.iterdir())
    assert [p.name for p in inputs.read_only_bag.parent.iterdir()] == ["bag"]
    assert sorted(p.name for p in inputs.read_only_bag.iterdir()) == sorted(
        p.name for p in inputs.leo.iterdir() if p.name not in ("metadata.yaml", offline_cache.DIRECTORY)
    )
    for name in ("l4", "r5", "m3", "w3", "d2"):
        assert not list((inputs.root / "out").glob(f"{name}/**/metadata.yaml"))


def test_a_bag_of_a_scenario_not_registered_here_still_scores(inputs: Inputs) -> None:
    """A bag carries its resolved scenario (run_config.yaml): its name need not be registered to score it."""
    bag = inputs.root / "renamed"
    shutil.copytree(inputs.leo, bag)
    run = yaml.safe_load((bag / "run_config.yaml").read_text())
    run["scenario"]["scenario"] = "no_such_study"
    (bag / "run_config.yaml").write_text(yaml.safe_dump(run, sort_keys=False))
    res = script("score.py", str(bag), "--json", timeout=60)
    assert res.returncode == 0, res.stderr
    assert '"scenario": "no_such_study"' in res.stdout


# ------------------------------------------------------------------------------ the guard, in-process

COMMANDS = [
    "bench_eval.cli.launch",
    "bench_eval.cli.score",
    "bench_eval.cli.montecarlo",
    "bench_eval.cli.sweep",
    "bench_eval.cli.replay",
    "bench_eval.cli.demo",
    "bench_engine.cli.recover_bag",
    "bench_engine.run",
    "bench_ccsds.cli.export",
    "bench_ccsds.cli.import_tdm",
]


@pytest.mark.parametrize("module", COMMANDS)
def test_help_documents_the_exit_codes(module: str, capsys) -> None:
    with pytest.raises(SystemExit) as exit_:
        importlib.import_module(module).main(["--help"])
    assert exit_.value.code == 0
    out = capsys.readouterr().out
    assert "exit codes:" in out and "\n  0 " in out and "\n  2 " in out and "\n  70 " in out and "128+N" in out


def test_a_bug_is_a_traceback_then_one_line_saying_so(capsys) -> None:

    def buggy(argv):
        return {}["no such key"]

    assert run_main(buggy, []) == BUG
    err = capsys.readouterr().err
    assert err.startswith("Traceback") and "KeyError" in err
    assert err.splitlines()[-1] == (
        "error: internal error (a bug): KeyError: 'no such key' — please report it with the traceback above"
    )


def test_no_space_names_the_path_and_the_way_out(capsys) -> None:

    def full(argv):
        with writing("/data/runs/x"):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))  # as a write() on a full disk raises it

    def full_in_a_thread(argv):  # the bag writer's thread reports its error wrapped, e.g. RuntimeError
        raise RuntimeError("writing bag /data/runs/x/bag failed") from OSError(errno.ENOSPC, "No space left")

    assert run_main(full, []) == BAD_INPUT
    assert capsys.readouterr().err == (
        "error: cannot write /data/runs/x: no space left on device (the disk is "
        "full or a file size limit is reached): free some space or choose another "
        "output directory\n"
    )
    assert run_main(full_in_a_thread, []) == BAD_INPUT
    assert "no space left (the disk is full" in capsys.readouterr().err


def test_a_file_in_the_way_is_named(tmp_path: Path) -> None:
    (tmp_path / "a_file").write_text("")
    for path in (tmp_path / "a_file", tmp_path / "a_file" / "run" / "bag"):  # the file, or under it
        try:
            path.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            assert os_error_line(err) == (
                f"{tmp_path / 'a_file'} is a file, not a directory: choose another output directory or remove the file"
            )
        else:
            raise AssertionError(f"mkdir {path} succeeded")


def test_interrupted_and_expected_errors_of_the_command(capsys) -> None:

    class Mine(Exception):
        pass

    def interrupted(argv):
        raise KeyboardInterrupt

    def mine(argv):
        raise Mine("nothing to do\n  here")

    assert run_main(interrupted, []) == 130 and capsys.readouterr().err == "error: interrupted\n"
    assert run_main(mine, [], expected={Mine: 1}) == 1 and capsys.readouterr().err == "error: nothing to do here\n"
