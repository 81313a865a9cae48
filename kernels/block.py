"""Advance a block of runs together, the loop over runs innermost, so that it vectorises.

A block holds up to a few dozen runs ("lanes") laid out structure-of-arrays
(ω as W[3, n], q as Q[4, n], body as B[body.N_FIELDS, n]).  Each step runs the method's
``lane_step`` (lanes.py) over all lanes in one branch-free loop that LLVM
turns into packed AVX/AVX-512 code; after the steps up to the next sample,
the rare lanes whose state came out non-finite (a rotation angle beyond the
polynomial's range, or a run blowing up) are redone from before those steps
with ``ieee_step`` (the method's own ``step``, never raising).  Every lane
therefore gets exactly what ``step`` computes: results are bit-identical to
the single-trajectory driver (driver.py), whatever the block size or thread
count.  Where a division by zero occurs (rk4 after its quaternion
overflowed), both paths give inf/NaN (``error_model="numpy"``) and the run
ends with status "non-finite".

Runs of a block may have different dt and strides: the block advances by the
steps until the nearest lane's next sample, records the lanes due, and a run
that is finished or diverged (driver._diverged) leaves the block by swapping
with the last active lane, so it costs the others nothing.

entry.py builds ``advance_block = make_advance_block(step)`` for each method
and a cached parallel ``run_blocks``, one prange iteration per thread, each
running its queue of blocks planned by ``plan_blocks`` (as for ``run_batch``,
the step is bound as a global so that the kernel can be cached).
"""

import numpy as np
from numba import njit

from .body import N_FIELDS as N_BODY
from .body import body_lane, body_lane_free, body_lane_symmetric_top
from .driver import STATUS_OK, _diverged, _record
from .lanes import has_series, ieee_step, lane_step
from .rigid_body import divergence_scale

# The loop over lanes always covers whole vectors of this many lanes (8 doubles
# fill an AVX-512 register): a scalar remainder of up to 7 lanes would cost as
# much as the whole vectorised part of a 64-lane block.
VECTOR = 8


# After a sample interval where more than 1/WIDE_FRACTION of a block's lanes turned
# by SMALL_ANGLE or more in a rotation, the block redoes it with the wide pass
# (lane_step(step, wide=True): the longer series up to WIDE_ANGLE) and runs a stretch
# of the next intervals with it; where more than that fraction needed libm even so,
# with the libm pass (ieee_step inlined and vectorised).  The fast pass itself stays
# free of the longer series' operations.  A stretch is WIDE_INTERVALS intervals; when
# the fast pass fails again in the interval right after one, the next stretch is twice
# as long, up to MAX_STRETCH: a block that keeps turning that far (lie_poisson4 at
# dt = 1e-3 s on the 50 Hz top) would otherwise pay a failed fast interval in every
# eight.  Where the fast pass has not held yet (a block's first interval, the first
# after a stretch), it is tried for one step before the rest of the interval.  Which
# pass computes a lane never changes its bits, only the cost.
WIDE_FRACTION = 4
WIDE_INTERVALS = 7
MAX_STRETCH = 16 * WIDE_INTERVALS


# Lane-pass modes: what every lane of a block shares, as a compile-time constant of its pass
# (_make_pass).  GENERAL: anything; SYMMETRIC_TOP: I1 == I2 != 0 and the centre of mass on e3
# (the heavy top, the free disc); FREE: no gravity (mgl = mgc1 = mgc2 = 0), any moments.
GENERAL, SYMMETRIC_TOP, FREE = 0, 1, 2


@njit(cache=True, error_model="numpy")
def block_mode(B, n):
    """The pass mode (GENERAL, SYMMETRIC_TOP or FREE) that lanes 0 .. n − 1 of B all allow."""
    symmetric, free = True, True
    for j in range(n):
        axial = B[4, j] == 0.0 and B[5, j] == 0.0
        symmetric = symmetric and B[0, j] == B[1, j] and B[0, j] != 0.0 and axial
        free = free and axial and B[3, j] == 0.0
    return SYMMETRIC_TOP if symmetric else FREE if free else GENERAL


def make_block_steps(step):
    """``steps(W, Q, B, DT, S, BAD, n_lanes, m, mode, wide, stretch) -> (wide, stretch)``: m steps of
    ``step`` on lanes 0 .. n_lanes − 1.  ``wide`` > 0: intervals left on the wide pass, < 0: on the libm
    pass; ``stretch``: the length of the last stretch on either, 0 once the fast pass has held, −1 before
    the block's first interval.  Where the fast pass has not held yet (``stretch`` ≠ 0) it is tried for one
    step before the other m − 1.

    W (3, ≥ n_lanes) body ω (rad/s), Q (4, ·) quaternions, updated in place;
    B (N_BODY, ·) bodies, DT (·,) steps (s); S (7, ·) float and BAD (·,) uint8
    scratch.  ``mode`` (block_mode) promises what every lane shares (_make_pass).

    The m steps run unchecked with ``lane_step``; a lane that ends non-finite
    is redone from its state before them with ``ieee_step``.  That catches
    every lane where ``lane_step`` differed from ``step``: its NaN lands in q,
    and a NaN quaternion stays NaN (each method multiplies or adds it into the
    next).  Checking once per m steps instead of after each one saves ~20 %.
    When many lanes turn by more than SMALL_ANGLE a rotation, all lanes are redone
    with the wide pass, and when many need libm even so (rotations beyond
    WIDE_ANGLE), with the vectorised libm pass; either is used for a stretch of
    the next intervals too (``wide`` counts them down; the stretch doubles while
    the fast pass keeps failing right after one; each has a SYMMETRIC_TOP and a
    GENERAL pass only).  A step without rotation series (lanes.has_series) has
    the fast pass alone: its non-finite lanes go straight to ``ieee_step``.
    """
    series = has_series(step)
    fast = lane_step(step)
    # A lane left non-finite is redone by the step's own IEEE code, inlined: the libm pass's function, or
    # without rotation series the fast pass's (the same function then, lanes.has_series).
    exact = ieee_step(step, inline=True) if series else fast
    general, symmetric_pass, free_pass = (_make_pass(fast, mode) for mode in (GENERAL, SYMMETRIC_TOP, FREE))

    # inline="always": numba inlines these into advance_block before typing, so none is compiled alone
    # (each numba function optimises and emits again the machine code of all it calls: a block kernel's
    # cold compile 10-16 % shorter, the same speed).  with_wide and with_libm stay functions: ``steps``
    # calls each twice, and would hold two copies of their passes.
    @njit(error_model="numpy", inline="always")
    def count_bad(W, Q, BAD, n_lanes):
        n_bad = 0
        for j in range(n_lanes):
            x = W[0, j] + W[1, j] + W[2, j] + Q[0, j] + Q[1, j] + Q[2, j] + Q[3, j]
            bad = not x - x == 0.0  # inf or NaN somewhere
            BAD[j] = bad
            n_bad += bad
        return n_bad

    @njit(error_model="numpy", inline="always")
    def save(W, Q, S, n_lanes):
        for j in range(n_lanes):
            S[0, j], S[1, j], S[2, j] = W[0, j], W[1, j], W[2, j]
            S[3, j], S[4, j], S[5, j], S[6, j] = Q[0, j], Q[1, j], Q[2, j], Q[3, j]

    @njit(error_model="numpy", inline="always")
    def restore(W, Q, S, n_lanes):
        for j in range(n_lanes):
            W[0, j], W[1, j], W[2, j] = S[0, j], S[1, j], S[2, j]
            Q[0, j], Q[1, j], Q[2, j], Q[3, j] = S[3, j], S[4, j], S[5, j], S[6, j]

    @njit(error_model="numpy", inline="always")
    def redo_bad(W, Q, B, DT, S, BAD, n_lanes, m):
        """The lanes marked in BAD, m steps of ``exact`` from their state in S, one lane at a time."""
        for j in range(n_lanes):
            if BAD[j]:
                w, q = (S[0, j], S[1, j], S[2, j]), (S[3, j], S[4, j], S[5, j], S[6, j])
                body = body_lane(B, j)
                for _ in range(m):
                    w, q = exact(w, q, DT[j], body)
                W[0, j], W[1, j], W[2, j] = w
                Q[0, j], Q[1, j], Q[2, j], Q[3, j] = q

    @njit(error_model="numpy", inline="always")
    def with_fast(W, Q, B, DT, n_lanes, m, mode):
        for _ in range(m):
            if mode == SYMMETRIC_TOP:
                symmetric_pass(W, Q, B, DT, n_lanes)
            elif mode == FREE:
                free_pass(W, Q, B, DT, n_lanes)
            else:
                general(W, Q, B, DT, n_lanes)

    if not series:
        # No rotation series in the step: the wide and libm passes would be the fast pass again
        # (lanes.has_series), so a lane it leaves non-finite is redone by ``exact`` at once, and the
        # four passes that would repeat it are never compiled (about half the block kernel's compile).

        @njit(error_model="numpy", inline="always")
        def one_pass_steps(W, Q, B, DT, S, BAD, n_lanes, m, mode, wide, stretch):
            save(W, Q, S, n_lanes)
            with_fast(W, Q, B, DT, n_lanes, m, mode)
            if count_bad(W, Q, BAD, n_lanes):
                redo_bad(W, Q, B, DT, S, BAD, n_lanes, m)
            return 0, 0

        return one_pass_steps

    with_wide, with_libm = _two_mode_passes(lane_step(step, wide=True)), _two_mode_passes(exact)

    @njit(error_model="numpy", inline="always")
    def steps(W, Q, B, DT, S, BAD, n_lanes, m, mode, wide, stretch):
        if wide < 0:
            with_libm(W, Q, B, DT, n_lanes, m, mode)
            return wide + 1, stretch
        save(W, Q, S, n_lanes)
        ran_wide = wide > 0
        if ran_wide:
            with_wide(W, Q, B, DT, n_lanes, m, mode)
            wide -= 1
        else:
            done = 0
            while done < m:  # one call site: the passes are inlined once (compile time)
                # Where the fast pass is unproven (the block's first interval, or the first after a stretch
                # on a dearer pass) one step first, so that lanes that still turn too far are found after one
                # step instead of m (a sweep of 4 samples a run lost a quarter of its steps to the failed pass).
                k = 1 if done == 0 and stretch != 0 else m - done
                with_fast(W, Q, B, DT, n_lanes, k, mode)
                done += k
                if done < m and WIDE_FRACTION * count_bad(W, Q, BAD, n_lanes) > n_lanes:
                    break
        n_bad = count_bad(W, Q, BAD, n_lanes)
        if WIDE_FRACTION * n_bad > n_lanes and not ran_wide:  # the fast pass: many lanes turned further
            stretch = min(2 * stretch, MAX_STRETCH) if stretch > 0 else WIDE_INTERVALS
            restore(W, Q, S, n_lanes)
            with_wide(W, Q, B, DT, n_lanes, m, mode)
            wide = stretch
            n_bad = count_bad(W, Q, BAD, n_lanes)
        elif not ran_wide:
            stretch = 0  # the fast pass held: a later failure starts with a short stretch again
        if WIDE_FRACTION * n_bad > n_lanes:  # the wide pass: many lanes need libm
            restore(W, Q, S, n_lanes)
            with_libm(W, Q, B, DT, n_lanes, m, mode)
            stretch = max(stretch, WIDE_INTERVALS)
            return -stretch, stretch
        if n_bad:
            redo_bad(W, Q, B, DT, S, BAD, n_lanes, m)
        return wide, stretch

    return steps


def _two_mode_passes(step):
    """``passes(W, Q, B, DT, n_lanes, m, mode)``: m steps of ``step`` on every lane, by the SYMMETRIC_TOP
    pass where ``mode`` is that and the GENERAL pass otherwise (the wide and libm passes have no FREE pass
    of their own: blocks rarely need them)."""
    general, symmetric = _make_pass(step, GENERAL), _make_pass(step, SYMMETRIC_TOP)

    @njit(error_model="numpy")
    def passes(W, Q, B, DT, n_lanes, m, mode):
        for _ in range(m):
            if mode == SYMMETRIC_TOP:
                symmetric(W, Q, B, DT, n_lanes)
            else:
                general(W, Q, B, DT, n_lanes)

    return passes


def _make_pass(fast, mode):
    """One step of every lane with ``fast``.

    The step's branches on the body (I1 == I2 in free_flow, the centre of mass
    on e3 and M g c = 0 in gravity_torque) are data to LLVM, so the vectorised
    loop computes both sides.  ``mode`` (a compile-time constant) passes what
    every lane shares as constants, so LLVM folds those branches:
    SYMMETRIC_TOP passes the body as (I1, I1, I3, mgl, 0.0, 0.0), I1 made
    provably not NaN, and drops the asymmetric free flow (lie_poisson: 11.5 →
    3.4 ns/step) and the general torque; FREE passes (I1, I2, I3, 0.0, 0.0, 0.0)
    and drops the torque.  Bit for bit the same as GENERAL on the lanes the mode
    admits (so that not even the sign of a zero differs: the folded branches are
    the ones those lanes take, and they never read the replaced fields).
    """

    @njit(error_model="numpy", forceinline=True)
    def lane_pass(W, Q, B, DT, n_lanes):
        for j in range(n_lanes):
            if mode == SYMMETRIC_TOP:
                I1 = B[0, j]
                body = body_lane_symmetric_top(B, j, I1 if I1 == I1 else 1.0)
            elif mode == FREE:
                body = body_lane_free(B, j)
            else:
                body = body_lane(B, j)
            w, q = fast((W[0, j], W[1, j], W[2, j]), (Q[0, j], Q[1, j], Q[2, j], Q[3, j]), DT[j], body)
            W[0, j], W[1, j], W[2, j] = w
            Q[0, j], Q[1, j], Q[2, j], Q[3, j] = q

    return lane_pass


def make_advance_block(step):
    """``advance_block(runs, w0, q0, bodies, dts, strides, threshold, out, status, n_steps, state)``
    for one method: integrates the runs listed in ``runs`` (int64 indices into the
    batch arrays) exactly as driver.make_advance's ``advance_run`` does each of them.
    ``state`` (n, 7): each run's (ω, q) when it left the block (its last sample, or where it
    diverged), from which a later call continues it bit for bit (the runner's time segments)."""
    steps = make_block_steps(step)

    @njit(error_model="numpy")
    def advance_block(runs, w0, q0, bodies, dts, strides, threshold, out, status, n_steps, state):
        n = runs.size
        size = -(-n // VECTOR) * VECTOR  # lanes n .. size − 1 are parked
        W, Q, B = np.empty((3, size)), np.empty((4, size)), np.empty((N_BODY, size))
        DT, TOL = np.zeros(size), np.zeros(size)
        RUN, LEFT, K = np.empty(size, np.int64), np.zeros(size, np.int64), np.ones(size, np.int64)
        S, BAD = np.empty((7, size)), np.zeros(size, np.uint8)
        for j in range(size):
            i = runs[min(j, n - 1)]
            RUN[j] = i
            for c in range(N_BODY):
                B[c, j] = bodies[i, c]
            if j >= n:
                _park(W, Q, DT, j)
                continue
            for c in range(3):
                W[c, j] = w0[i, c]
            for c in range(4):
                Q[c, j] = q0[i, c]
            _save_state(state, i, W, Q, j)
            DT[j] = dts[i]
            LEFT[j] = max(strides[i], 0)
            w = (W[0, j], W[1, j], W[2, j])
            body = body_lane(B, j)
            _record(out, i, 0, w, (Q[0, j], Q[1, j], Q[2, j], Q[3, j]), body)
            TOL[j] = threshold * divergence_scale(w, body)
            status[i] = STATUS_OK
            n_steps[i] = 0
        # np.int64, here and for j below: a variable first set to a literal is typed Literal[int] until
        # its loop's other assignments are seen, and numba compiled ``steps`` (and _swap_lanes) for both.
        mode, wide, stretch = block_mode(B, size), np.int64(0), np.int64(-1)  # -1: the fast pass not yet tried
        active = n if out.shape[1] > 1 else 0
        while active > 0:
            m = LEFT[0]
            for j in range(1, active):
                m = min(m, LEFT[j])
            wide, stretch = steps(W, Q, B, DT, S, BAD, -(-active // VECTOR) * VECTOR, m, mode, wide, stretch)
            j = np.int64(0)
            while j < active:
                LEFT[j] -= m
                if LEFT[j] > 0:
                    j += 1
                    continue
                i, k = RUN[j], K[j]
                _record(out, i, k, (W[0, j], W[1, j], W[2, j]), (Q[0, j], Q[1, j], Q[2, j], Q[3, j]), body_lane(B, j))
                n_steps[i] += strides[i]
                if _diverged(out, i, k, TOL[j], status) or k == out.shape[1] - 1:
                    _save_state(state, i, W, Q, j)
                    active -= 1
                    _swap_lanes(j, active, W, Q, B, DT, TOL, RUN, LEFT, K)
                    _park(W, Q, DT, active)
                    continue  # the lane moved into j has not been counted down yet
                K[j] = k + 1
                LEFT[j] = max(strides[i], 0)
                j += 1

    return advance_block


@njit(cache=True, error_model="numpy")
def _save_state(state, i, W, Q, j):
    """state[i] = lane j's (ω_1..3, q_0..3)."""
    for c in range(3):
        state[i, c] = W[c, j]
    for c in range(4):
        state[i, 3 + c] = Q[c, j]


@njit(cache=True, error_model="numpy")
def _park(W, Q, DT, j):
    """Lane j no longer counts: rest it (ω = 0, q = 1, dt = 0) so that the loop over
    lanes can keep stepping it, finite and cheap, for the sake of whole vectors."""
    for c in range(3):
        W[c, j] = 0.0
    Q[0, j], Q[1, j], Q[2, j], Q[3, j] = 1.0, 0.0, 0.0, 0.0
    DT[j] = 0.0


@njit(cache=True, error_model="numpy")
def _swap_lanes(j, last, W, Q, B, DT, TOL, RUN, LEFT, K):
    for c in range(3):
        W[c, j], W[c, last] = W[c, last], W[c, j]
    for c in range(4):
        Q[c, j], Q[c, last] = Q[c, last], Q[c, j]
    for c in range(B.shape[0]):
        B[c, j], B[c, last] = B[c, last], B[c, j]
    DT[j], DT[last] = DT[last], DT[j]
    TOL[j], TOL[last] = TOL[last], TOL[j]
    RUN[j], RUN[last] = RUN[last], RUN[j]
    LEFT[j], LEFT[last] = LEFT[last], LEFT[j]
    K[j], K[last] = K[last], K[j]


def plan_blocks(strides, threads, max_lanes):
    """(runs, starts, queues): blocks of run indices runs[starts[b]:starts[b+1]]; thread t of
    run_blocks' prange runs blocks queues[t] .. queues[t+1] − 1, one after another.

    Runs are grouped by stride (so by step count: a block's lanes finish
    together), each group split into equal blocks of at most ``max_lanes``
    (whole vectors of ``VECTOR`` lanes where they can), into at least
    2 × ``threads`` blocks when the group is big enough.  Blocks go to the
    threads' queues largest first, each to the least loaded queue (work =
    stride × padded lanes).  The plan is static: numba's OpenMP and
    workqueue layers schedule a prange statically, so a block cannot move to
    an idle thread; a run that diverges early only shortens its block.
    """
    strides = np.asarray(strides, dtype=np.int64)
    blocks = []
    for s in np.unique(strides):
        group = np.flatnonzero(strides == s)
        n_blocks = max(-(-group.size // max_lanes), min(2 * threads, -(-group.size // VECTOR)))
        lanes = -(-group.size // (n_blocks * VECTOR)) * VECTOR
        blocks.extend(
            (max(int(s), 1) * -(-b.size // VECTOR) * VECTOR, b)
            for b in np.split(group, range(lanes, group.size, lanes))
        )
    blocks.sort(key=lambda wb: -wb[0])
    load, queue = np.zeros(max(threads, 1)), [[] for _ in range(max(threads, 1))]
    for work, b in blocks:
        t = int(np.argmin(load))
        load[t] += work
        queue[t].append(b)
    ordered = [b for q in queue for b in q]
    runs = np.concatenate(ordered).astype(np.int64) if ordered else np.zeros(0, np.int64)
    starts = np.cumsum([0] + [len(b) for b in ordered]).astype(np.int64)
    queues = np.cumsum([0] + [len(q) for q in queue]).astype(np.int64)
    return runs, starts, queues
