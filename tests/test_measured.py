"""Measured camera data: validation, screening, markers anywhere, kinematics on the model grid."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as hs
from paper_rod import paper_rod

from crgpr.discovery.synthetic import camera_frame
from crgpr.io import write_parquet
from crgpr.measured.kinematics import marker_matrix, node_angles, segment_angles, smooth_kinematics
from crgpr.measured.records import MeasuredDataError, ScreenSettings, load_measured, validate_frame
from crgpr.physics.params import SimSettings
from crgpr.physics.simulate import simulate, velocities

ROD = paper_rod(N=10)
ST = ScreenSettings(min_rate_hz=200.0, min_samples=20, outlier_k=8.0, outlier_min_m=5e-3, geometry_tol=0.15)


@pytest.fixture(scope="module")
def traj():
    return simulate(85.0, ROD, SimSettings(dt=1e-4, t_end=0.4, record_every=50, scheme="variational"))


def _frame(traj, noise=0.0, seed=0, **camera):
    return camera_frame(traj.t, traj.q, ROD, {"noise_std_m": noise, **camera}, np.random.default_rng(seed),
                        ROD.ds)


def _val(df, st=ST):
    return validate_frame(df, "cam.parquet", ROD.L0, ROD.ds, st)


def test_valid_frame_round_trip(tmp_path, traj):
    path = tmp_path / "m.parquet"
    write_parquet(_frame(traj), path)
    meas = load_measured(path, ROD.L0, ROD.ds, ST)
    assert meas.x.shape == (len(traj.t), 11)
    np.testing.assert_allclose(meas.x, traj.q[..., 0])
    np.testing.assert_allclose(meas.s, ROD.s)
    assert meas.rate_hz == pytest.approx(200.0)
    assert meas.outliers.sum() == 0 and np.all(meas.missing_fraction == 0)


def test_rows_in_any_order_give_the_same_data(traj):
    df = _frame(traj, noise=1e-3)
    a = _val(df)
    b = _val(df.sample(frac=1.0, random_state=3))
    np.testing.assert_array_equal(a.x, b.x)
    np.testing.assert_array_equal(a.y, b.y)


def test_markers_at_arbitrary_s_and_no_base_marker(traj):
    s = [0.07, 0.15, 0.24, 0.31, 0.4, 0.48]
    meas = _val(_frame(traj, markers_s=s))
    np.testing.assert_allclose(meas.s, s)
    assert not meas.has_base


@pytest.mark.parametrize("mutate, message", [
    (lambda d: d.drop(columns="y"), "missing column"),
    (lambda d: d.drop(columns="node"), "s or node"),
    (lambda d: d.assign(t=d["t"].where(d.index != 7)), "'t' has 1 NaN"),
    (lambda d: d.assign(x=d["x"].astype(object).where(d.index != 5, "abc")), "non-numeric"),
    (lambda d: pd.concat([d, d.iloc[[12]]]), "duplicate rows"),
    (lambda d: d.assign(t=np.where(d["t"] > 0.2, d["t"] + 0.002, d["t"])), "uneven time sampling"),
    (lambda d: d[d["t"] < 0.05], "frames with data"),
    (lambda d: d[d["node"] < 3], "at least 4 markers"),
    (lambda d: d.assign(node=d["node"] * 2), "outside the rod"),
    (lambda d: d.assign(t=d["t"] * 2.0), "below the minimum 200 Hz"),
    (lambda d: d.assign(x=d["x"] * 3.0, y=d["y"] * 3.0), "impossible geometry"),
    (lambda d: d.iloc[:0], "no rows"),
])
def test_bad_input_is_rejected_with_a_clear_message(traj, mutate, message):
    df = mutate(_frame(traj).copy())
    with pytest.raises(MeasuredDataError, match=message) as err:
        _val(df)
    assert "cam.parquet" in str(err.value)


def test_a_zero_row_file_names_the_file(tmp_path):
    path = tmp_path / "empty.parquet"
    write_parquet(pd.DataFrame({"t": [], "node": [], "x": [], "y": []}), path)
    with pytest.raises(MeasuredDataError, match="empty.parquet: no rows"):
        load_measured(path, ROD.L0, ROD.ds, ST)


def test_missing_file_is_named(tmp_path):
    with pytest.raises(MeasuredDataError, match="nope.parquet"):
        load_measured(tmp_path / "nope.parquet", ROD.L0, ROD.ds, ST)


def test_dropped_frames_and_occlusions_are_tolerated_and_reported(traj):
    meas = _val(_frame(traj, noise=1e-3, drop_frames=0.1, occluded=0.1))
    # the uniform time grid keeps the dropped frames inside the record (as missing samples)
    assert meas.x.shape[0] >= len(traj.t) - 3
    np.testing.assert_allclose(np.diff(meas.t), 0.005, rtol=1e-9)
    assert np.all((meas.missing_fraction > 0.05) & (meas.missing_fraction < 0.4))
    assert any("missing samples" in n for n in meas.notes)
    assert meas.summary()["missing_fraction"] == pytest.approx(list(meas.missing_fraction))


def test_gross_outliers_are_excluded_and_reported(traj):
    clean = _val(_frame(traj, noise=1e-3, seed=1))
    assert clean.outliers.sum() == 0  # no false alarms on clean 1 mm data
    df = _frame(traj, noise=1e-3, seed=1)
    bad_rows = [40, 41 + 11 * 20, 5 + 11 * 60]  # (t, node) rows: marker at the origin
    df.loc[bad_rows, ["x", "y"]] = 0.0
    meas = _val(df)
    assert meas.outliers.sum() >= 3
    for r in bad_rows:
        k, j = divmod(r, 11)
        assert meas.outliers[k, j] and not np.isfinite(meas.x[k, j])
    assert any("outlier" in n for n in meas.notes)


def test_swapped_neighbouring_markers_are_excluded(traj):
    df = _frame(traj, noise=1e-3, seed=2)
    k = 30
    i, j = 11 * k + 5, 11 * k + 6
    df.loc[[i, j], ["x", "y"]] = df.loc[[j, i], ["x", "y"]].to_numpy()
    meas = _val(df)
    assert meas.outliers[k, 5] and meas.outliers[k, 6]


def test_zeroed_bytes_in_the_file_are_not_silently_accepted(tmp_path, traj):
    """200 zero bytes in the middle of the file: an error, or the damage is excluded and reported."""
    path = tmp_path / "m.parquet"
    write_parquet(_frame(traj, noise=1e-3), path)
    raw = bytearray(path.read_bytes())
    for start in (len(raw) // 3, len(raw) // 2, 2 * len(raw) // 3):
        bad = raw.copy()
        bad[start:start + 200] = bytes(200)
        p = tmp_path / f"z{start}.parquet"
        p.write_bytes(bytes(bad))
        try:
            meas = load_measured(p, ROD.L0, ROD.ds, ST)
        except MeasuredDataError as exc:
            assert str(p) in str(exc)
            continue
        changed = meas.outliers.sum() + np.sum(meas.missing_fraction > 0)
        assert changed > 0 and meas.notes, "corrupted file accepted without a word"


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(hs.data())
def test_fuzz_loader_raises_only_its_own_error(data):
    """No table makes validation crash with anything but MeasuredDataError."""
    n = data.draw(hs.integers(0, 80))
    floats = hs.one_of(hs.floats(allow_nan=True, allow_infinity=True), hs.integers(-5, 30))
    cols = data.draw(hs.lists(hs.sampled_from(["t", "node", "s", "x", "y", "z"]), unique=True, max_size=6))
    df = pd.DataFrame({c: data.draw(hs.lists(floats, min_size=n, max_size=n)) for c in cols})
    if data.draw(hs.booleans()) and n and cols:
        df = df.astype(object)
        df.iloc[0, 0] = data.draw(hs.text(max_size=3))
    try:
        meas = _val(df, ScreenSettings(1.0, 2, 8.0, 5e-3, 0.15))
    except MeasuredDataError:
        return
    assert meas.x.shape == meas.y.shape


@settings(max_examples=25, deadline=None)
@given(hs.binary(min_size=0, max_size=400))
def test_fuzz_random_bytes_are_rejected(tmp_path_factory, blob):
    p = tmp_path_factory.mktemp("fz") / "f.parquet"
    p.write_bytes(b"PAR1" + blob + b"PAR1")
    with pytest.raises(MeasuredDataError):
        load_measured(p, ROD.L0, ROD.ds, ST)


def test_angles_from_positions_match_the_simulator(traj):
    """Segment angles are the mid-segment angles of rod.py (nu2 ~ 0); nodal angles follow."""
    phi = segment_angles(traj.q[..., 0], traj.q[..., 1])
    tb = 0.5 * (traj.q[..., 1:, 2] + traj.q[..., :-1, 2])
    assert np.max(np.abs(phi - tb)) < 2e-3
    th = node_angles(phi)
    assert np.sqrt(np.mean((th[:, 1:] - traj.q[:, 1:, 2]) ** 2)) < 0.01


def test_unwrapping_in_time_and_along_s():
    """A rod spun through +-pi keeps continuous angles (no 2 pi jumps)."""
    t = np.linspace(0, 1, 50)
    ang = 2.5 + 2.0 * t[:, None] + 1.5 * np.linspace(0, 0.5, 11)[None, :]
    x = np.cumsum(np.c_[np.zeros(50), 0.05 * np.cos(ang[:, :-1])], axis=1)
    y = np.cumsum(np.c_[np.zeros(50), 0.05 * np.sin(ang[:, :-1])], axis=1)
    np.testing.assert_allclose(segment_angles(x, y), ang[:, :-1], atol=1e-9)


def _kin_errors(traj, kin):
    v_true = velocities(traj)
    inner = slice(5, -5)
    ve = np.sqrt(np.mean((kin.v[inner, 1:, :2] - v_true[inner, 1:, :2]) ** 2))
    vt = np.sqrt(np.mean(v_true[inner, 1:, :2] ** 2))
    th = np.sqrt(np.mean((kin.q[inner, 1:, 2] - traj.q[inner, 1:, 2]) ** 2))
    return ve / vt, th


def test_gp_smoothing_recovers_velocities_and_angles(traj):
    """Project GP prefilter on 1 mm noisy camera data: angles and velocities close to truth."""
    meas = _val(_frame(traj, noise=1e-3))
    kin = smooth_kinematics(meas, ROD, seed=0)
    assert 0.5e-3 < kin.noise_std_m < 2e-3  # the GP finds the camera's noise level
    rel_v, th = _kin_errors(traj, kin)
    assert rel_v < 0.25 and th < 0.02
    assert math.isfinite(float(np.sum(kin.a)))


def test_markers_anywhere_with_drops_give_the_rod_on_the_model_grid(traj):
    """6 markers off the model nodes, no base marker, 10 % dropped frames and occlusions: the
    rod on the model's own grid (N = 10) is still close to the simulator's."""
    meas = _val(_frame(traj, noise=1e-3, markers_s=[0.07, 0.15, 0.24, 0.31, 0.4, 0.48],
                       drop_frames=0.1, occluded=0.1))
    kin = smooth_kinematics(meas, ROD, seed=0)
    assert kin.q.shape == (len(traj.t), ROD.N + 1, 3)
    rel_v, th = _kin_errors(traj, kin)
    assert rel_v < 0.3 and th < 0.03
    M = marker_matrix(meas.s, ROD)  # comparison points: the markers
    assert M.shape == (6, ROD.N + 1)
    np.testing.assert_allclose(M.sum(axis=1), 1.0)
