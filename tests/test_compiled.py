"""runtime.compiled.preload: the compiled kernels' cached signatures are loaded before any call."""
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_preload_loads_the_cached_signatures_before_the_first_call():
    pytest.importorskip("numba")
    from runtime.crowd.planner import kernels
    if not kernels.AVAILABLE:
        pytest.skip("numba kernels are switched off")
    kernels._wrap(0.5)          # the kernel is compiled and its signature is in numba's cache
    code = ("import runtime.compiled as C, runtime.crowd.planner.kernels as K\n"
            "assert not K._wrap.overloads\n"
            "n = C.preload()\n"
            "print(n, len(K._wrap.overloads), C.preload())\n")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True)
    n, loaded, again = map(int, out.stdout.split())
    assert n >= 1 and loaded >= 1      # loaded by preload, not by a call
    assert again == 0                  # once per process
