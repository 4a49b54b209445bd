"""Measured camera data: validation errors, angles from positions, GP smoothing (issue 6)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from crgpr.discovery.measured import (
    MeasuredDataError,
    camera_frame,
    load_measured,
    node_angles,
    segment_angles,
    smooth_kinematics,
    validate_frame,
)
from crgpr.io import write_parquet
from crgpr.physics.params import RodParams, SimSettings
from crgpr.physics.simulate import simulate, velocities


@pytest.fixture(scope="module")
def traj():
    return simulate(85.0, RodParams(N=10), SimSettings(dt=1e-4, t_end=0.4, record_every=50))


def _frame(traj, noise=0.0):
    return camera_frame(traj.t, traj.q, noise, np.random.default_rng(0))


def test_valid_frame_round_trip(tmp_path, traj):
    df = _frame(traj)
    path = tmp_path / "m.parquet"
    write_parquet(df, path)
    meas = load_measured(path)
    assert meas.x.shape == (len(traj.t), 11)
    np.testing.assert_allclose(meas.x, traj.q[..., 0])
    assert meas.rate_hz == pytest.approx(200.0)


@pytest.mark.parametrize("mutate, message", [
    (lambda d: d.drop(columns="y"), "missing column"),
    (lambda d: d.assign(x=d["x"].where(d.index != 7)), "NaN"),
    (lambda d: d.assign(t=d["t"].where(d["t"] != d["t"].unique()[3], d["t"].unique()[1])),
     "not strictly increasing"),
    (lambda d: d.assign(t=np.where(d["t"] > 0.2, d["t"] + 0.002, d["t"])), "uneven time sampling"),
    (lambda d: d[d["t"] < 0.05], "time samples"),
    (lambda d: d[d["node"] != 4], "without gaps"),
    (lambda d: d.assign(t=d["t"] * 2.0), "below the minimum 200 Hz"),
    (lambda d: d.iloc[:-1], "every node needs every time"),
])
def test_bad_input_is_rejected_with_a_clear_message(traj, mutate, message):
    df = mutate(_frame(traj).copy())
    with pytest.raises(MeasuredDataError, match=message) as err:
        validate_frame(df, "cam.parquet", min_rate_hz=200.0, min_samples=20)
    assert "cam.parquet" in str(err.value)


def test_missing_file_is_named(tmp_path):
    with pytest.raises((FileNotFoundError, MeasuredDataError), match="nope.parquet"):
        load_measured(tmp_path / "nope.parquet")


def test_angles_from_positions_match_the_simulator(traj):
    """Segment angles are the mid-segment angles of rod.py (nu2 ~ 0); nodal angles follow."""
    phi = segment_angles(traj.q[..., 0], traj.q[..., 1])
    tb = 0.5 * (traj.q[..., 1:, 2] + traj.q[..., :-1, 2])
    assert np.max(np.abs(phi - tb)) < 2e-3
    th = node_angles(phi)
    err = th[:, 1:] - traj.q[:, 1:, 2]
    assert np.sqrt(np.mean(err**2)) < 0.01


def test_unwrapping_in_time_and_along_s():
    """A rod spun through +-pi keeps continuous angles (no 2 pi jumps)."""
    t = np.linspace(0, 1, 50)
    s = np.linspace(0, 0.5, 11)
    ang = 2.5 + 2.0 * t[:, None] + 1.5 * s[None, :]  # crosses pi in time and along s
    x = np.cumsum(np.c_[np.zeros(50), 0.05 * np.cos(ang[:, :-1])], axis=1)
    y = np.cumsum(np.c_[np.zeros(50), 0.05 * np.sin(ang[:, :-1])], axis=1)
    phi = segment_angles(x, y)
    np.testing.assert_allclose(phi, ang[:, :-1], atol=1e-9)


def test_gp_smoothing_recovers_velocities_and_angles(traj):
    """Project GP prefilter on 1 mm noisy camera data: angles and velocities close to truth."""
    meas = validate_frame(_frame(traj, noise=1e-3), "cam", min_samples=20)
    kin = smooth_kinematics(meas, seed=0)
    assert 0.5e-3 < kin.noise_std_m < 2e-3  # the GP finds the camera's noise level
    v_true = velocities(traj)
    inner = slice(5, -5)
    vt = np.sqrt(np.mean(v_true[inner, 1:, :2] ** 2))
    ve = np.sqrt(np.mean((kin.v[inner, 1:, :2] - v_true[inner, 1:, :2]) ** 2))
    assert ve < 0.25 * vt
    # far better than central differences of the noisy positions
    xy = np.stack([meas.x, meas.y], axis=-1)
    fd = (xy[2:] - xy[:-2]) / (2 * meas.dt)
    fd_err = np.sqrt(np.mean((fd[4:-4, 1:] - v_true[5:-5, 1:, :2]) ** 2))
    assert ve < 0.2 * fd_err
    th_err = np.sqrt(np.mean((kin.q[inner, 1:, 2] - traj.q[inner, 1:, 2]) ** 2))
    assert th_err < 0.02
    assert math.isfinite(float(np.sum(kin.a)))


def test_camera_frame_subsamples_nodes():
    q = np.zeros((3, 21, 3))
    q[..., 0] = np.linspace(0, 0.5, 21)
    df = camera_frame(np.array([0.0, 0.005, 0.01]), q, 0.0, np.random.default_rng(0), node_stride=2)
    assert isinstance(df, pd.DataFrame)
    assert df["node"].max() == 10
    np.testing.assert_allclose(df[df["node"] == 10]["x"], 0.5)
