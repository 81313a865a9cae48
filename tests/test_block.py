"""The block path (block.py, lanes.py) against the one-run-at-a-time path (driver.py): same bits.

Every method × scene, on batches that mix spins (rotation angles per step on
both sides of WIDE_ANGLE, so the libm fix-up runs), tilts and dt (several
strides, so step counts differ), with runs that diverge mid-block and drop out.
"""

import functools
import itertools

import numba
import numpy as np
import pytest

from gyrolab.kernels.batch import MIN_BLOCK_RUNS, integrate, sample_schedule
from gyrolab.kernels.block import MAX_STRETCH, VECTOR, WIDE_INTERVALS, make_block_steps, plan_blocks
from gyrolab.kernels.body import is_driven
from gyrolab.kernels.driver import N_FIELDS, STATUS_ENERGY, STATUS_NONFINITE, STATUS_OK
from gyrolab.kernels.lanes import (
    _half_angle_or_nan,
    _half_angle_wide_or_nan,
    _quat_from_rotvec_or_nan,
    _quat_from_rotvec_wide_or_nan,
    has_series,
    ieee_step,
    lane_step,
)
from gyrolab.kernels.registry import METHODS, uses_blocks
from gyrolab.kernels.rotation import SMALL_ANGLE, WIDE_ANGLE, half_angle, quat_from_rotvec
from gyrolab.kernels.scenes import SCENES, build_scene

EVERY, T_END = 1e-2, 0.2
# Scenes the block path runs: a driven body (a torque that depends on time) always goes one by one.
BLOCK_SCENES = [name for name in SCENES if not is_driven([build_scene(name, 1.0, 0.0).body])]
# Methods with a block kernel; the others (BLOCKS = False) run one by one on every path.
BLOCK_METHODS = [name for name, module in METHODS.items() if uses_blocks(module)]


def mixed_batch(scene, fs=(2.0, 50.0, 400.0), thetas=(5.0, 60.0, 120.0), dts=(1e-4, 5e-4, 2e-3, 1e-2)):
    """Kernel inputs (bodies, omega0, q0, dt, stride) of every (f, θ0, dt), and n_samples."""
    rows = []
    for f, theta0, dt in itertools.product(fs, thetas, dts):
        sc = build_scene(scene, f, theta0)
        stride, n_samples = sample_schedule(dt, EVERY, T_END)
        rows.append((sc.body, sc.omega0, sc.q0, dt, stride))
    bodies, omega0, q0, dt, stride = (np.array(column) for column in zip(*rows))
    return (bodies, omega0, q0, dt, stride.astype(np.int64)), n_samples


def assert_same(a, b):
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x, y)  # NaN == NaN here, -0.0 == 0.0 is checked below
    assert np.array_equal(np.signbit(a[0]), np.signbit(b[0]))


def run_blocks(method, inputs, n_samples, runs, starts, threshold=10.0):
    """The method's block kernel with a hand-made block plan (blocks dealt to 2 queues)."""
    bodies, omega0, q0, dt, stride = inputs
    n = len(bodies)
    out, status, n_steps = np.empty((n, n_samples, N_FIELDS)), np.zeros(n, np.int8), np.zeros(n, np.int64)
    n_blocks = len(starts) - 1
    METHODS[method].run_blocks(
        omega0,
        q0,
        bodies,
        dt,
        stride,
        threshold,
        out,
        status,
        n_steps,
        np.asarray(runs, np.int64),
        np.asarray(starts, np.int64),
        np.array([0, n_blocks // 2, n_blocks], np.int64),
        np.empty((n, 7)),
    )
    return out, status, n_steps


def test_driven_bodies_go_one_by_one_whatever_the_path():
    """forced_body on 64 runs with path="blocks" is the driven one-by-one kernel's result (the block
    kernels do not see time), for every scene but it the block path is tested below."""
    assert "forced_body" not in BLOCK_SCENES and "heavy_body" in BLOCK_SCENES
    inputs, n_samples = mixed_batch("forced_body")
    runs = integrate("rk4", *inputs, n_samples, path="runs")
    assert_same(integrate("rk4", *inputs, n_samples, path="blocks"), runs)
    bodies, omega0, q0, dt, stride = inputs
    out, status, n_steps = np.empty_like(runs[0]), np.zeros(len(dt), np.int8), np.zeros(len(dt), np.int64)
    iterations = np.zeros((len(dt), 2), np.int64)
    METHODS["rk4"].run_batch_driven(omega0, q0, bodies, dt, stride, 10.0, out, status, n_steps, iterations)
    assert not iterations.any()  # rk4 has no solver
    assert_same((out, status, n_steps), runs)


# `pytest -m "not slow"` keeps the symmetric pass (the top) and the general one (the box) of every method
FAST_SCENES = ("heavy_top", "free_asymmetric")


@pytest.mark.parametrize(
    "scene", [pytest.param(s, marks=() if s in FAST_SCENES else pytest.mark.slow) for s in BLOCK_SCENES]
)
@pytest.mark.parametrize("method", BLOCK_METHODS)
def test_blocks_equal_runs_bit_for_bit(method, scene):
    """36 runs (not a whole number of 8-lane vectors): 2, 50, 400 Hz x θ0 5°, 60°, 120° x dt 1e-4 .. 1e-2
    (ω dt from 1e-3 to 25 rad), 0.2 s.  The non-symplectic methods lose some runs to the energy check
    mid-way (measured 6 or 9 of 36); every output array is the same bits on either path, with blocks
    planned by stride, with all runs in one block of mixed strides, and in blocks of 8 mixed runs."""
    inputs, n_samples = mixed_batch(scene)
    n = len(inputs[0])
    reference = integrate(method, *inputs, n_samples, path="runs")
    assert (np.abs(inputs[1]).max(axis=1) * inputs[3]).max() > WIDE_ANGLE  # the fix-up path runs
    if method in ("seed_next", "seed_prev", "rk4"):  # the batch exercises the lanes' early exit
        assert (reference[1] == STATUS_ENERGY).any() and (reference[1] == STATUS_OK).any()
        assert (reference[2][reference[1] == STATUS_ENERGY] < reference[2].max()).all()
    assert_same(integrate(method, *inputs, n_samples, path="blocks"), reference)
    assert_same(run_blocks(method, inputs, n_samples, np.arange(n), [0, n]), reference)
    shuffled = np.random.default_rng(3).permutation(n)
    assert_same(run_blocks(method, inputs, n_samples, shuffled, np.r_[0:n:VECTOR, n]), reference)


@pytest.mark.parametrize("method", ["lie_poisson", "seed_next"])
def test_blocks_mixing_symmetric_and_asymmetric_bodies(method):
    """Heavy tops (I1 = I2: the symmetric pass) and boxes (I1 ≠ I2) in the same blocks (general pass):
    same bits as one by one."""
    top, n_samples = mixed_batch("heavy_top", thetas=(60.0,))
    box, _ = mixed_batch("free_asymmetric", thetas=(60.0,))
    inputs = tuple(np.concatenate([a, b]) for a, b in zip(top, box))
    assert_same(
        integrate(method, *inputs, n_samples, path="blocks"), integrate(method, *inputs, n_samples, path="runs")
    )


def test_methods_off_the_block_path_have_no_block_kernel_and_run_one_by_one():
    """A method with BLOCKS = False (the exact-free-flow splittings) gets no run_blocks to compile, and
    path="blocks" or "auto" on 64 runs gives the one-by-one kernel's bits."""
    off = [name for name in METHODS if name not in BLOCK_METHODS]
    assert {"strang_exact", "strang_exact4", "split6_exact", "suzuki4_exact"} <= set(off)
    assert all(not hasattr(METHODS[name], "run_blocks") for name in off)
    assert all(hasattr(METHODS[name], "run_blocks") for name in BLOCK_METHODS)
    inputs, n_samples = mixed_batch("heavy_top", fs=np.linspace(1.0, 60.0, 16), thetas=(60.0,), dts=(1e-3,) * 4)
    assert len(inputs[0]) >= MIN_BLOCK_RUNS
    runs = integrate("strang_exact", *inputs, n_samples, path="runs")
    assert (runs[1] == STATUS_OK).all()
    assert_same(integrate("strang_exact", *inputs, n_samples, path="blocks"), runs)
    assert_same(integrate("strang_exact", *inputs, n_samples), runs)


def test_blocks_do_not_depend_on_threads():
    """seed_next, heavy top, 100 runs: 1 and 2 threads give the same bits (blocks are planned per thread
    count, so the blocking differs too)."""
    inputs, n_samples = mixed_batch("heavy_top", fs=np.linspace(1.0, 60.0, 25), dts=(1e-4, 1e-3))
    inputs = tuple(np.concatenate([x, x]) for x in inputs)
    threads = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = integrate("seed_next", *inputs, n_samples, path="blocks")
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
        assert_same(integrate("seed_next", *inputs, n_samples, path="blocks"), one)
    finally:
        numba.set_num_threads(threads)


def test_auto_path_uses_blocks_from_min_block_runs():
    """The default path is the block kernel from MIN_BLOCK_RUNS runs up: rk4's overflowing run (below)
    tells the paths apart."""
    inputs, n_samples = mixed_batch("heavy_top", fs=(400.0,), thetas=(5.0,), dts=(2e-3,) * MIN_BLOCK_RUNS)
    _, status, _ = integrate("rk4", *inputs, n_samples, 1e300)
    assert (status == STATUS_NONFINITE).all()
    with pytest.raises(ValueError, match="path='fast'"):
        integrate("rk4", *inputs, n_samples, path="fast")


def test_overflowing_run_ends_nonfinite_and_leaves_its_block_alone():
    """rk4, 400 Hz, dt = 2e-3 (ω dt = 5 rad) with no energy check: |q| overflows and the step would divide
    by zero.  On the block path those runs end "non-finite" (NaN after their first non-finite sample) and the
    other runs of their block (50 Hz, or dt = 1e-4) come out as the one-by-one path computes them alone."""
    inputs, n_samples = mixed_batch("heavy_top", fs=(50.0, 400.0), thetas=(5.0, 60.0), dts=(2e-3, 1e-4))
    blocks = run_blocks("rk4", inputs, n_samples, np.arange(len(inputs[0])), [0, len(inputs[0])], 1e300)
    bad = blocks[1] == STATUS_NONFINITE
    np.testing.assert_array_equal(bad, (inputs[1][:, 2] > 2000) & (inputs[3] == 2e-3))
    for i in np.flatnonzero(bad):
        k = blocks[2][i] // inputs[4][i]
        assert 1 <= k < n_samples - 1 and np.isfinite(blocks[0][i, :k]).all()
        assert not np.isfinite(blocks[0][i, k]).all() and np.isnan(blocks[0][i, k + 1 :]).all()
    good = tuple(x[~bad] for x in inputs)
    assert_same(tuple(x[~bad] for x in blocks), integrate("rk4", *good, n_samples, 1e300, path="runs"))


@pytest.mark.slow
def test_a_step_without_rotation_series_has_one_lane_pass():
    """lanes.has_series follows a step's calls to the helpers lane_step replaces: seed_next, lie_poisson4 and
    cg4 reach them, rk4, mujoco_euler and no_squish do not (their fast, wide and libm passes would be one
    function).  For those make_block_steps compiles the fast pass alone: with 4 of 8 rk4 lanes overflowing
    (more than the quarter that sends a series method to its wide pass) steps() asks for no stretch, and
    every lane ends with the bits of its bare steps, NaN where they overflow."""
    assert [has_series(METHODS[name].step) for name in ("seed_next", "lie_poisson4", "cg4")] == [True] * 3
    assert [has_series(METHODS[name].step) for name in ("rk4", "mujoco_euler", "no_squish")] == [False] * 3
    step = METHODS["rk4"].step
    bare, steps = ieee_step(step), make_block_steps(step)
    sc = build_scene("heavy_top", 50.0, 45.0)
    n, dt, m = VECTOR, 2e-3, 100
    W = np.array([[0.0] * n, [0.0] * n, [2 * np.pi * f for f in (50.0, 400.0) * (n // 2)]])
    Q, B, DT = np.tile(np.array(sc.q0)[:, None], (1, n)), np.tile(np.array(sc.body)[:, None], (1, n)), np.full(n, dt)
    expected = []
    for j in range(n):
        w, q = tuple(W[:, j]), tuple(Q[:, j])
        for _ in range(m):
            w, q = bare(w, q, dt, sc.body)
        expected.append(w + q)
    expected = np.array(expected)
    assert np.isnan(expected[1::2]).any(axis=1).all() and np.isfinite(expected[::2]).all()
    assert steps(W, Q, B, DT, np.empty((7, n)), np.zeros(n, np.uint8), n, m, True, 0, -1) == (0, 0)
    np.testing.assert_array_equal(np.vstack([W, Q]).T, expected)


def test_runs_path_reports_the_overflowing_run():
    """rk4's quaternion overflows: its normalisation divides by zero.  With error_model="numpy" the run ends
    non-finite; with numba's default the exception would be lost inside the prange (run unwritten, status ok)."""
    inputs, n_samples = mixed_batch("heavy_top", fs=(50.0, 400.0), thetas=(5.0, 60.0), dts=(2e-3, 1e-4))
    _, status, n_steps = integrate("rk4", *inputs, n_samples, 1e300, path="runs")
    assert (status == STATUS_NONFINITE).sum() == 2
    assert (n_steps[status == STATUS_OK] == (n_samples - 1) * inputs[4][status == STATUS_OK]).all()


@pytest.mark.parametrize(
    "quat, half, edge",
    [
        (_quat_from_rotvec_or_nan, _half_angle_or_nan, SMALL_ANGLE),
        (_quat_from_rotvec_wide_or_nan, _half_angle_wide_or_nan, WIDE_ANGLE),
    ],
)
def test_replaced_helpers_switch_exactly_where_rotation_py_does(quat, half, edge):
    """Below their edge (SMALL_ANGLE for the fast pass's helpers: the series; WIDE_ANGLE for the wide pass's:
    the series and, from SMALL_ANGLE, its longer form) the NaN-poisoned helpers are rotation.py's, bit for
    bit; from the first angle where rotation.py takes another branch on, they return NaN."""
    u = np.array([0.6, -0.48, 0.64])
    angles = [0.0, 1e-12, 0.1, np.nextafter(SMALL_ANGLE, 0.0), SMALL_ANGLE, 0.3, 0.5, np.nextafter(WIDE_ANGLE, 0.0)]
    for angle in [a for a in angles if a < edge]:
        assert quat(*(angle * u)) == quat_from_rotvec(*(angle * u))
        assert half(-angle) == half_angle(-angle) and half(angle) == half_angle(angle)
    v = edge * np.array([0.0, 0.0, 1.0])  # angle2 = edge² exactly: the next branch
    assert np.isnan(quat(*v)[0]) and not np.isnan(quat_from_rotvec(*v)[0])
    for angle in (edge, 1.0, np.inf, np.nan):
        assert np.isnan(half(angle)[0]) and np.isnan(half(-angle)[0])


@pytest.mark.slow
@pytest.mark.parametrize("wide", [False, True])
@pytest.mark.parametrize("method", ["seed_next", "lie_poisson"])
def test_lane_step_is_step_for_small_rotations_and_nan_for_large(method, wide):
    """lane_step gives step's bits while every rotation of the step is below SMALL_ANGLE (here ≤ 0.15 rad;
    with wide=True below WIDE_ANGLE, here ≤ 0.5 rad), and NaN once one is beyond (≥ 0.23 rad; wide ≥ 1.15
    rad), which sends the lane to the fix-up; ieee_step is step."""
    step, exact = METHODS[method].step, ieee_step(METHODS[method].step)
    fast = lane_step(step, wide=wide)
    body = build_scene("heavy_top", 10.0, 30.0).body
    q, dt = (0.9, 0.1, -0.3, 0.2), 1e-3
    for angle in (1e-9, 0.05, 0.15, 0.3, 0.5, 1.5, 3.0):
        # |ω| dt = angle; lie_poisson's free flow turns by 0.77 angle about (ω1, ω2, ω3 I3/I1).
        w = (0.6 * angle / dt, -0.48 * angle / dt, 0.64 * angle / dt)
        expected = step(w, q, dt, body)
        assert exact(w, q, dt, body) == expected
        got = fast(w, q, dt, body)
        if angle < (0.8 if wide else 0.2):
            assert got == expected
        else:
            assert np.isnan(got[1]).all()


@functools.cache
def seed_next_block_steps():
    """make_block_steps(seed_next's step), compiled once per test process (~7 s) for the tests below."""
    return make_block_steps(METHODS["seed_next"].step)


@pytest.mark.slow
def test_block_loop_is_vectorised():
    """The loop over lanes compiles to packed double arithmetic (SSE2 and up: <2 x double> or wider).
    Guards against a change to a step that LLVM cannot vectorise (a libm call outside the two helpers
    lanes.py replaces, a helper called as module.function, a Python-error-model division)."""
    steps = seed_next_block_steps()
    n = VECTOR
    W, Q, B, DT = np.zeros((3, n)), np.zeros((4, n)), np.ones((4, n)), np.zeros(n)
    Q[0] = 1.0
    steps(W, Q, B, DT, np.empty((7, n)), np.zeros(n, np.uint8), n, 1, False, 0, 0)
    ir = steps.inspect_llvm(steps.signatures[0])
    assert "fdiv <" in ir and "fmul <" in ir and " x double>" in ir


def large_rotation_lanes(scale):
    """seed_next on 8 heavy-top lanes spun so that |ω| dt = scale × (0.25, 0.5, 0.75, 1.5, 3, 5, 10, 20)
    (dt = 1e-4 s), and each lane's state after 100 bare steps."""
    step = METHODS["seed_next"].step
    sc = build_scene("heavy_top", 50.0, 45.0)
    n, dt = VECTOR, 1e-4
    spins = np.array([0.25, 0.5, 0.75, 1.5, 3.0, 5.0, 10.0, 20.0]) * scale / dt
    W = np.array([[0.0] * n, [0.0] * n, spins])
    Q, B, DT = np.tile(np.array(sc.q0)[:, None], (1, n)), np.tile(np.array(sc.body)[:, None], (1, n)), np.full(n, dt)
    expected = []
    for j in range(n):
        w, q = tuple(W[:, j]), tuple(Q[:, j])
        for _ in range(100):
            w, q = step(w, q, dt, sc.body)
        expected.append(w + q)
    return seed_next_block_steps(), (W, Q, B, DT, np.empty((7, n)), np.zeros(n, np.uint8), n), np.array(expected)


@pytest.mark.slow
@pytest.mark.parametrize("unproven", [0, -1])
@pytest.mark.parametrize(
    "scale, lanes_on_wide, returned",
    [(WIDE_ANGLE / 25, 2, ((0, 0), (0, 0))), (WIDE_ANGLE / 12, 4, ((7, 7), (6, 7)))],
)
def test_many_rotations_beyond_the_series_switch_the_block_to_the_wide_pass(scale, lanes_on_wide, returned, unproven):
    """A few lanes (2 of 8) turning by SMALL_ANGLE or more a step are redone one by one; more (4 of 8, one of
    them beyond WIDE_ANGLE) make steps() redo the interval with the wide pass and ask for it for a stretch of
    WIDE_INTERVALS more (returns (intervals left, stretch), then counts down).  The same when the fast pass is
    unproven (stretch −1, a block's first interval: one fast step is tried before the other 49).  Every lane
    ends with the bits of 100 bare steps."""
    steps, (W, Q, B, DT, S, BAD, n), expected = large_rotation_lanes(scale)
    assert (W[2] * DT >= SMALL_ANGLE).sum() == lanes_on_wide and (W[2] * DT >= WIDE_ANGLE).sum() <= 1
    first = steps(W, Q, B, DT, S, BAD, n, 50, True, 0, unproven)
    assert (first, steps(W, Q, B, DT, S, BAD, n, 50, True, *first)) == returned
    assert returned[0][0] in (0, WIDE_INTERVALS)
    np.testing.assert_array_equal(np.vstack([W, Q]).T, expected)


@pytest.mark.slow
def test_the_wide_stretch_doubles_while_the_fast_pass_keeps_failing_and_resets_when_it_holds():
    """4 of 8 lanes keep turning past SMALL_ANGLE: after each stretch on the wide pass the fast pass fails
    again, so the stretches run 7, 14, 28, 56 intervals (a failed fast interval every 8, 15, 29, 57 instead
    of every 8), capped at MAX_STRETCH; on lanes where the fast pass holds, the stretch is forgotten.  The
    passes only change the cost: 100 one-step intervals end on the bits of 100 bare steps."""
    steps, (W, Q, B, DT, S, BAD, n), expected = large_rotation_lanes(WIDE_ANGLE / 12)
    state, stretches = (0, 0), []
    for _ in range(100):
        state = steps(W, Q, B, DT, S, BAD, n, 1, True, *state)
        if state[0] == state[1]:  # a stretch starts
            stretches.append(state[1])
    assert stretches == [WIDE_INTERVALS, 2 * WIDE_INTERVALS, 4 * WIDE_INTERVALS, 8 * WIDE_INTERVALS]
    np.testing.assert_array_equal(np.vstack([W, Q]).T, expected)
    assert steps(W, Q, B, DT, S, BAD, n, 1, True, 0, MAX_STRETCH) == (MAX_STRETCH, MAX_STRETCH)
    steps, (W, Q, B, DT, S, BAD, n), _ = large_rotation_lanes(WIDE_ANGLE / 25)
    assert steps(W, Q, B, DT, S, BAD, n, 1, True, 0, 8 * WIDE_INTERVALS) == (0, 0)


@pytest.mark.slow
def test_many_large_rotations_switch_the_block_to_the_libm_pass():
    """5 of 8 lanes turn by WIDE_ANGLE or more per step: steps() redoes the interval with the wide pass, then,
    as that leaves the 5 lanes non-finite, with the vectorised libm pass, and asks for that for a stretch of
    WIDE_INTERVALS more (returns minus that count, then counts up); every lane ends with the bits of 100 bare
    steps."""
    steps, (W, Q, B, DT, S, BAD, n), expected = large_rotation_lanes(WIDE_ANGLE)
    assert steps(W, Q, B, DT, S, BAD, n, 50, True, 0, 0) == (-WIDE_INTERVALS, WIDE_INTERVALS)
    assert steps(W, Q, B, DT, S, BAD, n, 50, True, -WIDE_INTERVALS, WIDE_INTERVALS) == (
        -WIDE_INTERVALS + 1,
        WIDE_INTERVALS,
    )
    np.testing.assert_array_equal(np.vstack([W, Q]).T, expected)


def test_plan_blocks():
    """Every run in exactly one block; one stride per block; at most max_lanes lanes, whole vectors but for
    a group's last block; ≥ 2 blocks per thread when the runs allow; the threads' queues balanced (largest
    block first to the least loaded queue: within one largest block of each other)."""
    strides = np.array([5, 1, 5, 2, 2, 5, 1, 1, 1, 1] * 30)
    for threads in (1, 2, 3):
        runs, starts, queues = plan_blocks(strides, threads, 64)
        assert sorted(runs) == list(range(strides.size)) and queues[0] == 0 and queues[-1] == len(starts) - 1
        sizes = np.diff(starts)
        assert all(len(set(strides[runs[a:b]])) == 1 for a, b in zip(starts, starts[1:]))
        assert sizes.max() <= 64 and sum(size % VECTOR != 0 for size in sizes) <= len(set(strides))
        work = np.array([strides[runs[a]] * -(-(b - a) // VECTOR) * VECTOR for a, b in zip(starts, starts[1:])])
        load = [work[queues[t] : queues[t + 1]].sum() for t in range(threads)]
        assert len(queues) == threads + 1 and max(load) - min(load) <= work.max()
    assert list(np.diff(plan_blocks(np.full(256, 7), 2, 64)[1])) == [64] * 4
    assert list(np.diff(plan_blocks(np.full(12, 7), 2, 64)[1])) == [8, 4]
    # half the runs 200 steps per sample, half 1: each thread gets half of the long blocks
    strides = np.resize([200, 1], 256)
    runs, starts, queues = plan_blocks(strides, 2, 64)
    long_blocks = strides[runs[starts[:-1]]] == 200
    assert long_blocks[queues[0] : queues[1]].sum() == long_blocks[queues[1] : queues[2]].sum() == 2
