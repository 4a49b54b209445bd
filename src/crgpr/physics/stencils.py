"""The segment stencil shared by the compiled elastic kernels (``rod``, ``collocated``,
``kernels``): slopes, mid-segment angle and strains of segment j (paper Sec. III-A, eq. (9);
``rod`` module docstring)."""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True)
def _segment_strains(q, j, ds):
    """Segment j's slopes x'_j, y'_j, cos and sin of its mid-segment angle theta_bar_j, and its
    stretch nu1_j and shear nu2_j (module docstring): the strains every elastic kernel shares."""
    ex = (q[j + 1, 0] - q[j, 0]) / ds
    ey = (q[j + 1, 1] - q[j, 1]) / ds
    tb = 0.5 * (q[j, 2] + q[j + 1, 2])
    c = math.cos(tb)
    s = math.sin(tb)
    return ex, ey, c, s, c * ex + s * ey, -s * ex + c * ey
