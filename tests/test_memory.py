"""Process memory policy."""

from __future__ import annotations

import subprocess
import sys

import pytest


def test_retained_memory_is_reused_without_page_faults():
    """After ``retain_freed_memory()`` a freed 200 MB block is reused by the next one without faulting its
    pages in again (glibc); without it each block is mapped afresh. Run in fresh interpreters: the policy is
    process-wide."""
    if not sys.platform.startswith("linux"):
        pytest.skip("glibc's malloc only")
    code = """
import resource, sys
import numpy as np
from knitframe.numerics.memory import retain_freed_memory
applied = retain_freed_memory() and retain_freed_memory() if sys.argv[1] == "on" else False  # (idempotent)
faults = []
for _ in range(4):
    r0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    a = np.empty(25_000_000)  # 200 MB, written through, and a temporary as large
    a.fill(1.0)
    b = a * 2.0
    del a, b
    faults.append(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - r0)
print(int(applied), *faults)
"""
    out = {}
    for mode in ("off", "on"):
        res = subprocess.run([sys.executable, "-c", code, mode], capture_output=True, text=True, check=True)
        applied, *faults = map(int, res.stdout.split())
        out[mode] = (applied, faults)
    if not out["on"][0]:
        pytest.skip("not glibc")
    assert min(out["off"][1][1:]) > 100  # each block faulted in again (in 4 KB or 2 MB pages)
    assert max(out["on"][1][1:]) < 0.1 * min(out["off"][1][1:])
