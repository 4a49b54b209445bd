"""Step 2 of the workflow, the floor: the gap the model shows with nothing missing.

Camera noise and initial-state uncertainty (``noise_floor``, a parametric bootstrap) and the
model's own discretisation error (``discretisation_error``, Richardson on a grid twice as fine
with half the step) and a model-form difference the data may contain (``model_form_error``,
the clamp's form), added in quadrature by the workflow.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from crgpr.discovery.settings import DiscoverySettings
from crgpr.discovery.synthetic import aligned_settings
from crgpr.discovery.trajectory import TrajectoryFitter, augmented_params
from crgpr.measured.kinematics import Kinematics, marker_positions, smooth_kinematics
from crgpr.measured.records import Measured
from crgpr.physics.integrator import SimulationDiverged
from crgpr.physics.params import RodParams


def noise_floor(q_model: np.ndarray, meas: Measured, kin: Kinematics, params: RodParams, dt_max: float,
                st: DiscoverySettings) -> float:
    """Gap the nominal model would show from camera noise and initial-state uncertainty.

    Parametric bootstrap: the nominal trajectory re-measured at the same markers with the
    GP's noise estimate and the same missing samples, smoothed, and the nominal model fitted
    exactly as to the data (``TrajectoryFitter.fit``); the RMS of the resulting theta gaps.
    """
    rng = np.random.default_rng(st.seed + 99)
    valid = meas.valid
    pos = marker_positions(q_model, meas.s, params)
    gaps = []
    for r in range(st.bootstrap_replicates):
        noisy = pos + kin.noise_std_m * rng.standard_normal(pos.shape)
        x = np.where(valid, noisy[..., 0], np.nan)
        y = np.where(valid, noisy[..., 1], np.nan)
        mb = Measured(meas.t, meas.s, x, y, "bootstrap", meas.missing_fraction, np.zeros_like(valid))
        kin_b = smooth_kinematics(mb, params, seed=st.seed + 100 + r, max_points=st.gp_max_points)
        fb = TrajectoryFitter(params, kin_b, dt_max, n_modes=st.init_modes, window_s=st.init_window_s)
        gaps.append(fb.fit([], np.zeros(0), np.zeros(0), st.refine_max_nfev).rmse)
    return float(np.sqrt(np.mean(np.square(gaps)))) if gaps else 0.0


def discretisation_error(fitter: TrajectoryFitter, dt_max: float, names: tuple[str, ...] = (),
                         coef: np.ndarray | None = None, c0: np.ndarray | None = None,
                         degree: int = 5) -> float:
    """Estimated theta error of the model's own discretisation (grid and time step), as it
    shows in the gap after fitting [rad].

    The model (``names``, ``coef``) is fitted to the measured theta at the markers twice: on
    its grid N with its time step, and on a grid 2N with half that step, each with its own
    initial state: the same smooth base state (the measured nodal angles and rates at the
    first sample projected on polynomials of ``degree`` in s, so that camera noise does not
    excite grid-dependent high modes) and its own initial-state corrections fitted over the
    whole record (coefficients fixed, start ``c0``, e.g. the model's fitted corrections).
    The difference of the two fitted trajectories is what refining the discretisation changes
    in the best fit; for a scheme of second order in space and time (variational
    discretisation, Strang-split Verlet) e ~ (4/3) |q_(N,dt) - q_(2N,dt/2)| (Richardson). Both
    grids see the same data, so an initial rate that a fit invented to mimic a missing effect
    is not propagated into the estimate (one fitted state run on both grids gave 6-10x the
    error from the exact release on tip mass plus drag). The time step matters where the
    model is stiff (Kelvin-Voigt damping, full config: 0.0078 rad with the step halved,
    0.0025 with the grid alone; 0.0077 from the noise-free data-generating simulation)."""
    coef = np.zeros(0) if coef is None else np.asarray(coef, float)
    c0 = np.zeros(2 * fitter.n_modes) if c0 is None else np.asarray(c0, float)
    s = fitter.params.s
    deg = min(degree, fitter.params.N - 1)
    th = np.polynomial.Polynomial.fit(s, fitter.theta, deg)
    om = np.polynomial.Polynomial.fit(s, fitter.omega, deg)
    runs = []
    dt_model = aligned_settings(augmented_params(fitter.params, list(names), coef), dt_max, fitter.period,
                                fitter.n).dt
    for n_grid, dt_grid in ((fitter.params.N, dt_max), (2 * fitter.params.N, 0.5 * dt_model)):
        grid = fitter.params.replace(N=n_grid)
        g = fitter.on_grid(grid, th(grid.s), om(grid.s), dt_grid)
        try:
            c = g._window_fit(list(names), coef, c0, n=fitter.n)
            runs.append(g.simulate(list(names), coef, c)[..., 2] @ g.M.T)
        except SimulationDiverged:
            return 0.0
    return float(4.0 / 3.0 * np.sqrt(np.mean((runs[0] - runs[1]) ** 2)))


def model_form_error(fitter: TrajectoryFitter, dt_max: float, clamp_m: float, clamp_factor: float,
                     c0: np.ndarray | None = None, degree: int = 5) -> float:
    """Theta error [rad] a model-form difference the data may contain shows in the gap: the
    clamp's form. The nominal model on a grid 2N (half the step) is fitted to the measured
    theta as in ``discretisation_error``, once as it is and once with the rod's first
    ``clamp_m`` ``clamp_factor`` times stiffer (a clamp of finite length, which a user's rig, or
    another simulator's rigid first element, has and the model's point clamp does not; through
    ``rod.material``'s defect law, on whole segments of the 2N grid); the RMS difference of the
    two fitted trajectories at the markers (0 for ``clamp_factor`` 1). Our own N -> 2N
    refinement alone cannot show it: both grids share the point clamp."""
    if clamp_factor == 1.0:  # no other clamp form: no model-form part
        return 0.0
    c0 = np.zeros(2 * fitter.n_modes) if c0 is None else np.asarray(c0, float)
    s = fitter.params.s
    deg = min(degree, fitter.params.N - 1)
    th = np.polynomial.Polynomial.fit(s, fitter.theta, deg)
    om = np.polynomial.Polynomial.fit(s, fitter.omega, deg)
    fine = fitter.params.replace(N=2 * fitter.params.N)
    seg = max(1, int(round(clamp_m / fine.ds)))  # whole segments of the fine grid
    clamped = fine.replace(material=dataclasses.replace(
        fine.material, defect_start=0.0, defect_end=seg / fine.N, defect_factor=clamp_factor,
        defect_edge=0.1 / fine.N))
    dt_fine = 0.5 * aligned_settings(fitter.params, dt_max, fitter.period, fitter.n).dt
    runs = []
    for grid in (fine, clamped):
        dt_grid = min(dt_fine, aligned_settings(grid, dt_fine, fitter.period, fitter.n).dt)
        g = fitter.on_grid(grid, th(grid.s), om(grid.s), dt_grid)
        try:
            c = g._window_fit([], np.zeros(0), c0, n=fitter.n)
            runs.append(g.simulate([], np.zeros(0), c)[..., 2] @ g.M.T)
        except SimulationDiverged:
            return 0.0
    return float(np.sqrt(np.mean((runs[0] - runs[1]) ** 2)))
