"""The one error of reading results files and the exit status of bad input (no import of xarray here:
the runner, which only writes files, names them too)."""

EXIT_BAD_INPUT = 2  # every gyrolab command's exit status for bad input: a bad file, option or selection


class ResultsError(ValueError):
    """A results file that cannot be used as asked; the message is one line naming the file."""
