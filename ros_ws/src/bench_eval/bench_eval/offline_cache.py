"""Offline estimators' results kept beside the bag, so that scoring a bag again does not run them again.

An offline estimator (bench_eval.offline) may take minutes a run (grace_velocity's orbit fits). Its result, an
:class:`bench_eval.scoring.Estimates`, is written into the bag's directory as ``offline_cache/NAME-KEY.npz`` and
read back the next time the same estimator is run over the same bag, where KEY is the SHA-256 of:

* the bag: its run config and every MCAP file, byte for byte (a bag recorded or recovered again is another bag);
* the offline run: its name in the scenario, the registered estimator, its source and its params;
* the code's version (:func:`code_version`): the source of every module the estimator's entry point imports,
  directly or not, within the packages that register components of the bench (``tracking_bench.*`` entry
  points: the bench's own and any plugin's), every ``import`` statement counted, also inside functions (the bench
  imports lazily), and the versions of Python, numpy and scipy. Any edit of that code, even a comment, is a miss:
  a stale result is worse than a recomputed one.

A cache file is read as a hostile file: ``np.load`` without pickles, the archive's members and their declared
sizes checked before anything is decompressed, every array's kind and shape checked against the others. A file
that fails any check is ignored with a warning naming it and the reason (the estimator runs, and its result
replaces the file). Files are written atomically (a temporary file, then a rename), so a killed scorer leaves
the previous file or none. A bag directory that cannot be written (read-only, full) is scored without a cache,
with a warning.
"""
from __future__ import annotations

import ast
import hashlib
import importlib.util
import json
import os
import platform
import tempfile
import warnings
import zipfile
from functools import lru_cache
from pathlib import Path

import numpy as np
import scipy

from bench_engine import plugins

DIRECTORY = "offline_cache"
"""The cache's directory inside a bag directory."""
MEMBERS = ("steps", "t", "x", "P", "labels", "diagnostic_names", "diagnostic_values")
"""The arrays of a cache file (an Estimates)."""
MAX_BYTES = 1 << 32
"""The largest uncompressed size a cache file may declare (4 GiB: a day of grace_velocity's 18-state pair fit
holds ~45 MB); a larger one is refused before it is read."""


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
                parent = ".".join(parts[:len(parts) - node.level + 1])
                base = f"{parent}.{base}" if base else parent
            names.add(base)
            names.update(f"{base}.{alias.name}" for alias in node.names)
    return names


def _source(module: str) -> tuple[Path, bool] | None:
    """(source file, is a package) of an importable module, None for a name that is no module with a .py source."""
    try:
        spec = importlib.util.find_spec(module)
    except (ImportError, ValueError, AttributeError):  # a parent is no package, or the name is an attribute
        return None
    if spec is None or not spec.origin or not spec.origin.endswith(".py"):
        return None
    return Path(spec.origin), spec.submodule_search_locations is not None


@lru_cache(maxsize=None)
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


@lru_cache(maxsize=None)
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


def key(bag: Path, name: str, estimator: str, source: str, params: dict) -> str:
    """The cache key of the offline run ``name`` (registered ``estimator`` over ``source`` with ``params``) of a
    bag (module docstring)."""
    module = plugins.origin("offline", estimator).split(":")[0]
    text = json.dumps({"bag": bag_digest(bag), "name": name, "estimator": estimator,
                       "origin": plugins.origin("offline", estimator), "source": source, "params": params,
                       "code": code_version(module)}, sort_keys=True, default=repr)
    return hashlib.sha256(text.encode()).hexdigest()


def path(bag: Path, name: str, cache_key: str) -> Path:
    """Where the result of offline run ``name`` with ``cache_key`` is kept."""
    return Path(bag) / DIRECTORY / f"{name}-{cache_key[:32]}.npz"


# --- reading and writing ---------------------------------------------------------------------------------------

def _warn(text: str) -> None:
    warnings.warn(text, CacheWarning, stacklevel=3)


def load(file: Path):
    """The Estimates kept in ``file``; None when there is none, or with a warning when the file fails a check
    (module docstring)."""
    from bench_eval.scoring import Estimates
    if not file.is_file():
        return None
    try:
        with zipfile.ZipFile(file) as archive:
            infos = archive.infolist()
            members = sorted(info.filename for info in infos)
            if members != sorted(f"{m}.npy" for m in MEMBERS):
                raise ValueError(f"members {members}, expected {sorted(MEMBERS)}")
            if sum(info.file_size for info in infos) > MAX_BYTES:
                raise ValueError(f"it declares more than {MAX_BYTES} bytes of data")
            for info in infos:
                _check_header(archive, info)
        with np.load(file, allow_pickle=False) as z:
            a = {m: z[m] for m in MEMBERS}
        steps, t, x, P = a["steps"], a["t"], a["x"], a["P"]
        labels, names, values = a["labels"], a["diagnostic_names"], a["diagnostic_values"]
        k = len(steps)
        checks = [(steps.ndim == 1 and steps.dtype.kind == "i", "steps"), (t.shape == (k,) and t.dtype.kind == "f", "t"),
                  (x.ndim == 2 and len(x) == k and x.dtype.kind == "f", "x"),
                  (P.ndim == 3 and len(P) == k and P.shape[1] == P.shape[2] and P.dtype.kind == "f", "P"),
                  (labels.ndim == 1 and labels.dtype.kind == "U" and len(labels) == x.shape[1], "labels"),
                  (names.ndim == 1 and names.dtype.kind == "U", "diagnostic_names"),
                  (values.shape == (len(names), k) and values.dtype.kind == "f", "diagnostic_values")]
        bad = [what for ok, what in checks if not ok]
        if bad:
            raise ValueError(f"inconsistent arrays: {', '.join(bad)}")
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, NotImplementedError) as err:
        _warn(f"ignored the offline-estimator cache file {file} ({type(err).__name__}: {err}); running the "
              "estimator again")
        return None
    return Estimates(steps.astype(np.int64), t.astype(float), x.astype(float), P.astype(float),
                     [str(s) for s in labels], {str(n): v.astype(float) for n, v in zip(names, values)})


def _check_header(archive: zipfile.ZipFile, info: zipfile.ZipInfo) -> None:
    """A member's .npy header: a plain number or text dtype, and a shape its declared size holds (numpy would
    otherwise allocate whatever the header claims before reading)."""
    with archive.open(info) as f:
        version = np.lib.format.read_magic(f)
        readers = {(1, 0): np.lib.format.read_array_header_1_0, (2, 0): np.lib.format.read_array_header_2_0}
        if version not in readers:
            raise ValueError(f"{info.filename}: .npy format {version} (written: 1.0)")
        shape, _, dtype = readers[version](f)
    if dtype.hasobject or dtype.kind not in "iufU":
        raise ValueError(f"{info.filename}: dtype {dtype} is not a plain number or text")
    if int(np.prod(shape, dtype=object)) * dtype.itemsize > info.file_size:
        raise ValueError(f"{info.filename}: shape {shape} does not fit its {info.file_size} bytes")


def store(file: Path, est) -> None:
    """Write ``est`` (an Estimates) to ``file`` atomically; a warning when the directory cannot be written."""
    names = sorted(est.diagnostics)
    arrays = {"steps": np.asarray(est.steps, dtype=np.int64), "t": np.asarray(est.t, dtype=float),
              "x": np.asarray(est.x, dtype=float), "P": np.asarray(est.P, dtype=float),
              "labels": np.array([str(s) for s in est.labels], dtype=str).reshape(-1),
              "diagnostic_names": np.array(names, dtype=str).reshape(-1),
              "diagnostic_values": np.array([est.diagnostics[n] for n in names], dtype=float).reshape(
                  len(names), len(est.steps))}
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
        _warn(f"could not keep the offline estimator's result in {file.parent} ({err.strerror or err}); scored "
              "without a cache")
