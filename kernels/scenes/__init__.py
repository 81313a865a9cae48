"""Scenes: a body, the forces on it and how its initial state is built.

A scene module provides ``OPTIONS`` (defaults of its options, the keys of
``conf/scene/<name>.yaml``) and ``build(f, theta0, **options) -> Scene``;
register it here.  What a scene declares through its body is all the kernels
compute: M g l = 0 skips the torque, I1 = I2 takes the closed-form free flow.
"""
from . import free_asymmetric, free_symmetric, heavy_top
from .common import Scene, check_finite, tilt_quaternion

SCENES = {
    "heavy_top": heavy_top,
    "free_symmetric": free_symmetric,
    "free_asymmetric": free_asymmetric,
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
        raise ValueError(
            f"scene.{unknown[0]}: not an option of scene {name!r} "
            f"(options: {', '.join(module.OPTIONS)})"
        )
    merged = {**module.OPTIONS, **options}
    check_finite({"f": f, "theta0": theta0, **merged})
    if f < 0:
        raise ValueError(f"f={f}: the spin frequency must be >= 0 Hz")
    if not 0.0 <= theta0 <= 180.0:
        raise ValueError(f"theta0={theta0}: the tilt must lie in [0, 180] degrees")
    return module.build(float(f), float(theta0), **merged)


__all__ = ["SCENES", "Scene", "build_scene", "get_scene", "tilt_quaternion"]
