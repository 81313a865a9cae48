"""Files of older layouts read as today's: renamed dims, today's body, what they lack left absent.

Every reader opens files through ``current`` (gyrolab/results/reader.py does), so
analysis code speaks only today's names.

What an older layout lacks (``ABSENT_BEFORE``, per-sample and per-run variables alike) stays
absent: it is never filled in on reading, so a reader cannot take an invented value for a stored
one.  The reader (``layout.required_variables``), ``validate`` and gyrolab-compare (which reports a
variable only one file's older layout lacks as not compared) follow ``ABSENT_BEFORE``.  The one
exception is gyrolab-combine, which writes today's layout: the per-run solver counts
(``SOLVER_COUNTS``) of a member of layout 0 to 3 are filled with ``NOT_COUNTED`` (-1, "not
counted", the value an engine package's runs carry), as are the grid points a member does not have.

Layouts: 0 (no ``layout_version`` attr) to 4 (``layout.LAYOUT_VERSION``); see ``ABSENT_BEFORE`` and
``RENAMED_AT`` for what each changed, and docs/design.md.
"""

from ..kernels.body import FIELDS as BODY_FIELDS

# Files of older layouts hold the same grid and variables less these; every reader opens them.
# Layout 0: files written before layout_version existed (gyrolab at c0ed527 and earlier), without
# stored run inputs.  Layout 1: no gamma, and a body of four fields (I1, I2, I3, mgl: the centre of
# mass on e3), read as today's Body with mgc1 = mgc2 = 0.  Layout 2: a body of six fields (no
# driving torque), read as today's Body with the drive zero.  Layouts 0 to 3: no per-run solver
# counts (``solver_iterations``, ``solver_iterations_max``: added at layout 4).
SOLVER_COUNTS = ("solver_iterations", "solver_iterations_max")
ABSENT_BEFORE = {0: ("L", "gamma", *SOLVER_COUNTS), 1: ("gamma", *SOLVER_COUNTS), 2: SOLVER_COUNTS, 3: SOLVER_COUNTS}
# The solver counts of a run whose iterations were not counted (an engine package's: its solver is
# not visible), and what gyrolab-combine fills in where a member has none.
NOT_COUNTED = -1
# Dims renamed at a layout: {layout: {old name: new name}}, applied to files of every earlier layout.
# Layout 3: ``method`` -> ``integrator`` (``method`` is a keyword of xarray's .sel).
RENAMED_AT = {3: {"method": "integrator"}}


def file_layout_version(ds):
    """The layout version of an opened file: its ``layout_version`` attr; 0 for a gyrolab file from
    before that attr (it carries ``gyrolab_version`` and a ``config``); None for anything else."""
    if "layout_version" in ds.attrs:
        try:
            return int(ds.attrs["layout_version"])
        except (TypeError, ValueError):
            return None
    return 0 if "gyrolab_version" in ds.attrs and "config" in ds.attrs else None


def with_current_body(ds):
    """``ds`` with its stored ``body`` on today's ``body_param`` fields: a layout-1 body (I1, I2, I3,
    mgl: the centre of mass on e3) gains mgc1 = mgc2 = 0 and a layout-2 body a zero drive, which is
    what they meant.  Files without stored bodies, or with today's, come back unchanged."""
    if "body" not in ds.data_vars or list(ds["body_param"].values) == list(BODY_FIELDS):
        return ds
    known = [str(v) for v in ds["body_param"].values]
    if known != list(BODY_FIELDS[: len(known)]):
        return ds  # not an older gyrolab body: leave it for the reader's checks to name
    return ds.reindex(body_param=list(BODY_FIELDS), fill_value=0.0)


def with_current_dims(ds, version=None):
    """``ds`` with the dims (and their coordinates) of an older layout renamed as RENAMED_AT says
    (a layout-2 file's ``method`` becomes ``integrator``).  Files of today's layout, and files that
    are not gyrolab's (no layout version), come back unchanged."""
    version = file_layout_version(ds) if version is None else version
    if version is None:
        return ds
    renames = {
        old: new
        for since, names in RENAMED_AT.items()
        if version < since
        for old, new in names.items()
        if old in ds.dims and new not in ds.variables
    }
    return ds.rename(renames) if renames else ds


def current(ds):
    """``ds`` as today's layout names it: renamed dims (``with_current_dims``) and today's body
    (``with_current_body``).  Every reader opens files through this, so analysis code speaks only
    today's names; what an older layout lacks stays absent (``ABSENT_BEFORE``)."""
    return with_current_body(with_current_dims(ds))
