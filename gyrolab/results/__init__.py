"""The results file: its layout, its migrations, combined files' members, and the one way to open one.

- ``layout``: the dims, variables, units and attrs every writer and reader uses;
- ``migrate``: files of older layouts read as today's;
- ``members``: the members of a combined file (gyrolab-combine);
- ``identity``: the config keys that identify a file's data;
- ``reader``: ``open_results``, ``open_members``, ``open_file``, ``find_results``
  and the one ``ResultsError`` (one line, exit ``EXIT_BAD_INPUT``).

Readers open files only through ``reader``; writers build them with
``layout.to_dataset`` (runner/store.py, runner/assembly.py, gyrolab-combine).
"""

from .reader import EXIT_BAD_INPUT, ResultsError, find_results, open_file, open_members, open_results

__all__ = ["EXIT_BAD_INPUT", "ResultsError", "find_results", "open_file", "open_members", "open_results"]
