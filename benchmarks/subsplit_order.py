"""Which order of the axis rotations should the free-body sub-splitting use?

Run:  python benchmarks/subsplit_order.py [--t-end 2] [--dts 1e-3,1e-4]

free_flow.py splits the asymmetric free flow H = Σ L_k²/(2 I_k) into exact rotations about single body
axes, e_a(h/2) e_b(h/2) e_c(h) e_b(h/2) e_a(h/2) with (a, b, c) = (1, 2, 3).  Fassò (J. Comput. Phys.
189, 2003, "Comparison of splitting algorithms for the rigid body") reports that the choice of (a, b, c)
changes the energy error by orders of magnitude.  This measures all six symmetric orderings on the
free_asymmetric scene's box, I = (1e-4, 3e-4, 2e-4) (so e1 is the smallest, e3 the intermediate, e2 the
largest moment), ω = (eps ω3, 0, ω3), f = 10 Hz, for eps = 1e-3 (the scene's default, 2.5e-7 from the
separatrix) and eps = 0.1:

- max |E − E0| / E0 over the run (the splitting conserves |L| and the lab L exactly, not E);
- the orientation error max |R − R_exact| at t_end against the exact flow (kernels/euler_poinsot.py).

The axis rotation is free_flow._axis_rotation's formula (copied here so that the benchmark does not depend
on a private helper).
"""

import argparse
import itertools
import math
import os

import numpy as np
from numba import njit

from gyrolab.kernels.euler_poinsot import free_body
from gyrolab.kernels.rotation import ck_matrix, half_angle, quat_mul, quat_normalize


@njit(error_model="numpy")
def axis_rotation(w, q, axis, h, body):
    """Flow of L_k²/(2 I_k): the body turns by φ = ω_k h about e_k, L_b by −φ (as free_flow._axis_rotation)."""
    c, s = half_angle(w[axis] * h)
    cos_phi = 1.0 - 2.0 * s * s
    sin_phi = 2.0 * s * c
    I = (body[0], body[1], body[2])
    L = (I[0] * w[0], I[1] * w[1], I[2] * w[2])
    if axis == 0:
        q = quat_mul(q, (c, s, 0.0, 0.0))
        L = (L[0], cos_phi * L[1] + sin_phi * L[2], -sin_phi * L[1] + cos_phi * L[2])
    elif axis == 1:
        q = quat_mul(q, (c, 0.0, s, 0.0))
        L = (cos_phi * L[0] - sin_phi * L[2], L[1], sin_phi * L[0] + cos_phi * L[2])
    else:
        q = quat_mul(q, (c, 0.0, 0.0, s))
        L = (cos_phi * L[0] + sin_phi * L[1], -sin_phi * L[0] + cos_phi * L[1], L[2])
    return (L[0] / I[0], L[1] / I[1], L[2] / I[2]), q


@njit(error_model="numpy")
def run(w, q, dt, body, n, a, b, c):
    """n steps of e_a(h/2) e_b(h/2) e_c(h) e_b(h/2) e_a(h/2); returns (w, q, max relative energy error)."""
    I1, I2, I3 = body[0], body[1], body[2]
    E0 = 0.5 * (I1 * w[0] * w[0] + I2 * w[1] * w[1] + I3 * w[2] * w[2])
    worst = 0.0
    half = 0.5 * dt
    for _ in range(n):
        w, q = axis_rotation(w, q, a, half, body)
        w, q = axis_rotation(w, q, b, half, body)
        w, q = axis_rotation(w, q, c, dt, body)
        w, q = axis_rotation(w, q, b, half, body)
        w, q = axis_rotation(w, q, a, half, body)
        q = quat_normalize(q)
        E = 0.5 * (I1 * w[0] * w[0] + I2 * w[1] * w[1] + I3 * w[2] * w[2])
        worst = max(worst, abs(E / E0 - 1.0))
    return w, q, worst


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--t-end", type=float, default=2.0)
    parser.add_argument("--dts", default="1e-3,1e-4")
    args = parser.parse_args()
    dts = [float(x) for x in args.dts.split(",")]
    I = (1e-4, 3e-4, 2e-4)
    body = I + (0.0, 0.0, 0.0)  # kernels/body.py Body: a free body
    omega3 = 2 * math.pi * 10.0
    q0 = (1.0, 0.0, 0.0, 0.0)
    print(
        f"# subsplit_order: box I = {I}, f = 10 Hz, t_end = {args.t_end} s; load average "
        f"{' '.join(f'{x:.2f}' for x in os.getloadavg())}"
    )
    print("# axes named by body index: e1 (I=1e-4, smallest), e2 (3e-4, largest), e3 (2e-4, intermediate)\n")
    for eps in (1e-3, 0.1):
        w0 = (eps * omega3, 0.0, omega3)
        print(f"## eps = {eps}\n")
        print("| ordering | " + " | ".join(f"max dE/E, dt={dt:g} | R error, dt={dt:g}" for dt in dts) + " |")
        print("|---|" + "---:|---:|" * len(dts))
        rows = []
        for a, b, c in itertools.permutations((0, 1, 2)):
            name = f"e{a + 1} e{b + 1} e{c + 1} e{b + 1} e{a + 1}"
            cells = []
            for dt in dts:
                n = int(round(args.t_end / dt))
                w, q, dE = run(w0, q0, dt, body, n, a, b, c)
                _, q_exact = free_body(I, w0, q0, [n * dt])
                cells.append((dE, np.abs(ck_matrix(q) - ck_matrix(tuple(q_exact[0]))).max()))
            rows.append((name, cells))
            shipped = " (shipped)" if (a, b, c) == (0, 1, 2) else ""
            print(f"| {name}{shipped} | " + " | ".join(f"{dE:.2e} | {dR:.2e}" for dE, dR in cells) + " |", flush=True)
        best = min(rows, key=lambda r: r[1][-1][0])
        print(f"\nsmallest energy error at dt = {dts[-1]:g}: {best[0]}\n")
    # Is the best ordering a property of the body or of the state?  Two published test bodies.
    print("## other bodies: max dE/E over 20 s at dt = 1e-3\n")
    others = {
        "I = (1, 2, 3), w0 = (0.7, -1.1, 0.4)": ((1.0, 2.0, 3.0), (0.7, -1.1, 0.4)),
        "HLW I = (2, 1, 2/3), L0 = (cos 1.1, 0, sin 1.1)": (
            (2.0, 1.0, 2.0 / 3.0),
            (math.cos(1.1) / 2.0, 0.0, 1.5 * math.sin(1.1)),
        ),
    }
    for label, (I_o, w_o) in others.items():
        cells = []
        for a, b, c in itertools.permutations((0, 1, 2)):
            _, _, dE = run(w_o, q0, 1e-3, I_o + (0.0,), 20_000, a, b, c)
            cells.append(f"e{a + 1}e{b + 1}e{c + 1}: {dE:.2e}")
        print(f"- {label}: " + ", ".join(cells))


if __name__ == "__main__":
    main()
