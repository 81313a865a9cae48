"""How far do last-bit changes and coefficient changes move the stored regression datasets?

    python tests/data/sensitivity.py

The evidence behind the regression tolerance (tests/data/README.md).  For each
stored dataset, every run is re-integrated through the batch kernels with

- last-bit changes, standing in for another CPU's libm or another numba:
  the initial ω and quaternion moved by 4 ulp, or dt by 1 and 8 ulp (every
  step's increments then change in their last bits);
- a coefficient change in lie_poisson4 (its runs only): the outer Yoshida
  weight w1 = 1/(2 − 2^(1/3)) times (1 + 1e-6), and with 2^(1/3) written
  as 1.26 (a 6e-5 relative change);

and the largest |change| of each variable is printed divided by the largest
|value| of that variable in the stored file: the quantity the regression
tolerance (SCALED_TOL in regenerate.py) bounds.
"""

import numpy as np
import xarray as xr
import yaml

from gyrolab.kernels.batch import integrate, sample_schedule
from gyrolab.kernels.driver import N_FIELDS
from gyrolab.kernels.methods.lie_poisson4 import W1
from gyrolab.kernels.scenes import build_scene
from gyrolab.results.layout import sample_variables
from gyrolab.results.migrate import current

from regenerate import DATASETS, SCALED_TOL, dataset_methods, lie_poisson4_with, read_pack, stored_path

ULP = 2.0**-52


def runs(ds):
    """(method, f, theta0, dt, scene, stride, n_samples, threshold) of every run of a stored file."""
    config = yaml.safe_load(ds.attrs["config"])
    options = dict(config["scene"])
    name = options.pop("name")
    for m in ds["integrator"].values.tolist():
        for f in ds["f"].values:
            for theta0 in ds["theta0"].values:
                for dt in ds["dt"].values:
                    stride, n = sample_schedule(float(dt), config["output"]["every"], config["sweep"]["t_end"])
                    yield (
                        m,
                        f,
                        theta0,
                        dt,
                        build_scene(name, float(f), float(theta0), **options),
                        stride,
                        n,
                        config["runner"]["divergence_threshold"],
                    )


def scaled_change(ds, perturb=None, kernel=None, only=None):
    """{variable: max |change| / max |stored value|} over the runs (of method ``only``)."""
    worst = {}
    for m, f, theta0, dt, sc, stride, n, threshold in runs(ds):
        if only and m != only:
            continue
        w0, q0, h = np.array([sc.omega0]), np.array([sc.q0]), float(dt)
        if perturb:
            w0, q0, h = perturb(w0, q0, h)
        if kernel is None:
            samples = integrate(m, np.array([sc.body]), w0, q0, h, stride, n, threshold)[0]
        else:
            samples = np.empty((1, n, N_FIELDS))
            kernel(
                w0,
                q0,
                np.array([sc.body]),
                np.array([h]),
                np.array([stride]),
                threshold,
                samples,
                np.zeros(1, np.int8),
                np.zeros(1, np.int64),
                np.zeros((1, 2), np.int64),
            )
        stored = ds.sel({"integrator": m, "f": f, "theta0": theta0, "dt": dt})
        for var, values in sample_variables(samples[0]).items():
            if var not in ds:  # a file of an older layout lacks the newer variables
                continue
            change = np.nanmax(np.abs(values - stored[var].values)) / np.nanmax(np.abs(ds[var].values))
            worst[var] = max(worst.get(var, 0.0), change)
    return worst


PERTURBATIONS = {
    "omega0, q0 by 4 ulp": lambda w, q, h: (w * (1 + 4 * ULP), q * (1 - 4 * ULP), h),
    "dt by 1 ulp": lambda w, q, h: (w, q, h * (1 + ULP)),
    "dt by 8 ulp": lambda w, q, h: (w, q, h * (1 + 8 * ULP)),
}
COEFFICIENTS = {
    "lie_poisson4 w1 x (1+1e-6)": W1 * (1 + 1e-6),
    "lie_poisson4 2^(1/3) as 1.26": 1.0 / (2.0 - 1.26),
}


def main():
    kernels = {label: lie_poisson4_with(w1) for label, w1 in COEFFICIENTS.items()}
    print(f"largest |change| / largest |stored value| per variable; regression tolerance {SCALED_TOL:g}")
    for name in DATASETS:
        ds = xr.concat(
            [current(read_pack(stored_path(name, m))) for m in dataset_methods(name)],
            dim="integrator",
            data_vars="minimal",
            coords="minimal",
            compat="override",
            combine_attrs="override",
        )
        print(f"{name}")
        rows = {"rerun as is": scaled_change(ds)}
        rows.update({label: scaled_change(ds, perturb=p) for label, p in PERTURBATIONS.items()})
        rows.update({label: scaled_change(ds, kernel=k, only="lie_poisson4") for label, k in kernels.items()})
        for label, worst in rows.items():
            print(
                f"  {label:30s} max {max(worst.values()):8.1e}   " + " ".join(f"{v}={e:.0e}" for v, e in worst.items())
            )


if __name__ == "__main__":
    main()
