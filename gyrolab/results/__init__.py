"""The results file: its layout, its migrations, combined files' members, and the one way to open one.

- ``layout``: the dims, variables, units and attrs every writer and reader uses;
- ``migrate``: files of older layouts read as today's;
- ``members``: the members of a combined file (gyrolab-combine);
- ``identity``: the config keys that identify a file's data;
- ``reader``: ``open_results``, ``open_members``, ``open_file``, ``find_results``
  and the one ``ResultsError`` (one line, exit ``EXIT_BAD_INPUT``; both in ``errors``).

Readers open files only through ``reader``; writers build them with
``layout.to_dataset`` (runner/store.py, runner/assembly.py, gyrolab-combine).

The reader's functions are imported on first use (``__getattr__``): the reader imports xarray
(~0.35 s with pandas), which the runner, writing files through h5py, does not need.
"""

from .errors import EXIT_BAD_INPUT, ResultsError

_READER = ("find_results", "open_file", "open_members", "open_results")

__all__ = ["EXIT_BAD_INPUT", "ResultsError", *_READER]


def __getattr__(name):
    if name in _READER:
        from . import reader

        return getattr(reader, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
