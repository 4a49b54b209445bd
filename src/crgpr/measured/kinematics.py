"""Rod kinematics on the model's grid from screened marker positions (GP smoothing).

1. Time: every marker's x(t) and y(t) is smoothed and differentiated by the project's GP
   (``crgpr.gp.fit_gp``: Matern-5/2 with a quadratic basis, paper Table II state GPs) on its
   own usable samples (missing and excluded samples are simply absent: the GP handles
   irregular data). The hyperparameters, shared by all markers, maximise the joint log
   marginal likelihood (R&W Sec. 2.7) of the frames where every marker is seen, on outputs in
   metres, so that sigma_n is the camera's noise.
2. Space: the chord angles psi_k between neighbouring markers (base first: a base marker,
   else the origin) and their analytic time derivatives are the mean tangent angles of the
   rod over each chord. The model's segment angles phi_j (the mid-segment angles of
   ``rod.py``, paper Sec. III-A) follow from the penalised least squares
   min |W phi - psi|^2 + lam |D2 phi|^2, W_kj = share of chord k covered by segment j, D2 the
   second difference (a cubic-spline prior on the angle): one linear operator
   S = (W^T W + lam D2^T D2)^-1 W^T, lam by generalised cross-validation pooled over frames,
   applied to psi and its rates alike (so they stay consistent). A rigidly clamped rod
   (``crgpr learn``) instead fits the nodal angles theta_i themselves, theta_0 one clamp angle
   for the record and its rates zero, with a higher-order penalty (``clamped_angle_fit``),
   or that penalty on a moment profile (``weighted_angle_fit``, an option of ``crgpr learn``).
3. The rod is rebuilt unstretched and unsheared from the base: nodal angles
   theta_i = (phi_{i-1} + phi_i) / 2 (linear extrapolation at the ends; the fitted theta_i and
   phi_j = (theta_j + theta_{j+1}) / 2 when clamped), positions
   r_i = r_b + sum_{j<i} ds nu1^0 (cos phi_j, sin phi_j), and their exact time derivatives;
   positions, velocities and accelerations are then pinned to the smoothed markers (their
   differences interpolated linearly in s), so that markers on model nodes keep their own
   GP derivatives.
The model keeps its own grid; it is compared with the data at the marker positions
(``marker_matrix``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from crgpr.measured.records import Measured
from crgpr.physics.params import RodParams


@dataclass
class Kinematics:
    """Smoothed configuration q, velocity v, acceleration a: (n_t, N+1, 3) = (x, y, theta)."""

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    noise_std_m: float  # GP noise level of the positions [m]
    base_segment_angle: np.ndarray  # phi_0(t) [rad]
    s_markers: np.ndarray  # marker arc lengths [m] (the comparison points)
    kappa_noise: np.ndarray | None = None  # clamped fit: noise sd of each segment's curvature [1/m]
    kappa_operator: np.ndarray | None = None  # clamped fit: L (N, N), rebuilt curvature = L true curvature


def segment_angles(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Chord angles (n_t, n-1) between consecutive points, unwrapped in time and along s."""
    phi = np.arctan2(np.diff(y, axis=-1), np.diff(x, axis=-1))
    phi = np.unwrap(phi, axis=0)  # continuous in time per chord
    first = np.unwrap(phi[0])  # continuous along s at the first sample
    phi += 2.0 * math.pi * np.round((first - phi[0]) / (2.0 * math.pi))
    return phi


def node_angles(phi: np.ndarray) -> np.ndarray:
    """Nodal angles from segment (mid-segment) angles; linear operator, also for rates."""
    n = phi.shape[-1]
    out = np.empty(phi.shape[:-1] + (n + 1,))
    out[..., 1:-1] = 0.5 * (phi[..., 1:] + phi[..., :-1])
    if n >= 2:
        out[..., 0] = 1.5 * phi[..., 0] - 0.5 * phi[..., 1]
        out[..., -1] = 1.5 * phi[..., -1] - 0.5 * phi[..., -2]
    else:
        out[..., 0] = out[..., -1] = phi[..., 0]
    return out


def angle_kinematics(x, y, vx, vy, ax, ay) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Chord angle psi and its first two time derivatives from point kinematics."""
    dx, dy = np.diff(x, axis=-1), np.diff(y, axis=-1)
    dvx, dvy = np.diff(vx, axis=-1), np.diff(vy, axis=-1)
    dax, day = np.diff(ax, axis=-1), np.diff(ay, axis=-1)
    r2 = dx**2 + dy**2
    phi = segment_angles(x, y)
    w = (dx * dvy - dy * dvx) / r2
    alpha = (dx * day - dy * dax) / r2 - 2.0 * w * (dx * dvx + dy * dvy) / r2
    return phi, w, alpha


def marker_matrix(s_markers: np.ndarray, params: RodParams) -> np.ndarray:
    """Linear interpolation (n_m, N+1) from nodal values to the markers (base excluded)."""
    s = np.asarray(s_markers, float)
    s = s[s > 1e-9]
    u = np.clip(s / params.ds, 0.0, params.N)
    i = np.minimum(np.floor(u).astype(int), params.N - 1)
    f = u - i
    M = np.zeros((s.size, params.N + 1))
    M[np.arange(s.size), i] = 1.0 - f
    M[np.arange(s.size), i + 1] += f
    return M


def chord_operator(s_points: np.ndarray, params: RodParams) -> np.ndarray:
    """W (n_chords, N): share of chord k (between consecutive points) covered by segment j."""
    edges = np.arange(params.N + 1) * params.ds
    a, b = s_points[:-1], s_points[1:]
    lo = np.maximum(a[:, None], edges[None, :-1])
    hi = np.minimum(b[:, None], edges[None, 1:])
    return np.maximum(hi - lo, 0.0) / (b - a)[:, None]


def _gcv_lambda(scale: float, fit) -> float | None:
    """The lam of ``scale * logspace(-8, 3, 45)`` minimising pooled GCV, mean(r^2) / dof^2, where
    ``fit(lam)`` returns the residuals r over the fitting frames and the residual degrees of
    freedom dof (n_chords - trace of the hat matrix); None if no lam leaves dof > 0."""
    best = None
    for lam in scale * np.logspace(-8, 3, 45):
        r, dof = fit(lam)
        if dof <= 1e-6:
            continue
        gcv = float(np.mean(r**2)) / dof**2
        if best is None or gcv < best[0]:
            best = (gcv, lam)
    return None if best is None else best[1]


def spatial_operator(W: np.ndarray, psi_frames: np.ndarray) -> tuple[np.ndarray, float]:
    """S = (W^T W + lam D2^T D2)^-1 W^T with lam by pooled GCV over the given frames."""
    n_seg = W.shape[1]
    D2 = np.diff(np.eye(n_seg), 2, axis=0)
    P = D2.T @ D2
    WtW = W.T @ W
    scale = np.trace(WtW) / max(np.trace(P), 1e-300)

    def fit(lam: float) -> tuple[np.ndarray, float]:
        H = W @ np.linalg.solve(WtW + lam * P, W.T)
        return psi_frames - psi_frames @ H.T, W.shape[0] - float(np.trace(H))

    lam = _gcv_lambda(scale, fit)
    if lam is None:  # as many free parameters as chords: the least-curvature interpolant
        lam = scale * 1e-8
    return np.linalg.solve(WtW + lam * P, W.T), lam


def clamped_angle_fit(W: np.ndarray, psi_frames: np.ndarray, psi_all: np.ndarray, order: int
                      ) -> tuple[np.ndarray, np.ndarray, float, float, np.ndarray]:
    """Nodal angles of a clamped rod from chord angles: operator, clamp vector, clamp angle, lam
    and the noise sd of each segment's angle difference theta_{j+1} - theta_j.

    The unknowns are the nodal angles theta_0..theta_N of the model (``rod.py``), whose
    segment j is straight at the mid-segment angle (theta_j + theta_{j+1}) / 2 (paper Sec. III-A;
    exact for an unsheared rod), so chord k sees ``W A theta`` (A the mid-segment average).
    The clamp fixes theta_0 = c in every frame, one constant for the record: per frame
    min |W A theta - psi|^2 + lam |D theta|^2 subject to theta_0 = c, D the ``order``-th
    difference along s, c minimising the sum over frames (closed form: the objective is
    quadratic in c) and lam by GCV pooled over ``psi_frames``. Order 4 penalises d2 kappa/ds2
    only: the static moment balance m'' = load makes a gravity-loaded cantilever's curvature
    quadratic in s, which order 2 (d kappa/ds, a cubic-spline prior) shrinks where it is largest,
    at the clamp (order 2 on the camera record of the training run: kappa_0 0.90x, clamp
    0.045 rad low; ``benchmarks/camera_curvature_bias.py``). Returns S
    (N, n_chords) and h (N,) with theta_1..N = S psi - h c, so that rates, whose clamp value is
    zero, are S dpsi/dt; c from ``psi_all``. The chord-angle noise variance is the pooled
    residual sum of squares over the residual degrees of freedom (``psi_all``), propagated
    through the linear operator to the differences (kappa_j's noise sd = that / ds); NaN
    where no lam leaves residual degrees of freedom (as many unknowns as chords): unknown.
    """
    n_seg = W.shape[1]
    A = 0.5 * (np.eye(n_seg, n_seg + 1) + np.eye(n_seg, n_seg + 1, 1))
    B = W @ A
    b0, B1 = B[:, 0], B[:, 1:]
    D = np.diff(np.eye(n_seg + 1), order, axis=0)
    d0, D1 = D[:, 0], D[:, 1:]
    BtB, P = B1.T @ B1, D1.T @ D1
    scale = np.trace(BtB) / max(np.trace(P), 1e-300)

    def solve(lam: float, psi: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
        M = BtB + lam * P
        S = np.linalg.solve(M, B1.T)
        h = np.linalg.solve(M, B1.T @ b0 + lam * D1.T @ d0)
        a = psi @ (B1 @ S).T - psi  # residual at c = 0, (n_t, n_chords)
        u = b0 - B1 @ h
        b = psi @ (D1 @ S).T  # penalty vector at c = 0
        w = d0 - D1 @ h
        c = -float(np.sum(a @ u) + lam * np.sum(b @ w)) / (psi.shape[0] * float(u @ u + lam * w @ w))
        return S, h, c, a + c * u

    def fit(lam: float) -> tuple[np.ndarray, float]:
        S, _, _, r = solve(lam, psi_frames)
        return r, W.shape[0] - float(np.trace(B1 @ S))

    best = _gcv_lambda(scale, fit)
    lam = scale * 1e-8 if best is None else best
    S, h, c, r = solve(lam, psi_all)
    dof = W.shape[0] - float(np.trace(B1 @ S))
    sigma_psi = math.sqrt(float(np.sum(r**2)) / (psi_all.shape[0] * dof)) if best is not None else math.nan
    Dk = np.diff(np.vstack([np.zeros((1, W.shape[0])), S]), axis=0)  # theta_{j+1} - theta_j per chord noise
    return S, h, c, lam, sigma_psi * np.sqrt(np.sum(Dk**2, axis=1))


def curvature_operator(S: np.ndarray, W: np.ndarray, ds: float) -> np.ndarray:
    """L (N, N): the clamped angle fit's rebuilt segment curvatures as a linear map of the true
    ones, kappa_hat = L kappa (for the fit's own clamp angle; ``clamped_angle_fit``).

    Nodal angles theta = c + C kappa (C the cumulative sum times ds, theta_0 = c), mid-segment
    angles A theta, chord angles W A theta; the fit returns theta_1..N = S psi - h c, and the
    constant c passes through exactly (S W A 1 - h = 1), so kappa_hat = D [0; S W A C] kappa / ds
    with D the first difference. Where the curvature's profile is not the penalty's (near the
    clamp) L is far from the identity: row 0 spreads the clamp segment's curvature over the next
    three segments on a 1 mm camera record."""
    n_seg = W.shape[1]
    A = 0.5 * (np.eye(n_seg, n_seg + 1) + np.eye(n_seg, n_seg + 1, 1))
    C = np.vstack([np.zeros((1, n_seg)), np.tril(np.ones((n_seg, n_seg)))]) * ds
    theta = np.vstack([np.zeros((1, n_seg)), S @ W @ A @ C])
    return np.diff(theta, axis=0) / ds


def weighted_angle_fit(W: np.ndarray, psi: np.ndarray, rows: np.ndarray, order: int, c: float,
                       weights: np.ndarray, centre: float, ds: float, lam: float | None = None
                       ) -> tuple[np.ndarray, np.ndarray, float]:
    """Nodal angles of a clamped rod whose smoothness prior is on a bending-moment profile: per
    frame t operator S_t and constant g_t, theta_1..N = S_t psi_t + g_t, and lam.

    ``clamped_angle_fit`` penalises the roughness of the curvature along s; the static moment
    balance makes the bending moment m(s), not the curvature, the smooth profile (m'' = load),
    and where the law is nonlinear the two differ most where the curvature is largest, at the
    clamp. Here frame t penalises the ``order - 1``-th difference along s of
    w_t * (kappa - ``centre``), with w_t (N,) the law's relative secant stiffness about
    ``centre`` at that frame's curvatures (``weights`` (n_t, N), from a first reconstruction:
    ``learning.camera``): m(kappa) - m(centre) = secant * (kappa - centre), m(centre) a
    constant that differences remove; ``ds`` the segment length. Uniform weights give
    ``clamped_angle_fit``'s penalty. theta_0 = ``c`` (the clamp angle of that fit); ``lam``
    None: by GCV pooled over the frames ``rows`` (the grid and criterion of
    ``clamped_angle_fit``). Rates take the same S_t (the weights held fixed)."""
    n_seg = W.shape[1]
    A = 0.5 * (np.eye(n_seg, n_seg + 1) + np.eye(n_seg, n_seg + 1, 1))
    B = W @ A
    b0, B1 = B[:, 0], B[:, 1:]
    BtB = B1.T @ B1
    first = np.diff(np.eye(n_seg + 1), 1, axis=0)

    def penalty(w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        D = np.diff(w[:, None] * first, order - 1, axis=0)
        e = np.diff(w * centre * ds, order - 1)  # the penalty is on D theta - e (theta differences: kappa ds)
        return D[:, 1:], e - D[:, 0] * c

    pens = [penalty(np.asarray(w, float)) for w in weights]
    scale = np.trace(BtB) / max(float(np.mean([np.sum(D1**2) for D1, _ in pens])), 1e-300)

    def solve(lam: float, t: int) -> tuple[np.ndarray, np.ndarray]:
        D1, f = pens[t]
        X = np.linalg.solve(BtB + lam * D1.T @ D1, np.c_[B1.T, lam * D1.T @ f - B1.T @ b0 * c])
        return X[:, :-1], X[:, -1]

    def fit(lam: float) -> tuple[np.ndarray, float]:
        r, dof = [], 0.0
        for t in rows:
            S, g = solve(lam, int(t))
            r.append(B1 @ (S @ psi[t] + g) + b0 * c - psi[t])
            dof += W.shape[0] - float(np.trace(B1 @ S))
        return np.array(r), dof / len(rows)

    if lam is None:
        best = _gcv_lambda(scale, fit)
        lam = scale * 1e-8 if best is None else best
    out = [solve(lam, t) for t in range(psi.shape[0])]
    return np.stack([o[0] for o in out]), np.stack([o[1] for o in out]), lam


def _time_smooth(t: np.ndarray, A: np.ndarray, noise_std_min: float, seed: int, max_points: int,
                 hyper_points: int, n_restarts: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """GP smoothing of every column of A (NaN = missing) with shared hyperparameters."""
    from crgpr.gp import fit_gp

    ok = np.isfinite(A)
    full = ok.all(axis=1)
    init = {"lengthscales": 0.2, "sigma_f": 0.1, "sigma_n": max(noise_std_min, 1e-3)}

    def pick(idx: np.ndarray) -> np.ndarray:
        if idx.size > max_points:
            idx = idx[np.unique(np.linspace(0, idx.size - 1, max_points).round().astype(int))]
        return idx

    if full.sum() >= 30:
        rows = pick(np.nonzero(full)[0])
        Yh = A[rows]
    else:  # few complete frames: the best-seen marker alone sets the hyperparameters
        j = int(np.argmax(ok.sum(axis=0)))
        rows = pick(np.nonzero(ok[:, j])[0])
        Yh = A[rows, j]
    gp = fit_gp(t[rows], Yh, kernel="matern52", basis="quadratic", standardise_y=False,
                sigma_n_min=noise_std_min or None, n_restarts=n_restarts, seed=seed, init=init,
                hyper_subset=hyper_points if rows.size > hyper_points else None, factorise=False)
    ell_phys = np.asarray(gp.lengthscales) * gp.x_scale
    m = np.empty_like(A)
    d1 = np.empty_like(A)
    d2 = np.empty_like(A)
    # markers sharing the same usable samples share one factorisation
    groups: dict[bytes, list[int]] = {}
    for j in range(A.shape[1]):
        groups.setdefault(np.packbits(ok[:, j]).tobytes(), []).append(j)
    for cols in groups.values():
        rows = pick(np.nonzero(ok[:, cols[0]])[0])
        x_scale = float(np.std(t[rows])) or 1.0
        fixed = {"sigma_f": gp.sigma_f, "lengthscales": ell_phys / x_scale, "sigma_n": gp.sigma_n}
        g = fit_gp(t[rows], A[np.ix_(rows, cols)], kernel="matern52", basis="quadratic",
                   standardise_y=False, fixed=fixed)
        a0, a1, a2 = g.predict_derivatives(t)
        shape = (t.size, len(cols))
        m[:, cols], d1[:, cols], d2[:, cols] = a0.reshape(shape), a1.reshape(shape), a2.reshape(shape)
    return m, d1, d2, float(gp.sigma_n)


def smooth_kinematics(meas: Measured, params: RodParams, noise_std_min: float = 0.0, seed: int = 0,
                      max_points: int = 1500, hyper_points: int = 120, n_restarts: int = 1,
                      spatial_fit_times: int = 40, clamp_order: int | None = None,
                      moment_weights: tuple[np.ndarray, float] | None = None) -> Kinematics:
    """q, v, a on the model grid and the measured times (module docstring, steps 1-3).

    ``clamp_order``: the base angle is one constant of the record (a rigid clamp); the nodal
    angles are then fitted directly, theta_0 shared by every frame and its rates zero, with
    this difference order penalised (``clamped_angle_fit``), instead of segment angles with
    the ends extrapolated (None: the base may turn, as in the discovery workflow).
    ``moment_weights`` (clamped only): (weights (n_t, N), centre) of ``weighted_angle_fit``, whose
    prior on the moment profile then gives the angles and rates; the clamp angle, the curvature
    noise and the operator L stay those of the curvature prior (``clamped_angle_fit``).
    """
    t = meas.t
    x, vx, ax, nx = _time_smooth(t, meas.x, noise_std_min, seed, max_points, hyper_points, n_restarts)
    y, vy, ay, ny = _time_smooth(t, meas.y, noise_std_min, seed + 1, max_points, hyper_points, n_restarts)
    s_m = meas.s
    if meas.has_base:  # a clamp does not move: the base marker's mean position
        bx, by = float(np.nanmean(meas.x[:, 0])), float(np.nanmean(meas.y[:, 0]))
        x, y = x[:, 1:], y[:, 1:]
        vx, vy, ax, ay = vx[:, 1:], vy[:, 1:], ax[:, 1:], ay[:, 1:]
        s_m = s_m[1:]
    else:
        bx = by = 0.0
    n_t = t.size
    z = np.zeros((n_t, 1))
    pts = np.r_[0.0, s_m]
    psi, dpsi, ddpsi = angle_kinematics(np.c_[z + bx, x], np.c_[z + by, y], np.c_[z, vx], np.c_[z, vy],
                                        np.c_[z, ax], np.c_[z, ay])
    W = chord_operator(pts, params)
    rows = np.unique(np.linspace(0, n_t - 1, min(spatial_fit_times, n_t)).round().astype(int))
    if clamp_order is not None:
        S, h, c, _, dth_sd = clamped_angle_fit(W, psi[rows], psi, clamp_order)
        kappa_noise = dth_sd / params.ds
        kappa_operator = curvature_operator(S, W, params.ds)
        zero_t = np.zeros((n_t, 1))
        if moment_weights is None:
            th = np.c_[zero_t + c, psi @ S.T - c * h]
            dth, ddth = np.c_[zero_t, dpsi @ S.T], np.c_[zero_t, ddpsi @ S.T]
        else:
            St, g, _ = weighted_angle_fit(W, psi, rows, clamp_order, c, moment_weights[0], moment_weights[1],
                                          params.ds)
            th = np.c_[zero_t + c, np.einsum("tjk,tk->tj", St, psi) + g]
            dth = np.c_[zero_t, np.einsum("tjk,tk->tj", St, dpsi)]
            ddth = np.c_[zero_t, np.einsum("tjk,tk->tj", St, ddpsi)]
        phi, dphi, ddphi = (0.5 * (f[:, 1:] + f[:, :-1]) for f in (th, dth, ddth))
    else:
        S, _ = spatial_operator(W, psi[rows])
        phi, dphi, ddphi = psi @ S.T, dpsi @ S.T, ddpsi @ S.T
        th, dth, ddth = node_angles(phi), node_angles(dphi), node_angles(ddphi)
        kappa_noise = kappa_operator = None
    seg = params.ds * params.nu1_0
    c, s = np.cos(phi), np.sin(phi)
    zero = np.zeros((n_t, params.N + 1))

    def integrate(dx: np.ndarray, dy: np.ndarray, x0: float = 0.0, y0: float = 0.0):
        X, Y = zero.copy(), zero.copy()
        X[:, 0], Y[:, 0] = x0, y0
        X[:, 1:] = x0 + np.cumsum(seg * dx, axis=1)
        Y[:, 1:] = y0 + np.cumsum(seg * dy, axis=1)
        return X, Y

    qx, qy = integrate(c, s, bx, by)
    vxm, vym = integrate(-s * dphi, c * dphi)
    axm, aym = integrate(-c * dphi**2 - s * ddphi, -s * dphi**2 + c * ddphi)
    # pin the rebuilt rod to the smoothed markers: add the markers' differences, linear in
    # s between them (0 at the base, constant beyond the last marker); where the markers are
    # the model's nodes the translational kinematics are the markers' own GP derivatives
    E = np.stack([np.interp(params.s, s_m, col) for col in np.eye(s_m.size)], axis=1)
    E[params.s < s_m[0]] *= (params.s[params.s < s_m[0]] / s_m[0])[:, None]
    Mk = marker_matrix(s_m, params)
    qx, qy = qx + (x - qx @ Mk.T) @ E.T, qy + (y - qy @ Mk.T) @ E.T
    vxm, vym = vxm + (vx - vxm @ Mk.T) @ E.T, vym + (vy - vym @ Mk.T) @ E.T
    axm, aym = axm + (ax - axm @ Mk.T) @ E.T, aym + (ay - aym @ Mk.T) @ E.T
    q = np.stack([qx, qy, th], axis=-1)
    v = np.stack([vxm, vym, dth], axis=-1)
    a = np.stack([axm, aym, ddth], axis=-1)
    return Kinematics(t, q, v, a, 0.5 * (nx + ny), phi[:, 0].copy(), s_m.copy(), kappa_noise, kappa_operator)


def marker_positions(q: np.ndarray, s_markers: np.ndarray, params: RodParams) -> np.ndarray:
    """Positions (n_t, n_m, 2) of points at arc lengths s on rods q (n_t, N+1, 3).

    Linear along each segment (exact for an unstretched rod: the segment is straight)."""
    u = np.clip(np.asarray(s_markers, float) / params.ds, 0.0, params.N)
    i = np.minimum(np.floor(u).astype(int), params.N - 1)
    f = (u - i)[None, :, None]
    return (1.0 - f) * q[:, i, :2] + f * q[:, i + 1, :2]
