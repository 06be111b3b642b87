"""Loading the runtime's compiled kernels before the first tick.

The kernels compiled with numba (``cache=True``) are loaded from numba's disk cache on their first
call with each argument signature, 3-10 ms each. In a live World that first call lands inside
some tick, over its budget. :func:`preload` loads every signature the cache holds for the
runtime's kernels at once (about a quarter of a second), so a World pays it at construction,
like a game's loading screen.

It reads numba's cache index, which is not numba's public API: any error skips the kernel it
happened on (it is then loaded on its first call, as without this module). Without numba it does
nothing.
"""
from __future__ import annotations

import importlib

__all__ = ["preload", "KERNEL_MODULES"]

KERNEL_MODULES = ("runtime.pose_kernels", "runtime.crowd.spacetime", "runtime.crowd.reservations",
                  "runtime.crowd.clearance", "runtime.crowd.planner.kernels")

_done = False


def preload() -> int:
    """Load every cached signature of the kernels in :data:`KERNEL_MODULES` (once per
    process); returns the number loaded."""
    global _done
    if _done:
        return 0
    _done = True
    try:
        from numba.core.registry import CPUDispatcher
    except ImportError:
        return 0
    n = 0
    for name in KERNEL_MODULES:
        mod = importlib.import_module(name)
        for disp in list(vars(mod).values()):
            if not isinstance(disp, CPUDispatcher) or disp._cache is None:
                continue
            try:
                magic = disp.targetctx.codegen().magic_tuple()
                for key in list(disp._cache._cache_file._load_index()):
                    sig = key[0]
                    if key[1] == magic and sig not in disp.overloads:
                        disp.compile(sig)
                        n += 1
            except Exception:       # not numba's public API: this kernel loads on first call
                continue
    return n
