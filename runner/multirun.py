"""Check every job of a ``gyrolab -m`` multirun before the first one starts.

Hydra composes the jobs only as it launches them, so a bad value in the
third job would surface after two jobs of work.  This callback (wired in
``conf/config.yaml`` under ``hydra.callbacks``) expands the sweep overrides
as Hydra's basic sweeper does, composes each job's config and builds its
grid; bad input exits with status 2 and one line naming the job, the key and
the value, before any directory is made.
"""

from pathlib import Path

from hydra.core.global_hydra import GlobalHydra
from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.errors import HydraException
from hydra.experimental.callback import Callback
from hydra.types import RunMode
from omegaconf import open_dict
from omegaconf.errors import OmegaConfBaseException

from .config import ConfigError


class PrecheckCallback(Callback):
    def on_multirun_start(self, config, **kwargs):
        from hydra._internal.core_plugins.basic_sweeper import BasicSweeper

        # Which of the sweep directory and its parents exist before Hydra makes them (its sweeper runs
        # after this hook): a dry run removes only those it made (on_multirun_end).
        sweep = Path(str(config.hydra.sweep.dir)).absolute()
        self.made = [d for d in (sweep, sweep.parent, sweep.parent.parent) if not d.exists()]

        from .app import describe_hydra_error, fail
        from .grid import build_grid

        loader = GlobalHydra.instance().config_loader()
        parser = OverridesParser.create(config_loader=loader)
        # as BasicSweeper.sweep: the config's hydra.sweeper.params (experiment=verdict's scene=glob(*)), then
        # the command line's overrides
        params = [f"{k}={v}" for k, v in (config.hydra.sweeper.get("params") or {}).items()]
        arguments = params + list(config.hydra.overrides.task)
        jobs = BasicSweeper.split_arguments(parser.parse_overrides(arguments), None)[0]
        for overrides in jobs:
            try:
                cfg = loader.load_configuration(
                    config_name=kwargs.get("config_name"), overrides=overrides, run_mode=RunMode.RUN
                )
            except (HydraException, OmegaConfBaseException) as err:
                fail(f"{describe_hydra_error(err, overrides)} (in job {' '.join(overrides)})")
            with open_dict(cfg):
                del cfg["hydra"]
            try:
                grid = build_grid(cfg)
            except ConfigError as err:
                fail(f"{err} (in job {' '.join(overrides)})")
            self.grids = getattr(self, "grids", []) + [grid]

    def on_multirun_end(self, config, **kwargs):
        """A dry run leaves nothing behind: Hydra wrote the sweep's multirun.yaml before any job (each
        job only estimated and wrote nothing); it goes, and so do the sweep directory and its two
        parents (Hydra's default ``multirun/<YYYY-MM-DD>/<HH-MM-SS>``) where this multirun made them and
        they are empty.  A directory that existed before, even empty, stays."""
        if not (config.get("runner") or {}).get("dry_run"):
            return
        verdict = (config.hydra.get("callbacks") or {}).get("verdict")
        if verdict is not None and getattr(self, "grids", None):
            print(verdict_estimate(self.grids, verdict.get("stability", 10.0), config.runner.get("threads")))
        sweep = Path(str(config.hydra.sweep.dir)).absolute()
        (sweep / "multirun.yaml").unlink(missing_ok=True)
        for directory in getattr(self, "made", []):  # innermost first; never one that was there before
            try:
                directory.rmdir()  # only an empty directory: anything else there is not ours to remove
            except OSError:
                break


def verdict_estimate(grids, stability, threads=None):
    """The dry run's line for the verdict study's post-step (analysis/verdicts/study.py) over the jobs'
    ``grids``: reading the files, the (|w| dt)_crit bisection over ``stability`` s, figures, writing."""
    from ..analysis import verdict_seconds
    from .grid import step_rate
    from .preflight import resolve_threads

    parts = verdict_seconds(grids, float(stability or 0.0), step_rate, resolve_threads(threads))
    words = ", ".join(f"{part} {seconds:.3g} s" for part, seconds in parts.items())
    return f"gyrolab dry run: the verdict after the jobs: estimated {sum(parts.values()):.3g} s ({words})"
