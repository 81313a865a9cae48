"""Scenes: a body, the forces on it and how its initial state is built.

A scene is one module here plus ``conf/scene/<name>.yaml`` and one line in
``NAMES``.  The module provides:

- a docstring whose first line is "name: summary";
- ``OPTIONS``: defaults of its options (exactly the keys of the yaml);
- ``CONSERVED``: the invariants the exact motion keeps (names from
  kernels/invariants.py); figures, tests and verdicts read this, never the
  scene's name;
- ``CLOSED_FORM``: the name of its exact solution in kernels/closed_form.py
  (``"heavy_top_nutation"``, ``"free_symmetric"``) or None;
- ``build(f, theta0, **options) -> Scene``: the body (kernels/body.py) and
  initial state for spin f (Hz) and tilt θ0 (deg).

An option is a number, a bool, a string or a list of numbers (a body-frame
vector such as heavy_body's ``com``, forced_body's time ``window``).  What a scene declares
through its body is all the kernels compute: M g c = 0 skips the torque,
I1 = I2 takes the closed-form free flow.
"""

import importlib

from ..invariants import check_names
from .common import Scene, check_finite, tilt_quaternion

# One line per scene: the module kernels/scenes/<name>.py (and conf/scene/<name>.yaml).
NAMES = (
    "heavy_top",
    "free_symmetric",
    "free_asymmetric",
    "heavy_body",
    "kovalevskaya",
    "forced_body",
)
SCENES = {name: importlib.import_module(f".{name}", __package__) for name in NAMES}


for _name, _module in SCENES.items():
    check_names(_module.CONSERVED, f"scene {_name}.CONSERVED")


def scenes():
    """{name: {"options", "conserved", "closed_form", "doc"}} for every registered scene."""
    return {
        name: {
            "options": dict(mod.OPTIONS),
            "conserved": mod.CONSERVED,
            "closed_form": mod.CLOSED_FORM,
            "doc": (mod.__doc__ or "").strip().splitlines()[0],
        }
        for name, mod in SCENES.items()
    }


def get_scene(name):
    """The scene module registered as ``name``; ValueError naming the choices."""
    try:
        return SCENES[name]
    except KeyError:
        raise ValueError(f"unknown scene {name!r}; choose from {', '.join(SCENES)}") from None


def build_scene(name, f, theta0, **options):
    """Body and initial state of scene ``name`` for spin f (Hz) and tilt θ0 (deg)."""
    module = get_scene(name)
    unknown = sorted(set(options) - set(module.OPTIONS))
    if unknown:
        raise ValueError(f"scene.{unknown[0]}: not an option of scene {name!r} (options: {', '.join(module.OPTIONS)})")
    merged = {**module.OPTIONS, **options}
    check_finite({"f": f, "theta0": theta0, **merged})
    if f < 0:
        raise ValueError(f"f={f}: the spin frequency must be >= 0 Hz")
    if not 0.0 <= theta0 <= 180.0:
        raise ValueError(f"theta0={theta0}: the tilt must lie in [0, 180] degrees")
    return module.build(float(f), float(theta0), **merged)


__all__ = ["SCENES", "Scene", "build_scene", "get_scene", "scenes", "tilt_quaternion"]
