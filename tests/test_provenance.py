"""What ran, recorded truthfully: a numba cache that cannot go stale, the commit as built, the import
from a checkout root."""

import importlib
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from numba.core.dispatcher import Dispatcher

import gyrolab
from gyrolab.kernels import compile_keys, compiled_files
from gyrolab.runner import provenance

CHECKOUT = Path(__file__).resolve().parents[1]
PROBE = """
import gyrolab, gyrolab.kernels as k
ds = gyrolab.simulate(scene="heavy_top", method="lie_poisson", f=10.0, theta0=45.0, dt=1e-3, t_end=0.05, every=1e-2)
print(k.__file__, k.SOURCE_HASH, repr(float(ds.energy[-1])))
"""


def cached_files(cache):
    """{path: size} of every file numba cached under ``cache``."""
    return {str(p.relative_to(cache)): p.stat().st_size for p in cache.rglob("*") if p.is_file()}


def probe(tree, cache):
    """(kernels file, source hash, final energy) of a lie_poisson run from the source tree ``tree``."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache), "PYTHONPATH": str(tree)}
    done = subprocess.run([sys.executable, "-c", PROBE], cwd=tree, env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    return done.stdout.split()


@pytest.mark.slow
def test_editing_a_kernel_helper_never_runs_stale_machine_code(tmp_path):
    """A copy of the source tree runs lie_poisson (cache filled), then its kick in free_flow.py, a helper
    that numba inlines into lie_poisson's cached kernels, is doubled: the next run, with the same cache
    directory and nothing cleared, gives the doubled kick's result, the same bits as a run on an empty
    cache.  (Plain numba caching checks only the kernel's own file and ran the old kick.)  Between the two,
    an edit of a scene and a copy of the tree at another path each compile nothing."""
    tree = tmp_path / "tree"
    for name in ("gyrolab", "kernels", "runner", "analysis", "conf"):
        shutil.copytree(CHECKOUT / name, tree / name, ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(CHECKOUT / "pyproject.toml", tree)
    cache = tmp_path / "cache"
    path, before_hash, before = probe(tree, cache)
    assert Path(path).resolve() == (tree / "kernels" / "__init__.py").resolve()  # the copy ran, not the install
    assert probe(tree, cache)[2] == before  # warm cache, same code: same bits
    # Editing a scene (pure Python, in no compile key) compiles nothing: the cache gains no file.
    filled = cached_files(cache)
    scene = tree / "kernels" / "scenes" / "heavy_top.py"
    scene.write_text(scene.read_text() + "\n# an edit of a scene file\n")
    _, edited_hash, edited = probe(tree, cache)
    assert edited == before and edited_hash != before_hash  # provenance names the edit; the bits are the same
    assert cached_files(cache) == filled
    # The same source at another path (a second clone, another venv, a reinstall) compiles nothing either.
    elsewhere = tmp_path / "another_clone"
    shutil.copytree(tree, elsewhere, ignore=shutil.ignore_patterns("__pycache__"))
    assert probe(elsewhere, cache)[2] == before
    assert cached_files(cache) == filled
    free_flow = tree / "kernels" / "free_flow.py"
    text = free_flow.read_text()
    kick = "w[0] + h * tau[0] * (1.0 / body[0]),"  # _kick_by, under kick and kick_at
    assert kick in text
    free_flow.write_text(text.replace(kick, kick.replace("h * tau", "2.0 * h * tau")))
    _, after_hash, after = probe(tree, cache)
    assert after_hash != before_hash and after != before
    assert probe(tree, tmp_path / "empty-cache")[2] == after


def copy_kernels(tmp_path):
    tree = tmp_path / "kernels"
    shutil.copytree(CHECKOUT / "kernels", tree, ignore=shutil.ignore_patterns("__pycache__"))
    return tree


def edited(tree, rel, text="\n# edited\n"):
    path = tree / rel
    path.write_text(path.read_text() + text)
    return compile_keys(tree)


def test_compile_keys_follow_what_numba_compiles(tmp_path):
    """A scene, the closed forms, the reference or the registry's names edited: no key changes (nothing
    recompiles).  A core helper edited: every key changes.  A method edited: its key and those of the
    methods importing it change, no other."""
    tree = copy_kernels(tmp_path)
    keys = compile_keys(tree)
    assert len(set(keys.values())) > 20 and all(str(p).startswith(str(tree.resolve())) for p in keys)
    for rel in ("scenes/heavy_top.py", "scenes/common.py", "closed_form.py", "reference.py", "registry.py"):
        assert edited(tree, rel) == keys, rel
    method = lambda name: str((tree / "methods" / f"{name}.py").resolve())  # noqa: E731
    after = edited(tree, "methods/bullet_explicit.py")
    changed = {p for p in keys if after[p] != keys[p]}
    assert changed == {method("bullet_explicit"), method("bullet_implicit_body")}
    after_core = edited(tree, "free_flow.py")
    assert all(after_core[p] != after[p] for p in keys)


DECORATOR = re.compile(r"^\s*@(numba\.)?(njit|jit|vectorize|guvectorize|cfunc)\b", re.MULTILINE)


def code_names(code):
    """Every global name a code object and its nested code objects read."""
    names = set(code.co_names)
    for const in code.co_consts:
        if hasattr(const, "co_names"):
            names |= code_names(const)
    return names


def test_files_out_of_the_compile_keys_hold_no_compiled_code():
    """What NOT_COMPILED leaves out of the keys compiles nothing, and no compiled function reads a name
    defined there, so compiled code can never hold a stale copy of it."""
    root = CHECKOUT / "kernels"
    compiled = set(compiled_files(root))
    left_out = [p for p in root.rglob("*.py") if p not in compiled]
    assert {p.name for p in left_out} >= {"closed_form.py", "reference.py", "registry.py", "heavy_top.py"}
    for path in left_out:
        assert not DECORATOR.search(path.read_text()), path
    pure = {
        "gyrolab.kernels." + ".".join(p.relative_to(root).with_suffix("").parts).removesuffix(".__init__")
        for p in left_out
    }
    checked = 0
    for path in compiled:
        name = "gyrolab.kernels." + ".".join(path.relative_to(root).with_suffix("").parts)
        module = importlib.import_module(name.removesuffix(".__init__"))
        for obj in list(vars(module).values()):
            if isinstance(obj, Dispatcher) and obj.py_func.__module__ == module.__name__:
                checked += 1
                for used in code_names(obj.py_func.__code__):
                    source = getattr(vars(module).get(used), "__module__", None)
                    assert source not in pure, (name, obj.py_func.__name__, used, source)
    assert checked > 50


def test_recorded_commit_is_the_built_one_never_a_git_call_on_the_installed_files(monkeypatch):
    """With build info (a regular install) the commit comes from it and git is never asked; without it,
    only a package running from its own work tree asks git, about that tree."""
    try:
        from gyrolab import _build_info
    except ImportError:
        _build_info = None

    def no_git(*args, **kwargs):
        raise AssertionError(f"git called at run time: {args}")

    if _build_info is not None:
        monkeypatch.setattr(provenance.subprocess, "run", no_git)
        assert provenance.code_state() == (_build_info.GIT_COMMIT, _build_info.GIT_DIRTY, "build")
    else:
        commit, dirty, source = provenance.code_state()
        assert source == "work tree" and provenance.PACKAGE_DIR == CHECKOUT
        head = subprocess.run(["git", "-C", str(CHECKOUT), "rev-parse", "HEAD"], capture_output=True, text=True)
        assert commit == head.stdout.strip() and dirty in (0, 1)


def test_results_record_layout_code_and_library_versions():
    ds = gyrolab.simulate(method="rk4", f=10.0, dt=1e-3, t_end=0.01, every=1e-3)
    assert ds.attrs["layout_version"] >= 1
    attrs = provenance.provenance("a: 1\n", 2)
    from gyrolab.kernels import SOURCE_HASH

    assert attrs["kernel_source_hash"] == SOURCE_HASH and len(SOURCE_HASH) == 16
    for name in ("numpy", "numba", "scipy", "h5py", "h5netcdf", "xarray"):
        assert attrs[f"{name}_version"] not in ("", "absent"), name
    assert attrs["git_source"] in ("build", "work tree")


@pytest.mark.slow
def test_import_gyrolab_from_the_checkout_root():
    """`python -c "import gyrolab; print(gyrolab.methods())"` where the README's install leaves you."""
    done = subprocess.run(
        [sys.executable, "-c", "import gyrolab; print(sorted(gyrolab.methods()))"],
        cwd=CHECKOUT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    assert "'lie_poisson'" in done.stdout and "'seed_next'" in done.stdout


TWIN = '''"""{name}: a test method (kick and free flow, in one order or the other)."""
from numba import njit

from ..free_flow import free_flow, kick

ORDER = 1
SYMPLECTIC = True
PRESERVES = ()


@njit(cache=True, error_model="numpy")
def step(w, q, dt, body):
    {body}
'''
TWINS = {
    "twin_a": "w = kick(w, q, dt, body)\n    return free_flow(w, q, dt, body)",
    "twin_b": "w, q = free_flow(w, q, dt, body)\n    return kick(w, q, dt, body), q",
}
RUN_TWINS = """
import sys, numpy as np
from gyrolab.kernels.batch import integrate
from gyrolab.kernels.scenes import build_scene
sc = build_scene("heavy_top", 10.0, 45.0)
for name in sys.argv[1:]:
    out = integrate(name, np.array([sc.body]), np.array([sc.omega0]), np.array([sc.q0]), 1e-3, 10, 11, path="runs")
    print(name, repr(float(out[0][0, -1, 6])))
"""


def run_twins(tree, cache, *names):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache), "PYTHONPATH": str(tree)}
    done = subprocess.run(
        [sys.executable, "-c", RUN_TWINS, *names], cwd=tree, env=env, capture_output=True, text=True, timeout=600
    )
    assert done.returncode == 0, done.stderr
    return dict(line.split() for line in done.stdout.splitlines())


@pytest.mark.slow
def test_kernels_cached_by_different_processes_never_share_code(tmp_path):
    """Two methods with the same call structure, each compiled alone from an empty cache in its own
    process (so both processes number their functions alike), the two caches merged into one, then
    loaded together in a third process: each must give its own result.  With numba's per-process
    function counter as it is (reset in a copy of the tree) the third process runs twin_a's code for
    twin_b: the collision is real, and the random start in kernels/__init__.py is what prevents it."""
    tree = tmp_path / "tree"
    for name in ("gyrolab", "kernels", "runner", "analysis", "conf"):
        shutil.copytree(CHECKOUT / name, tree / name, ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(CHECKOUT / "pyproject.toml", tree)
    for name, body in TWINS.items():
        (tree / "kernels" / "methods" / f"{name}.py").write_text(TWIN.format(name=name, body=body))
    registry = tree / "kernels" / "registry.py"
    names = '    "no_gyro",\n    "twin_a",\n    "twin_b",\n'
    registry.write_text(registry.read_text().replace('    "no_gyro",\n', names))
    init = tree / "kernels" / "__init__.py"
    fixed = init.read_text()
    guard = "bytecode.FunctionIdentity._unique_ids = itertools.count(secrets.randbits(40) + 1)"
    assert guard in fixed
    for variant, text in (("numba's counter", fixed.replace(guard, "pass")), ("random start", fixed)):
        init.write_text(text)
        tag = variant.split()[0].strip("'")
        caches = [tmp_path / f"cache-{tag}-{name}" for name in TWINS]
        alone = {**run_twins(tree, caches[0], "twin_a"), **run_twins(tree, caches[1], "twin_b")}
        assert alone["twin_a"] != alone["twin_b"]
        merged = tmp_path / f"cache-{tag}"
        shutil.copytree(caches[0], merged)
        shutil.copytree(caches[1], merged, dirs_exist_ok=True)  # shared helpers: the same code either way
        together = run_twins(tree, merged, "twin_a", "twin_b")
        if variant == "random start":
            assert together == alone
        else:
            assert together["twin_b"] == alone["twin_a"], (variant, together, alone)  # the bug, reproduced
