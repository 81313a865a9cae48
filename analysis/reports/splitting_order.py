"""Which axis order should an axis splitting use?  The six orders over the inertia triangle.

    python -m gyrolab.analysis.reports.splitting_order [-o docs/splitting_order.md]

Every axis splitting of the free rigid body (the free flow of lie_poisson and its compositions on an
asymmetric body, NO_SQUISH's free rotor in LAMMPS, HOOMD-blue, DL_POLY, jax-md) turns the body about its
three principal axes in a symmetric sequence a(h/2) b(h/2) c(h) b(h/2) a(h/2)
(``kernels.free_flow.axis_splitting``).  The six choices of (a, b, c) cost the same and are all second
order; their error constants differ with the moments (Fassò, J. Comput. Phys. 189, 527, 2003).

Orders are named here by the moments' ranks, not by axis labels: with I_L ≥ I_M ≥ I_S, "L-M-S" is
L(h/2) M(h/2) S(h) M(h/2) L(h/2).  A code's fixed order in axis labels becomes a rank order through
the way it labels the principal axes: 1-2-3-2-1 (gyrolab's free_flow) is L-M-S when I1 ≥ I2 ≥ I3 and
S-M-L when I1 ≤ I2 ≤ I3; the MD codes' 3-2-1-2-3 is S-M-L and L-M-S respectively.  (LAMMPS's
``MathEigen::jacobi3`` at lammps/lammps 05562ad5, src/math_eigen.cpp, returns the moments sorted
increasing and fix rigid takes its body axes in that order, so its NO_SQUISH turns L-M-S; a code that
keeps its input frame gets whichever order its user's body description implies.)  "Sorted by
principal moment" is read here as either order with the middle moment in the middle, L-M-S or S-M-L;
the study says which of the two, if either, is best.

The study (all numbers in docs/splitting_order.md come from ``study()`` with its defaults): bodies with
I_L = 1 kg m² on a lattice of the triangle I_L ≥ I_M ≥ I_S, I_M + I_S ≥ I_L (I_S ≥ 0.1 so that |ω| h ≤ 0.2),
plus a water molecule (SPC/E geometry); for each, eight motions with |L| = 1 kg m²/s in fixed random
body directions, q0 = 1; h = 0.02 s for 100 s (5000 steps).  Per motion: the energy error max_n |E_n − E_0|/E_0
and the orientation error at 100 s, the angle of R_exact⁻¹ R (rad) against the exact Euler–Poinsot flow
(kernels.euler_poinsot.free_body).  Per body and order: the median over the motions, and its factor
over the best order's.  NO_SQUISH with m substeps is its order at h/m, m times (on a free body the kicks
vanish, so DL_POLY's 10 rotor substeps are exactly this): 100× smaller errors at 10× the rotor's cost.
"""

import argparse
import itertools
import math
import sys
from pathlib import Path

import numpy as np
from numba import njit

from ...kernels.body import Body
from ...kernels.euler_poinsot import free_body
from ...kernels.free_flow import axis_splitting

RANK = "LMS"  # axis 0, 1, 2 of the sorted body: largest, middle, smallest moment
ORDERS = tuple(itertools.permutations(range(3)))  # (outer, middle, inner) as sorted-body axes
H = 0.02  # s
T_END = 100.0  # s
N_MOTIONS = 8
SEED = 2003  # the L directions' seed (Fassò's year)
GRID = 14  # lattice points along I_M
I_S_MIN = 0.1  # kg m²: keeps |ω| h ≤ |L| h / I_S = 0.2


def order_name(order):
    """An order's name by moment rank: (0, 1, 2) as (outer, middle, inner) sorted-body axes is "L-M-S"."""
    return "-".join(RANK[k] for k in order)


# Who ships which order, in rank terms (module docstring): a fixed label order and a labelling convention.
SHIPPED = {
    "L-M-S": "NO_SQUISH (3-2-1-2-3) with moments sorted increasing (LAMMPS);"
    " gyrolab free_flow (1-2-3-2-1) with I1 ≥ I2 ≥ I3",
    "S-M-L": "gyrolab free_flow with I1 ≤ I2 ≤ I3; NO_SQUISH with moments sorted decreasing",
}


# Figure titles: which fixed order each sorted one is (SHIPPED, short).
TAGS = {"L-M-S": "\nNO_SQUISH, I ascending", "S-M-L": "\nNO_SQUISH, I descending"}


def water_moments():
    """Principal moments (I_L, I_M, I_S) of SPC/E water normalised to I_L = 1: r_OH = 1 Å, ∠HOH =
    109.47° (Berendsen, Grigera & Straatsma 1987), masses O 15.9994 u, H 1.008 u.  A planar body, so
    I_L = I_M + I_S: it lies on the triangle's planar edge."""
    half = math.radians(109.47) / 2.0
    m = np.array([15.9994, 1.008, 1.008])
    r = np.array([[0.0, 0.0, 0.0], [math.sin(half), math.cos(half), 0.0], [-math.sin(half), math.cos(half), 0.0]])
    r = r - (m[:, None] * r).sum(axis=0) / m.sum()
    inertia = sum(mi * (ri @ ri * np.eye(3) - np.outer(ri, ri)) for mi, ri in zip(m, r))
    moments = np.sort(np.linalg.eigvalsh(inertia))[::-1]
    return tuple(moments / moments[0])


def triangle_points(n=GRID, i_s_min=I_S_MIN):
    """(I_M, I_S) of a lattice inside the triangle 1 ≥ I_M ≥ I_S, I_M + I_S ≥ 1, I_S ≥ i_s_min, kept a
    half spacing off its edges (on I_M = I_S or I_M = 1 the body is symmetric and some orders coincide)."""
    d = 0.5 / n
    pts = []
    for i_m in 0.5 + d * (np.arange(n) + 0.5):
        for i_s in np.arange(i_s_min, 1.0, d):
            if i_s + d / 2 <= i_m and i_m + i_s >= 1.0 + d / 2:
                pts.append((float(i_m), float(i_s)))
    return pts


def motions(n=N_MOTIONS, seed=SEED):
    """n body angular momenta (kg m²/s) of norm 1 in random directions, the same for every body."""
    v = np.random.default_rng(seed).normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1)[:, None]


@njit(cache=True, error_model="numpy")
def _run(w, q, h, steps, substeps, body, order):
    """``steps`` steps of h (s), each ``substeps`` axis splittings of h/substeps; returns the largest
    |E_n − E_0| / E_0 over the steps and the final (ω, q)."""
    I1, I2, I3 = body[0], body[1], body[2]
    e0 = I1 * w[0] * w[0] + I2 * w[1] * w[1] + I3 * w[2] * w[2]
    worst = 0.0
    hs = h / substeps
    for _ in range(steps):
        for _ in range(substeps):
            w, q = axis_splitting(w, q, hs, body, order)
        worst = max(worst, abs(I1 * w[0] * w[0] + I2 * w[1] * w[1] + I3 * w[2] * w[2] - e0))
    return worst / e0, w, q


def _angle(q_exact, q):
    """Angle (rad) of the rotation R(q_exact)⁻¹ R(q)."""
    dot = abs(float(np.dot(q_exact, q)))
    return 2.0 * math.acos(min(1.0, dot))


def body_errors(moments, h=H, t_end=T_END, substeps=1, n_motions=N_MOTIONS):
    """Median over the motions of (energy error, orientation error (rad) at t_end) for each of ORDERS,
    on the body with principal moments ``moments`` = (I_L, I_M, I_S) (kg m², sorted decreasing); arrays (6,)."""
    body = Body(*moments, 0.0)  # a free body
    steps = int(round(t_end / h))
    L = motions(n_motions)
    omegas = L / np.asarray(moments)
    q0 = np.array([1.0, 0.0, 0.0, 0.0])
    _, q_exact = free_body(np.asarray(moments), omegas, q0, np.array([steps * h]))
    energy = np.empty((len(ORDERS), len(L)))
    orient = np.empty_like(energy)
    for i, order in enumerate(ORDERS):
        for j, w0 in enumerate(omegas):
            e, _, q = _run((w0[0], w0[1], w0[2]), (1.0, 0.0, 0.0, 0.0), h, steps, substeps, body, order)
            energy[i, j] = e
            orient[i, j] = _angle(q_exact[j, 0], np.array(q))
    return np.median(energy, axis=1), np.median(orient, axis=1)


def study(n=GRID, h=H, t_end=T_END, n_motions=N_MOTIONS):
    """The whole study: {"points": (P, 2) (I_M, I_S), "energy"/"orient": (P, 6) medians over motions,
    "water": (I_L, I_M, I_S), "water_energy"/"water_orient": (6,), and NO_SQUISH's 10 substeps at water
    in each rank order, "water10_energy"/"water10_orient": (6,)}."""
    pts = triangle_points(n)
    res = [body_errors((1.0, i_m, i_s), h, t_end, 1, n_motions) for i_m, i_s in pts]
    water = water_moments()
    we, wo = body_errors(water, h, t_end, 1, n_motions)
    we10, wo10 = body_errors(water, h, t_end, 10, n_motions)
    return {
        "points": np.array(pts),
        "energy": np.array([r[0] for r in res]),
        "orient": np.array([r[1] for r in res]),
        "water": water,
        "water_energy": we,
        "water_orient": wo,
        "water10_energy": we10,
        "water10_orient": wo10,
        "h": h,
        "t_end": t_end,
        "n_motions": n_motions,
    }


def factors(errors):
    """Each order's error over the best order's at the same body (rows: bodies or one body)."""
    errors = np.atleast_2d(errors)
    return errors / errors.min(axis=1, keepdims=True)


def markdown(res):
    """docs/splitting_order.md: the water table, the triangle table and the conclusions, from ``res``."""
    names = [order_name(o) for o in ORDERS]
    wl, wm, ws = res["water"]
    fe, fo = factors(res["water_energy"])[0], factors(res["water_orient"])[0]
    lines = [
        "# Axis order of the splittings: which of the six, for which body",
        "",
        "Generated by `python -m gyrolab.analysis.reports.splitting_order` (analysis/reports/splitting_order.py"
        " says how); the figure is `splitting_order.png`.",
        f"Free body, h = {res['h']:g} s, {res['t_end']:g} s, |L| = 1 kg m²/s, median over {res['n_motions']} motions;"
        " orders named by moment rank (L-M-S = L(h/2) M(h/2) S(h) M(h/2) L(h/2)).",
        "",
        f"## SPC/E water (I_M/I_L = {wm / wl:.4f}, I_S/I_L = {ws / wl:.4f})",
        "",
        "| order | shipped as | max abs(ΔE)/E | orientation error (rad) | × best (energy) | × best (orientation) |",
        "|---|---|---|---|---|---|",
    ]
    for i, name in enumerate(names):
        lines.append(
            f"| {name} | {SHIPPED.get(name, '')} | {res['water_energy'][i]:.3g} | {res['water_orient'][i]:.3g}"
            f" | {fe[i]:.3g} | {fo[i]:.3g} |"
        )
    for name in ("L-M-S", "S-M-L"):
        i = names.index(name)
        lines.append(
            f"| {name}, 10 substeps (DL_POLY's default) | 10× the rotor's cost | {res['water10_energy'][i]:.3g}"
            f" | {res['water10_orient'][i]:.3g} | | |"
        )
    fe_all, fo_all = factors(res["energy"]), factors(res["orient"])
    best_e, best_o = fe_all.argmin(axis=1), fo_all.argmin(axis=1)
    n = len(res["points"])
    lines += [
        "",
        f"## Over the inertia triangle ({n} bodies, I_L = 1, I_S ≥ {I_S_MIN:g})",
        "",
        "| order | best energy at | median × best (energy) | max × best (energy) |"
        " best orientation at | median × best (orientation) | max × best (orientation) |",
        "|---|---|---|---|---|---|---|",
    ]
    for i, name in enumerate(names):
        lines.append(
            f"| {name} | {np.mean(best_e == i):.0%} | {np.median(fe_all[:, i]):.3g} | {fe_all[:, i].max():.3g}"
            f" | {np.mean(best_o == i):.0%} | {np.median(fo_all[:, i]):.3g} | {fo_all[:, i].max():.3g} |"
        )
    lines += ["", "## What this says", ""] + [f"- {s}" for s in conclusions(res)]
    lines += [
        "",
        "`lie_poisson_sorted` is lie_poisson with its axis splitting in the S-M-L order whatever the scene's"
        " axis labels (kernels/free_flow.py `moment_sorted_order`); `lie_poisson` turns 1-2-3-2-1 in the labels.",
    ]
    return "\n".join(lines) + "\n"


def conclusions(res):
    """Sentences read off the numbers (none typed in): the best order, how the sorted orders and the
    MD codes' fixed order fare, for water and over the triangle."""
    names = [order_name(o) for o in ORDERS]
    out = []
    for key, what in (("energy", "energy error"), ("orient", "orientation error")):
        f = factors(res[key])
        best = np.bincount(f.argmin(axis=1), minlength=len(names))
        top = int(best.argmax())
        worst_median = int(np.median(f, axis=0).argmax())
        out.append(
            f"{what}: {names[top]} is best at {best[top] / len(f):.0%} of the triangle's bodies; the worst order"
            f" by median, {names[worst_median]}, is {np.median(f[:, worst_median]):.3g}× the best (up to"
            f" {f[:, worst_median].max():.3g}×)."
        )
        sorted_best = np.minimum(f[:, names.index("L-M-S")], f[:, names.index("S-M-L")])
        out.append(
            f"{what}, sorted by moment (the better of L-M-S and S-M-L): best at {np.mean(sorted_best == 1.0):.0%}"
            f" of the bodies, median {np.median(sorted_best):.3g}× the best, at worst {sorted_best.max():.3g}×."
        )
        fw = factors(res[f"water_{key}"])[0]
        out.append(
            f"water, {what}: best {names[int(fw.argmin())]}; NO_SQUISH's 3-2-1-2-3 loses"
            f" {fw[names.index('L-M-S')]:.3g}× with moments sorted increasing (LAMMPS),"
            f" {fw[names.index('S-M-L')]:.3g}× sorted decreasing."
        )
    return out


def figure(res, path):
    """Two rows (energy, orientation) of six triangles (the orders): each body coloured by its error over
    the best order's at that body (log scale, shared), water starred; written through io.save_figure."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm

    from ..io import save_figure

    names = [order_name(o) for o in ORDERS]
    pts = res["points"]
    fig, axes = plt.subplots(2, 6, figsize=(17, 8), sharex=True, sharey=True, layout="constrained")
    wm, ws = res["water"][1] / res["water"][0], res["water"][2] / res["water"][0]
    vmax = max(factors(res["energy"]).max(), factors(res["orient"]).max())
    norm = LogNorm(1.0, max(vmax, 10.0))
    for row, (key, what) in enumerate((("energy", "energy error"), ("orient", "orientation error"))):
        f = factors(res[key])
        fw = factors(res[f"water_{key}"])[0]
        for i, name in enumerate(names):
            ax = axes[row, i]
            sc = ax.scatter(pts[:, 0], pts[:, 1], c=f[:, i], norm=norm, cmap="viridis", s=34, marker="s")
            ax.plot([0.5, 1.0, 1.0, 0.5], [0.5, 0.0, 1.0, 0.5], color="0.5", lw=0.8)
            ax.plot([wm], [ws], marker="*", ms=13, color="red", mec="k")
            ax.set_title(f"{name}-{name[2]}-{name[0]}{TAGS.get(name, '')}\nwater × {fw[i]:.3g}", fontsize=10)
            ax.set_aspect("equal")
            ax.set_xlim(0.48, 1.02)
            ax.set_ylim(0.0, 1.02)
            if i == 0:
                ax.set_ylabel(f"{what}\nI_S / I_L")
            if row == 1:
                ax.set_xlabel("I_M / I_L")
    cb = fig.colorbar(sc, ax=axes, shrink=0.8)
    cb.set_label("error ÷ best order's error at that body")
    fig.suptitle(
        f"Axis order of the free-body splitting: six orders over the inertia triangle (h = {res['h']:g} s,"
        f" {res['t_end']:g} s, |L| = 1, median of {res['n_motions']} motions); ★ SPC/E water\n"
        "edges: planar bodies (I_M + I_S = I_L, lower left), symmetric (I_M = I_S upper left, I_M = I_L right)",
        fontsize=11,
    )
    return save_figure(fig, path)


def main(argv=None):
    """Run the study; write the Markdown (-o) and the figure beside it."""
    from ...safe_files import UnsafePathError, check_output, write_text

    p = argparse.ArgumentParser(prog="splitting_order", description=__doc__.split("\n")[0])
    p.add_argument("-o", "--output", required=True, help="the Markdown file to write (docs/splitting_order.md)")
    args = p.parse_args(argv)
    out = Path(args.output)
    try:
        check_output(out)
        check_output(out.with_suffix(".png"))
    except (UnsafePathError, OSError) as err:
        sys.stderr.write(f"splitting_order: error: {err}\n")
        return 2
    res = study()
    try:  # each file is written whole or not at all (safe_files); a failed write is one line, exit 1
        png = figure(res, out.with_suffix(".png"))
        write_text(out, markdown(res))
    except (UnsafePathError, OSError) as err:
        sys.stderr.write(f"splitting_order: error: could not write the results: {' '.join(str(err).split())}\n")
        return 1
    print(f"wrote {out} and {png}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
