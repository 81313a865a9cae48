"""The OpenMP threads' spin that gyrolab sets on import (gyrolab/__init__.py; benchmarks/bench_contention.py)."""

import os
import subprocess
import sys

import pytest

SHOW = "import os, gyrolab; print(os.environ.get('GOMP_SPINCOUNT'), os.environ.get('OMP_WAIT_POLICY'))"


def imported_with(**variables):
    """(GOMP_SPINCOUNT, OMP_WAIT_POLICY) as a fresh ``import gyrolab`` leaves them, from ``variables``."""
    env = {k: v for k, v in os.environ.items() if k not in ("GOMP_SPINCOUNT", "OMP_WAIT_POLICY")}
    done = subprocess.run(
        [sys.executable, "-c", SHOW], env={**env, **variables}, capture_output=True, text=True, check=True
    )
    return tuple(done.stdout.split())


@pytest.mark.slow
def test_import_shortens_the_spin_unless_the_user_chose():
    """Neither variable set: GOMP_SPINCOUNT=10000 (libgomp's 300,000 made another process's threads wait
    for the cores); a spin count or a wait policy the user set is left as it is, and no count is added to
    a policy (ACTIVE's spin would otherwise be cut short)."""
    assert imported_with() == ("10000", "None")
    assert imported_with(GOMP_SPINCOUNT="300000") == ("300000", "None")
    assert imported_with(OMP_WAIT_POLICY="ACTIVE") == ("None", "ACTIVE")
    assert imported_with(OMP_WAIT_POLICY="PASSIVE") == ("None", "PASSIVE")
