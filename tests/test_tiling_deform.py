"""Laplacian path deformation of motion patches (Kim, Hwang, Hyun and Lee 2012, section 3)."""
import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from runtime.motion.planar import rotate_xz
from runtime.tiling.deform import DEFAULT_LIMITS, PatchDeformer, port_row_targets
from runtime.tiling.synthetic import meet_patch
from test_tiling_util import graph, singles  # noqa: F401  (fixtures)


def _walk(singles):
    return next(p for p in singles.patches if "walk" in p.labels and p.fragments[0].num_frames > 30)


def test_handles_land_exactly_and_others_hold(singles):
    p = _walk(singles)
    d = PatchDeformer(p)
    r = np.zeros(d.num_port_rows)
    f = d.port_frame[1]
    r[6:12] = port_row_targets(d, 1, d.xz[f] + [0.12, -0.05], d.heading[f] + 0.08, d.time[f] + 0.15)
    xz, h, t = d.deform(r, np.arange(6, 12))
    assert np.allclose(xz[f], d.xz[f] + [0.12, -0.05], atol=1e-9)
    assert h[f] == pytest.approx(d.heading[f] + 0.08, abs=1e-9) and t[f] == pytest.approx(d.time[f] + 0.15, abs=1e-9)
    e = d.port_frame[0]
    assert np.allclose(xz[e], d.xz[e], atol=1e-8) and abs(h[e] - d.heading[e]) < 1e-8 and abs(t[e] - d.time[e]) < 1e-8
    stretch, bend, shift, _ = d.measures(xz, h, t)
    # spread along the path: per frame far below the total offset, inside the limits
    assert stretch.max() < 0.02 and shift.max() < 0.015 and bend.max() < 5.0
    assert DEFAULT_LIMITS.ok(stretch.max(), bend.max(), shift.max())
    # ... and a drag far beyond what ~1 s of motion can absorb breaks them
    r[6:12] = port_row_targets(d, 1, d.xz[f] + [1.5, 0.0], d.heading[f], d.time[f] + 0.9)
    xz, h, t = d.deform(r, np.arange(6, 12))
    s2, b2, sh2, _ = d.measures(xz, h, t)
    assert not DEFAULT_LIMITS.ok(s2.max(), b2.max(), sh2.max())


def test_rigid_motion_costs_nothing(singles):
    p = _walk(singles)
    d = PatchDeformer(p)
    th, off = 0.15, np.array([0.3, -0.2])
    r = np.zeros(d.num_port_rows)
    for j in range(2):
        f = d.port_frame[j]
        r[6 * j:6 * j + 6] = port_row_targets(d, j, rotate_xz(d.xz[f], th) + off, d.heading[f] + th, d.time[f] + 0.2)
    xz, h, t = d.deform(r)
    stretch, bend, shift, _ = d.measures(xz, h, t)
    assert stretch.max() < 2e-3 and shift.max() < 1e-4 and bend.max() < 1.0
    assert np.abs(xz - (rotate_xz(d.xz, th) + off)).max() < 0.02
    assert d.energy(r) < 0.05 * d.energy(np.where(np.arange(len(r)) < 6, 0.0, r))


def test_step1_matches_a_direct_constrained_solve(singles):
    """The precomputed handle map equals solving the constrained least squares from scratch."""
    p = _walk(singles)
    d = PatchDeformer(p)
    r = np.zeros(d.num_port_rows)
    f = d.port_frame[1]
    r[6:12] = port_row_targets(d, 1, d.xz[f] + [0.05, 0.1], d.heading[f] - 0.05, d.time[f] - 0.1)
    u = d.H @ r                                     # (4, N): x, z, heading, time
    # direct KKT solve of step 1 with scipy (rebuilding the operator from its definition)
    N = d.N
    seg = np.flatnonzero(d.seg_valid)
    dd = d.xz[seg + 1] - d.xz[seg]
    ws = 1.0 / np.maximum(np.hypot(dd[:, 0], dd[:, 1]), 0.02)
    rows = []
    for comp, sgn in ((0, -1.0), (1, 1.0)):
        R = sp.lil_matrix((len(seg), 4 * N))
        for k, i in enumerate(seg):
            R[k, comp * N + i + 1] = ws[k]
            R[k, comp * N + i] = -ws[k]
            R[k, 2 * N + i] = sgn * ws[k] * dd[k, 1 - comp]
        rows.append(R.tocsr())
    for comp, w in ((2, 1.0), (3, 1.0)):
        R = sp.lil_matrix((len(seg), 4 * N))
        for k, i in enumerate(seg):
            R[k, comp * N + i + 1] = w
            R[k, comp * N + i] = -w
        rows.append(R.tocsr())
    rows.append(sp.identity(4 * N, format="csr") * 1e-3)
    D = sp.vstack(rows).tocsc()
    C = sp.lil_matrix((12, 4 * N))
    for j in range(2):
        fr, nb = d.port_frame[j], d.port_nb[j]
        for k, c in enumerate((fr, N + fr, nb, N + nb, 2 * N + fr, 3 * N + fr)):
            C[6 * j + k, c] = 1.0
    K = sp.bmat([[D.T @ D, C.T], [C, None]]).tocsc()
    sol = spla.spsolve(K, np.concatenate([np.zeros(4 * N), r]))
    assert np.allclose(sol[:4 * N].reshape(4, N), u, atol=1e-6)


def test_interpersonal_constraint_kept_under_rotation(graph):
    p = meet_patch(graph, seed=1)
    d = PatchDeformer(p)
    c = p.constraints[0]
    # drag entry 0 by 0.4 m and 20 degrees, entry 1 by 0.2 m: the patch bends and turns
    r = np.zeros(d.num_port_rows)
    cols = []
    for j, dp, dth in ((0, [0.4, 0.1], 0.35), (2, [-0.2, 0.0], 0.2)):
        f = d.port_frame[j]
        r[6 * j:6 * j + 6] = port_row_targets(d, j, d.xz[f] + dp, d.heading[f] + dth, d.time[f] + 0.1)
        cols += list(range(6 * j, 6 * j + 6))
    xz, h, t = d.deform(r, np.array(cols))
    ia = d.frag_start[c.frag_a] + c.frame_a
    ib = d.frag_start[c.frag_b] + c.frame_b
    rel = rotate_xz(xz[ib] - xz[ia], -h[ia])
    assert np.abs(rel - c.rel_position).max() < 1e-6
    assert abs((h[ib] - h[ia] - c.rel_direction + np.pi) % (2 * np.pi) - np.pi) < 1e-6
    assert t[ib] - t[ia] == pytest.approx(c.dt, abs=1e-9)
    # the constraint really is under load: the partner moved
    assert np.abs(xz[ia] - d.xz[ia]).max() > 0.05
