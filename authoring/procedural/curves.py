"""Smooth scalar curves used to shape motion: easing, ramps, bumps, Hermite segments, keyframe
splines, and a one-sided smoothing that only ever lowers a signal (for reach limits)."""
from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicHermiteSpline

__all__ = ["smoothstep", "smootherstep", "bump", "bump_integral", "hermite", "keyframes",
           "lower_envelope", "gaussian", "ramp"]


def smoothstep(x):
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def smootherstep(x):
    x = np.clip(x, 0.0, 1.0)
    return x * x * x * (x * (6.0 * x - 15.0) + 10.0)


def bump(x):
    """sin^2 window on [0, 1] (0 outside): zero value and slope at both ends, mean 1/2."""
    x = np.clip(x, 0.0, 1.0)
    return np.sin(np.pi * x) ** 2


def bump_integral(x):
    """Integral of :func:`bump` normalised to go from 0 at x<=0 to 1 at x>=1."""
    x = np.clip(x, 0.0, 1.0)
    return x - np.sin(2.0 * np.pi * x) / (2.0 * np.pi)


def hermite(p0, m0, p1, m1, s):
    """Cubic Hermite segment; ``m0``/``m1`` are tangents per unit of ``s`` (already scaled
    by the segment duration). Broadcasts ``s`` (N,) against (..., D) values as (N, D)."""
    s = np.asarray(s, dtype=np.float64)
    s2 = s * s
    s3 = s2 * s
    h00 = 2 * s3 - 3 * s2 + 1
    h10 = s3 - 2 * s2 + s
    h01 = -2 * s3 + 3 * s2
    h11 = s3 - s2
    if np.ndim(p0) == 0:
        return h00 * p0 + h10 * m0 + h01 * p1 + h11 * m1
    return (h00[:, None] * p0 + h10[:, None] * m0 + h01[:, None] * p1 + h11[:, None] * m1)


def keyframes(times, values, t):
    """Monotone piecewise-cubic (Fritsch-Carlson) interpolation through keys, with zero
    velocity at the first and last key; held constant outside. No overshoot between keys
    (a pelvis moving down onto a seat never dips below it). ``values`` is (K,) or (K, D)."""
    times = np.asarray(times, dtype=np.float64)
    values = np.asarray(values, dtype=np.float64)
    v2 = values.reshape(len(times), -1)
    h = np.diff(times)
    delta = np.diff(v2, axis=0) / h[:, None]
    m = np.zeros_like(v2)
    if len(times) > 2:
        d0, d1 = delta[:-1], delta[1:]
        h0, h1 = h[:-1, None], h[1:, None]
        w1 = 2 * h1 + h0
        w2 = h1 + 2 * h0
        same = d0 * d1 > 0
        with np.errstate(divide="ignore", invalid="ignore"):
            hm = (w1 + w2) / (w1 / d0 + w2 / d1)
        m[1:-1] = np.where(same, hm, 0.0)
    cs = CubicHermiteSpline(times, v2, m, axis=0)
    out = cs(np.clip(t, times[0], times[-1]))
    return out.reshape((len(np.atleast_1d(t)),) + values.shape[1:]) if np.ndim(t) else out.reshape(values.shape[1:])


def gaussian(x, sigma):
    """Gaussian smoothing along axis 0 with edge padding (support 3 sigma)."""
    if sigma <= 0:
        return x
    r = int(np.ceil(3 * sigma))
    k = np.exp(-0.5 * (np.arange(-r, r + 1) / sigma) ** 2)
    k /= k.sum()
    pad = np.concatenate([np.repeat(x[:1], r, axis=0), x, np.repeat(x[-1:], r, axis=0)], axis=0)
    if x.ndim == 1:
        return np.convolve(pad, k, mode="valid")
    out = np.empty_like(x)
    for i in range(x.shape[1]):
        out[:, i] = np.convolve(pad[:, i], k, mode="valid")
    return out


def lower_envelope(corr, sigma):
    """Smooth a non-positive correction signal without ever making it less negative:
    a running minimum over the Gaussian support followed by the Gaussian (the blur of an
    erosion over the blur's own support stays below the input)."""
    if sigma <= 0 or not np.any(corr < 0):
        return corr
    r = int(np.ceil(3 * sigma))
    pad = np.concatenate([np.full(r, corr[0]), corr, np.full(r, corr[-1])])
    win = np.lib.stride_tricks.sliding_window_view(pad, 2 * r + 1)
    eroded = win.min(axis=1)
    return np.minimum(gaussian(eroded, sigma), 0.0)


def ramp(t, a, b):
    """:func:`smootherstep` from 0 at time ``a`` to 1 at time ``b`` (a step when ``b <= a``)."""
    return smootherstep((t - a) / max(b - a, 1e-6))
