"""JAX's persistent compilation cache for the JAX engines (kernels/real/jax_cache.py): where it goes, that
the user's own setting wins, and that a second process loads what the first compiled."""

import importlib.util
import subprocess
import sys

import pytest

from helpers import environment

pytestmark = pytest.mark.skipif(importlib.util.find_spec("jax") is None, reason="jax is not installed")

# In a child: the cache setting is the process's, and jax would stay in this worker's memory.
CHILD = """
import jax, jax.numpy as jnp
from gyrolab.kernels.real.jax_cache import use_compilation_cache
use_compilation_cache(jax)
print(jax.config.jax_compilation_cache_dir)
print(float(jax.jit(lambda x: jnp.sin(x) * 3.0 + x)(jnp.float32(0.5))))
"""


def child(**env):
    run = subprocess.run(
        [sys.executable, "-c", CHILD], capture_output=True, text=True, env=environment(**env), timeout=300
    )
    assert run.returncode == 0, run.stderr
    return run.stdout.split()


def test_the_cache_is_gyrolabs_unless_the_user_chose_one_and_a_second_process_loads_it(tmp_path):
    home = tmp_path / "xdg"
    first = child(XDG_CACHE_HOME=home)
    assert first[0] == str(home / "gyrolab" / "jax")
    entries = sorted(p.name for p in (home / "gyrolab" / "jax").glob("*-cache"))
    assert any(name.startswith("jit_") for name in entries), entries  # small compiles kept too
    used = {p.name: p.read_bytes() for p in (home / "gyrolab" / "jax").glob("*-atime")}  # JAX's last use
    second = child(XDG_CACHE_HOME=home)  # the same program: read from the cache, nothing added
    assert second == first
    assert sorted(p.name for p in (home / "gyrolab" / "jax").glob("*-cache")) == entries
    assert all((home / "gyrolab" / "jax" / name).read_bytes() != stamp for name, stamp in used.items())
    mine = tmp_path / "mine"
    assert child(XDG_CACHE_HOME=home, JAX_COMPILATION_CACHE_DIR=mine)[0] == str(mine)
