"""Where the nanoseconds of a block step go: seed_next on the heavy top, one thread, variants of the lane loop.

Run:  python benchmarks/profile_block.py [--lanes 64] [--steps 20000] [--repeat 7]

Each line times m steps of a block of lanes (block.make_block_steps' loop, no sampling) with one thing
changed; the differences say what each part costs.  The variant that changes arithmetic (I⁻¹ applied by
divisions, as euler_rhs did before it multiplied by reciprocals) is for measurement only: it does not give
seed_next's bits.  Also prints the packed instructions of the shipped loop body (the count of vdivpd is the
count of divisions per vector).
"""

import argparse
import re
import time

import numba
import numpy as np
from numba import njit

from gyrolab.kernels.block import make_block_steps
from gyrolab.kernels.lanes import lane_step
from gyrolab.kernels.methods.seed_next import rk4_frozen_torque, step
from gyrolab.kernels.rigid_body import gravity_torque
from gyrolab.kernels.rotation import rotate_body_step
from gyrolab.kernels.scenes import build_scene


@njit
def _euler_rhs_division(w, tau, body):
    """euler_rhs as it was before issue 22: I⁻¹ by three divisions per call (other bits)."""
    I1, I2, I3 = body[0], body[1], body[2]
    return (
        (tau[0] + (I2 - I3) * w[1] * w[2]) / I1,
        (tau[1] + (I3 - I1) * w[2] * w[0]) / I2,
        (tau[2] + (I1 - I2) * w[0] * w[1]) / I3,
    )


@njit
def _step_division(w, q, dt, body):
    tau = gravity_torque(q, body)
    h = 0.5 * dt
    k1 = _euler_rhs_division(w, tau, body)
    k2 = _euler_rhs_division((w[0] + h * k1[0], w[1] + h * k1[1], w[2] + h * k1[2]), tau, body)
    k3 = _euler_rhs_division((w[0] + h * k2[0], w[1] + h * k2[1], w[2] + h * k2[2]), tau, body)
    k4 = _euler_rhs_division((w[0] + dt * k3[0], w[1] + dt * k3[1], w[2] + dt * k3[2]), tau, body)
    s = dt * (1.0 / 6.0)
    wn = (
        w[0] + s * (k1[0] + 2.0 * (k2[0] + k3[0]) + k4[0]),
        w[1] + s * (k1[1] + 2.0 * (k2[1] + k3[1]) + k4[1]),
        w[2] + s * (k1[2] + 2.0 * (k2[2] + k3[2]) + k4[2]),
    )
    return wn, rotate_body_step(q, wn[0] * dt, wn[1] * dt, wn[2] * dt)


@njit
def _omega_only(w, q, dt, body):
    return rk4_frozen_torque(w, gravity_torque(q, body), dt, body), q


@njit
def _rotation_only(w, q, dt, body):
    return w, rotate_body_step(q, w[0] * dt, w[1] * dt, w[2] * dt)


def _plain_loop(fast):
    """The lane loop alone: no checkpoint, no non-finite check (no fix-up possible)."""

    @njit(error_model="numpy")
    def steps(W, Q, B, DT, n, m):
        for _ in range(m):
            for j in range(n):
                w, q = fast(
                    (W[0, j], W[1, j], W[2, j]),
                    (Q[0, j], Q[1, j], Q[2, j], Q[3, j]),
                    DT[j],
                    # the body's 12 fields (kernels/body.py), I2 taken as I1 (a symmetric top)
                    (B[0, j], B[0, j], B[2, j], B[3, j], B[4, j], B[5, j])
                    + (B[6, j], B[7, j], B[8, j], B[9, j], B[10, j], B[11, j]),
                )
                W[0, j], W[1, j], W[2, j] = w
                Q[0, j], Q[1, j], Q[2, j], Q[3, j] = q

    return steps


def block(n):
    sc = build_scene("heavy_top", 50.0, 45.0)
    W = np.tile(np.array(sc.omega0)[:, None], (1, n)) * (1 + 0.1 * np.arange(n) / n)
    Q = np.tile(np.array(sc.q0)[:, None], (1, n))
    B = np.tile(np.array(sc.body)[:, None], (1, n))
    return W, Q, B, np.full(n, 1e-4), np.empty((7, n)), np.zeros(n, np.uint8)


def timed(call, n, m, repeat):
    call(1)
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        call(m)
        times.append(time.perf_counter() - start)
    return float(np.median(times)) / (n * m) * 1e9


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lanes", type=int, default=64)
    parser.add_argument("--steps", type=int, default=20000)
    parser.add_argument("--repeat", type=int, default=7)
    args = parser.parse_args()
    numba.set_num_threads(1)
    n, m = args.lanes, args.steps
    W, Q, B, DT, S, BAD = block(n)

    shipped = make_block_steps(step)
    rows = [
        (
            f"shipped steps(): {m} steps, then the non-finite check (symmetric pass)",
            timed(lambda k: shipped(W, Q, B, DT, S, BAD, n, k, True, 0, 0), n, m, args.repeat),
        )
    ]
    rows.append(
        (
            "  same, general pass (I2 read from B)",
            timed(lambda k: shipped(W, Q, B, DT, S, BAD, n, k, False, 0, 0), n, m, args.repeat),
        )
    )
    for label, variant in [
        ("bare lane loop (as shipped, without checkpoint and check)", step),
        ("bare; reciprocals -> 12 divisions, as before issue 22 (other bits)", _step_division),
        ("bare; omega update only (torque + RK4 on Euler)", _omega_only),
        ("bare; rotation only (polynomial CK quaternion + product)", _rotation_only),
    ]:
        loop = _plain_loop(lane_step(variant))
        W, Q, B, DT, S, BAD = block(n)
        rows.append(("  " + label, timed(lambda k: loop(W, Q, B, DT, n, k), n, m, args.repeat)))
    print(f"# seed_next, heavy top, {n} lanes, {m} steps, 1 thread, medians of {args.repeat}\n")
    print("| lane loop | ns per lane-step |")
    print("|---|---:|")
    for label, ns in rows:
        print(f"| {label} | {ns:.2f} |")

    asm = shipped.inspect_asm(shipped.signatures[0])
    ops = re.findall(r"^\s+(v\w+)\s+[^\n]*zmm", asm, flags=re.M)
    counts = {}
    for op in ops:
        counts[op] = counts.get(op, 0) + 1
    print(
        "\nzmm instructions in the compiled steps() (its four lane passes: lane_step and libm, symmetric and "
        "general; the scalar fix-up has none): "
        + ", ".join(f"{op} {c}" for op, c in sorted(counts.items(), key=lambda kv: -kv[1])[:14])
    )


if __name__ == "__main__":
    main()
