"""What gyrolab does with an existing output, and how Hydra's errors become one line."""

import re

import pytest
from hydra import compose, initialize_config_module

from gyrolab.kernels.scenes import SCENES
from gyrolab.runner.app import describe_hydra_error, remove_empty_dirs
from gyrolab.runner.config import ConfigError, register_configs
from gyrolab.runner.preflight import output_state, resolve_output
from gyrolab.runner.store import Journal

register_configs()


@pytest.fixture
def out(tmp_path):
    return tmp_path / "results.h5"


def test_fresh_output_is_fresh_unless_a_resume_finds_nothing(out):
    for overwrite in (False, True):
        assert output_state(out, "h", overwrite, False) == "fresh"
    assert output_state(out, "h", True, True) == "fresh"
    with pytest.raises(ConfigError, match="runner.resume=true: nothing to resume"):
        output_state(out, "h", False, True)


def test_existing_file_needs_overwrite_or_a_matching_resume(out):
    out.write_bytes(b"not hdf5")
    with pytest.raises(ConfigError, match="exists; set output.overwrite=true"):
        output_state(out, "h", False, False)
    with pytest.raises(ConfigError, match="different config"):
        output_state(out, "h", False, True)  # unreadable: no hash to match
    assert output_state(out, "h", True, False) == "fresh"


def test_journal_resumes_only_with_the_same_config(out):
    Journal(out).create({"config_hash": "h"})
    with pytest.raises(ConfigError, match="runner.resume=true or start over"):
        output_state(out, "h", False, False)
    assert output_state(out, "h", False, True) == "resume"
    with pytest.raises(ConfigError, match="runner.resume=true: .* different config"):
        output_state(out, "other", False, True)
    assert output_state(out, "h", True, False) == "fresh"


def composition_error(*overrides):
    with initialize_config_module(config_module="gyrolab.conf", version_base=None):
        with pytest.raises(Exception) as info:
            compose("config", overrides=list(overrides))
    return describe_hydra_error(info.value, list(overrides))


@pytest.mark.parametrize(
    "override, line",
    [
        ("sweep.t_end=ten", "sweep.t_end=ten: Value 'ten' of type 'str' could not be converted to Float"),
        (
            "scene=plate",
            "scene=plate: unknown scene; choose from " + ", ".join(sorted(SCENES)),
        ),
        ("sweep.tend=3", "sweep.tend=3: Key 'tend' not in 'SweepConfig'"),
        (
            "sweep.f=5",
            "sweep.f=5: Invalid value assigned: int is not a ListConfig, list or tuple. "
            "(sweep axes are lists, e.g. sweep.f=[10])",
        ),
    ],
)
def test_hydra_errors_become_one_line_with_key_and_value(override, line):
    assert composition_error(override) == line


@pytest.mark.parametrize(
    "overrides, hint",
    [
        (("sweep.f=5",), "(sweep axes are lists, e.g. sweep.f=[10])"),
        (
            ("scene=heavy_body", "scene.com=3"),
            "(scene.com is a body-frame vector of three numbers [x, y, z], e.g. scene.com=[0.03,0.01,0.1])",
        ),
        (("output.variables=theta",), "(output.variables is a list of names, e.g. output.variables=[theta,energy])"),
    ],
)
def test_a_value_that_should_be_a_list_gets_the_hint_of_its_key(overrides, hint):
    """scene.com=3 was told that sweep axes are lists."""
    line = composition_error(*overrides)
    assert line.startswith(f"{overrides[-1]}: ") and line.endswith(hint)
    assert line.count("(") == 1


@pytest.mark.parametrize("path", ["sub/", "a/sub/", "/abs/sub/", "sub/.", ".", ".."])
def test_an_output_path_naming_a_directory_is_refused(tmp_path, path):
    """output.path=sub/ wrote the results into a file named sub."""
    with pytest.raises(ConfigError, match=rf"output.path={re.escape(path)}: names a directory, not a file"):
        resolve_output(path, tmp_path)
    assert resolve_output("sub/results.h5", tmp_path) == tmp_path.resolve() / "sub" / "results.h5"


@pytest.mark.parametrize("overwrite", [False, True])
def test_a_journal_that_cannot_be_resumed_says_what_to_do(out, overwrite):
    """runner.resume=true over a journal of another config or other kernel code, or a damaged one, is refused
    whatever output.overwrite (a resume never discards the runs it was asked to finish), and the message
    says what to do: leave out runner.resume=true, with output.overwrite=true.  It used to say "set
    output.overwrite=true" when it was set."""
    action = "leave out runner.resume=true" + (
        " (output.overwrite=true is set)" if overwrite else " and set output.overwrite=true"
    )
    Journal(out).create({"config_hash": "h"})
    with pytest.raises(ConfigError, match="different config") as info:
        output_state(out, "other", overwrite, True)
    assert str(info.value).endswith(f"to discard them and start over, {action}")
    Journal(out).create({"config_hash": "h", "kernel_source_hash": "0123456789abcdef-old-code"})
    with pytest.raises(ConfigError, match="other kernel code") as info:
        output_state(out, "h", overwrite, True)
    assert str(info.value).endswith(f"or to discard them and start over, {action}")
    Journal(out).manifest_path.write_bytes(b"{")
    with pytest.raises(ConfigError, match="damaged journal manifest") as info:
        output_state(out, "h", overwrite, True)
    assert str(info.value).endswith(f"to discard the journal and start over, {action}")
    assert output_state(out, "h", True, False) == "fresh"  # what the message says: overwrite, no resume


def test_only_empty_directories_are_removed(tmp_path):
    (tmp_path / "outputs" / "day" / "time").mkdir(parents=True)
    (tmp_path / "outputs" / "day" / "other").mkdir()
    remove_empty_dirs(tmp_path / "outputs" / "day" / "time", tmp_path)
    assert sorted(p.name for p in (tmp_path / "outputs" / "day").iterdir()) == ["other"]
    remove_empty_dirs(tmp_path / "outputs" / "day" / "other", tmp_path)
    assert list(tmp_path.iterdir()) == []


def test_a_signal_swallowed_by_a_finalizer_is_raised_before_the_results_are_renamed(tmp_path, monkeypatch):
    """A signal's exception raised inside a weakref callback is printed as "Exception ignored" and
    lost (seen in CI: a SIGHUP during assembly, exit 0). The handler also records the signal, and
    raise_pending() raises it again just before the results file would be renamed into place."""
    import signal
    import weakref

    from gyrolab.runner import signals as app
    from gyrolab.safe_files import atomic_replace

    monkeypatch.setattr(app, "_PENDING", [])

    class Thing:
        pass

    thing = Thing()
    keep = weakref.ref(thing, lambda _: app._raise_interrupted(signal.SIGHUP, None))
    del thing  # the callback raises Interrupted inside the finalizer: swallowed
    assert keep() is None and app._PENDING == [signal.SIGHUP]
    out = tmp_path / "results.h5"
    with pytest.raises(app.Interrupted):
        atomic_replace(out, lambda tmp: tmp.write_bytes(b"data"), before_replace=app.raise_pending)
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_an_interrupt_swallowed_by_a_finalizer_prints_no_traceback(monkeypatch, capfd):
    """Python reports an exception raised in a finalizer as "Exception ignored ... Traceback"; the
    sweep's one-line interrupt message must stay the only output, so the hook gyrolab installs keeps
    quiet about a recorded interrupt, and passes any other unraisable exception on."""
    import signal
    import sys
    import weakref

    from gyrolab.runner import signals as app

    monkeypatch.setattr(app, "_PENDING", [])
    monkeypatch.setattr(sys, "unraisablehook", app.quiet_swallowed_interrupts(sys.__unraisablehook__))

    class Thing:
        pass

    thing = Thing()
    keep = weakref.ref(thing, lambda _: app._raise_interrupted(signal.SIGHUP, None))
    del thing
    assert keep() is None and app._PENDING == [signal.SIGHUP]
    assert capfd.readouterr().err == ""

    def fail_in_finalizer(_):
        raise ValueError("a real bug in a finalizer")

    thing = Thing()
    keep = weakref.ref(thing, fail_in_finalizer)
    del thing
    err = capfd.readouterr().err
    assert "ValueError: a real bug in a finalizer" in err and "Traceback" in err
