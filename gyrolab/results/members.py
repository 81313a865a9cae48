"""Members of a combined file (gyrolab-combine): which dim stacks them, their labels, one member.

A combined file stacks one-scene results files along a leading ``scene`` or
``job`` dim; ``member`` gives one of them back as a one-scene Dataset.
"""

import json
import math

import numpy as np

from .layout import GRID_DIMS, RUN_VARIABLES, STATUS_ABSENT

# The leading dim gyrolab-combine stacks files along (analysis/files/combine.py): one scene per member, or
# jobs of one scene with different options.  A selection ``scene=NAME`` / ``job=K`` picks a member.
MEMBER_DIMS = ("scene", "job")


def member_dim(ds):
    """The dim a combined file stacks its members along (``scene`` or ``job``), or None."""
    return next((d for d in MEMBER_DIMS if d in ds.dims and "combined_from" in ds.attrs), None)


def member_labels(ds):
    """The members of a combined file as a selection names them: scene names, or job indices."""
    dim = member_dim(ds)
    if dim == "scene":
        return [str(v) for v in ds["scene"].values]
    return [str(k) for k in range(ds.sizes[dim])] if dim else []


def member(ds, label):
    """Member ``label`` (member_labels) of the combined ``ds`` as a one-scene results Dataset: the attrs that
    differed between members (stored by gyrolab-combine as coordinates along ``dim``: scene options,
    conserved, closed_form, t_end, ...) are its attrs again, and the grid values, times and run
    inputs that only other members have (status -1, NaN) are left out."""
    dim = member_dim(ds)
    k = member_labels(ds).index(str(label))
    one = ds.isel({dim: k})
    attrs = dict(one.attrs)
    for name in [c for c in one.coords if c != dim and ds[c].dims == (dim,)]:
        value = one[name].values.item() if one[name].ndim == 0 else one[name].values
        if one[name].attrs.get("encoding") == "json":
            value = np.asarray(json.loads(value)) if value else ""
        if isinstance(value, bytes):
            value = value.decode()
        if not (isinstance(value, str) and value == "") and not (isinstance(value, float) and math.isnan(value)):
            attrs[name] = value
        one = one.drop_vars(name)
    if dim == "scene":
        attrs["scene"] = label
    one = one.drop_vars([dim], errors="ignore")
    one = one.drop_vars([v for v in one.data_vars if "source" in one[v].dims])
    present = one["status"] != STATUS_ABSENT
    keep = {d: present.any(dim=[o for o in GRID_DIMS if o != d]).values for d in GRID_DIMS}
    one = one.isel({d: np.flatnonzero(mask) for d, mask in keep.items()})
    if "t_end" in attrs:  # a member of a shorter sweep: its own samples only
        one = one.isel(time=np.flatnonzero(one["time"].values <= float(attrs["t_end"]) * (1 + 1e-12)))
    for name, (dtype, _) in RUN_VARIABLES.items():  # integers again (an older combined file lacks the solver counts)
        if name in one.data_vars and np.dtype(dtype).kind in "iu":
            one[name] = one[name].astype(dtype)
    attrs["combined_member"] = f"{dim}={label}"
    return one.assign_attrs(attrs)
