"""Parquet / JSON / npz I/O: atomic writes, provenance metadata, schema checks.

Every writer goes through a temporary file in the target directory and an atomic rename,
so a failed or interrupted step never leaves a file that looks complete. Files get the
usual permissions (0666 minus the umask, 0644 by default), not the 0600 of a temporary
file. A whole output directory is written the same way (``atomic_dir``) under an exclusive
lock, so two runs into one directory cannot both report success.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import functools
import json
import os
import shutil
import subprocess
import tempfile
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from crgpr import __version__

META_KEY = b"crgpr"


# the tracked paths whose uncommitted changes mark the code version "dirty"
_CODE_PATHS = ("src", "workflow", "Snakefile", "pyproject.toml")


@functools.cache
def code_version() -> str:
    """Package version plus the git commit of the source tree when available.

    ``0.1.0+g1a2b3c4`` for a clean checkout, ``0.1.0+g1a2b3c4.dirty`` when the code
    (``src/``, ``workflow/``, ``Snakefile``, ``pyproject.toml``) has uncommitted changes,
    ``0.1.0`` for an installed wheel. Results and the config are not code: a run that
    rewrites committed tables does not make later stamps dirty, and the config values a
    file depends on are in its own metadata.
    """
    here = Path(__file__).resolve().parent
    for parent in [here, *here.parents]:
        if (parent / ".git").exists():
            try:
                head = subprocess.run(["git", "-C", str(parent), "rev-parse", "--short", "HEAD"],
                                      capture_output=True, text=True, timeout=10).stdout.strip()
                status = subprocess.run(["git", "-C", str(parent), "status", "--porcelain", "--",
                                         *_CODE_PATHS], capture_output=True, text=True, timeout=10)
            except (OSError, subprocess.SubprocessError):
                return __version__
            if not head:
                return __version__
            dirty = status.returncode != 0 or bool(status.stdout.strip())
            return f"{__version__}+g{head}" + (".dirty" if dirty else "")
    return __version__


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_path(path: str | Path, suffix: str = "") -> Iterator[Path]:
    """Yield a temporary path next to ``path``; rename it into place only on success."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix or ".tmp", dir=path.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        if tmp_path.exists():  # mkstemp makes 0600; give the file the permissions of open()
            os.chmod(tmp_path, 0o666 & ~_umask())
        os.replace(tmp_path, path)
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


class OutputLocked(RuntimeError):
    """Another process is writing the same output directory."""


@contextlib.contextmanager
def output_lock(path: str | Path) -> Iterator[None]:
    """Hold an exclusive lock on output ``path`` (lock file ``.NAME.lock`` beside it).

    Raises ``OutputLocked`` at once if another process holds it: two runs into one output
    must not both report success. The lock file is removed on release.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    lock = path.parent / f".{path.name}.lock"
    while True:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o666 & ~_umask())
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            os.close(fd)
            if exc.errno in (errno.EAGAIN, errno.EACCES, errno.EWOULDBLOCK):
                raise OutputLocked(f"{path}: another run is writing this output right now "
                                   f"(lock {lock}); wait for it or choose another output") from None
            raise
        try:  # the holder before us may have removed the file between our open and flock
            same = os.fstat(fd).st_ino == os.stat(lock).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    try:
        yield
    finally:
        with contextlib.suppress(FileNotFoundError):
            lock.unlink()
        os.close(fd)


@contextlib.contextmanager
def atomic_dir(path: str | Path) -> Iterator[Path]:
    """Yield a temporary directory next to ``path``; it replaces ``path`` only on success.

    Locked with ``output_lock`` for the whole write. An existing ``path`` must be a
    directory (it is replaced as a whole); on failure it is left untouched and the
    temporary directory is removed.
    """
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise FileExistsError(f"{path}: exists and is not a directory")
    with output_lock(path):
        tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent))
        old = None
        try:
            yield tmp
            os.chmod(tmp, 0o777 & ~_umask())
            if path.exists():
                old = path.parent / f"{tmp.name}.old"
                os.replace(path, old)
            try:
                os.replace(tmp, path)
            except OSError:
                if old is not None:
                    os.replace(old, path)
                    old = None
                raise
        finally:
            if tmp.exists():
                shutil.rmtree(tmp, ignore_errors=True)
            if old is not None:
                shutil.rmtree(old, ignore_errors=True)


def write_parquet(df: pd.DataFrame, path: str | Path, metadata: dict[str, Any] | None = None) -> None:
    """Write ``df`` atomically with ``metadata`` (JSON) and the code version in the footer."""
    meta = {"code_version": code_version(), **(metadata or {})}
    table = pa.Table.from_pandas(df, preserve_index=False)
    existing = table.schema.metadata or {}
    blob = json.dumps(meta, default=_json_default).encode()
    table = table.replace_schema_metadata({**existing, META_KEY: blob})
    with atomic_path(path, ".parquet") as tmp:
        pq.write_table(table, tmp)


def read_parquet(path: str | Path, required: Sequence[str] = ()) -> pd.DataFrame:
    """Read a Parquet file; raise ValueError naming the file and any missing column."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file")
    try:
        df = pq.read_table(path).to_pandas()
    except (pa.ArrowInvalid, OSError) as exc:
        raise ValueError(f"{path}: not a readable Parquet file: {exc}") from exc
    missing = [c for c in required if c not in df.columns]
    if missing:
        raise ValueError(f"{path}: missing column(s) {missing}; has {list(df.columns)}")
    return df


TABLE_SUFFIXES: tuple[str, ...] = (".parquet", ".csv")
# CSV numbers parsed to the nearest double (as Parquet stores them): pandas 3's parser does it
# by default and deprecates the option that pandas 2 needs for it
_CSV_EXACT: dict[str, Any] = ({} if int(pd.__version__.split(".")[0]) >= 3
                               else {"float_precision": "round_trip"})


def read_table(path: str | Path, required: Sequence[str] = ()) -> pd.DataFrame:
    """Read a user's table by its extension: ``.parquet`` or ``.csv`` (any case).

    Every failure is one line naming the file: ``FileNotFoundError`` for a missing file,
    ``ValueError`` for another extension (naming the accepted ones), an unreadable or empty
    file, or a missing column of ``required``. CSV: comma-separated with a header row,
    blanks after the commas and a byte-order mark ignored, empty cells and ``nan`` read as
    missing, numbers parsed to the same doubles as Parquet holds (round-trip precision);
    values are not converted here (the caller names a non-numeric column).
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in TABLE_SUFFIXES:
        raise ValueError(f"{path}: unsupported file type {path.suffix or '(no extension)'}; "
                         f"expected one of {', '.join(TABLE_SUFFIXES)}")
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such file")
    if suffix == ".parquet":
        try:
            df = read_parquet(path)
        except ValueError:
            raise
        except Exception as exc:  # noqa: BLE001 - a corrupt file may fail anywhere in the decoder
            raise ValueError(f"{path}: not a readable Parquet file: {type(exc).__name__}: {exc}") from exc
    else:
        try:
            df = pd.read_csv(path, skipinitialspace=True, encoding="utf-8-sig", **_CSV_EXACT)
        except pd.errors.EmptyDataError as exc:
            raise ValueError(f"{path}: empty CSV file (no header row)") from exc
        except Exception as exc:  # noqa: BLE001 - the parser's many ways to fail on a bad file
            raise ValueError(f"{path}: not a readable CSV file: {type(exc).__name__}: {exc}") from exc
    missing = [c for c in required if c not in df.columns]
    if missing:
        raise ValueError(f"{path}: missing column(s) {missing}; has {list(df.columns)}")
    return df


def read_metadata(path: str | Path) -> dict[str, Any]:
    """The crgpr metadata dict stored by ``write_parquet`` (empty if none)."""
    meta = pq.read_schema(path).metadata or {}
    raw = meta.get(META_KEY)
    return json.loads(raw) if raw else {}


def frame_to_grid(df: pd.DataFrame, columns: Sequence[str], source: str = "table"
                  ) -> tuple[np.ndarray, np.ndarray]:
    """A long (t, node) table as arrays: times (n_t,) and values (n_t, n_nodes, len(columns)).

    Rows are sorted by (t, node); a table that is not a full grid raises ValueError naming
    ``source``.
    """
    df = df.sort_values(["t", "node"])
    t = np.unique(df["t"].to_numpy())
    n_nodes = int(df["node"].max()) + 1
    if len(df) != t.size * n_nodes:
        raise ValueError(f"{source}: not a full (t, node) grid ({len(df)} rows, {t.size} times x "
                         f"{n_nodes} nodes)")
    return t, df[list(columns)].to_numpy().reshape(t.size, n_nodes, len(columns))


def write_json(obj: Any, path: str | Path) -> None:
    with atomic_path(path, ".json") as tmp:
        tmp.write_text(json.dumps(obj, indent=2, sort_keys=False, default=_json_default) + "\n")


def write_npz(path: str | Path, **arrays: np.ndarray) -> None:
    """Save arrays (no object arrays: the file must load with allow_pickle=False)."""
    for k, a in arrays.items():
        if np.asarray(a).dtype == object:
            raise TypeError(f"{path}: array {k!r} has dtype object; refusing to pickle")
    with atomic_path(path, ".npz") as tmp, open(tmp, "wb") as fh:
        np.savez(fh, **arrays)


def load_npz(path: str | Path) -> dict[str, np.ndarray]:
    with np.load(path, allow_pickle=False) as data:
        return {k: data[k] for k in data.files}


def write_csv(df: pd.DataFrame, path: str | Path, **kw: Any) -> None:
    with atomic_path(path, ".csv") as tmp:
        df.to_csv(tmp, index=False, **kw)


def write_text(text: str, path: str | Path) -> None:
    with atomic_path(path, Path(path).suffix or ".txt") as tmp:
        tmp.write_text(text)


def _json_default(o: Any) -> Any:
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")
