"""PINN baselines (paper Sec. V, "Baseline Comparisons"): physics-only and data-assisted.

A fully connected network maps (t, s, theta0) to the full state
z = [x, y, theta, p_x, p_y, p_theta] of the planar Cosserat rod. It is trained on the
residual of eq. (9) (Sec. III-A),

    dz/dt = (J - R) H_z(z) + G u,        G u = [0, 0, 0, 0, -rho A g, 0],

with the continuous stress resultants n_1 = EA (nu1 - nu1^0), n_2 = GA (nu2 - nu2^0),
m = EI (kappa - kappa^0) and the variationally correct sign of the couple
(dH/dtheta = -d_s m - (nu1 n_2 - nu2 n_1); see ``crgpr.physics.rod``: the paper's sign is a typo),
plus the free-tip conditions n_1 = n_2 = m = 0 at s = L0. The data-assisted variants add a
mean-squared error on ground-truth samples (N_init = 1: 85 deg; N_init = 8: config
``angles.pinn_train_deg``).

Non-dimensionalisation (all loss terms O(1)): length L0, time T = sqrt(L0 / g), force
F0 = rho A g L0, translational momentum rho A L0 / T, angular momentum rho I / T, moment
F0 L0. With these the momentum rows read

    d_t p_x = d_s q_x - zeta_t p_x,      d_t p_y = d_s q_y - 1 - zeta_t p_y,
    eps d_t p_th = d_s m + (nu1 n_2 - nu2 n_1) - zeta_r p_th,

with zeta_t = zeta T / (rho A), zeta_r = zeta / (T F0), eps = rho I / (rho A L0^2) and the
force / moment coefficients EA / F0, GA / F0, EI / (F0 L0^2).

Loss = w_kin * mean(rows 1-3^2) + w_mom * mean(rows 4-6^2) + w_tip * mean(tip^2)
       + w_data * MSE(z / std(z_data)).
The momentum rows and the tip forces amplify a strain error by EA / F0 (about 600 for the
paper's rod), so a network that fits the data but whose x, y are not yet consistent with theta
to 1e-3 has a momentum loss 1e5-1e6 times its data loss. With O(1) weights the data-assisted
PINNs collapse to the stationary rod (measured: RMS(theta - theta0) ~ 1e-3 rad); the config
therefore weights rows 4-6 and the tip by (F0 / EA)^2 ~ 3e-6, i.e. measures them in strain
units. (Adam is invariant to a common scale of the loss; for the physics-only variant only the
balance between the kinematic and the momentum rows changes.)

Hard constraints (our choice, the paper gives no architecture): with sigma = s / L0 and
phi(t) = 1 - exp(-t / T),

    x = L0 sigma cos(theta0) + sigma phi N_x,   y likewise,   theta = theta0 + sigma phi N_theta,
    p = sigma phi N_p,

so the clamped base (x = y = 0, theta = theta0, p = 0 at s = 0) and the initial straight rod
at rest hold exactly; the free-tip conditions are a soft loss. theta0 enters the network as
(cos theta0, sin theta0) and time additionally through a few Fourier features of t / t_end.
Physics collocation points sample t in [0, t_end], s in [0, L0] and theta0 uniformly in
[0, 360) deg for every variant (the physics loss is what could make a PINN extrapolate).
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import torch
from torch import nn

from crgpr.config import ConfigError, rod_params
from crgpr.io import read_parquet
from crgpr.physics.params import RodParams
from crgpr.physics.rod import STATE_NAMES
from crgpr.physics.simulate import TRAJECTORY_COLUMNS
from crgpr.seeds import pinn_seed

log = logging.getLogger(__name__)

STATE = STATE_NAMES
VARIANTS: dict[str, str] = {
    "pinn_physics": "physics only, no data",
    "pinn_data_1": "data-assisted, N_init = 1 (angles.train_deg)",
    "pinn_data_8": "data-assisted, N_init = 8 (angles.pinn_train_deg)",
}
ACTIVATIONS = ("tanh", "sin")


# --------------------------------------------------------------------------------------
# scales and the physics residual of eq. (9), Sec. III-A
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Scales:
    """Reference scales and non-dimensional coefficients of eq. (9) (Sec. III-A)."""

    L: float  # length scale L0 [m]
    T: float  # time scale sqrt(L0 / g) [s]
    F0: float  # force scale rho A g L0 [N]
    P_t: float  # translational momentum-per-length scale rho A L0 / T [kg/s]
    P_r: float  # angular momentum-per-length scale rho I / T [kg m / s]
    a: float  # EA / F0
    b: float  # GA / F0
    beta: float  # EI / (F0 L0^2)
    eps: float  # rho I / (rho A L0^2)
    zeta_t: float  # zeta T / (rho A)
    zeta_r: float  # zeta / (T F0)
    nu1_0: float
    nu2_0: float
    kappa0_L: float  # kappa0 L0

    @classmethod
    def from_params(cls, p: RodParams) -> Scales:
        if p.g <= 0:
            raise ConfigError("rod.g must be > 0 for the PINN's time scale sqrt(L0 / g)")
        T = math.sqrt(p.L0 / p.g)
        F0 = p.rhoA * p.g * p.L0
        return cls(L=p.L0, T=T, F0=F0, P_t=p.rhoA * p.L0 / T, P_r=p.rhoI / T, a=p.EA / F0,
                   b=p.GA / F0, beta=p.EI / (F0 * p.L0**2), eps=p.rhoI / (p.rhoA * p.L0**2),
                   zeta_t=p.zeta * T / p.rhoA, zeta_r=p.zeta / (T * F0), nu1_0=p.nu1_0,
                   nu2_0=p.nu2_0, kappa0_L=p.kappa0 * p.L0)

    def state_scale(self) -> np.ndarray:
        """Multiply a non-dimensional state by this to get SI units (x, y, theta, p_x, p_y, p_th)."""
        return np.array([self.L, self.L, 1.0, self.P_t, self.P_t, self.P_r])


def stress_resultants(z: torch.Tensor, z_s: torch.Tensor, sc: Scales) -> dict[str, torch.Tensor]:
    """Strains and non-dimensional stress resultants from the state and its s-derivative."""
    th = z[..., 2]
    c, s = torch.cos(th), torch.sin(th)
    xs, ys = z_s[..., 0], z_s[..., 1]
    nu1 = c * xs + s * ys
    nu2 = -s * xs + c * ys
    n1 = sc.a * (nu1 - sc.nu1_0)
    n2 = sc.b * (nu2 - sc.nu2_0)
    m = sc.beta * (z_s[..., 2] - sc.kappa0_L)
    return {"nu1": nu1, "nu2": nu2, "n1": n1, "n2": n2, "m": m,
            "q_x": n1 * c - n2 * s, "q_y": n1 * s + n2 * c}


def ph_residual(z: torch.Tensor, z_t: torch.Tensor, z_s: torch.Tensor, z_ss: torch.Tensor,
                sc: Scales) -> torch.Tensor:
    """Residual dz/dt - (J - R) H_z - G u of eq. (9) (Sec. III-A), non-dimensional, (..., 6).

    ``z`` (..., 6) is the non-dimensional state, ``z_t`` its derivative in t / T, ``z_s`` and
    ``z_ss`` (..., >= 3) the first and second derivatives of (x, y, theta) in s / L0. The
    s-derivatives of q_x, q_y and m are expanded by the chain rule. Rows 1-3 are the
    kinematic rows d_t q = p / mass, rows 4-6 the balance of linear and angular momentum.
    """
    th = z[..., 2]
    c, s = torch.cos(th), torch.sin(th)
    xs, ys, ths = z_s[..., 0], z_s[..., 1], z_s[..., 2]
    xss, yss, thss = z_ss[..., 0], z_ss[..., 1], z_ss[..., 2]
    nu1 = c * xs + s * ys
    nu2 = -s * xs + c * ys
    nu1_s = c * xss + s * yss + ths * nu2
    nu2_s = -s * xss + c * yss - ths * nu1
    n1 = sc.a * (nu1 - sc.nu1_0)
    n2 = sc.b * (nu2 - sc.nu2_0)
    n1_s, n2_s = sc.a * nu1_s, sc.b * nu2_s
    qx_s = n1_s * c - n2_s * s - ths * (n1 * s + n2 * c)
    qy_s = n1_s * s + n2_s * c + ths * (n1 * c - n2 * s)
    m_s = sc.beta * thss
    couple = nu1 * n2 - nu2 * n1
    px, py, pth = z[..., 3], z[..., 4], z[..., 5]
    return torch.stack([
        z_t[..., 0] - px,
        z_t[..., 1] - py,
        z_t[..., 2] - pth,
        z_t[..., 3] - qx_s + sc.zeta_t * px,
        z_t[..., 4] - qy_s + 1.0 + sc.zeta_t * py,
        sc.eps * z_t[..., 5] - m_s - couple + sc.zeta_r * pth,
    ], dim=-1)


def tip_residual(z: torch.Tensor, z_s: torch.Tensor, sc: Scales) -> torch.Tensor:
    """Free-tip conditions n_1 = n_2 = 0 (in F0) and m = 0 (as kappa L0 - kappa0 L0), (..., 3)."""
    r = stress_resultants(z, z_s, sc)
    return torch.stack([r["n1"], r["n2"], z_s[..., 2] - sc.kappa0_L], dim=-1)


# --------------------------------------------------------------------------------------
# network
# --------------------------------------------------------------------------------------
class PINN(nn.Module):
    """MLP (t, s, theta0) -> z (non-dimensional) with the hard constraints of the module doc.

    ``forward`` gives z; ``forward_derivatives`` propagates dz/dt, dz/ds and d2z/ds2 through
    the layers in closed form (forward-mode, one stacked matmul per layer), which is several
    times cheaper than nested reverse-mode autograd for a 4-input network.
    """

    def __init__(self, width: int, depth: int, activation: str, n_fourier: int, t_end_nd: float):
        super().__init__()
        if activation not in ACTIVATIONS:
            raise ConfigError(f"baselines.pinn.activation = {activation!r}; use one of {sorted(ACTIVATIONS)}")
        self.activation = activation
        self.t_end_nd = float(t_end_nd)
        self.register_buffer("freqs", math.pi * torch.arange(1, n_fourier + 1, dtype=torch.float32))
        n_in = 4 + 2 * n_fourier
        self.layers = nn.ModuleList(nn.Linear(n_in if i == 0 else width, width) for i in range(depth))
        self.head = nn.Linear(width, 6)
        for lin in [*self.layers, self.head]:
            nn.init.xavier_normal_(lin.weight)
            nn.init.zeros_(lin.bias)

    def _features(self, t: torch.Tensor, s: torch.Tensor, th0: torch.Tensor):
        """Input features and their t-derivatives (the s-derivative is 2 on feature 1 only)."""
        tau = t / self.t_end_nd
        arg = tau[:, None] * self.freqs[None, :]
        sn, cs = torch.sin(arg), torch.cos(arg)
        f = torch.cat([torch.stack([2.0 * tau - 1.0, 2.0 * s - 1.0, torch.cos(th0), torch.sin(th0)], 1),
                       sn, cs], 1)
        w = self.freqs[None, :] / self.t_end_nd
        f_t = torch.cat([torch.full_like(f[:, :1], 2.0 / self.t_end_nd), torch.zeros_like(f[:, :3]),
                         w * cs, -w * sn], 1)
        return f, f_t

    def _act(self, a: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Activation value, first and second derivative."""
        if self.activation == "tanh":
            h = torch.tanh(a)
            d1 = 1.0 - h * h
            return h, d1, -2.0 * h * d1
        h = torch.sin(a)
        return h, torch.cos(a), -h

    def _constrain(self, t, s, th0, out):
        gate_t = s * torch.exp(-t)
        phi = 1.0 - torch.exp(-t)
        gate = s * phi
        base = torch.stack([s * torch.cos(th0), s * torch.sin(th0), th0, torch.zeros_like(s),
                            torch.zeros_like(s), torch.zeros_like(s)], 1)
        return base, gate[:, None], gate_t[:, None], phi[:, None]

    def forward(self, t: torch.Tensor, s: torch.Tensor, th0: torch.Tensor) -> torch.Tensor:
        """t = time / T, s = arc length / L0, th0 [rad], each (n,); returns z (n, 6)."""
        h, _ = self._features(t, s, th0)
        for lin in self.layers:
            h = self._act(lin(h))[0]
        out = self.head(h)
        base, gate, _, _ = self._constrain(t, s, th0, out)
        return base + gate * out

    def forward_derivatives(self, t: torch.Tensor, s: torch.Tensor, th0: torch.Tensor
                            ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """z, dz/dt, dz/ds, d2z/ds2 (each (n, 6)) in the non-dimensional variables."""
        n = t.shape[0]
        h, h_t = self._features(t, s, th0)
        h_s = torch.zeros_like(h)
        h_s[:, 1] = 2.0
        h_ss = torch.zeros_like(h)
        for lin in self.layers:
            a = lin(h)
            da = torch.cat([h_t, h_s, h_ss], 0) @ lin.weight.T
            a_t, a_s, a_ss = da[:n], da[n:2 * n], da[2 * n:]
            h, d1, d2 = self._act(a)
            h_t, h_s, h_ss = d1 * a_t, d1 * a_s, d1 * a_ss + d2 * a_s * a_s
        out = self.head(h)
        dout = torch.cat([h_t, h_s, h_ss], 0) @ self.head.weight.T
        o_t, o_s, o_ss = dout[:n], dout[n:2 * n], dout[2 * n:]
        base, gate, gate_t, phi = self._constrain(t, s, th0, out)
        base_s = torch.zeros_like(base)
        base_s[:, 0] = torch.cos(th0)
        base_s[:, 1] = torch.sin(th0)
        z = base + gate * out
        z_t = gate_t * out + gate * o_t
        z_s = base_s + phi * out + gate * o_s
        z_ss = 2.0 * phi * o_s + gate * o_ss
        return z, z_t, z_s, z_ss


def derivatives(model: PINN, t: torch.Tensor, s: torch.Tensor, th0: torch.Tensor,
                create_graph: bool = True) -> tuple[torch.Tensor, ...]:
    """z, dz/dt, dz/ds and d2z/ds2 of the network by nested reverse-mode autograd (reference
    implementation for tests; training uses ``PINN.forward_derivatives``)."""
    t = t.detach().requires_grad_(True)
    s = s.detach().requires_grad_(True)
    z = model(t, s, th0)
    z_t, z_s, z_ss = [], [], []
    for k in range(6):
        gt, gs = torch.autograd.grad(z[:, k].sum(), (t, s), create_graph=True)
        z_t.append(gt)
        z_s.append(gs)
    for k in range(6):
        (gss,) = torch.autograd.grad(z_s[k].sum(), (s,), create_graph=create_graph, retain_graph=True)
        z_ss.append(gss)
    return z, torch.stack(z_t, 1), torch.stack(z_s, 1), torch.stack(z_ss, 1)


# --------------------------------------------------------------------------------------
# training
# --------------------------------------------------------------------------------------
def pinn_settings(cfg: dict[str, Any]) -> dict[str, Any]:
    try:
        return dict(cfg["baselines"]["pinn"])
    except KeyError as exc:
        raise ConfigError("config: missing section baselines.pinn") from exc


def variant_angles(cfg: dict[str, Any], variant: str) -> list[int]:
    """Training angles [deg] of a PINN variant (empty for the physics-only one)."""
    if variant not in VARIANTS:
        raise ConfigError(f"unknown PINN variant {variant!r}; known: {sorted(VARIANTS)}")
    if variant == "pinn_physics":
        return []
    if variant == "pinn_data_1":
        return [int(cfg["angles"]["train_deg"])]
    return [int(a) for a in cfg["angles"]["pinn_train_deg"]]


def variant_seed(cfg: dict[str, Any], variant: str) -> int:
    """Seed of one variant, derived from the global seed and the variant name."""
    return pinn_seed(cfg["seed"], variant)


def load_training_data(paths: dict[int, str], sc: Scales) -> tuple[np.ndarray, np.ndarray]:
    """Ground-truth samples as inputs (t/T, s/L0, theta0 [rad]) and non-dimensional z (n, 6).

    The clamped base node is left out (the hard constraint fixes it).
    """
    X, Z = [], []
    cols = ("theta0_deg", "t", "node", "s", *STATE)
    for angle, path in sorted(paths.items()):
        df = read_parquet(path, required=cols)
        df = df[df["node"] > 0]
        th0 = np.full(len(df), math.radians(angle))
        X.append(np.stack([df["t"].to_numpy() / sc.T, df["s"].to_numpy() / sc.L, th0], 1))
        Z.append(df[list(STATE)].to_numpy() / sc.state_scale())
    if not X:
        return np.zeros((0, 3)), np.zeros((0, 6))
    return np.concatenate(X), np.concatenate(Z)


def train_pinn(cfg: dict[str, Any], variant: str, data_paths: dict[int, str],
               threads: int = 1) -> tuple[PINN, pd.DataFrame, dict[str, Any]]:
    """Train one PINN variant; returns the model, the loss history and run information."""
    ps = pinn_settings(cfg)
    params = rod_params(cfg)
    sc = Scales.from_params(params)
    angles = variant_angles(cfg, variant)
    missing = sorted(set(angles) - set(data_paths))
    if missing:
        raise ConfigError(f"{variant}: no ground-truth file given for angle(s) {missing}")
    seed = variant_seed(cfg, variant)
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    torch.set_num_threads(max(1, int(threads)))
    t_end_nd = float(cfg["simulation"]["t_end_s"]) / sc.T
    model = PINN(int(ps["width"]), int(ps["depth"]), str(ps["activation"]),
                 int(ps["fourier_features"]), t_end_nd)
    X, Z = load_training_data({a: data_paths[a] for a in angles}, sc)
    z_std = Z.std(axis=0) if len(Z) else np.ones(6)
    z_std = np.where(z_std > 0, z_std, 1.0)
    Xt = torch.tensor(X, dtype=torch.float32)
    Zt = torch.tensor(Z / z_std, dtype=torch.float32)
    z_std_t = torch.tensor(z_std, dtype=torch.float32)
    w = ps["loss_weights"]
    w_kin, w_mom, w_tip, w_data = (float(w["kinematic"]), float(w["momentum"]), float(w["tip_bc"]),
                                   float(w["data"]))
    use_data = len(angles) > 0
    warmup = float(ps["physics_warmup"])
    n_it = int(ps["iterations"])
    opt = torch.optim.Adam(model.parameters(), lr=float(ps["learning_rate"]))
    gamma = (float(ps["learning_rate_final"]) / float(ps["learning_rate"])) ** (1.0 / max(1, n_it))
    sched = torch.optim.lr_scheduler.ExponentialLR(opt, gamma)
    n_col, n_tip, n_dat = int(ps["collocation_points"]), int(ps["tip_points"]), int(ps["data_batch"])
    gen = torch.Generator().manual_seed(seed)
    hist: list[dict[str, float]] = []
    every = int(ps["log_every"])
    t0 = time.perf_counter()
    for it in range(1, n_it + 1):
        tc = torch.rand(n_col, generator=gen) * t_end_nd
        scol = torch.rand(n_col, generator=gen)
        thc = torch.rand(n_col, generator=gen) * (2 * math.pi)
        z, z_t, z_s, z_ss = model.forward_derivatives(tc, scol, thc)
        r = ph_residual(z, z_t, z_s, z_ss, sc)
        rms = (r**2).mean(0)
        l_kin, l_mom = rms[:3].sum(), rms[3:].sum()
        tt = torch.rand(n_tip, generator=gen) * t_end_nd
        tht = torch.rand(n_tip, generator=gen) * (2 * math.pi)
        zt_, _, zs_tip, _ = model.forward_derivatives(tt, torch.ones(n_tip), tht)
        l_tip = (tip_residual(zt_, zs_tip, sc) ** 2).mean(0).sum()
        ramp = min(1.0, it / (warmup * n_it)) if (use_data and warmup > 0) else 1.0
        loss = ramp * (w_kin * l_kin + w_mom * l_mom + w_tip * l_tip)
        l_dat = torch.zeros(())
        if use_data:
            idx = torch.from_numpy(rng.integers(0, len(Xt), n_dat))
            xb = Xt[idx]
            pred = model(xb[:, 0], xb[:, 1], xb[:, 2]) / z_std_t
            l_dat = ((pred - Zt[idx]) ** 2).mean()
            loss = loss + w_data * l_dat
        opt.zero_grad(set_to_none=True)
        loss.backward()
        if float(ps["grad_clip"]) > 0.0:  # 0 = off (schema)
            nn.utils.clip_grad_norm_(model.parameters(), float(ps["grad_clip"]))
        opt.step()
        sched.step()
        if not torch.isfinite(loss):
            raise RuntimeError(f"{variant}: loss became non-finite at iteration {it}")
        if it % every == 0 or it == 1 or it == n_it:
            row = {"iteration": it, "wall_s": time.perf_counter() - t0, "lr": opt.param_groups[0]["lr"],
                   "physics_ramp": ramp,
                   "loss": loss.item(), "loss_kinematic": l_kin.item(), "loss_momentum": l_mom.item(),
                   "loss_tip_bc": l_tip.item(), "loss_data": l_dat.item()}
            row.update({f"res_rms_{n}": v.sqrt().item() for n, v in zip(STATE, rms, strict=True)})
            hist.append(row)
            if it % (every * 10) == 0 or it == n_it:
                log.info("%s it %d: loss %.4g (kin %.3g mom %.3g tip %.3g data %.3g) %.1f s", variant, it,
                         row["loss"], row["loss_kinematic"], row["loss_momentum"], row["loss_tip_bc"],
                         row["loss_data"], row["wall_s"])
    info = {"variant": variant, "seed": seed, "angles_deg": angles, "n_data": int(len(X)),
            "train_seconds": time.perf_counter() - t0, "threads": int(threads), "scales": vars(sc),
            "settings": ps, "z_std": z_std.tolist()}
    return model, pd.DataFrame(hist), info


def build_model(cfg: dict[str, Any]) -> PINN:
    ps = pinn_settings(cfg)
    sc = Scales.from_params(rod_params(cfg))
    return PINN(int(ps["width"]), int(ps["depth"]), str(ps["activation"]), int(ps["fourier_features"]),
                float(cfg["simulation"]["t_end_s"]) / sc.T)


def load_model(cfg: dict[str, Any], path: str | Path) -> PINN:
    """Rebuild the network from the config and load its state dict (weights_only=True)."""
    model = build_model(cfg)
    state = torch.load(path, map_location="cpu", weights_only=True)
    try:
        model.load_state_dict(state)
    except RuntimeError as exc:
        raise ConfigError(f"{path}: weights do not match baselines.pinn (width/depth/"
                          f"fourier_features changed since training?): {exc}") from exc
    model.eval()
    return model


def predict(model: PINN, params: RodParams, theta0_deg: float, t: np.ndarray,
            chunk: int = 65536) -> np.ndarray:
    """Network state in SI units on the grid t x nodes, (n_t, N+1, 6)."""
    sc = Scales.from_params(params)
    s = params.s
    tt, ss = np.meshgrid(t / sc.T, s / sc.L, indexing="ij")
    tt, ss = tt.ravel(), ss.ravel()
    th = np.full(tt.shape, math.radians(theta0_deg))
    out = np.empty((len(tt), 6))
    with torch.no_grad():
        for i in range(0, len(tt), chunk):
            sl = slice(i, i + chunk)
            z = model(torch.tensor(tt[sl], dtype=torch.float32), torch.tensor(ss[sl], dtype=torch.float32),
                      torch.tensor(th[sl], dtype=torch.float32))
            out[sl] = z.double().numpy()
    return (out * sc.state_scale()).reshape(len(t), len(s), 6)


def prediction_frame(z: np.ndarray, t: np.ndarray, params: RodParams, theta0_deg: float) -> pd.DataFrame:
    """Predicted states in the ground-truth schema (TRAJECTORY_COLUMNS)."""
    n_t, n_nodes, _ = z.shape
    df = pd.DataFrame({
        "theta0_deg": np.full(n_t * n_nodes, float(theta0_deg)),
        "t": np.repeat(t, n_nodes),
        "node": np.tile(np.arange(n_nodes, dtype=np.int32), n_t),
        "s": np.tile(params.s, n_t),
    })
    for k, name in enumerate(STATE):
        df[name] = z[..., k].ravel()
    return df[list(TRAJECTORY_COLUMNS)]
