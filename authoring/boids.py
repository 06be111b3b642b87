"""Boids flock recorder: the input of data-driven groups (Lai, Chenney and Fan 2005, section 2;
Reynolds 1987).

Every agent steers by separation, alignment and cohesion with its neighbours, relaxes towards a
cruising speed, and adds a smooth random *wander* (an Ornstein-Uhlenbeck steering force per
agent) and a *soft bound* that pulls
agents back towards the centre of the play area once they stray beyond ``bound_radius`` — so
the flock keeps turning and revisits similar configurations, which is what makes a motion graph
of it well connected. Speeds are kept within ``[min_speed, max_speed]``.

The simulation is vectorized over agents and over independent flocks (state arrays shaped
``(flocks, agents, dim)``); the recorder runs one flock. Integration is semi-implicit Euler at
the recording rate, so the recorded velocity of frame ``k`` equals the backward difference
``(x[k] - x[k-1]) * fps`` exactly.

Coordinates: ``dim == 2`` stores the ground plane as columns ``(x, z)``; ``dim == 3`` stores
``(x, y, z)`` with +Y up (metres, seconds).
"""
from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field

import numpy as np

from runtime.limits import MAX_FLOCK_AGENT_SECONDS, MAX_FLOCK_AGENTS, MAX_FLOCK_SECONDS

__all__ = ["BoidsParams", "BoidsSim", "Recording", "record_flock"]


@dataclass(frozen=True)
class BoidsParams:
    """Rule parameters (metres, seconds). Defaults give a cohesive, steadily turning flock."""

    n_agents: int = 20
    dim: int = 2
    fps: float = 30.0
    min_speed: float = 1.0
    cruise_speed: float = 2.0       # agents relax towards this speed (max_speed is rarely reached)
    max_speed: float = 3.0
    w_speed: float = 1.5
    max_accel: float = 4.0
    neighbor_radius: float = 9.0
    separation_radius: float = 1.6
    w_separation: float = 5.0
    w_alignment: float = 2.5
    w_cohesion: float = 1.0
    w_wander: float = 1.2
    wander_time: float = 1.5        # correlation time of the wander force, s
    bound_radius: float = 18.0      # soft bound: horizontal radius of the play area
    w_bound: float = 0.6            # pull per metre beyond the bound
    altitude: float = 20.0          # 3D: height of the play area's centre
    vertical_scale: float = 0.3     # 3D: bound half-height = bound_radius * vertical_scale
    spawn_radius: float = 3.0
    warmup: float = 10.0            # simulated seconds discarded before recording

    def __post_init__(self):
        if self.dim not in (2, 3):
            raise ValueError(f"dim must be 2 or 3, got {self.dim}")
        if self.n_agents < 2:
            raise ValueError(f"a flock needs at least 2 agents, got {self.n_agents}")
        if self.n_agents > MAX_FLOCK_AGENTS:
            raise ValueError(f"a flock of {self.n_agents} agents is more than the limit of {MAX_FLOCK_AGENTS} "
                             "(each step compares every pair of agents)")
        if not (0 < self.min_speed <= self.max_speed):
            raise ValueError("speeds must satisfy 0 < min_speed <= max_speed")
        if self.fps <= 0:
            raise ValueError("fps must be positive")


class BoidsSim:
    """``n_flocks`` independent boids flocks advanced together (vectorized over flocks and agents)."""

    def __init__(self, params: BoidsParams, n_flocks: int = 1, seed: int = 0):
        self.p = params
        self.rng = np.random.default_rng(seed)
        B, N, D = int(n_flocks), params.n_agents, params.dim
        centre = self._centre()
        # spawn in a disc/ball around the centre, headed roughly the same way
        u = self.rng.normal(size=(B, N, D))
        u /= np.linalg.norm(u, axis=-1, keepdims=True)
        r = params.spawn_radius * self.rng.uniform(size=(B, N, 1)) ** (1.0 / D)
        self.x = centre + u * r
        heading = self.rng.uniform(-np.pi, np.pi, size=(B, 1))
        v = np.zeros((B, N, D))
        speed = 0.5 * (params.min_speed + params.max_speed)
        hx, hz = np.sin(heading), np.cos(heading)
        v[..., 0] = hx * speed
        v[..., -1] = hz * speed
        self.v = v + 0.2 * self.rng.normal(size=(B, N, D))
        self.w = self.rng.normal(size=(B, N, D))
        self._eye = np.eye(N, dtype=bool)
        self.dt = 1.0 / params.fps
        self._decay = np.exp(-self.dt / params.wander_time)
        self._kick = np.sqrt(1.0 - self._decay ** 2)

    def _centre(self) -> np.ndarray:
        c = np.zeros(self.p.dim)
        if self.p.dim == 3:
            c[1] = self.p.altitude
        return c

    def step(self) -> None:
        """Advance one recording step (semi-implicit Euler)."""
        p, x, v = self.p, self.x, self.v
        d = x[:, None, :, :] - x[:, :, None, :]              # d[b, i, j] = x_j - x_i
        dist2 = np.einsum("bijk,bijk->bij", d, d)
        nb = (dist2 < p.neighbor_radius ** 2) & ~self._eye
        nbf = nb.astype(np.float64)
        cnt = nbf.sum(-1, keepdims=True)
        inv = 1.0 / np.maximum(cnt, 1.0)
        has = cnt > 0
        align = np.where(has, nbf @ v * inv - v, 0.0)
        coh = np.where(has, nbf @ x * inv - x, 0.0)
        close = (dist2 < p.separation_radius ** 2) & ~self._eye
        wsep = np.where(close, 1.0 / np.maximum(dist2, 1e-6), 0.0)
        sep = wsep.sum(-1, keepdims=True) * x - wsep @ x     # sum_j (x_i - x_j) / |x_i - x_j|^2
        # soft bound (an ellipsoid in 3D, flattened vertically)
        rel = x - self._centre()
        if p.dim == 3:
            rel = rel * np.array([1.0, 1.0 / p.vertical_scale, 1.0])
        rn = np.linalg.norm(rel, axis=-1, keepdims=True)
        excess = np.maximum(rn - p.bound_radius, 0.0)
        bound = -rel / np.maximum(rn, 1e-9) * excess
        self.w = self._decay * self.w + self._kick * self.rng.normal(size=self.w.shape)
        sp0 = np.linalg.norm(v, axis=-1, keepdims=True)
        cruise = (p.cruise_speed - sp0) * v / np.maximum(sp0, 1e-9)
        a = (p.w_separation * sep + p.w_alignment * align + p.w_cohesion * coh
             + p.w_wander * self.w + p.w_bound * bound + p.w_speed * cruise)
        an = np.linalg.norm(a, axis=-1, keepdims=True)
        a *= np.minimum(1.0, p.max_accel / np.maximum(an, 1e-12))
        v = v + a * self.dt
        sp = np.linalg.norm(v, axis=-1, keepdims=True)
        v *= np.clip(sp, p.min_speed, p.max_speed) / np.maximum(sp, 1e-12)
        self.v = v
        self.x = x + v * self.dt


@dataclass
class Recording:
    """A recorded flock: ``positions``/``velocities`` (frames, agents, dim) at ``fps``."""

    params: BoidsParams
    seed: int
    positions: np.ndarray
    velocities: np.ndarray
    sim_seconds: float = 0.0            # wall time spent simulating the recorded part
    meta: dict = field(default_factory=dict)

    @property
    def fps(self) -> float:
        return self.params.fps

    @property
    def dim(self) -> int:
        return self.params.dim

    @property
    def n_frames(self) -> int:
        return self.positions.shape[0]

    @property
    def n_agents(self) -> int:
        return self.positions.shape[1]

    @property
    def virtual_seconds(self) -> float:
        return (self.n_frames - 1) / self.fps

    @property
    def cost_per_virtual_second(self) -> float:
        """Wall seconds of simulation per simulated second (one flock)."""
        return self.sim_seconds / max(self.virtual_seconds, 1e-12)

    @property
    def max_step(self) -> float:
        """Largest per-step displacement of any agent in the recording (metres)."""
        d = np.diff(self.positions, axis=0)
        return float(np.sqrt((d * d).sum(-1)).max())

    def params_dict(self) -> dict:
        return asdict(self.params)


def record_flock(params: BoidsParams, seconds: float, seed: int = 0, progress=None) -> Recording:
    """Simulate one flock for ``warmup + seconds`` and record the last ``seconds``.

    ``progress``: optional callable ``progress(n_steps)`` called as steps complete (e.g. a tqdm
    ``update``). Same parameters and seed give bit-identical arrays.
    """
    if not 0 < seconds <= MAX_FLOCK_SECONDS:
        raise ValueError(f"seconds must be positive and at most {MAX_FLOCK_SECONDS:g}, got {seconds}")
    if params.n_agents * seconds > MAX_FLOCK_AGENT_SECONDS:
        raise ValueError(f"{params.n_agents} agents x {seconds:g} s is more than the limit of "
                         f"{MAX_FLOCK_AGENT_SECONDS:g} agent-seconds of recording")
    sim = BoidsSim(params, 1, seed)
    n_warm = int(round(params.warmup * params.fps))
    n_rec = int(round(seconds * params.fps)) + 1
    for _ in range(n_warm):
        sim.step()
    pos = np.empty((n_rec, params.n_agents, params.dim))
    vel = np.empty_like(pos)
    pos[0], vel[0] = sim.x[0], sim.v[0]
    t0 = time.perf_counter()
    chunk = max(1, n_rec // 100)
    for k in range(1, n_rec):
        sim.step()
        pos[k], vel[k] = sim.x[0], sim.v[0]
        if progress is not None and k % chunk == 0:
            progress(chunk)
    elapsed = time.perf_counter() - t0
    if progress is not None:
        progress((n_rec - 1) % chunk)
    return Recording(params, int(seed), pos, vel, elapsed)
