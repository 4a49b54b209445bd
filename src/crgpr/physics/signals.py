"""Input sequences u(t) of the actuation channels (``physics.ports``): signals and input files.

A sequence gives the values (n_t, n_channels) of every channel of ``ports.CHANNELS`` at any
times; a channel it does not name is zero. Two kinds:

* ``SignalInputs``: per channel one signal of the config (``ports.signals``):
  ``constant`` u = value; ``step`` u = value for t >= t_s, else 0; ``sine``
  u = offset + amplitude sin(2 pi f t + phase); ``multisine`` u = amplitude sum_k sin(2 pi f_k t
  + phi_k) over n_tones frequencies evenly spaced in [f_min, f_max] with phases phi_k drawn
  uniformly from a generator seeded by ``seed``; ``chirp`` u = amplitude sin(2 pi (f0 t +
  (f1 - f0) t^2 / (2 t1))), the frequency sweeping linearly from f0 at t = 0 to f1 at t1.
* ``TabulatedInputs``: a file (Parquet, or CSV by its ``.csv`` suffix) with a column ``t`` [s]
  and one column per channel, named as in ``CHANNELS``; linear interpolation between its rows.
  ``read_inputs`` rejects, in one line naming the file and column, an unknown column, a missing,
  non-finite or non-increasing ``t``, a non-finite value, or (``t_end``) a time range that does
  not cover [0, t_end].
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import pandas as pd

from crgpr.io import read_table
from crgpr.physics.ports import CHANNELS


class InputsError(ValueError):
    """A bad input file or signal (one line naming the file or key and the column)."""


class Inputs(Protocol):
    """An input sequence: ``values(t)`` -> (n_t, n_channels) in ``CHANNELS`` order; ``present``
    names the channels it drives (the others are zero)."""

    @property
    def present(self) -> tuple[str, ...]: ...

    def values(self, t: np.ndarray) -> np.ndarray: ...

    def describe(self) -> dict[str, Any]: ...


def _signal(spec: dict[str, Any], t: np.ndarray) -> np.ndarray:
    """One channel's signal (module docstring) at times t [s]."""
    kind = spec["kind"]
    if kind == "constant":
        return np.full(t.shape, float(spec["value"]))
    if kind == "step":
        return np.where(t >= float(spec["t_s"]), float(spec["value"]), 0.0)
    if kind == "sine":
        return float(spec["offset"]) + float(spec["amplitude"]) * np.sin(
            2 * np.pi * float(spec["frequency_hz"]) * t + float(spec["phase_rad"]))
    if kind == "multisine":
        f = np.linspace(float(spec["f_min_hz"]), float(spec["f_max_hz"]), int(spec["n_tones"]))
        phi = np.random.default_rng(int(spec["seed"])).uniform(0.0, 2 * np.pi, f.size)
        return float(spec["amplitude"]) * np.sin(2 * np.pi * f * t[:, None] + phi).sum(axis=1)
    if kind == "chirp":
        f0, f1, t1 = float(spec["f0_hz"]), float(spec["f1_hz"]), float(spec["t1_s"])
        return float(spec["amplitude"]) * np.sin(2 * np.pi * (f0 * t + 0.5 * (f1 - f0) / t1 * t * t))
    raise InputsError(f"unknown signal kind {kind!r}")


@dataclass(frozen=True)
class SignalInputs:
    """Channel -> signal spec (a ``ports.signals`` entry); ``name`` for the records."""

    signals: dict[str, dict[str, Any]]
    name: str = ""

    def __post_init__(self) -> None:
        bad = [c for c in self.signals if c not in CHANNELS]
        if bad:
            raise InputsError(f"signal {self.name!r}: unknown channel(s) {bad}; expected {list(CHANNELS)}")

    @property
    def present(self) -> tuple[str, ...]:
        return tuple(c for c in CHANNELS if c in self.signals)

    def values(self, t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        out = np.zeros((t.size, len(CHANNELS)))
        for k, c in enumerate(CHANNELS):
            if c in self.signals:
                out[:, k] = _signal(self.signals[c], t.reshape(-1))
        return out

    def describe(self) -> dict[str, Any]:
        return {"kind": "signals", "name": self.name, "signals": self.signals}


@dataclass(frozen=True)
class TabulatedInputs:
    """Input values ``u`` (n, n_channels) at increasing times ``t`` (n,), linearly interpolated."""

    t: np.ndarray
    u: np.ndarray
    source: str = ""
    present: tuple[str, ...] = field(default=CHANNELS)

    def values(self, t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=float).reshape(-1)
        return np.stack([np.interp(t, self.t, self.u[:, k]) for k in range(len(CHANNELS))], axis=1)

    def describe(self) -> dict[str, Any]:
        return {"kind": "file", "source": self.source, "channels": list(self.present),
                "t_range_s": [float(self.t[0]), float(self.t[-1])]}


def read_inputs(path: str | Path, t_end: float | None = None, t_start: float = 0.0) -> TabulatedInputs:
    """An input file (module docstring), checked; ``[t_start, t_end]`` must lie in its t range."""
    path = Path(path)
    try:
        df = read_table(path)  # Parquet or CSV by extension, one-line errors
    except (ValueError, FileNotFoundError) as exc:
        raise InputsError(str(exc).splitlines()[0]) from None
    if "t" not in df.columns:
        raise InputsError(f"{path}: no column 't' (time [s])")
    unknown = [str(c) for c in df.columns if c != "t" and c not in CHANNELS]
    if unknown:
        raise InputsError(f"{path}: unknown column {unknown[0]!r}; expected t and channels of "
                          f"{list(CHANNELS)}")
    present = tuple(c for c in CHANNELS if c in df.columns)
    cols = {}
    for c in ("t", *present):
        try:
            v = pd.to_numeric(df[c], errors="raise").to_numpy(dtype=float)
        except (ValueError, TypeError):
            raise InputsError(f"{path}: column {c!r} is not numeric") from None
        if not np.all(np.isfinite(v)):
            raise InputsError(f"{path}: column {c!r} has {int((~np.isfinite(v)).sum())} non-finite value(s)")
        cols[c] = v
    t = cols["t"]
    if t.size < 2:
        raise InputsError(f"{path}: column 't' needs at least 2 rows, has {t.size}")
    if np.any(np.diff(t) <= 0):
        row = int(np.argmax(np.diff(t) <= 0)) + 1
        raise InputsError(f"{path}: column 't' is not strictly increasing (row {row})")
    if t_end is not None and (t[0] > t_start + 1e-12 or t[-1] < t_end - 1e-12):
        raise InputsError(f"{path}: column 't' spans [{t[0]:g}, {t[-1]:g}] s, which does not cover "
                          f"[{t_start:g}, {t_end:g}] s")
    u = np.zeros((t.size, len(CHANNELS)))
    for k, c in enumerate(CHANNELS):
        if c in cols:
            u[:, k] = cols[c]
    return TabulatedInputs(t, u, str(path), present)


def inputs_frame(inputs: Inputs, t: np.ndarray) -> pd.DataFrame:
    """The input file (``t`` and the channels the sequence drives) of a sequence sampled at times t."""
    u = inputs.values(t)
    return pd.DataFrame({"t": np.asarray(t, dtype=float),
                         **{c: u[:, k] for k, c in enumerate(CHANNELS) if c in inputs.present}})
