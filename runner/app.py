"""The ``gyrolab`` command (a Hydra app): config → grid → chunks → one results file.

Usage examples are in README.md ("Using it"); ``gyrolab --help`` lists the
config groups.  The results go to ``output.path`` (default ``results.h5``) in
Hydra's output directory, figures to ``figures/`` next to it.

This module is the entry point: Hydra's composition, and every error before
or during it turned into one line on stderr and exit status 2, before any work
and without leaving files behind.  The rest, one concern a module:
runner/signals.py (Ctrl-C, SIGTERM and SIGHUP: keep the journal, print the
resume command, exit 128 + the signal number), runner/preflight.py (the checks
before any work, and the dry run's plan), runner/sweep.py (the sweep: run the
missing runs, assemble the file, draw the figures; a full disk or another I/O
error is one line and exit 1 with the journal intact) on a backend
(runner/local_backend.py, this process's threads, or runner/dask_backend.py).
A reader of stdout that stops early (``gyrolab --help | head -5``) ends gyrolab quietly with exit status
141 (128 + SIGPIPE; gyrolab/pipes.py).
Test hook: the environment variable GYROLAB_TEST_CHUNK_DELAY (seconds) sleeps
after each stored chunk.
"""

import os
import re
import sys
from pathlib import Path

import hydra
from hydra.core.hydra_config import HydraConfig
from hydra.errors import HydraException
from omegaconf.errors import OmegaConfBaseException

from ..pipes import quiet_on_broken_pipe, stop_on_broken_pipe
from ..results import EXIT_BAD_INPUT
from ..safe_files import OutputBusyError, UnsafePathError
from .config import ConfigError, register_configs
from .preflight import check_run_dirs
from .signals import exit_status, handle_signals, ignore_signals, signal_name
from .sweep import run_sweep


def fail(message):
    """Print one line and exit with the bad-input status."""
    sys.stderr.write(f"gyrolab: error: {' '.join(str(message).split())}\n")
    sys.stderr.flush()
    sys.exit(EXIT_BAD_INPUT)


def remove_empty_dirs(directory, stop):
    """Remove ``directory`` and its parents while they are empty, up to ``stop`` (excluded)."""
    directory, stop = Path(directory).resolve(), Path(stop).resolve()
    while directory != stop and stop in directory.parents:
        try:
            directory.rmdir()
        except OSError:
            return
        directory = directory.parent


@hydra.main(version_base=None, config_path="pkg://gyrolab.conf", config_name="config")
def hydra_main(cfg):
    run_dir = HydraConfig.get().runtime.output_dir
    try:
        return run_sweep(cfg, run_dir)
    except (ConfigError, OutputBusyError, UnsafePathError) as err:
        remove_empty_dirs(run_dir, os.getcwd())
        fail(err)
    except BrokenPipeError:  # here, or Hydra reports the job as failed on stderr
        stop_on_broken_pipe()
    finally:
        if cfg.runner.dry_run:
            remove_empty_dirs(run_dir, os.getcwd())


# --------------------------------------------------------------------------- errors from Hydra itself


def describe_hydra_error(err, argv):
    """One line naming the key and value of a composition error from Hydra/OmegaConf."""
    cause = err.__cause__ if isinstance(err.__cause__, OmegaConfBaseException) else None
    text = str(err)
    missing = re.search(r"Could not find '([^']+)/([^']+)'", text)
    if missing:
        group, name = missing.groups()
        options = re.search(rf"Available options in '{re.escape(group)}':\n((?:\t.*\n?)*)", text)
        choices = ", ".join(o.strip() for o in options.group(1).splitlines()) if options else ""
        return f"{group}={name}: unknown {group}" + (f"; choose from {choices}" if choices else "")
    key = getattr(cause or err, "full_key", None)
    override = re.search(r"override '([^']+)'", text) or re.search(r"override (\S+)", text)
    token = getattr(err, "override", None) or (override.group(1) if override else None)
    if token and "=" not in token:
        token = next((a for a in argv if a.lstrip("+~").startswith(token + "=")), token)
    if token is None and key:
        token = next((a for a in argv if a.lstrip("+~").startswith(f"{key}=")), key)
    reason = str(cause) if cause is not None else text
    if cause is None and override and "\n" in text:
        reason = text.split("\n", 1)[1]
    lines = [line.strip() for line in reason.strip().splitlines() if line.strip()]
    if lines and lines[0].endswith("raised while composing config:") and len(lines) > 1:
        lines = lines[1:]  # Hydra's heading; the reason is on the next line
    reason = lines[0] if lines else type(err).__name__
    if key is None:
        key = next(
            (line.split(":", 1)[1].strip() for line in text.splitlines() if line.strip().startswith("full_key:")), None
        )
        if key and token is None:
            token = next((a for a in argv if a.lstrip("+~").startswith(f"{key}=")), None)
            in_file = re.search(r"In '([^']+)'", text)
            token = token or (f"{key} (in {in_file.group(1)}.yaml)" if in_file else key)
    if "is not a ListConfig" in reason:
        reason += list_hint((token or key or "").lstrip("+~").split("=", 1)[0])
    return f"{token}: {reason}" if token else reason


def list_hint(name):
    """A hint, in parentheses, for a value given to ``name`` (a full key) that takes a list."""
    from ..kernels.scenes import SCENES

    if name.startswith("sweep."):
        return " (sweep axes are lists, e.g. sweep.f=[10])"
    option = name.split(".", 1)[1] if name.startswith("scene.") else None
    vectors = [m.OPTIONS[option] for m in SCENES.values() if isinstance(m.OPTIONS.get(option), (list, tuple))]
    if vectors:
        example = ",".join(f"{float(v):g}" for v in vectors[0])
        return f" ({name} is a body-frame vector of three numbers [x, y, z], e.g. {name}=[{example}])"
    if name == "output.variables":
        return " (output.variables is a list of names, e.g. output.variables=[theta,energy])"
    return f" ({name} takes a list, in brackets)" if name else ""


def describe_yaml_error(err):
    """One line naming the file, line and problem of a YAML syntax error in a config file."""
    mark = getattr(err, "problem_mark", None) or getattr(err, "context_mark", None)
    where = f"{mark.name}, line {mark.line + 1}, column {mark.column + 1}" if mark is not None else "a config file"
    problem = getattr(err, "problem", None) or str(err).splitlines()[0]
    return f"{where}: YAML syntax error: {problem}"


@quiet_on_broken_pipe
def main():
    """Console entry point ``gyrolab``.  When the reader of stdout closes the pipe (``gyrolab --help | head -5``,
    ``gyrolab runner.dry_run=true ... | head -3``), gyrolab stops quietly, no traceback, with status 141
    (gyrolab/pipes.py); a write that fails while the runs are computed is runner/sweep.py's I/O error."""
    return _main()


def _main():
    import yaml

    register_configs()
    if os.environ.get("HYDRA_FULL_ERROR"):  # the user asked for Hydra's own tracebacks
        return hydra_main()
    os.environ["HYDRA_FULL_ERROR"] = "1"  # let composition errors reach us instead of a printed trace
    handle_signals()
    try:
        check_run_dirs(sys.argv[1:])
        hydra_main()
    except (ConfigError, OutputBusyError, UnsafePathError) as err:
        fail(err)
    except (HydraException, OmegaConfBaseException) as err:
        fail(describe_hydra_error(err, sys.argv[1:]))
    except yaml.YAMLError as err:
        fail(describe_yaml_error(err))
    except (FileExistsError, FileNotFoundError, NotADirectoryError, PermissionError) as err:  # Hydra's mkdir
        fail(f"hydra.run.dir: cannot make {err.filename}: {err.strerror}")
    except KeyboardInterrupt as err:  # before the sweep started (imports, composition, checks)
        ignore_signals()
        sys.stderr.write(f"gyrolab: interrupted ({signal_name(err)}) before any run started; nothing was saved\n")
        sys.exit(exit_status(err))


if __name__ == "__main__":
    main()
