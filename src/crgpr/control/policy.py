"""The portable control policy: a tip-pose law evaluated from data alone (docs/control.md).

    u(t) = clip(u_ff(t) + K_p e(t) + K_d de/dt(t), u_min, u_max),
    e = [x*, y*, phi*](t) - [x, y, phi](t)

with [x, y, phi] the tip position [m] and the last segment's angle [rad] (atan2 of the last
segment's chord); the angle error is wrapped into [-pi, pi).
``K_p``, ``K_d`` are (channels x 3); a row of zeros where a gain is not used,
and a zero column for phi when no angle is targeted. Regulation holds one target and one u_ff;
tracking reads u_ff(t) and the target path (t, x*, y*, phi* and their rates) from tables,
linearly interpolated and held at their ends.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

POLICY_KIND = "crgpr_tip_policy"


@dataclass(frozen=True)
class Policy:
    """The law of the module doc. ``t_path`` (n,) with ``u_ff`` (n, channels) and ``target``,
    ``target_rate`` (n, 3) for tracking; n = 1 (t_path = [0]) for regulation."""

    channels: tuple[str, ...]
    t_path: np.ndarray
    u_ff: np.ndarray
    target: np.ndarray
    target_rate: np.ndarray
    K_p: np.ndarray
    K_d: np.ndarray
    u_min: np.ndarray
    u_max: np.ndarray

    def _at(self, table: np.ndarray, t: float) -> np.ndarray:
        if self.t_path.size == 1:
            return table[0]
        return np.array([np.interp(t, self.t_path, table[:, k]) for k in range(table.shape[1])])

    def reference(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(u_ff, target pose, target rate) at time t [s]."""
        return self._at(self.u_ff, t), self._at(self.target, t), self._at(self.target_rate, t)

    def __call__(self, t: float, pose: np.ndarray, rate: np.ndarray) -> np.ndarray:
        """Inputs (channels,) at time t for the tip pose [x, y, phi] and its rate."""
        u_ff, tgt, tgt_rate = self.reference(t)
        e = tgt - np.asarray(pose, dtype=float)
        e[2] = (e[2] + np.pi) % (2 * np.pi) - np.pi
        de = tgt_rate - np.asarray(rate, dtype=float)
        return np.clip(u_ff + self.K_p @ e + self.K_d @ de, self.u_min, self.u_max)


def tip_pose(q: np.ndarray) -> np.ndarray:
    """Tip pose [x, y, phi] of configurations q (..., N+1, 3): tip position, last segment's angle."""
    d = q[..., -1, :2] - q[..., -2, :2]
    return np.concatenate([q[..., -1, :2], np.arctan2(d[..., 1], d[..., 0])[..., None]], axis=-1)


def tip_pose_rate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rate of ``tip_pose`` for configurations q and velocities v = dq/dt (..., N+1, 3)."""
    d = q[..., -1, :2] - q[..., -2, :2]
    dd = v[..., -1, :2] - v[..., -2, :2]
    w = (d[..., 0] * dd[..., 1] - d[..., 1] * dd[..., 0]) / (d[..., 0] ** 2 + d[..., 1] ** 2)
    return np.concatenate([v[..., -1, :2], w[..., None]], axis=-1)


def to_document(policy: Policy, u_ff_file: str | None = None, target_file: str | None = None,
                extra: dict[str, Any] | None = None) -> dict[str, Any]:
    """The policy as JSON data (docs/control.md). Tracking policies name their tables
    (``u_ff_file``: t + one column per channel; ``target_file``: t, x, y, phi, dx, dy, dphi),
    relative to the policy file."""
    doc: dict[str, Any] = {"kind": POLICY_KIND, "channels": list(policy.channels),
                           "law": "u = clip(u_ff(t) + K_p e + K_d de/dt, u_min, u_max), "
                                  "e = [x*, y*, phi*] - [x, y, phi]",
                           "K_p": policy.K_p.tolist(), "K_d": policy.K_d.tolist(),
                           "u_min": policy.u_min.tolist(), "u_max": policy.u_max.tolist()}
    if policy.t_path.size == 1:
        doc.update(u_ff=policy.u_ff[0].tolist(), target=policy.target[0].tolist())
    else:
        if u_ff_file is None or target_file is None:
            raise ValueError("a tracking policy needs its u_ff_file and target_file names")
        doc.update(u_ff_file=u_ff_file, target_file=target_file)
    doc.update(extra or {})
    return doc


def tables(policy: Policy) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The u_ff table and the target table of a tracking policy."""
    uf = pd.DataFrame({"t": policy.t_path, **{c: policy.u_ff[:, k] for k, c in enumerate(policy.channels)}})
    names = ("x", "y", "phi")
    tg = pd.DataFrame({"t": policy.t_path, **{n: policy.target[:, k] for k, n in enumerate(names)},
                       **{f"d{n}": policy.target_rate[:, k] for k, n in enumerate(names)}})
    return uf, tg


def _read_table(path: Path) -> pd.DataFrame:
    return pd.read_csv(path) if path.suffix == ".csv" else pd.read_parquet(path)


def from_document(doc: dict[str, Any], base: str | Path = ".") -> Policy:
    """The policy of a document written by ``to_document`` (tables read relative to ``base``)."""
    ch = tuple(doc["channels"])
    arr = {k: np.asarray(doc[k], dtype=float) for k in ("K_p", "K_d", "u_min", "u_max")}
    if "u_ff" in doc:
        t = np.zeros(1)
        u = np.asarray(doc["u_ff"], dtype=float)[None]
        tgt = np.asarray(doc["target"], dtype=float)[None]
        rate = np.zeros_like(tgt)
    else:
        uf = _read_table(Path(base) / doc["u_ff_file"])
        tg = _read_table(Path(base) / doc["target_file"])
        t = uf["t"].to_numpy(float)
        u = uf[list(ch)].to_numpy(float)
        tgt = np.column_stack([np.interp(t, tg["t"], tg[n]) for n in ("x", "y", "phi")])
        rate = np.column_stack([np.interp(t, tg["t"], tg[f"d{n}"]) for n in ("x", "y", "phi")])
    return Policy(ch, t, u, tgt, rate, arr["K_p"], arr["K_d"], arr["u_min"], arr["u_max"])
