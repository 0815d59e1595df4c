"""Offline results kept beside the bag, so that scoring a bag again does not compute them again.

The scorer computes two things per run from its bag alone, which may take a minute a run (grace_velocity's
orbit fits and its orbit bound): the offline estimators' estimates (bench_eval.offline: an
:class:`bench_eval.bag_data.Estimates`) and the bounds (bench_eval.bounds: a :class:`bench_eval.bounds.BoundSeries`).
Each result is written into the bag's directory as ``offline_cache/GROUP-NAME-KEY.npz`` (GROUP ``offline`` or
``bounds``, NAME its name in the scenario's ``scoring`` section) and read back the next time the same
computation runs over the same bag, where KEY is the SHA-256 of:

* the bag: its run config and every MCAP file, byte for byte (a bag recorded or recovered again is another bag);
* the computation: its name, the registered component (estimator or bound) and its entry point, its source (an
  offline estimator's) and its params;
* the code's version (:func:`code_version`): the source of every module the component's entry point imports,
  directly or not, within the packages that register components of the bench (``tracking_bench.*`` entry
  points: the bench's own and any plugin's), every ``import`` statement counted, also inside functions (the bench
  imports lazily), and the versions of Python, numpy and scipy. Any edit of that code, even a comment, is a miss:
  a stale result is worse than a recomputed one.

A cache file is read as a hostile file: the archive's members must be stored uncompressed (as ``np.savez``
writes them), every member's .npy header is checked (a plain number or text dtype, no pickles) and its data
must lie inside the member, every array's kind and shape is checked against the others. The arrays are then
mapped read-only from the file (an ndarray over an ``np.memmap``), not copied: a day of orbit-fit covariances
is read only as the scorer uses it, and a scoring worker hands the main process the file's name, not its arrays
(bench_eval.scoring.prepare_runs). Files are only ever replaced whole (below), so a mapped file never changes
under its reader. A file that fails any check is ignored with a warning naming it and the reason (the
result is computed again and replaces the file). Files are written atomically (a temporary file, then a
rename), so a killed scorer leaves the previous file or none. A bag directory that cannot be written (read-only,
full) is scored without a cache, with a warning.
"""

from __future__ import annotations

import ast
import dataclasses
import hashlib
import importlib.util
import json
import os
import platform
import struct
import tempfile
import warnings
import zipfile
from functools import cache
from pathlib import Path
from typing import BinaryIO

import numpy as np
import scipy

from bench_engine import plugins
from bench_engine.settings import Settings

DIRECTORY = "offline_cache"
"""The cache's directory inside a bag directory."""
MEMBERS = {
    "offline": ("steps", "t", "x", "P", "labels", "diagnostic_names", "diagnostic_values"),
    "bounds": ("steps", "t", "P", "labels"),
}
"""The arrays of a cache file, by group: an Estimates, a BoundSeries."""
MAX_BYTES = 1 << 32
"""The largest uncompressed size a cache file may declare (4 GiB: a day of an 18-state estimate at 5 s holds
~45 MB); a larger one is refused before it is read."""


_LOCAL_HEADER = struct.Struct("<4s5H3L2H")
"""A zip local file header: signature, five 2-byte and three 4-byte fields, then the file name's and the extra
field's lengths (PKWARE APPNOTE 4.3.7)."""


class CacheWarning(UserWarning):
    """A cache file was ignored (damaged, hostile, of another layout) or could not be written."""


# --- the key ---------------------------------------------------------------------------------------------------


def _own_packages() -> set[str]:
    """The top-level packages of every registered component (the bench's and any plugin's)."""
    own = set()
    for group in plugins.GROUPS:
        for name in plugins.names(group):
            own.add(plugins.origin(group, name).split(":")[0].split(".")[0])
    return own


def _imported(source: bytes, module: str, is_package: bool) -> set[str]:
    """Every module name an ``import`` statement of ``source`` (module ``module``) may name: ``import a.b``,
    ``from a import b`` (a, and a.b in case b is a submodule), relative imports resolved."""
    names: set[str] = set()
    package = module if is_package else module.rpartition(".")[0]
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")
                parent = ".".join(parts[: len(parts) - node.level + 1])
                base = f"{parent}.{base}" if base else parent
            names.add(base)
            names.update(f"{base}.{alias.name}" for alias in node.names)
    return names


@cache
def _package_dirs(top: str) -> tuple[Path, ...]:
    """The directories of a top-level package (found without importing anything below it)."""
    spec = importlib.util.find_spec(top)
    return tuple(Path(p) for p in (spec.submodule_search_locations or [])) if spec is not None else ()


def _source(module: str) -> tuple[Path, bool] | None:
    """(source file, is a package) of a module of an own package, located on disk without importing it; None
    for a name that is no module with a .py source (e.g. an attribute named in ``from a import b``)."""
    top, *rest = module.split(".")
    for root in _package_dirs(top):
        base = root.joinpath(*rest)
        if (base / "__init__.py").is_file():
            return base / "__init__.py", True
        if rest and base.with_suffix(".py").is_file():
            return base.with_suffix(".py"), False
    return None


@cache
def code_version(module: str) -> str:
    """SHA-256 of the source of ``module`` and of every module it imports, transitively, within the packages
    that register bench components (module docstring), with the versions of Python, numpy and scipy."""
    own = _own_packages()
    found: dict[str, bytes] = {}
    todo = [module]
    while todo:
        name = todo.pop()
        if name in found or name.split(".")[0] not in own:
            continue
        located = _source(name)
        if located is None:
            continue
        path, is_package = located
        found[name] = path.read_bytes()
        parents = [".".join(name.split(".")[:i]) for i in range(1, name.count(".") + 1)]
        todo += parents + sorted(_imported(found[name], name, is_package))
    digest = hashlib.sha256()
    for name in sorted(found):
        digest.update(name.encode() + b"\0" + hashlib.sha256(found[name]).digest())
    digest.update(f"python {platform.python_version()} numpy {np.__version__} scipy {scipy.__version__}".encode())
    return digest.hexdigest()


@cache
def _bag_digest(bag: Path, stamp: tuple) -> str:
    digest = hashlib.sha256()
    for path in [bag / "run_config.yaml", *sorted(bag.glob("*.mcap"))]:
        digest.update(path.name.encode() + b"\0")
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                digest.update(block)
    return digest.hexdigest()


def bag_digest(bag: Path) -> str:
    """SHA-256 of a bag's run config and MCAP files (computed once per process while they are unchanged)."""
    bag = Path(bag).resolve()
    files = [bag / "run_config.yaml", *sorted(bag.glob("*.mcap"))]
    stamp = tuple((p.name, p.stat().st_size, p.stat().st_mtime_ns) for p in files)
    return _bag_digest(bag, stamp)


def key(bag: Path, group: str, name: str, component: str, params: Settings | dict, source: str | None = None) -> str:
    """The cache key of computation ``name`` of a bag: the registered ``component`` of entry-point group
    ``group`` (``offline``, ``bounds``) with ``params`` (its typed settings: bench_engine.settings; and an offline
    estimator's ``source``); module docstring."""
    origin = plugins.origin(group, component)
    if dataclasses.is_dataclass(params):
        params = dataclasses.asdict(params)
    text = json.dumps(
        {
            "bag": bag_digest(bag),
            "group": group,
            "name": name,
            "component": component,
            "origin": origin,
            "source": source,
            "params": params,
            "code": code_version(origin.split(":")[0]),
        },
        sort_keys=True,
        default=repr,
    )
    return hashlib.sha256(text.encode()).hexdigest()


def path(bag: Path, group: str, name: str, cache_key: str) -> Path:
    """Where the result of computation ``name`` of ``group`` with ``cache_key`` is kept."""
    return Path(bag) / DIRECTORY / f"{group}-{name}-{cache_key[:32]}.npz"


# --- reading and writing ---------------------------------------------------------------------------------------


def _warn(text: str) -> None:
    warnings.warn(text, CacheWarning, stacklevel=3)


def load(file: Path, group: str) -> dict[str, np.ndarray] | None:
    """The arrays (:data:`MEMBERS` of ``group``) kept in ``file``, checked; None when there is none, or with a
    warning when the file fails a check (module docstring)."""
    if not file.is_file():
        return None
    members = MEMBERS[group]
    try:
        with zipfile.ZipFile(file) as archive:
            infos = archive.infolist()
            names = sorted(info.filename for info in infos)
            if names != sorted(f"{m}.npy" for m in members):
                raise ValueError(f"members {names}, expected {sorted(members)}")
            if sum(info.file_size for info in infos) > MAX_BYTES:
                raise ValueError(f"it declares more than {MAX_BYTES} bytes of data")
        with open(file, "rb") as f:
            arrays = {info.filename[: -len(".npy")]: _mapped(f, file, info) for info in infos}
        bad = [what for ok, what in _checks(arrays) if not ok]
        if bad:
            raise ValueError(f"inconsistent arrays: {', '.join(bad)}")
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, NotImplementedError) as err:
        _warn(f"ignored the cache file {file} ({type(err).__name__}: {err}); computing its result again")
        return None
    return arrays


def _checks(a: dict[str, np.ndarray]) -> list[tuple[bool, str]]:
    """(passes, what) of every consistency check of a file's arrays."""
    steps, t, P, labels = a["steps"], a["t"], a["P"], a["labels"]
    k, n = len(steps), len(labels)
    checks = [
        (steps.ndim == 1 and steps.dtype.kind == "i", "steps"),
        (t.shape == (k,) and t.dtype.kind == "f", "t"),
        (labels.ndim == 1 and labels.dtype.kind == "U", "labels"),
    ]
    if "x" not in a:  # a bound: its covariance over its labels
        return checks + [(P.shape == (k, n, n) and P.dtype.kind == "f", "P")]
    x, names, values = a["x"], a["diagnostic_names"], a["diagnostic_values"]
    return checks + [
        (x.shape == (k, n) and x.dtype.kind == "f", "x"),
        (P.ndim == 3 and len(P) == k and P.shape[1] == P.shape[2] and P.dtype.kind == "f", "P"),
        (names.ndim == 1 and names.dtype.kind == "U", "diagnostic_names"),
        (values.shape == (len(names), k) and values.dtype.kind == "f", "diagnostic_values"),
    ]


def _mapped(f: BinaryIO, file: Path, info: zipfile.ZipInfo) -> np.ndarray:
    """A stored member's array, mapped read-only from the file after its .npy header is checked: a plain number
    or text dtype, and a shape whose data lies inside the member (numpy would otherwise map or allocate
    whatever the header claims)."""
    if info.compress_type != zipfile.ZIP_STORED:
        raise ValueError(f"{info.filename}: compressed (written: stored)")
    f.seek(info.header_offset)
    local = f.read(_LOCAL_HEADER.size)
    if len(local) != _LOCAL_HEADER.size or local[:4] != b"PK\x03\x04":
        raise ValueError(f"{info.filename}: no local file header at byte {info.header_offset}")
    name_length, extra_length = _LOCAL_HEADER.unpack(local)[-2:]
    start = info.header_offset + _LOCAL_HEADER.size + name_length + extra_length
    f.seek(start)
    version = np.lib.format.read_magic(f)
    readers = {(1, 0): np.lib.format.read_array_header_1_0, (2, 0): np.lib.format.read_array_header_2_0}
    if version not in readers:
        raise ValueError(f"{info.filename}: .npy format {version} (written: 1.0)")
    shape, fortran, dtype = readers[version](f)
    if dtype.hasobject or dtype.kind not in "iufU":
        raise ValueError(f"{info.filename}: dtype {dtype} is not a plain number or text")
    offset = f.tell()
    if offset - start + int(np.prod(shape, dtype=object)) * dtype.itemsize > info.file_size:
        raise ValueError(f"{info.filename}: shape {shape} does not fit its {info.file_size} bytes")
    if 0 in shape:
        return np.zeros(shape, dtype)  # (mmap cannot map nothing)
    # a plain ndarray over the map (its base): np.memmap's Python-level indexing is slower on every slice
    return np.asarray(np.memmap(file, dtype, "r", offset, shape, "F" if fortran else "C"))


def store(file: Path, result, instead: str = "scored without a cache") -> bool:
    """Write ``result`` (a bench_eval.bag_data.Estimates or a bench_eval.bounds.BoundSeries: steps, t, P, labels,
    and an Estimates' x and diagnostics) to ``file`` atomically; True once it is there, False with a warning
    (saying what happens ``instead``) when the directory cannot be written."""
    arrays = {
        "steps": np.asarray(result.steps, dtype=np.int64),
        "t": np.asarray(result.t, dtype=float),
        "P": np.asarray(result.P, dtype=float),
        "labels": np.array([str(s) for s in result.labels], dtype=str).reshape(-1),
    }
    if hasattr(result, "x"):
        names = sorted(result.diagnostics)
        arrays.update(
            x=np.asarray(result.x, dtype=float),
            diagnostic_names=np.array(names, dtype=str).reshape(-1),
            diagnostic_values=np.array([result.diagnostics[n] for n in names], dtype=float).reshape(
                len(names), len(result.steps)
            ),
        )
    tmp = None
    try:
        file.parent.mkdir(exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{file.stem}-", suffix=".tmp", dir=file.parent)
        with os.fdopen(fd, "wb") as f:
            np.savez(f, **arrays)
        os.replace(tmp, file)
    except OSError as err:
        if tmp is not None and os.path.exists(tmp):
            os.unlink(tmp)
        _warn(f"could not keep a result in {file.parent} ({err.strerror or err}); {instead}")
        return False
    return True
