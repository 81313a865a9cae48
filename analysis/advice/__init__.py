"""Advice for the user's own body (issue 25): ``advise(...)`` (advisor.py, the ``gyrolab-advise`` command in
cli.py), the error model (model.py, errors.py, calibrate.py) and the engine updates' stability (predict.py).

``from gyrolab.analysis.advice import advise`` imports the kernels only when first used."""


def __getattr__(name):
    if name in ("advise", "Advice", "AdviceError"):
        from . import advisor

        return getattr(advisor, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
