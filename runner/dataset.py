"""The per-sample variables of a results Dataset, their units and how they are derived.

The batch kernels store axis, ω, E, L_z and L_3 per sample; θ and φ are derived
here from the axis (φ unwrapped along time, so the sample interval must resolve
the precession: less than half a turn of azimuth per sample).
"""
import numpy as np

from ..kernels.driver import STATUS_LEGEND

VARIABLE_ATTRS = {
    "axis": {"units": "1", "long_name": "symmetry axis R e3 in the lab frame"},
    "theta": {"units": "rad", "long_name": "tilt: angle between e3 and lab z"},
    "phi": {"units": "rad", "long_name": "azimuth of the axis tip, unwrapped"},
    "energy": {"units": "J", "long_name": "total energy 1/2 w.Iw + M g l cos(theta)"},
    "Lz": {"units": "kg m2 s-1", "long_name": "lab vertical angular momentum (R I w).z"},
    "L3": {"units": "kg m2 s-1", "long_name": "angular momentum along the symmetry axis I3 w3"},
    "omega": {"units": "rad s-1", "long_name": "body angular velocity (body-frame components)"},
    "status": {
        "units": "1",
        "long_name": "run status",
        "legend": "; ".join(f"{k}: {v}" for k, v in STATUS_LEGEND.items()),
    },
    "n_steps": {"units": "1", "long_name": "time steps taken"},
    "wall_time": {"units": "s", "long_name": "wall-clock time of the run"},
}
COORD_ATTRS = {
    "method": {"long_name": "integration method"},
    "f": {"units": "Hz", "long_name": "spin frequency (w3 = 2 pi f)"},
    "theta0": {"units": "deg", "long_name": "initial tilt"},
    "dt": {"units": "s", "long_name": "time step"},
    "time": {"units": "s", "long_name": "time"},
    "xyz": {"long_name": "vector component (lab x, y, z or body 1, 2, 3)"},
}


def sample_variables(samples):
    """Per-sample arrays from kernel samples (..., time, 9).

    Returns {name: array}; vectors keep a trailing axis of length 3.
    """
    axis = samples[..., 0:3]
    return {
        "axis": axis,
        "theta": np.arccos(np.clip(axis[..., 2], -1.0, 1.0)),
        "phi": unwrap_nan(np.arctan2(axis[..., 1], axis[..., 0])),
        "energy": samples[..., 6],
        "Lz": samples[..., 7],
        "L3": samples[..., 8],
        "omega": samples[..., 3:6],
    }


def unwrap_nan(phase):
    """np.unwrap along the last axis that leaves trailing NaN (diverged runs) in place."""
    filled = np.where(np.isnan(phase), 0.0, phase)
    return np.where(np.isnan(phase), np.nan, np.unwrap(filled, axis=-1))
