"""The Solfec heavy top's energy table: every method's max |ΔH|/H over ~10 s at Solfec's three steps.

    python -m gyrolab.analysis.reports.solfec_top [METHOD ...]

The top of conf/experiment/solfec_heavy_top.yaml (Simo & Wong 1991 as Solfec validates on it:
J = diag(5, 5, 1), M g l = 20, Λ(0) = exp(skew(0.05, 0, 0)), W(0) = (0, 0, 50) rad/s, H = 1269.975)
stepped by each registered method's ``step`` at h = 1e-3, 3e-3, 9e-3 s for 9.999 s (the experiment's
t_end: 1111 steps of 9e-3); the entry is the largest |H(t_n) − H(0)| / H(0) over all steps (the exact
motion keeps H).  A run that turns non-finite reads "diverged".  tests/test_solfec_top.py prints the table (pytest -s).
"""

import math
import sys

import numpy as np

from ...kernels.registry import METHODS, stepper
from ...kernels.rigid_body import energy
from ...kernels.scenes import build_scene

DTS = (1e-3, 3e-3, 9e-3)
T_END = 9.999  # s: 1111 steps of 9e-3 (the experiment's t_end, a multiple of its 9e-3 s samples)
# heavy_body's options for Solfec's top (the experiment file's scene block; its f and θ0 below)
OPTIONS = {"I1": 5.0, "I2": 5.0, "I3": 1.0, "com": [0.0, 0.0, 1.0], "M": 20.0, "g": 1.0}
F = 50.0 / (2.0 * math.pi)  # Hz: 2πf = 50.0 rad/s exactly
THETA0 = 2.864788975654116  # deg: math.radians gives 0.05 exactly


def solfec_scene():
    """The Scene of Solfec's heavy symmetric top (heavy_body, moments normalised as published)."""
    return build_scene("heavy_body", F, THETA0, omega1=0.0, omega2=0.0, allow_unphysical=True, **OPTIONS)


def max_energy_error(name, dt, scene=None, t_end=T_END):
    """max over the steps of |H − H(0)| / H(0) for method ``name`` at step dt (s); inf when the run
    turns non-finite."""
    sc = scene or solfec_scene()
    (start, step_carried), body = stepper(METHODS[name]), sc.body
    w, q = sc.omega0, sc.q0
    c = start(w, q, body)  # a method's carried state (registry.stepper) threads through
    h0 = energy(w, q, body)
    worst = 0.0
    for _ in range(int(round(t_end / dt))):
        w, q, c = step_carried(w, q, c, dt, body)
        err = abs(energy(w, q, body) - h0) / h0
        if not err < math.inf:  # NaN or inf: the run diverged
            return math.inf
        worst = max(worst, err)
    return worst


def energy_table(names=None, dts=DTS):
    """{method: [max |ΔH|/H at each dt]} for ``names`` (default: every registered method)."""
    sc = solfec_scene()
    return {name: [max_energy_error(name, dt, sc) for dt in dts] for name in (names or METHODS)}


def markdown(table, dts=DTS):
    """The table as Markdown, one row per method."""
    lines = ["| method | " + " | ".join(f"h = {d:g} s" for d in dts) + " |", "|---|" + "---|" * len(dts)]
    for name, errors in table.items():
        cells = ("diverged" if not np.isfinite(e) else f"{e:.2g}" for e in errors)
        lines.append(f"| `{name}` | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv=None):
    names = (sys.argv[1:] if argv is None else argv) or None
    unknown = [n for n in names or () if n not in METHODS]
    if unknown:
        print(f"unknown method {unknown[0]!r}; choose from {', '.join(METHODS)}", file=sys.stderr)
        return 2
    print(markdown(energy_table(names)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
