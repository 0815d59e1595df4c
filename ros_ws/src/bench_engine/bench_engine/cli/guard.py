"""How every bench command ends: an expected failure is ONE line on stderr (what is wrong, what to do) and a
documented exit code; a traceback only for a bug, followed by one line saying it is one.

    def command() -> None:
        sys.exit(run_main(main))

Expected failures: ``ScenarioError`` (a scenario, parameter or option), a bag that is not one or is damaged
(``bench_engine.bag_errors.BagError``: damaged, unrecoverable, unsupported), a ROS domain held by another run,
and the operating system refusing a file (no such file, a file where a directory should be, read-only or no
permission, no space left): all exit code :data:`BAD_INPUT`. A command adds its own (``expected``). Anything
else is a bug: exit code :data:`BUG`. Argument errors are one line too (:class:`ArgumentParser`).
"""

from __future__ import annotations

import argparse
import errno
import os
import signal
import sys
import textwrap
import traceback
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path

from bench_engine.errors import ScenarioError

OK, FAILED, BAD_INPUT, BUG = 0, 1, 2, 70
"""Exit codes shared by every command (70: sysexits' EX_SOFTWARE); 128+N: interrupted by signal N."""

NO_SPACE = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG}
NOT_ALLOWED = {errno.EACCES, errno.EPERM, errno.EROFS}
IN_THE_WAY = {errno.EEXIST, errno.ENOTDIR, errno.EISDIR}
MISSING = {errno.ENOENT}
FILE_ERRNOS = NO_SPACE | NOT_ALLOWED | IN_THE_WAY | MISSING

_BAG_ERRORS = (("bench_engine.bag_errors", "BagError"), ("bench_engine.domains", "DomainInUse"))
"""Expected errors of modules a command may not have loaded (an error of a module never loaded cannot occur)."""


def exit_codes(**specific: str) -> str:
    """The ``--help`` epilog listing a command's exit codes: ``specific`` maps ``c0``, ``c1``, … to the text of
    code 0, 1, …; codes 2 (unless given), 70 and 128+N are the same for every command."""
    codes = {int(k[1:]): v for k, v in specific.items()}
    codes.setdefault(
        BAD_INPUT,
        "bad input, stopped before anything ran: an unknown or invalid scenario, "
        "parameter or option, a bag that is not one or is damaged, or an output path "
        "that cannot be written (a file, read-only, no space left)",
    )
    codes[BUG] = "internal error, a bug: a traceback, then a line saying so (please report it)"
    lines = [
        textwrap.fill(text, 110, initial_indent=f"  {code:<6} ", subsequent_indent=" " * 9)
        for code, text in sorted(codes.items())
    ]
    lines.append("  128+N  interrupted by signal N")
    return "exit codes:\n" + "\n".join(lines) + "\nEvery failure but a bug is one line on stderr: 'error: …'."


class ArgumentParser(argparse.ArgumentParser):
    """argparse, with a usage error on one line (``PROG: error: MESSAGE (see PROG --help)``, exit code 2) and
    the description and epilog printed as written."""

    def __init__(self, *args, **kwargs) -> None:
        kwargs.setdefault("formatter_class", argparse.RawDescriptionHelpFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(BAD_INPUT, f"{self.prog}: error: {' '.join(message.split())} (see {self.prog} --help)\n")


def is_file_error(err: BaseException | None) -> bool:
    """Whether ``err`` is the operating system refusing a file (rather than, e.g., a network failure)."""
    return isinstance(err, OSError) and err.errno in FILE_ERRNOS


def file_error_in(err: BaseException | None) -> OSError | None:
    """The file error ``err`` is, or was raised from (``raise … from``: e.g. the bag writer's thread reports
    its OSError as the cause of a RuntimeError); None if there is none."""
    seen = 0
    while err is not None and seen < 20:
        if is_file_error(err):
            return err  # type: ignore[return-value]
        err, seen = err.__cause__, seen + 1
    return None


def os_error_line(err: OSError) -> str:
    """One line for a file error: the path, what happened, what to do."""
    path = err.filename if err.filename is not None else "a file"
    what = (err.strerror or str(err)).lower() if err.errno is not None else str(err)
    if err.errno in NO_SPACE:
        return (
            f"cannot write {path}: {what} (the disk is full or a file size limit is reached): free some "
            f"space or choose another output directory"
        )
    if err.errno in NOT_ALLOWED:
        return f"cannot write {path}: {what} (read-only or no permission): choose a writable output directory"
    if err.errno in IN_THE_WAY:
        for part in [Path(path), *Path(path).parents]:  # the file in the way: PATH or one of its parents
            if part.exists() or part.is_symlink():
                if not part.is_dir():
                    return f"{part} is a file, not a directory: choose another output directory or remove the file"
                break
        return f"{path}: {what}: choose another path"
    if err.errno in MISSING:
        return f"{path}: no such file or directory: check the path"
    return f"{path}: {what}"


PROBE_BYTES = 64 * 1024
"""What :func:`check_writable` writes: less than any run writes (its configuration, logs and bag)."""


def check_writable(directory: str | Path) -> None:
    """Create ``directory`` if needed and write (then remove) a small file in it, so that an output directory
    that is a file, read-only or full stops a command before it starts anything; raises the OSError."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    probe = directory / f".bench-write-test-{os.getpid()}"
    try:
        with open(probe, "wb") as f:
            f.write(bytes(PROBE_BYTES))
            f.flush()
            os.fsync(f.fileno())
    except OSError as err:
        err.filename = str(directory)  # the directory, not the probe, is what the user chose
        raise
    finally:
        probe.unlink(missing_ok=True)


def check_output(path: str | Path) -> None:
    """Stop a command early, before it validates or builds anything, when ``path`` cannot be its output
    directory: a file is in the way (``path`` itself or a parent), or ``path`` exists and takes no file
    (read-only, full: :func:`check_writable`). Creates nothing; raises the OSError."""
    path = Path(path)
    for part in [path, *path.parents]:
        if part.exists():
            if not part.is_dir():
                raise NotADirectoryError(errno.ENOTDIR, os.strerror(errno.ENOTDIR), str(part))
            if part == path:
                check_writable(path)
            return


@contextmanager
def writing(path: str | Path) -> Iterator[None]:
    """Name ``path`` in a file error raised inside the block without a file name of its own (a ``write`` on an
    open file: no space left)."""
    try:
        yield
    except OSError as err:
        if err.filename is None and err.errno in FILE_ERRNOS:
            err.filename = str(path)
        raise


def _expected_code(err: BaseException, expected: Mapping[type, int]) -> int | None:
    for kind, code in expected.items():
        if isinstance(err, kind):
            return code
    if isinstance(err, ScenarioError):
        return BAD_INPUT
    for module, name in _BAG_ERRORS:
        kind = getattr(sys.modules.get(module), name, None)
        if kind is not None and isinstance(err, kind):
            return BAD_INPUT
    if file_error_in(err) is not None:
        return BAD_INPUT
    if (
        isinstance(err, (FileNotFoundError, FileExistsError, NotADirectoryError, IsADirectoryError, PermissionError))
        and err.errno is None
    ):
        return BAD_INPUT  # raised by the bench with a message of its own
    return None


def run_main(
    main: Callable[[list[str] | None], int], argv: list[str] | None = None, expected: Mapping[type, int] | None = None
) -> int:
    """``main(argv)``'s exit code; an expected error (module docstring, and ``expected``: class -> exit code)
    becomes one line on stderr and its code, any other a traceback and a line saying it is a bug (code 70)."""
    try:
        return main(argv)
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return 128 + signal.SIGINT
    except BrokenPipeError as err:  # stdout closed early (e.g. piped into head): nothing left to say
        if err.filename is None:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            return 128 + signal.SIGPIPE
        raise
    except Exception as err:  # noqa: BLE001 - the one place a command's failure is told
        code = _expected_code(err, expected or {})
        if code is None:
            traceback.print_exc()
            what = " ".join(f"{type(err).__name__}: {err}".split()).removesuffix(":")
            print(f"error: internal error (a bug): {what} — please report it with the traceback above", file=sys.stderr)
            return BUG
        file_error = file_error_in(err)
        line = os_error_line(file_error) if file_error is not None else str(err)
        print(f"error: {' '.join(line.split())}", file=sys.stderr)
        return code
