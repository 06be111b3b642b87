"""Group configurations and the discrete-agent comparison metric (Lai, Chenney and Fan 2005,
sections 4.1-4.2).

Configuration frame (4.1): origin ``O_c = mean_i x_i`` (the centroid), x axis along the mean
velocity ``X_c = mean_i v_i``; in 3D the roll is fixed by the world up direction,
``Y_c = up x X_c`` (normalised) and ``Z_c = X_c x Y_c``.

Distance (4.2)::

    E(A, B) = min_{M, X} 1/N sum_i |x_i(A) - X x_{M(i)}(B)|^2

over one-to-one correspondences ``M = M_{B<-A}`` (``perm[i]`` = the slot of B that agent ``i``
of A moves to) and rigid motions ``X = X_{A<-B}``. It is minimised by alternation: the
Kuhn-Munkres assignment (``scipy.optimize.linear_sum_assignment``) for ``M`` with ``X`` fixed,
then the closed-form best alignment for ``X`` with ``M`` fixed, starting from the transform
that aligns the two configuration frames, until the distance stops falling. Each half step
minimises over its variable with the other fixed, so the sequence never increases.

The rigid motions allowed are those that keep world up: a rotation about +Y (yaw) and a
translation. In 2D (the ground plane, coordinates ``(x, z)``) that is every rigid motion; in 3D
it is the group under which the paper's configuration frame (roll fixed by world up) is
equivariant, so the metric is exactly invariant to it, and playing a clip after a transition
never tilts or rolls the flock. For a fixed matching the best translation aligns the
centroids and the best yaw is ``atan2(sum a_x b_z - a_z b_x, sum a_x b_x + a_z b_z)`` over the
centred, matched points. The configuration-frame start uses the same restriction: centroids
aligned and the horizontal headings of the mean velocities aligned.

Velocity term (``velocity_weight`` w, seconds): each agent's cost also gets
``w^2 |v_i(A) - R v_{M(i)}(B)|^2``. The paper's Figure 2 calls two groups similar only when the
agents are arranged the same way *with respect to the group's velocity*; with positions alone a
free rotation would also match a group to a copy of itself flying sideways. ``w = 0`` is the
paper's position-only formula; the DDG builder uses ``w = 0.5 s`` (a velocity error of 1 m/s
counts like a position error of 0.5 m, about what a half-second blend turns it into).

Lower bound (for pruning the difference matrix). With the best translation the centroids
coincide, so for centred points ``|a_i - R b_j| >= ||a_i| - |b_j||`` and, because the optimal
matching of two 1-D lists is the sorted order, ``E_pos >= 1/N sum_k (r_A(k) - r_B(k))^2`` for
the sorted distances ``r`` from the centroid. In 3D rotations about +Y keep each agent's
horizontal radius and height above the centroid, so ``E_pos >= 1/N [SSD(sorted rho) +
SSD(sorted height)]`` as well (the larger is used). The velocity part splits exactly into the
mean-velocity term ``|vbar_A - R vbar_B|^2 >= (|vbar_A| - |vbar_B|)^2`` (horizontal; plus the
vertical difference in 3D) and the deviations from the mean, bounded like the positions by
sorted deviation magnitudes. The three bounds add. None depends on agent labels or on a
yaw/translation of either configuration, and each is a dot-product form, so the bound of all
pairs is a few matrix products.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linear_sum_assignment

from .coords import horizontal_axes, yaw_rotate

__all__ = [
    "Match", "configuration_frame", "configuration_heading", "match", "match_batch", "energy",
    "best_yaw", "bound_features", "take_features", "lower_bound", "lower_bound_matrix",
]

# Relative slack taken off the lower bound so rounding can never lift it above the metric.
_BOUND_SLACK = 1e-10


def configuration_heading(velocities: np.ndarray) -> np.ndarray:
    """Heading (about +Y, 0 facing +Z) of the horizontal part of the mean velocity, (...)."""
    v = np.asarray(velocities)
    ix, iz = horizontal_axes(v.shape[-1])
    m = v.mean(axis=-2)
    return np.arctan2(m[..., ix], m[..., iz])


def configuration_frame(positions: np.ndarray, velocities: np.ndarray, up=(0.0, 1.0, 0.0)):
    """The configuration-space frame of a group (Lai, Chenney and Fan 2005, section 4.1).

    Returns ``(origin, axes)``: ``origin`` (..., D) is the centroid; ``axes`` (..., D, D) holds
    the unit axes as rows — ``X_c`` along the mean velocity and, in 2D, ``Y_c`` the in-plane
    perpendicular ``up x X_c``; in 3D ``Y_c = up x X_c`` and ``Z_c = X_c x Y_c``. World
    coordinates map to configuration coordinates by ``axes @ (x - origin)``. A zero mean
    velocity falls back to +Z; a vertical one takes ``Y_c`` from world +X.
    """
    x = np.asarray(positions, dtype=np.float64)
    v = np.asarray(velocities, dtype=np.float64)
    D = x.shape[-1]
    origin = x.mean(axis=-2)
    m = v.mean(axis=-2)
    if D == 2:
        n = np.linalg.norm(m, axis=-1, keepdims=True)
        X = np.where(n > 1e-12, m / np.maximum(n, 1e-300), np.array([0.0, 1.0]))
        Y = np.stack([X[..., 1], -X[..., 0]], axis=-1)       # (0,1,0) x (x,0,z) = (z, 0, -x)
        return origin, np.stack([X, Y], axis=-2)
    if D != 3:
        raise ValueError(f"configurations are 2D or 3D, got dimension {D}")
    up = np.asarray(up, dtype=np.float64)
    n = np.linalg.norm(m, axis=-1, keepdims=True)
    X = np.where(n > 1e-12, m / np.maximum(n, 1e-300), np.array([0.0, 0.0, 1.0]))
    Y = np.cross(up, X)
    yn = np.linalg.norm(Y, axis=-1, keepdims=True)
    Y = np.where(yn > 1e-9, Y / np.maximum(yn, 1e-300), np.array([1.0, 0.0, 0.0]))
    Z = np.cross(X, Y)
    return origin, np.stack([X, Y, Z], axis=-2)


@dataclass
class Match:
    """Result of comparing configuration A with B.

    ``distance`` is E (mean squared distance, m^2); ``perm`` is ``M_{B<-A}`` (agent ``i`` of A
    corresponds to slot ``perm[i]`` of B); ``yaw``/``translation`` is ``X_{A<-B}``, mapping B's
    coordinates onto A's (``A[i] ~ R_y(yaw) B[perm[i]] + translation``). ``trace`` lists the
    distance after every half step (assignment, alignment, assignment, ...) when requested.
    """

    distance: float
    perm: np.ndarray
    yaw: float
    translation: np.ndarray
    iterations: int
    trace: list = field(default_factory=list)

    @property
    def rms(self) -> float:
        return float(np.sqrt(max(self.distance, 0.0)))


def _sqnorm(d):
    """Squared norm over a short trailing axis (component-wise: faster than a reduction)."""
    out = d[..., 0] * d[..., 0]
    for k in range(1, d.shape[-1]):
        out = out + d[..., k] * d[..., k]
    return out


def energy(a, va, bm, vbm, yaw, w2: float) -> np.ndarray:
    """E for centred, already matched points: (P, N, D) arrays, ``yaw`` (P,) -> (P,)."""
    diff = a - yaw_rotate(bm, yaw[:, None])
    e = _sqnorm(diff)
    if w2:
        dv = va - yaw_rotate(vbm, yaw[:, None])
        e = e + w2 * _sqnorm(dv)
    return e.sum(-1) / a.shape[-2]


def best_yaw(a, va, bm, vbm, w2: float) -> np.ndarray:
    """The yaw (P,) minimising :func:`energy` for centred, already matched points (P, N, D):
    ``atan2(sum a_x b_z - a_z b_x, sum a_x b_x + a_z b_z)``, velocities weighted by ``w2``."""
    ix, iz = horizontal_axes(a.shape[-1])
    al = (a[..., ix] * bm[..., ix] + a[..., iz] * bm[..., iz]).sum(-1)
    be = (a[..., ix] * bm[..., iz] - a[..., iz] * bm[..., ix]).sum(-1)
    if w2:
        al = al + w2 * (va[..., ix] * vbm[..., ix] + va[..., iz] * vbm[..., iz]).sum(-1)
        be = be + w2 * (va[..., ix] * vbm[..., iz] - va[..., iz] * vbm[..., ix]).sum(-1)
    return np.arctan2(be, al)


def match_batch(a_pos, a_vel, b_pos, b_vel, velocity_weight: float = 0.0, max_iter: int = 100,
                trace: bool = False):
    """Compare ``P`` pairs of configurations at once: arrays (P, N, D).

    Returns ``(distance (P,), perm (P, N) int, yaw (P,), translation (P, D), iterations (P,))``,
    plus a list of per-pair traces when ``trace``. Each pair's numbers do not depend on which
    other pairs share the batch (reductions run over fixed-length trailing axes).
    """
    a_pos = np.asarray(a_pos, dtype=np.float64)
    b_pos = np.asarray(b_pos, dtype=np.float64)
    a_vel = np.asarray(a_vel, dtype=np.float64)
    b_vel = np.asarray(b_vel, dtype=np.float64)
    if a_pos.ndim != 3 or a_pos.shape != b_pos.shape or a_vel.shape != a_pos.shape or b_vel.shape != b_pos.shape:
        raise ValueError(f"expected matching (P, N, D) arrays, got {a_pos.shape}, {a_vel.shape}, "
                         f"{b_pos.shape}, {b_vel.shape}")
    P, N, D = a_pos.shape
    w2 = float(velocity_weight) ** 2
    ca = a_pos.mean(axis=1)
    cb = b_pos.mean(axis=1)
    a = a_pos - ca[:, None]
    b = b_pos - cb[:, None]
    yaw = configuration_heading(a_vel) - configuration_heading(b_vel)
    perm = np.zeros((P, N), dtype=np.int64)
    dist = np.full(P, np.inf)
    iters = np.zeros(P, dtype=np.int64)
    traces = [[] for _ in range(P)] if trace else None
    active = np.arange(P)
    for it in range(max_iter):
        if active.size == 0:
            break
        aa, va, bb, vb = a[active], a_vel[active], b[active], b_vel[active]
        y = yaw[active]
        rb = yaw_rotate(bb, y[:, None])
        # |a_i - R b_j|^2 = |a_i|^2 + |b_j|^2 - 2 a_i . R b_j: the squared norms add the same
        # constant to every complete assignment, so the assignment maximises the cross term
        gain = aa @ rb.transpose(0, 2, 1)
        if w2:
            rvb = yaw_rotate(vb, y[:, None])
            gain = gain + w2 * (va @ rvb.transpose(0, 2, 1))
        cost = -gain
        # assignment step: Kuhn-Munkres on the current alignment
        # (square problems: the row indices come back as 0..N-1)
        new_perm = np.array([linear_sum_assignment(c)[1] for c in cost], dtype=np.int64)
        bm = np.take_along_axis(bb, new_perm[:, :, None], axis=1)
        vbm = np.take_along_axis(vb, new_perm[:, :, None], axis=1)
        d_match = energy(aa, va, bm, vbm, y, w2)
        # alignment step: closed-form best yaw for this matching (centroids stay aligned)
        y_new = best_yaw(aa, va, bm, vbm, w2)
        d_align = energy(aa, va, bm, vbm, y_new, w2)
        if trace:
            for k, p in enumerate(active):
                traces[p].extend([float(d_match[k]), float(d_align[k])])
        prev = dist[active]
        changed = ~(new_perm == perm[active]).all(axis=1)
        better = d_align < prev
        upd = active[better]
        perm[upd] = new_perm[better]
        yaw[upd] = y_new[better]
        dist[upd] = d_align[better]
        iters[active] = it + 1
        # go on only while the matching changes and the distance still falls
        if it == 0:
            go = np.ones(active.size, dtype=bool)
        else:
            go = better & changed & (d_align < prev - 1e-14 * prev)
        active = active[go]
    # wrapped to (-pi, pi] through atan2 (the DDG stores these yaws; planar.wrap_angle's
    # (a + pi) % 2pi - pi rounds differently and maps pi to -pi)
    yaw = np.arctan2(np.sin(yaw), np.cos(yaw))
    trans = ca - yaw_rotate(cb, yaw)
    if trace:
        return dist, perm, yaw, trans, iters, traces
    return dist, perm, yaw, trans, iters


def match(a_pos, a_vel, b_pos, b_vel, velocity_weight: float = 0.0, max_iter: int = 100,
          trace: bool = False) -> Match:
    """Compare two configurations (N, D) (positions and velocities). See :class:`Match`."""
    out = match_batch(np.asarray(a_pos)[None], np.asarray(a_vel)[None], np.asarray(b_pos)[None],
                      np.asarray(b_vel)[None], velocity_weight, max_iter, trace)
    d, perm, yaw, t, it = out[:5]
    return Match(float(d[0]), perm[0], float(yaw[0]), t[0], int(it[0]), out[5][0] if trace else [])


def bound_features(positions: np.ndarray, velocities: np.ndarray | None = None,
                   velocity_weight: float = 0.0) -> dict:
    """Label- and motion-invariant descriptors of configurations (..., N, D) for the lower bound.

    Returns ``{"pos": [...], "vel": [...], "mean": array or None}`` of feature arrays (..., K).
    With ``SSD(f) = |f(A) - f(B)|^2 / N`` the metric satisfies
    ``E >= max_pos SSD + SSD(mean) + max_vel SSD``: the three terms bound the position part,
    the mean-velocity part and the velocity-deviation part of ``E`` (which add up), and each
    feature is a sorted list so its SSD is the best 1-D matching (module docstring).
    """
    x = np.asarray(positions, dtype=np.float64)
    N, D = x.shape[-2], x.shape[-1]
    ix, iz = horizontal_axes(D)
    c = x - x.mean(axis=-2, keepdims=True)
    out = {"pos": [], "vel": [], "mean": None}
    if D == 2:
        out["pos"].append(np.sort(np.sqrt(_sqnorm(c)), axis=-1))
    else:
        rho = np.sort(np.sqrt(c[..., ix] ** 2 + c[..., iz] ** 2), axis=-1)
        out["pos"].append(np.concatenate([rho, np.sort(c[..., 1], axis=-1)], axis=-1))
        out["pos"].append(np.sort(np.sqrt(_sqnorm(c)), axis=-1))
    w = float(velocity_weight)
    if w == 0.0 or velocities is None:
        return out
    v = np.asarray(velocities, dtype=np.float64)
    vm = v.mean(axis=-2, keepdims=True)
    u = v - vm
    s = w * np.sqrt(N)
    if D == 2:
        out["mean"] = s * np.sqrt(_sqnorm(vm))
        out["vel"].append(w * np.sort(np.sqrt(_sqnorm(u)), axis=-1))
    else:
        m = vm[..., 0, :]
        out["mean"] = s * np.stack([np.sqrt(m[..., ix] ** 2 + m[..., iz] ** 2), m[..., 1]], axis=-1)
        uh = np.sort(np.sqrt(u[..., ix] ** 2 + u[..., iz] ** 2), axis=-1)
        out["vel"].append(w * np.concatenate([uh, np.sort(u[..., 1], axis=-1)], axis=-1))
        out["vel"].append(w * np.sort(np.sqrt(_sqnorm(u)), axis=-1))
    return out


def take_features(f: dict, index) -> dict:
    """Select configurations ``index`` from a feature dict."""
    return {"pos": [a[index] for a in f["pos"]], "vel": [a[index] for a in f["vel"]],
            "mean": None if f["mean"] is None else f["mean"][index]}


def _ssd_pair(a, b, n):
    d = a - b
    return (d * d).sum(-1) / n - _BOUND_SLACK * ((a * a).sum(-1) + (b * b).sum(-1)) / n


def _ssd_matrix(a, b, n):
    na = (a * a).sum(-1)
    nb = (b * b).sum(-1)
    s = na[:, None] + nb[None, :]
    # the expanded form loses a few ulps of |a|^2 + |b|^2 to cancellation: take them off
    return (s - 2.0 * (a @ b.T)) / n - (_BOUND_SLACK + 64 * a.shape[-1] * np.finfo(np.float64).eps) * s / n


def _combine(fa, fb, n, ssd):
    total = None
    for part in ("pos", "vel"):
        best = None
        for a, b in zip(fa[part], fb[part]):
            t = ssd(a, b, n)
            best = t if best is None else np.maximum(best, t)
        if best is not None:
            best = np.maximum(best, 0.0)
            total = best if total is None else total + best
    if fa["mean"] is not None:
        total = total + np.maximum(ssd(fa["mean"], fb["mean"], n), 0.0)
    return total


def lower_bound(fa: dict, fb: dict, n_agents: int) -> np.ndarray:
    """Lower bound of E for paired descriptors (broadcasting over leading axes)."""
    return _combine(fa, fb, n_agents, _ssd_pair)


def lower_bound_matrix(fa: dict, fb: dict, n_agents: int) -> np.ndarray:
    """All-pairs lower bound (Ma, Mb) for descriptor dicts of Ma and Mb configurations."""
    return _combine(fa, fb, n_agents, _ssd_matrix)
