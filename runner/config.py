"""The config schema (dataclasses in Hydra's ConfigStore) and checks of single values.

Types and allowed keys are enforced by OmegaConf when Hydra composes the
config, so a wrong type or an unknown key fails before any work.  Scene
schemas are generated from each scene module's ``OPTIONS``: the keys of
``conf/scene/<name>.yaml`` are exactly the kernel's options.  Checks that need
the physics (scene builds, dt dividing output.every) live in ``grid.py``.

Units: sweep.f in Hz, sweep.theta0 in degrees, sweep.dt, sweep.t_end and
output.every in seconds.
"""

import dataclasses
import hashlib
import math
import re
from dataclasses import dataclass, field
from typing import Any, List, Optional

from omegaconf import MISSING, OmegaConf

from ..kernels.scenes import SCENES
from ..results.identity import RUN_ONLY, drop_neutral_defaults  # settings that change how a sweep is run, not its data
from .ranges import RESOLVERS, register_resolvers

BACKENDS = ("local", "dask")


class ConfigError(ValueError):
    """Bad input: the message is one line that names the key and the value."""


@dataclass
class SweepConfig:
    """Grid axes (lists): methods, spin f (Hz), tilt theta0 (deg), step dt (s); t_end (s)."""

    method: List[str] = field(default_factory=lambda: ["seed_next"])
    f: List[float] = field(default_factory=lambda: [10.0])
    theta0: List[float] = field(default_factory=lambda: [45.0])
    dt: List[float] = field(default_factory=lambda: [1e-4])
    t_end: float = 10.0


@dataclass
class OutputConfig:
    """every: sample interval (s); path: results file, relative to Hydra's output dir; figures: the
    figure kinds to draw after the sweep (names from analysis/figures/registry.py's registry; true: the
    default set, false: none); variables: the per-sample variables stored (names of
    gyrolab/results/layout.py's SAMPLE_VARIABLES; null: all; the per-run RUN_VARIABLES always)."""

    every: float = 1e-3
    path: str = "results.h5"
    overwrite: bool = False
    figures: Any = True
    variables: Optional[List[str]] = None


@dataclass
class RunnerConfig:
    """How the grid is run: resume, dry run, numba threads, chunk size (s), divergence test;
    backend local (numba threads in this process) or dask (a Dask cluster at ``address``,
    ``tcp://host:port`` or ``local``, or named by ``scheduler_file``; ``connect_timeout`` in s)."""

    resume: bool = False
    dry_run: bool = False
    threads: Optional[int] = None
    chunk_seconds: float = 1.0
    divergence_threshold: float = 10.0
    backend: str = "local"
    address: Optional[str] = None
    scheduler_file: Optional[str] = None
    connect_timeout: float = 10.0


@dataclass
class GyrolabConfig:
    scene: Any = MISSING
    sweep: SweepConfig = field(default_factory=SweepConfig)
    output: OutputConfig = field(default_factory=OutputConfig)
    runner: RunnerConfig = field(default_factory=RunnerConfig)


def scene_schema(name, module):
    """A dataclass with ``name`` plus one typed field per entry of the scene's OPTIONS."""
    fields = [("name", str, field(default=name))]
    for key, default in module.OPTIONS.items():
        if isinstance(default, (list, tuple)):  # a body-frame vector
            fields.append((key, List[float], field(default_factory=lambda v=list(default): list(v))))
            continue
        kind = str if isinstance(default, str) else bool if isinstance(default, bool) else float
        fields.append((key, kind, field(default=default)))
    return dataclasses.make_dataclass(f"{name.title().replace('_', '')}Scene", fields)


def register_configs():
    """Put the schemas into Hydra's ConfigStore (root ``gyrolab_schema``, ``schema/scene/<name>``)."""
    from hydra.core.config_store import ConfigStore

    register_resolvers()
    cs = ConfigStore.instance()
    cs.store(name="gyrolab_schema", node=GyrolabConfig)
    for name, module in SCENES.items():
        cs.store(group="schema/scene", name=name, node=scene_schema(name, module))


def check_figures(setting):
    """ConfigError unless ``output.figures`` is true, false or a list of registered figure names."""
    if setting is None or isinstance(setting, bool):
        return  # nothing to check: and the figure registry (matplotlib, xarray: ~0.4 s) stays unimported
    from ..analysis import figure_names

    if isinstance(setting, str):
        pass
    elif not OmegaConf.is_list(setting) and not isinstance(setting, (list, tuple)):
        raise ConfigError(f"output.figures={setting}: a list of figure names, or true / false")
    try:
        figure_names(OmegaConf.to_container(setting) if OmegaConf.is_list(setting) else setting)
    except ValueError as err:
        raise ConfigError(str(err)) from None


def check_variables(names):
    """ConfigError unless ``output.variables`` is null (all) or names each per-sample variable once."""
    from ..results.layout import chosen_variables

    if names is None:
        return
    if not OmegaConf.is_list(names) and not isinstance(names, (list, tuple)):
        raise ConfigError(f"output.variables={names}: a list of variable names, e.g. output.variables=[energy]")
    if len(names) == 0:
        raise ConfigError(
            "output.variables=[]: names no variable, so the file would hold none; "
            "leave it out (null: all) or name at least one"
        )
    try:
        chosen_variables(list(names))
    except ValueError as err:
        raise ConfigError(f"output.variables={_fmt(list(names))}: {err}") from None


def check_values(cfg):
    """ConfigError for the first value a type cannot rule out: NaN/inf, empty or
    duplicated axes, non-positive times and sizes, unknown backend, bad threads."""
    check_resolvable(cfg)
    check_keys(cfg)
    check_finite(OmegaConf.to_container(cfg, resolve=True))
    sweep, output, runner = cfg.sweep, cfg.output, cfg.runner
    for axis in ("method", "f", "theta0", "dt"):
        if not (OmegaConf.is_list(sweep[axis]) or isinstance(sweep[axis], (list, tuple))):  # a resolver's list
            raise ConfigError(f"sweep.{axis}={sweep[axis]}: a sweep axis is a list (e.g. sweep.{axis}=[{sweep[axis]}])")
        values = list(sweep[axis])
        if not values:
            raise ConfigError(f"sweep.{axis}=[]: needs at least one value")
        seen = set()
        for v in values:
            if v in seen:
                raise ConfigError(f"sweep.{axis}={_fmt(values)}: value {v} appears twice")
            seen.add(v)
    for v in sweep.dt:
        if not v > 0:
            raise ConfigError(f"sweep.dt={v}: the time step must be > 0 s")
    for v in sweep.f:
        if v < 0:
            raise ConfigError(f"sweep.f={v}: the spin frequency must be >= 0 Hz")
    for v in sweep.theta0:
        if not 0.0 <= v <= 180.0:
            raise ConfigError(f"sweep.theta0={v}: the tilt must lie in [0, 180] degrees")
    if not sweep.t_end > 0:
        raise ConfigError(f"sweep.t_end={sweep.t_end}: must be > 0 s")
    if sweep.t_end < max(sweep.dt):
        raise ConfigError(f"sweep.t_end={sweep.t_end}: shorter than the time step dt={max(sweep.dt)}")
    if not output.every > 0:
        raise ConfigError(f"output.every={output.every}: the sample interval must be > 0 s")
    if sweep.t_end < output.every:
        raise ConfigError(f"sweep.t_end={sweep.t_end}: shorter than the sample interval output.every={output.every}")
    last = last_sample(float(sweep.t_end), float(output.every))
    if last is not None:  # else the runs silently end early
        raise ConfigError(
            f"sweep.t_end={sweep.t_end}: not a multiple of output.every={output.every} (the last sample "
            f"would be at t = {last:.12g} s); make it one"
        )
    check_sizes(sweep, output)
    check_variables(output.variables)
    check_figures(output.figures)
    check_scene_options(cfg.scene)
    if not str(output.path).strip():
        raise ConfigError("output.path='': needs a file name")
    if runner.threads is not None and runner.threads < 1:
        raise ConfigError(f"runner.threads={runner.threads}: must be >= 1 (or null for all)")
    if not runner.chunk_seconds > 0:
        raise ConfigError(f"runner.chunk_seconds={runner.chunk_seconds}: must be > 0 s")
    if not runner.divergence_threshold > 0:
        raise ConfigError(f"runner.divergence_threshold={runner.divergence_threshold}: must be > 0")
    if runner.backend not in BACKENDS:
        raise ConfigError(f"runner.backend={runner.backend}: choose from {', '.join(BACKENDS)}")
    check_cluster(runner)


def last_sample(t_end, every):
    """None when the runs end at ``t_end``: it is a multiple of ``every`` to float64 rounding; else the time
    (s) of the last sample, where they would end.  The kernels' rule (kernels/batch.py sample_schedule:
    the samples of t = 0 to t_end / every rounded down, after raising it by 1e-12 relative, so a quotient
    rounded just under a whole number is that number), so no t_end they would cut short passes; the
    quotient is allowed as much over a whole number (0.3 / 0.1 is 2.9999999999999996, 1.1 / 0.1 is
    11.000000000000002), no more."""
    from ..kernels.batch import sample_schedule

    samples = t_end / every
    whole = sample_schedule(every, every, t_end)[1] - 1  # intervals the kernels store
    return None if samples - whole <= 1e-12 * samples else whole * every


# Largest sample count and step count of one run: beyond these the sizes overflow int64 arithmetic
# (steps, bytes) long before any machine could hold or run them.
MAX_SAMPLES = 2**40
MAX_STEPS = 2**62
# Spin frequencies (Hz) from which (2 pi f)^2 times a body's inertia is no longer a float64:
# every run would be infinite from t = 0.
MAX_F = 1e100


def check_sizes(sweep, output):
    """ConfigError when a run's sample count or step count cannot be represented (t_end/every,
    t_end/dt too large), or a spin frequency overflows the energy."""
    samples = sweep.t_end / output.every
    if not samples < MAX_SAMPLES:
        raise ConfigError(
            f"sweep.t_end={sweep.t_end}: {samples:.3g} samples of output.every={output.every} "
            f"per run; at most {MAX_SAMPLES:.3g} (raise output.every or lower sweep.t_end)"
        )
    for dt in sweep.dt:
        steps = sweep.t_end / dt
        if not steps < MAX_STEPS or not output.every / dt < MAX_STEPS:
            raise ConfigError(
                f"sweep.dt={dt}: {steps:.3g} steps per run over sweep.t_end={sweep.t_end}; at most {MAX_STEPS:.3g}"
            )
    for f in sweep.f:
        if f > MAX_F:
            raise ConfigError(
                f"sweep.f={f}: too fast: the spin energy overflows float64 "
                f"(every run is infinite from t = 0); at most {MAX_F:g} Hz"
            )


def check_scene_options(scene):
    """ConfigError for a scene option that the scene's other options make meaningless
    (heavy_top's ``phidot0`` is only read with ``init=precession``)."""
    options = OmegaConf.to_container(scene, resolve=True)
    module = SCENES.get(options.get("name"))
    if module is None:
        return
    if "phidot0" in module.OPTIONS and "init" in module.OPTIONS:
        phidot0, init = options.get("phidot0"), options.get("init")
        if phidot0 != module.OPTIONS["phidot0"] and init != "precession":
            raise ConfigError(f"scene.phidot0={phidot0}: only used with scene.init=precession (here scene.init={init})")


MAX_CONNECT_TIMEOUT = 86400.0  # s; beyond a day the event loop's timers overflow (1e308 did)


def check_cluster(runner):
    """ConfigError unless the cluster keys fit the backend (no network: dask_backend connects)."""
    given = [k for k in ("address", "scheduler_file") if runner[k] is not None]
    if runner.backend == "local" and given:
        raise ConfigError(f"runner.{given[0]}={runner[given[0]]}: only used with runner.backend=dask")
    if runner.backend == "dask" and not given:
        raise ConfigError(
            "runner.backend=dask: needs runner.address=tcp://host:port (or local) or runner.scheduler_file=<path>"
        )
    if len(given) == 2:
        raise ConfigError(
            f"runner.scheduler_file={runner.scheduler_file}: give runner.address "
            f"(here {runner.address}) or runner.scheduler_file, not both"
        )
    if not 0 < runner.connect_timeout <= MAX_CONNECT_TIMEOUT:
        raise ConfigError(
            f"runner.connect_timeout={runner.connect_timeout}: must be > 0 s and at most {MAX_CONNECT_TIMEOUT:g} s"
        )


def check_resolvable(cfg):
    """ConfigError naming the key and expression of the first interpolation that does not resolve
    (a range resolver's bad argument, runner/ranges.py; a list where a number belongs ...)."""
    from omegaconf.errors import OmegaConfBaseException

    for group in cfg:
        node = cfg[group]
        if not OmegaConf.is_config(node):
            continue
        raw = OmegaConf.to_container(node, resolve=False)
        for key in node:
            try:
                OmegaConf.to_container(OmegaConf.create({"v": node[key]}), resolve=True)
            except OmegaConfBaseException as err:
                text = str(err).splitlines()[0] if str(err) else type(err).__name__
                text = re.sub(r"^\w+ raised while resolving interpolation: ", "", text)
                text = re.sub(r"^While dereferencing interpolation '[^']*': ", "", text)
                if text.startswith("Unsupported interpolation type"):
                    text += f" (sweep ranges: {', '.join(RESOLVERS)}; runner/ranges.py)"
                raise ConfigError(f"{group}.{key}={raw[key]}: {text}") from None


def check_keys(cfg):
    """ConfigError for keys the schema does not know (``+key=value`` slips past OmegaConf)."""
    groups = {f.name: f.type for f in dataclasses.fields(GyrolabConfig)}
    for key in cfg:
        if key not in groups:
            raise ConfigError(f"{key}={_value(cfg, key)}: unknown config key (known: {', '.join(groups)})")
    for group, schema in groups.items():
        if not dataclasses.is_dataclass(schema):
            continue  # the scene: its options are checked against the scene module by build_scene
        known = [f.name for f in dataclasses.fields(schema)]
        for key in cfg[group]:
            if key not in known:
                raise ConfigError(
                    f"{group}.{key}={_value(cfg[group], key)}: unknown key of {group} (known: {', '.join(known)})"
                )


def _value(node, key):
    value = OmegaConf.to_container(node, resolve=True)[key]
    return _fmt(value) if isinstance(value, list) else value


def check_finite(node, key=""):
    """ConfigError naming the first float that is NaN or ±inf anywhere in a nested container."""
    if isinstance(node, dict):
        for name, value in node.items():
            check_finite(value, f"{key}.{name}" if key else str(name))
    elif isinstance(node, list):
        for value in node:
            check_finite(value, key)
    elif isinstance(node, float) and not math.isfinite(node):
        raise ConfigError(f"{key}={node}: must be a finite number")


def data_config(cfg):
    """The resolved config without the settings that do not change the results."""
    data = OmegaConf.to_container(cfg, resolve=True)
    for group, keys in RUN_ONLY.items():
        for key in keys:
            data.get(group, {}).pop(key, None)
    return drop_neutral_defaults(data)


def config_hash(cfg):
    """sha256 of the data-relevant part of the config: resume only joins runs of equal hash."""
    text = OmegaConf.to_yaml(OmegaConf.create(data_config(cfg)), sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()


def _fmt(values):
    return "[" + ",".join(str(v) for v in values) + "]"
