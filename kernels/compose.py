"""Compositions as data: a table of weights and a base step give the composed time-aware step.

A symmetric composition of a second-order symmetric step S is S(w_0 dt) S(w_1 dt) … S(w_{n−1} dt)
with weights summing to 1 (Yoshida 1990; Suzuki 1990; McLachlan 1995; Hairer, Lubich & Wanner,
*Geometric Numerical Integration*, §II.4 and §V.3).  A method file states its weights and calls one
of the two composers here; they compute every substep's size, time and merged kick from the table,
so no partial sum is typed by hand:

- ``compose_steps(base, weights)``: whole substeps ``base(w, q, s_k, w_k dt, body)`` of a
  time-aware base step (``step_driven(w, q, t, dt, body)``), substep k from ``s_k = t + c_k dt``
  with ``c_k = w_0 + … + w_{k−1}`` summed in Python (``s_0 = t``).  lie_poisson4.
- ``compose_kicks(kick_at, flow, weights)``: the same composition of the Strang step
  kick(½h) flow(h) kick(½h) with adjacent half kicks merged: n flows and n + 1 kicks of
  ``½ w_0, ½ (w_0 + w_1), …, ½ (w_{n−2} + w_{n−1}), ½ w_{n−1}`` times dt.  Time is a coordinate
  the flows advance and the kicks hold (the system made autonomous): kick 0 at t, kick k at
  ``t_k = t_{k−1} + w_{k−1} dt``, the last at t + dt.  strang_exact4, split6_exact, suzuki4_exact.

The two compute the substeps' times as the hand-unrolled code they replace did (partial sums
against a running time), operation for operation, so every stored result keeps its bits.

Both return ``composed(w, q, t, dt, body) -> (w, q)``, a numba function that is not cached by
itself.  ``compose_steps`` makes it a chain of small closures at import time, one per substep, each
calling the base step with its constants and then the next link, each ``forceinline`` so that LLVM
makes the chain one function body (numba treats a closure's free variables as compile-time constants,
so ``c * dt`` is the same multiplication by the same double as a global ``C * dt``): lie_poisson4's
substeps are a few dozen operations each, and unrolled they vectorise on the block path.
``compose_kicks`` is a loop over the table instead, so its flow is called at one place: the exact
Euler–Poinsot flow is a large function, and inlined at each of 3–7 substeps it made the exact
splittings the slowest kernels of all to compile (split6_exact's run and driven kernels 124 s against
strang_exact's 19 s; docs/benchmarks.md, "One call site of the exact flow"), while a ~200 ns flow hides
the loop's few cycles.  The method file wraps ``composed`` in its cached ``step_driven`` (and
``step``), which numba caches with the whole composition compiled in; lanes.py follows the chain
through the closure cells to recompile it for the block path, where it is inlined like any helper.
Measured against the hand-unrolled steps: same bits (tests/test_regression.py, every stored method
and config; the loop gives the chain's bits too); speed in docs/benchmarks.md; a second process loads
suzuki4_exact's step, step_driven, run_batch and run_batch_driven from the cache and compiles nothing
(``NUMBA_DEBUG_CACHE=1``: 4 loaded, 0 saved).  Alternatives weighed: a ``numba.literal_unroll`` loop
over the table needs the base step as an argument (a dispatcher passed as a value is lowered to a raw
pointer, which makes the caller uncacheable, driver.py); generated source would need ``exec``, which
static readers cannot follow (kernels/entry.py avoids it too).
"""

from numba import njit


def compose_steps(base, weights):
    """``composed(w, q, t, dt, body)``: ``base`` (a time-aware step ``(w, q, t, dt, body)``) for
    ``weights[k] * dt`` from ``t + (weights[0] + … + weights[k−1]) * dt``, k = 0 … n − 1."""
    weights = _check(weights)
    starts = [sum(weights[:k]) if k else None for k in range(len(weights))]  # the partial sums, left to right
    link = None
    for k in reversed(range(len(weights))):
        link = _substep(base, weights[k], starts[k], link)
    return link


def compose_kicks(kick_at, flow, weights):
    """``composed(w, q, t, dt, body)``: the Strang steps kick_at(½ h) flow(h) kick_at(½ h), h =
    ``weights[k] * dt``, one after another with adjacent half kicks merged; ``kick_at(w, q, h, t,
    body) -> w`` and ``flow(w, q, h, body) -> (w, q)``, times as in the module docstring.

    A loop over the table, not a chain: ``flow`` is called at one place, so LLVM inlines it once (the
    module docstring)."""
    weights = _check(weights)
    kicks = merged_kicks(weights)
    n = len(weights)

    @njit(error_model="numpy", forceinline=True)
    def composed(w, q, t, dt, body):
        s = t
        # A step of zero length is the identity, exactly (the exact flow at h = 0 returns its input only
        # to a few roundings).  It also makes the count one LLVM cannot know when compiling: a loop of a
        # known 3 it unrolls, inlining the flow three times (strang_exact4's kernels 42 s to compile
        # against 20 s; docs/benchmarks.md, "One call site of the exact flow").
        flows = n if dt != 0.0 else 0
        for k in range(flows):
            w = kick_at(w, q, kicks[k] * dt, s, body)
            w, q = flow(w, q, weights[k] * dt, body)
            s = s + weights[k] * dt
        # the last kick at t + dt (the running time s, which rounding has carried near t + dt, is not used)
        return kick_at(w, q, kicks[n] * dt, t + dt, body), q

    return composed


def merged_kicks(weights):
    """The n + 1 kicks, as fractions of dt, of n Strang steps of ``weights`` with adjacent half kicks
    merged: ½ w_0, ½ (w_0 + w_1), …, ½ (w_{n−2} + w_{n−1}), ½ w_{n−1}."""
    weights = _check(weights)
    return tuple([0.5 * weights[0]] + [0.5 * (a + b) for a, b in zip(weights, weights[1:])] + [0.5 * weights[-1]])


def _check(weights):
    """The weights as a tuple of floats; ValueError unless they sum to 1 (to 1e-12)."""
    weights = tuple(float(x) for x in weights)
    if not weights or abs(sum(weights) - 1.0) > 1e-12:
        raise ValueError(f"composition weights {weights} must sum to 1")
    return weights


def _substep(base, weight, start, rest):
    """``base`` for ``weight * dt`` from ``t + start * dt`` (from t itself when start is None), then
    ``rest`` (None: nothing after)."""
    if start is None and rest is None:

        @njit(error_model="numpy", forceinline=True)
        def only(w, q, t, dt, body):
            return base(w, q, t, weight * dt, body)

        return only
    if start is None:

        @njit(error_model="numpy", forceinline=True)
        def first(w, q, t, dt, body):
            w, q = base(w, q, t, weight * dt, body)
            return rest(w, q, t, dt, body)

        return first
    if rest is None:

        @njit(error_model="numpy", forceinline=True)
        def last(w, q, t, dt, body):
            return base(w, q, t + start * dt, weight * dt, body)

        return last

    @njit(error_model="numpy", forceinline=True)
    def middle(w, q, t, dt, body):
        w, q = base(w, q, t + start * dt, weight * dt, body)
        return rest(w, q, t, dt, body)

    return middle
