"""Compare two results files (the layout of gyrolab/results/layout.py) variable by variable: ``gyrolab-compare A B``.
Usage examples: README.md, "Using it".

One function does the work, ``compare_files(a, b, rtol, atol) -> Report``; the
command and the regression tests both call it.  Point by point, a value passes
when ``|a − b| <= atol + rtol·max(|a|, |b|)`` (symmetric in A and B); NaN in
both files at the same place counts as equal (a run that diverged in both),
NaN against a number is a difference.  ``--scaled X`` sets each variable's atol to
X times its largest |value| in B (the reference), so one number fits variables
of any units and scene.  ``status``, ``n_steps`` and the solver counts (``solver_iterations``,
``solver_iterations_max``) are compared exactly; ``wall_time`` is ignored (timing, not physics).  Tolerances default to
0: without options the files must be bit-identical.

The runs (integrator, f, theta0, dt) are matched by label, in any order; the files
must hold the same runs (``--shared-runs``: only those in both) and the same
time samples.  Files of every layout compare with each other (an older layout's ``method`` dim
is read as ``integrator``; a variable one file's older layout lacks, such as the solver counts
before layout 4, is named as not compared).  Two combined files (gyrolab-combine) compare member by member, the
members (``scene`` or ``job``) matched by label like the runs; ``gyrolab-compare combined.h5
scene=heavy_top one.h5`` compares one member with a one-scene file.  Differences in
gyrolab/numba/numpy version or in the data-relevant config are printed before the table.

Exit status: 0 within tolerance, 1 not, 2 the files cannot be compared
(one line on stderr saying why).
"""

import argparse
import math
import sys
from dataclasses import dataclass, field

import numpy as np

from ...pipes import quiet_on_broken_pipe
from ...results.layout import GRID_DIMS as RUN_DIMS
from ...results.layout import INPUT_VARIABLES

EXACT = ("status", "n_steps", "solver_iterations", "solver_iterations_max")
IGNORED = {"wall_time": "timing, not physics"}
VERSION_ATTRS = ("gyrolab_version", "numba_version", "numpy_version")
COORD_RTOL = 1e-9  # float coordinates (f, theta0, dt, time) match to this relative tolerance
EXIT_OK, EXIT_DIFFERENT, EXIT_INCOMPARABLE = 0, 1, 2


class CompareError(ValueError):
    """The files cannot be compared; the message is one line saying why."""


class OptionError(CompareError):
    """A bad tolerance option (not a number, or naming no variable of the files)."""


@dataclass
class VariableDiff:
    """Differences of one variable.  max_abs in the variable's units; max_rel = |a−b|/max(|a|,|b|);
    n_bad of n_values points out of tolerance (n_nan of them NaN against a number); worst =
    where |a−b| is largest compared with its tolerance (labels dict), None if identical."""

    name: str
    rtol: float
    atol: float
    exact: bool
    max_abs: float = 0.0
    max_rel: float = 0.0
    n_bad: int = 0
    n_nan: int = 0
    n_values: int = 0
    worst: dict = None

    @property
    def ok(self):
        return self.n_bad == 0


@dataclass
class Report:
    """Result of ``compare_files``: provenance notes (``versions``: gyrolab/numba/numpy versions that
    differ; ``configs``: data-relevant config keys that differ), one VariableDiff per compared
    variable, the run differing most and the count of runs out of tolerance."""

    a: str
    b: str
    headers: list
    versions: list
    configs: list
    grid: str
    ignored: dict
    variables: list = field(default_factory=list)
    n_runs: int = 0
    bad_runs: int = 0
    worst_run: dict = None
    worst_run_detail: str = None
    dropped: list = field(default_factory=list)

    @property
    def ok(self):
        return all(v.ok for v in self.variables)

    @property
    def exit_status(self):
        return EXIT_OK if self.ok else EXIT_DIFFERENT

    def failed(self):
        return [v.name for v in self.variables if not v.ok]

    def text(self):
        """The human-readable report: provenance first, then the table, then the verdict."""
        lines = [f"A: {self.a}  ({self.headers[0]})", f"B: {self.b}  ({self.headers[1]})"]
        lines += [f"PROVENANCE: {p}" for p in self.versions + self.configs]
        lines.append(f"grid: {self.grid}")
        lines += [f"not compared (only in one file): {d}" for d in self.dropped]
        lines += [f"ignored: {k} ({why})" for k, why in self.ignored.items()]
        rows = [("variable", "rtol", "atol", "max |A-B|", "max rel", "out of tol", "worst at")]
        for v in self.variables:
            tol = ("exact", "exact") if v.exact else (f"{v.rtol:.3g}", f"{v.atol:.3g}")
            bad = f"{v.n_bad}/{v.n_values}" + (f" ({v.n_nan} NaN)" if v.n_nan else "")
            rows.append(
                (v.name, *tol, f"{v.max_abs:.3g}", f"{v.max_rel:.3g}", bad, _where(v.worst) if v.worst else "-")
            )
        widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]) - 1)]
        for r in rows:
            lines.append("  ".join(c.ljust(w) for c, w in zip(r, widths)) + "  " + r[-1])
        if self.worst_run is not None:
            lines.append(f"run differing most: {_where(self.worst_run, run_only=True)} ({self.worst_run_detail})")
        if self.ok:
            lines.append(f"RESULT: OK, {len(self.variables)} variables of {self.n_runs} runs within tolerance")
        else:
            lines.append(
                f"RESULT: DIFFERENT, {', '.join(self.failed())} out of tolerance "
                f"in {self.bad_runs} of {self.n_runs} runs"
            )
        return "\n".join(lines)


def _detail(name, ratio, rel, absolute):
    if math.isinf(absolute):
        return f"{name}: NaN in one file, a number in the other"
    how = "exact comparison" if math.isinf(ratio) else f"{ratio:.3g} x its tolerance"
    return f"{name}: max |A-B| {absolute:.3g}, max rel {rel:.3g}, {how}"


def _where(labels, run_only=False):
    keys = ("scene", "job") + RUN_DIMS + (() if run_only else ("time", "xyz"))
    parts = []
    for k in keys:
        if k in labels:
            v = labels[k]
            parts.append(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}")
    return " ".join(parts)


# --------------------------------------------------------------------------- tolerances


def tolerance_for(tol, name):
    """Tolerance of variable ``name`` from a number (all variables) or a dict {name: value, "*": default}."""
    if isinstance(tol, dict):
        return float(tol.get(name, tol.get("*", 0.0)))
    return float(tol)


def parse_tolerances(items, option):
    """``["energy=1e-9", "1e-12"]`` -> ``{"energy": 1e-9, "*": 1e-12}``; CompareError on bad items: an
    empty name (``=1``), or a variable (or the default) given twice (the first value would be lost)."""
    out = {}
    for item in items or []:
        name, eq, value = item.rpartition("=")
        if eq and not name.strip():
            raise OptionError(f"{option} {item}: no variable before '=' (use {option} 1e-9 or {option} energy=1e-9)")
        name = name.strip() or "*"
        if name in out:
            what = "the default" if name == "*" else name
            raise OptionError(f"{option} {item}: {what} is given twice ({option} {out[name]:g} before)")
        try:
            number = float(value)
        except ValueError:
            raise OptionError(f"{option} {item}: not a number (use {option} 1e-9 or {option} energy=1e-9)") from None
        if not (math.isfinite(number) and number >= 0):
            raise OptionError(f"{option} {item}: must be a finite number >= 0")
        out[name] = number
    return out


# --------------------------------------------------------------------------- opening and matching


def open_results(path, label, member=None):
    """A results file in memory with today's names, through the one reader (gyrolab.results) and its
    checks; CompareError naming ``label`` (A or B) and the reader's one-line reason if it cannot be
    used.  A combined file (gyrolab-combine) opens whole, every member checked, its members along a
    leading ``scene``/``job`` dim, or as the one member ``member`` names ({"scene": NAME} or
    {"job": K})."""
    from ...results import ResultsError, open_file
    from ...results.members import member_dim
    from ...results.reader import members_of

    try:
        ds, version = open_file(path)
        members = members_of(path, ds, version, member)  # every member checked as its own results file
        if member_dim(ds) is not None and not member:
            return ds
        return with_source_provenance(members[0][1], ds) if member else members[0][1]
    except ResultsError as err:
        raise CompareError(f"{label}: {err}") from None


# The provenance gyrolab-combine keeps per input file, as ``source_<attr>`` variables along ``source``.
SOURCE_ATTRS = ("gyrolab_version", "git_commit", "created", "config")


def with_source_provenance(one, combined):
    """Member ``one`` of the combined Dataset ``combined`` with the provenance attrs (SOURCE_ATTRS) of the
    input files it came from, read from the ``source_*`` variables: the sources whose stored config is
    the member's config (else whose config names the member's scene).  Several sources with different
    values give them all, joined by ", "; attrs the member already carries are kept."""
    import yaml

    from ...limits import LimitError, safe_yaml

    if "source_config" not in combined.data_vars:
        return one

    def text(name, k):
        value = combined[name].values[k]
        return value.decode() if isinstance(value, bytes) else str(value)

    n = combined.sizes["source"]
    configs = [text("source_config", k) for k in range(n)]
    mine = [k for k in range(n) if configs[k] == str(one.attrs.get("config", ""))]
    if not mine:
        scene = str(one.attrs.get("scene", ""))
        names = []
        for config in configs:
            try:
                names.append(str(((safe_yaml(config) or {}).get("scene") or {}).get("name", "")))
            except (yaml.YAMLError, AttributeError, LimitError):
                names.append("")
        mine = [k for k in range(n) if names[k] == scene]
    attrs = {}
    for key in SOURCE_ATTRS:
        if key in one.attrs or f"source_{key}" not in combined.data_vars or not mine:
            continue
        values = list(dict.fromkeys(text(f"source_{key}", k) for k in mine))
        values = [v for v in values if v]
        if values:
            attrs[key] = ", ".join(values)
    return one.assign_attrs(attrs)


def run_dims(ds):
    """The dims that label a run: a combined file's member dim (``scene``/``job``), then RUN_DIMS."""
    from ...results.members import member_dim

    dim = member_dim(ds)
    return ((dim,) if dim else ()) + RUN_DIMS


def _match(values_a, values_b):
    """Index into values_b of each of values_a (None where absent); floats match to COORD_RTOL, to
    the nearest such value (an exact one first): a grid may hold values closer than COORD_RTOL
    (sweep.dt=[1e-3,1.0000000001e-3]), and each must pair with itself, not with its neighbour."""
    out = []
    for va in values_a:
        hit, best = None, None
        for j, vb in enumerate(values_b):
            if isinstance(va, str) or isinstance(vb, str):
                gap = 0.0 if str(va) == str(vb) else None
            else:
                gap = abs(float(va) - float(vb))
                gap = gap if gap <= COORD_RTOL * max(abs(float(va)), abs(float(vb))) else None
            if gap is not None and (best is None or gap < best):
                hit, best = j, gap
        out.append(hit)
    return out


def _fmt_values(values):
    return "[" + ", ".join(f"{v:g}" if isinstance(v, float) else str(v) for v in values) + "]"


def align(da, db, shared_runs=False):
    """(A, B) restricted to the same runs in A's order, and notes on runs left out.

    CompareError when the runs or the time samples differ (or share nothing)."""
    dropped = []
    sel_a, sel_b = {}, {}
    for dim in run_dims(da):
        va, vb = [v.item() for v in da[dim].values], [v.item() for v in db[dim].values]
        ia, ib = _match(va, vb), _match(vb, va)
        if None in ia or None in ib:
            if not shared_runs:
                raise CompareError(
                    f"different grids: {dim} is {_fmt_values(va)} in A and {_fmt_values(vb)} in B "
                    "(use --shared-runs to compare only the runs in both)"
                )
            keep = [i for i, j in enumerate(ia) if j is not None]
            if not keep:
                raise CompareError(
                    f"nothing to compare: no {dim} in both files (A {_fmt_values(va)}, B {_fmt_values(vb)})"
                )
            only_a = [va[i] for i, j in enumerate(ia) if j is None]
            only_b = [vb[i] for i, j in enumerate(ib) if j is None]
            dropped.append(f"{dim} {_fmt_values(only_a)} only in A, {_fmt_values(only_b)} only in B")
            sel_a[dim] = keep
            sel_b[dim] = [ia[i] for i in keep]
        else:
            sel_b[dim] = ia
    ta, tb = da["time"].values, db["time"].values
    if ta.shape != tb.shape or not np.allclose(ta, tb, rtol=COORD_RTOL, atol=COORD_RTOL * max(ta.max(), 1e-300)):
        raise CompareError(
            f"different grids: time has {ta.size} samples to {ta[-1]:g} s in A "
            f"and {tb.size} samples to {tb[-1]:g} s in B"
        )
    da = da.isel(sel_a) if sel_a else da
    db = db.isel(sel_b)
    return da, db, dropped


# --------------------------------------------------------------------------- provenance


def _header(ds):
    at = ds.attrs
    commit = str(at.get("git_commit", "?"))[:10] + ("+dirty" if at.get("git_dirty", 0) == 1 else "")
    return (
        f"gyrolab {at.get('gyrolab_version', '?')}, git {commit}, numba {at.get('numba_version', '?')}, "
        f"numpy {at.get('numpy_version', '?')}, created {at.get('created', '?')}"
    )


def _flatten(node, prefix=""):
    if isinstance(node, dict):
        out = {}
        for k, v in node.items():
            out.update(_flatten(v, f"{prefix}.{k}" if prefix else str(k)))
        return out
    return {prefix: node}


def data_config(text):
    """The flattened config of a file's ``config`` attr, without the keys that do not change data."""
    import yaml

    from ...limits import LimitError, safe_yaml
    from ...results.identity import RUN_ONLY, drop_neutral_defaults

    try:
        data = safe_yaml(text) or {}
    except (yaml.YAMLError, LimitError):  # bad syntax, or a bomb / recursive alias: compared as text
        data = None
    if not isinstance(data, dict):
        return {"config": str(text)}  # not a gyrolab config (a foreign or hand-made file): compared as text
    for group, keys in RUN_ONLY.items():
        node = data.get(group)
        for key in keys if isinstance(node, dict) else ():
            node.pop(key, None)
    return _flatten(drop_neutral_defaults(data))


def version_notes(da, db):
    """Lines naming each of gyrolab/numba/numpy version that differs between the files' makers."""
    notes = []
    for key in VERSION_ATTRS:
        va, vb = da.attrs.get(key), db.attrs.get(key)
        if (va is None) != (vb is None):  # a combined file keeps only SOURCE_ATTRS per input file
            notes.append(f"{key} recorded only in {'A' if vb is None else 'B'}")
        elif va != vb:
            notes.append(f"{key} differs: A {va}, B {vb}")
    return notes


def config_notes(da, db):
    """Lines naming the data-relevant config keys that differ (run-only keys such as output.path skipped)."""
    ca, cb = da.attrs.get("config"), db.attrs.get("config")
    if ca is None or cb is None:
        return [] if ca is None and cb is None else [f"config recorded only in {'A' if cb is None else 'B'}"]
    fa, fb = data_config(ca), data_config(cb)
    diffs = [
        f"{k}: A {fa.get(k, '(absent)')}, B {fb.get(k, '(absent)')}"
        for k in sorted(set(fa) | set(fb))
        if fa.get(k) != fb.get(k)
    ]
    return ["config differs: " + "; ".join(diffs)] if diffs else []


# --------------------------------------------------------------------------- the comparison


def _diff_block(a, b, exact):
    """Per-point |a−b|, relative difference and NaN-mismatch mask; NaN at the same place in both = equal."""
    if exact:
        a, b = a.astype(np.float64), b.astype(np.float64)
    nan_a, nan_b = np.isnan(a), np.isnan(b)
    one_nan = nan_a ^ nan_b
    with np.errstate(invalid="ignore", over="ignore"):
        d = np.where((a == b) | (nan_a & nan_b), 0.0, np.abs(a - b))
        d = np.where(one_nan, np.inf, d)
        scale = np.fmax(np.abs(a), np.abs(b))
        scale = np.where(np.isnan(scale), 0.0, scale)
        rel = np.where(d == 0, 0.0, np.where(scale > 0, d / np.where(scale > 0, scale, 1.0), np.inf))
    return d, rel, scale, one_nan


def _first_largest(key, tiebreak):
    """Flat index of the largest ``key`` (ties: largest ``tiebreak``, then the first in C order,
    i.e. the earliest time: where a NaN-filled divergence starts)."""
    key, tiebreak = key.ravel(), tiebreak.ravel()
    top = np.lexsort((tiebreak, key))[-1]
    return int(np.flatnonzero((key == key[top]) & (tiebreak == tiebreak[top]))[0])


def compare_variable(name, a, b, rtol, atol, exact, dims, coords, n_run_dims=len(RUN_DIMS)):
    """VariableDiff of one variable from aligned arrays a, b with dims ``dims``; also the per-run
    maxima (|a−b| / tolerance, relative difference, |a−b|) as arrays over the run dims (the first
    ``n_run_dims`` of ``dims``) and the per-run flag "some point out of tolerance"."""
    vd = VariableDiff(name, rtol, atol, exact)
    d, rel, scale, one_nan = _diff_block(a, b, exact)
    bound = np.zeros_like(d) if exact else atol + rtol * scale
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(d == 0, 0.0, np.where(bound > 0, d / np.where(bound > 0, bound, 1.0), np.inf))
    bad = d > bound
    vd.n_values, vd.n_bad, vd.n_nan = int(d.size), int(bad.sum()), int(one_nan.sum())
    finite = np.where(np.isinf(d), np.nan, d)
    vd.max_abs = float(np.nanmax(finite)) if np.isfinite(finite).any() else (math.inf if vd.n_nan else 0.0)
    finite_rel = np.where(np.isinf(rel), np.nan, rel)
    vd.max_rel = (
        float(np.nanmax(finite_rel)) if np.isfinite(finite_rel).any() else (math.inf if np.isinf(rel).any() else 0.0)
    )
    if d.size and d.max() > 0:
        at = np.unravel_index(_first_largest(ratio, rel), d.shape)
        vd.worst = {dim: coords[dim][i] for dim, i in zip(dims, at)}
    sample_axes = tuple(range(n_run_dims, d.ndim))
    run_ratio = ratio.max(axis=sample_axes) if sample_axes else ratio
    run_rel = rel.max(axis=sample_axes) if sample_axes else rel
    run_bad = bad.any(axis=sample_axes) if sample_axes else bad
    run_abs = d.max(axis=sample_axes) if sample_axes else d
    return vd, (run_ratio, run_rel, run_abs), run_bad


def compare_datasets(da, db, rtol=0.0, atol=0.0, ignore=(), shared_runs=False, scaled=None, names=("A", "B")):
    """Compare two opened results Datasets; see ``compare_files``."""
    from ...results.members import member_dim, member_labels
    from ...results.migrate import current

    da, db = current(da), current(db)
    ignored = dict(IGNORED)
    from ...results.layout import RUN_VARIABLES, SAMPLE_VARIABLES, absence_reason, held_variables

    for name in ignore:  # a misspelt --ignore would leave the variable compared and say nothing of it
        known = name in SAMPLE_VARIABLES or name in RUN_VARIABLES  # (absent from files of an older layout)
        if not known and name not in da.data_vars and name not in db.data_vars:
            held = sorted(set(da.data_vars) | set(db.data_vars))
            raise OptionError(f"--ignore {name}: no variable {name} in either file (variables: {', '.join(held)})")
    ignored.update({name: "asked" for name in ignore})
    dims = [member_dim(d) for d in (da, db)]
    if dims[0] != dims[1]:
        if dims[0] and dims[1]:
            raise CompareError(f"A is combined along {dims[0]} and B along {dims[1]}: compare one member of each")
        k = 0 if dims[0] else 1
        whole, one = (da, db) if k == 0 else (db, da)
        words = list(names)
        words.insert(k + 1, f"{dims[k]}={member_labels(whole)[0]}")
        raise CompareError(
            f"{'AB'[k]} is a combined file of {dims[k]}s {', '.join(member_labels(whole))}, {'AB'[1 - k]} "
            f"one scene ({one.attrs.get('scene')}): select a member after its file, "
            f"gyrolab-compare {' '.join(map(str, words))}"
        )
    if da.attrs.get("scene") != db.attrs.get("scene"):
        raise CompareError(f"different scenes: {da.attrs.get('scene')} in A and {db.attrs.get('scene')} in B")
    keys = run_dims(da)
    versions, configs = version_notes(da, db), config_notes(da, db)
    da, db, dropped = align(da, db, shared_runs)
    # The runs' inputs (body, initial state) are not results: a difference is a provenance note, and
    # files written before they were stored compare with files that have them.
    inputs = input_notes(da, db)
    # A combined file's provenance of its inputs (source_* along ``source``) is not results either.
    for d in (da, db):
        ignored.update({v: "provenance of the combined files" for v in d.data_vars if "source" in d[v].dims})
    va = [v for v in da.data_vars if v not in ignored and v not in INPUT_VARIABLES]
    vb = [v for v in db.data_vars if v not in ignored and v not in INPUT_VARIABLES]
    from ...results.migrate import ABSENT_BEFORE, file_layout_version

    # A file of an older layout lacks some variables: compare the rest, and say so.
    older = {name: set(ABSENT_BEFORE.get(file_layout_version(d), ())) for name, d in zip(names, (da, db))}
    for v in sorted((set(va) ^ set(vb)) & (older[names[0]] | older[names[1]])):
        dropped.append(f"variable {v} (not in the older layout of one file)")
        va, vb = [x for x in va if x != v], [x for x in vb if x != v]
    # A file written with output.variables holds only the chosen ones, one written before a variable was
    # added lacks it: compare the rest, and say so.
    unchosen = {name: set(SAMPLE_VARIABLES) - set(held_variables(d)) for name, d in zip(names, (da, db))}
    for v in sorted((set(va) ^ set(vb)) & (unchosen[names[0]] | unchosen[names[1]])):
        which, d = (names[0], da) if v in unchosen[names[0]] else (names[1], db)
        dropped.append(f"variable {v} (not stored in {which}: {absence_reason(d, v)})")
        va, vb = [x for x in va if x != v], [x for x in vb if x != v]
    for v in va:
        if v not in vb:
            raise CompareError(f"missing variables: {v} is in A but not in B")
    for v in vb:
        if v not in va:
            raise CompareError(f"missing variables: {v} is in B but not in A")
    for tol, option in ((rtol, "--rtol"), (atol, "--atol")):
        for key in tol if isinstance(tol, dict) else {}:
            if key != "*" and key not in va:
                raise OptionError(
                    f"{option} {key}={tol[key]}: no variable {key} to compare (variables: {', '.join(va)})"
                )
            if key in EXACT:
                raise OptionError(f"{option} {key}={tol[key]}: {key} is compared exactly")
    coords = {d: [x.item() for x in da[d].values] for d in da.dims}
    shape = tuple(da.sizes[d] for d in keys)
    scene = da.attrs.get("scene") or "combined"
    grid = (
        f"scene {scene}; "
        + " x ".join(f"{n} {d}" for d, n in zip(keys, shape))
        + f" = {int(np.prod(shape))} runs; {da.sizes['time']} samples, t = 0 to {coords['time'][-1]:g} s"
    )
    report = Report(
        a=names[0],
        b=names[1],
        headers=[_header(da), _header(db)],
        versions=versions + inputs,
        configs=configs,
        grid=grid,
        ignored={k: v for k, v in ignored.items() if k in da.data_vars or k in db.data_vars},
        dropped=dropped,
        n_runs=int(np.prod(shape)),
    )
    best = [np.full(shape, -1.0), np.full(shape, -1.0), np.zeros(shape)]  # ratio, rel, abs of the worst variable
    best_var = np.full(shape, "", dtype=object)
    any_bad = np.zeros(shape, dtype=bool)
    for name in va:
        xa, xb = da[name], db[name]
        if set(xa.dims) != set(xb.dims) or tuple(xa.dims[: len(keys)]) != keys:
            raise CompareError(f"different layout: {name} has dims {xa.dims} in A and {xb.dims} in B")
        a, b = xa.values, xb.transpose(*xa.dims).values
        exact = name in EXACT or not np.issubdtype(a.dtype, np.floating)
        vd, per_run, run_bad = compare_variable(
            name,
            a,
            b,
            tolerance_for(rtol, name),
            variable_atol(atol, scaled, name, b),
            exact,
            xa.dims,
            coords,
            len(keys),
        )
        report.variables.append(vd)
        better = (per_run[0] > best[0]) | ((per_run[0] == best[0]) & (per_run[1] > best[1]))
        for mine, theirs in zip(best, per_run):
            mine[better] = theirs[better]
        best_var[better] = name
        any_bad |= run_bad
    report.bad_runs = int(any_bad.sum())
    k = _first_largest(best[0], best[1])
    if best[0].ravel()[k] > 0:
        at = np.unravel_index(k, shape)
        report.worst_run = {d: coords[d][i] for d, i in zip(keys, at)}
        report.worst_run_detail = _detail(best_var[at], *(x[at] for x in best))
    return report


def input_notes(da, db):
    """Notes on the stored run inputs (body, omega0, q0) that differ between two aligned files: a
    provenance note, not a failure (the results decide), so files from before a change of the body
    record still compare."""
    notes = []
    for name in INPUT_VARIABLES:
        if name in da.data_vars and name in db.data_vars:
            a, b = da[name], db[name]
            if a.dims != b.dims or a.shape != b.shape or not np.array_equal(a.values, b.values):
                notes.append(f"run inputs differ: {name}")
    return notes


def variable_atol(atol, scaled, name, reference):
    """atol of one variable: given for it by name, else the larger of the default atol and
    ``scaled`` × its largest finite |value| in the reference (B)."""
    if isinstance(atol, dict) and name in atol:
        return float(atol[name])
    value = tolerance_for(atol, name)
    if scaled and np.issubdtype(reference.dtype, np.floating):
        finite = np.abs(reference[np.isfinite(reference)])
        value = max(value, scaled * float(finite.max()) if finite.size else 0.0)
    return value


def compare_files(a, b, rtol=0.0, atol=0.0, ignore=(), shared_runs=False, scaled=None, members=(None, None)):
    """Compare results files ``a`` and ``b`` (paths) variable by variable.

    rtol, atol: a number for every variable or a dict {variable: value, "*": default};
    a point passes when |a−b| <= atol + rtol·max(|a|,|b|) (atol in the variable's units).
    ``scaled``: atol of each variable not named in ``atol`` becomes at least ``scaled`` × its
    largest |value| in b.
    ``ignore``: more variables to skip (wall_time always is).  ``shared_runs``: compare only
    the runs present in both files.  ``members``: for a combined file, the member to compare
    ({"scene": NAME} or {"job": K}; None: the whole file, its members matched by label).
    Returns a Report; raises CompareError (one-line message) when the files cannot be compared.
    """
    da = open_results(a, "A", members[0])
    db = open_results(b, "B", members[1])
    names = [f"{p} {' '.join(f'{k}={v}' for k, v in (m or {}).items())}".strip() for p, m in zip((a, b), members)]
    return compare_datasets(da, db, rtol, atol, ignore, shared_runs, scaled, names=tuple(names))


def operands(words):
    """[(path, member)] of the command line's FILE [scene=NAME | job=K] FILE [...]: a member
    selection applies to the file before it (a word that is an existing file is a file)."""
    from pathlib import Path

    out = []
    for word in words:
        key, eq, value = word.partition("=")
        if eq and key in ("scene", "job") and not Path(word).exists():
            if not out:
                raise OptionError(f"{word}: a member selection follows the combined file it selects from")
            if out[-1][1]:
                raise OptionError(f"{word}: one member per file ({out[-1][0]} has {out[-1][1]})")
            out[-1] = (out[-1][0], {key: value})
        else:
            out.append((word, None))
    if len(out) != 2:
        raise OptionError(f"{' '.join(words)}: give two files, A and B (each may be followed by scene=NAME or job=K)")
    return out


# --------------------------------------------------------------------------- command line


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        sys.stderr.write(f"gyrolab-compare: error: {message}\n")
        sys.exit(EXIT_INCOMPARABLE)


def _non_negative(text):
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text}: not a number") from None
    if not (math.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(f"{text}: must be a finite number >= 0")
    return value


def build_parser():
    p = _Parser(
        prog="gyrolab-compare",
        description="Compare two gyrolab results files variable by variable.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="exit status: 0 within tolerance, 1 out of tolerance, 2 cannot compare",
    )
    p.add_argument(
        "files",
        nargs="+",
        metavar="A [scene=NAME|job=K] B [scene=NAME|job=K]",
        help="results files A (e.g. a fresh run) and B (e.g. the stored reference); after a combined file "
        "(gyrolab-combine), scene=NAME or job=K compares that member only",
    )
    p.add_argument(
        "--rtol",
        action="append",
        metavar="[VAR=]X",
        help="relative tolerance, for every variable or for VAR (repeatable; default 0)",
    )
    p.add_argument(
        "--atol",
        action="append",
        metavar="[VAR=]X",
        help="absolute tolerance in the variable's units, for every variable or for VAR (repeatable; default 0)",
    )
    p.add_argument(
        "--scaled",
        type=_non_negative,
        metavar="X",
        help="atol of each variable not given by --atol VAR=: at least X times its largest |value| in B",
    )
    p.add_argument(
        "--ignore",
        action="append",
        default=[],
        metavar="VAR",
        help="skip a variable (repeatable; a name no file or layout has is refused); wall_time is always skipped",
    )
    p.add_argument(
        "--shared-runs",
        action="store_true",
        help="compare only the runs (integrator, f, theta0, dt) present in both files",
    )
    return p


@quiet_on_broken_pipe
def main(argv=None):
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        (a, ma), (b, mb) = operands(args.files)
    except OptionError as err:  # a usage error, like argparse's own
        parser.error(str(err))
    try:
        rtol = parse_tolerances(args.rtol, "--rtol")
        atol = parse_tolerances(args.atol, "--atol")
        report = compare_files(a, b, rtol, atol, args.ignore, args.shared_runs, args.scaled, members=(ma, mb))
    except CompareError as err:
        kind = "error" if isinstance(err, OptionError) else "cannot compare"
        sys.stderr.write(f"gyrolab-compare: {kind}: {err}\n")
        return EXIT_INCOMPARABLE
    print(report.text())
    return report.exit_status


if __name__ == "__main__":
    sys.exit(main())
