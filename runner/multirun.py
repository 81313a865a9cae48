"""Check every job of a ``gyrolab -m`` multirun before the first one starts.

Hydra composes the jobs only as it launches them, so a bad value in the
third job would surface after two jobs of work.  This callback (wired in
``conf/config.yaml`` under ``hydra.callbacks``) expands the sweep overrides
as Hydra's basic sweeper does, composes each job's config and builds its
grid; bad input exits with status 2 and one line naming the job, the key and
the value, before any directory is made.
"""

import re
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

        from .app import describe_hydra_error, fail
        from .grid import build_grid

        loader = GlobalHydra.instance().config_loader()
        parser = OverridesParser.create(config_loader=loader)
        jobs = BasicSweeper.split_arguments(parser.parse_overrides(list(config.hydra.overrides.task)), None)[0]
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
                build_grid(cfg)
            except ConfigError as err:
                fail(f"{err} (in job {' '.join(overrides)})")

    def on_multirun_end(self, config, **kwargs):
        """A dry run leaves nothing behind: Hydra wrote the sweep's multirun.yaml before any job (each
        job only estimated and wrote nothing); it goes, and so does the sweep directory once empty (and
        Hydra's default ``multirun/<YYYY-MM-DD>`` above it, each once empty)."""
        if not (config.get("runner") or {}).get("dry_run"):
            return
        sweep = Path(str(config.hydra.sweep.dir))
        (sweep / "multirun.yaml").unlink(missing_ok=True)
        for directory in (sweep, sweep.parent, sweep.parent.parent):
            if directory is sweep.parent and not re.fullmatch(r"\d{4}-\d{2}-\d{2}", directory.name):
                break
            if directory is sweep.parent.parent and directory.name != "multirun":
                break
            try:
                directory.rmdir()  # only an empty directory: anything else there is not ours to remove
            except OSError:
                break
