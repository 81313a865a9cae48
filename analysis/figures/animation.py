"""A short GIF of the top from a stored run: the disc, the axis from the pivot, the trace of the tip.

Only the stored symmetry axis R e3 is used (the disc is drawn as a circle of
radius r at distance l along it; the spin about e3 is not drawn).  Frames are
every k-th stored sample so that the GIF shows ``seconds`` of simulated time
in at most ``max_frames`` frames.  matplotlib's PillowWriter (no ffmpeg needed).
"""

import math
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.animation import FuncAnimation, PillowWriter

from ..io import fmt_dt, pick, scene_label, scene_options, select


def animate(ds, out, sel=None, seconds=None, fps=20, max_frames=120):
    """Write a GIF of one run (first method/f/θ0 and smallest dt of ``sel``); return its path."""
    sel = sel or {}
    sub = select(ds, sel)
    method = pick(sub, "integrator")
    f = pick(sub, "f")
    th = pick(sub, "theta0")
    dt = pick(sub, "dt", prefer="min")
    run = sub.sel({"integrator": method, "f": f, "theta0": th, "dt": dt})
    time = sub.time.values
    seconds = min(float(time[-1]), 2.0) if seconds is None else float(seconds)
    n = int(np.searchsorted(time, seconds, side="right"))
    stride = max(1, math.ceil(n / max_frames))
    frames = np.arange(0, n, stride)
    axis = run.axis.values
    opts = scene_options(sub)
    arm, radius = float(opts.get("l", 1.0)), float(opts.get("r", 0.5))
    if "l" not in opts:  # free bodies: unit axis, a disc for scale
        arm, radius = 1.0, 0.3
    ring = np.linspace(0, 2 * math.pi, 49)

    fig = plt.figure(figsize=(5.0, 5.2))
    ax = fig.add_subplot(projection="3d")
    reach = arm + radius
    ax.set_xlim(-reach, reach)
    ax.set_ylim(-reach, reach)
    ax.set_zlim(-reach, reach)
    ticks = [-round(0.6 * reach, 2), 0.0, round(0.6 * reach, 2)]  # three ticks, off the corners: no collisions
    ax.set_xticks(ticks)
    ax.set_yticks(ticks)
    ax.set_zticks(ticks)
    ax.tick_params(labelsize=7, pad=0)
    ax.set_xlabel("x (m)", fontsize=8)
    ax.set_ylabel("y (m)", fontsize=8)
    ax.set_zlabel("z (m)", fontsize=8)
    ax.set_title(f"{scene_label(sub)}: {method}, f = {float(f):g} Hz, θ0 = {float(th):g}°, {fmt_dt(dt)}", fontsize=8)
    (axis_line,) = ax.plot([], [], [], "k-", lw=2)
    (disc_line,) = ax.plot([], [], [], color="C3", lw=1.5)
    (trace_line,) = ax.plot([], [], [], color="C0", lw=0.8)
    label = ax.text2D(0.02, 0.95, "", transform=ax.transAxes, fontsize=8)

    def disc(a):
        a = a / np.linalg.norm(a)
        helper = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        u = np.cross(a, helper)
        u /= np.linalg.norm(u)
        v = np.cross(a, u)
        return arm * a[:, None] + radius * (np.outer(u, np.cos(ring)) + np.outer(v, np.sin(ring)))

    def draw(k):
        a = axis[k]
        if not np.all(np.isfinite(a)):
            label.set_text(f"t = {time[k]:.3f} s (diverged)")
            return axis_line, disc_line, trace_line, label
        tip = arm * a
        axis_line.set_data_3d([0, tip[0]], [0, tip[1]], [0, tip[2]])
        d = disc(a)
        disc_line.set_data_3d(d[0], d[1], d[2])
        tr = arm * axis[: k + 1]
        trace_line.set_data_3d(tr[:, 0], tr[:, 1], tr[:, 2])
        label.set_text(f"t = {time[k]:.3f} s")
        return axis_line, disc_line, trace_line, label

    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    anim = FuncAnimation(fig, draw, frames=frames, blit=False)
    from ...safe_files import atomic_replace

    atomic_replace(out, lambda tmp: anim.save(tmp, writer=PillowWriter(fps=fps)))
    plt.close(fig)
    return out


def _render(ds, out, sel=None, seconds=None, fps=20):
    out = Path(out)
    return animate(ds, out.with_suffix(".gif") if out.suffix != ".gif" else out, sel=sel, seconds=seconds, fps=fps)


def _make_figure():
    from .record import Figure

    return Figure(
        "animation",
        "GIF of the top (disc, axis, tip trace) from a stored run",
        options={
            "--seconds": {"type": float, "default": None, "help": "simulated seconds shown (default: up to 2 s)"},
            "--fps": {"type": int, "default": 20, "help": "frames per second of the GIF (default 20)"},
        },
        file_name="animation.gif",
        render=_render,
    )


FIGURE = _make_figure()
