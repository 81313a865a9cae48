"""Method parameters: a method name with values, as a sweep gives it and a results file records it.

A method whose scheme has a free choice (the axis order of a splitting, NO_SQUISH's rotor substeps,
generalized-α's ρ∞) declares it in ``PARAMETERS`` and builds the variant in ``variant(**values)``
(kernels/methods/README.md).  A sweep names a variant by the method's name with the values in
parentheses::

    sweep.method: [lie_poisson, "lie_poisson(axes=S-M-L)", "no_squish(axes=1-2-3,substeps=10)"]

(on the command line, quote the element: ``'sweep.method=["lie_genalpha(rho_inf=0.6)",lie_genalpha]'``;
unquoted parentheses are Hydra's function-call syntax).  The name is made canonical before anything
runs (``canonical``): parameters in the order the method declares them, each value in its canonical
text, parameters at their default left out, and no parentheses at all when every value is the default
(``lie_poisson(axes=1-2-3)`` is ``lie_poisson``, the same bits).  That canonical name is the run's
``integrator`` coordinate in the results file, the journal's and the stored config's method: a file
says which variant ran in the one place that names methods.

This file is pure Python (numba compiles nothing here, kernels/__init__.py NOT_COMPILED): it turns text
into the kernel values a method's ``variant`` binds as compile-time constants (kernels/variants.py).
"""

import math
import re
from dataclasses import dataclass
from typing import Callable


@dataclass(frozen=True)
class Parameter:
    """One parameter of a method: its default as written in a name, ``parse`` (text → the kernel value,
    ValueError saying what it takes), ``text`` (kernel value → canonical text) and what it means."""

    default: str
    parse: Callable[[str], object]
    text: Callable[[object], str]
    doc: str


# Axis orders.  A splitting that turns the body about single principal axes in the symmetric sequence
# a(h/2) b(h/2) c(h) b(h/2) a(h/2) takes (a, b, c) as three codes: 0, 1, 2 the body record's axes e1, e2,
# e3 (labels, "3-2-1"), 3, 4, 5 the axes of the smallest, middle and largest moment of the body at hand
# (ranks, "S-M-L"), which kernels.free_flow.resolve_axes turns into axes per body.
_LABELS = {"1": 0, "2": 1, "3": 2, "S": 3, "M": 4, "L": 5}
_CODES = {code: label for label, code in _LABELS.items()}


def _parse_axes(text):
    parts = tuple(p.strip().upper() for p in text.split("-"))
    codes = tuple(_LABELS.get(p, -1) for p in parts)
    if len(parts) != 3 or sorted(codes) not in ([0, 1, 2], [3, 4, 5]):
        raise ValueError(
            f"{text!r} is not an axis order: give the three body axes in turn, a permutation of 1-2-3 "
            "(the body's axis labels) or of S-M-L (by moment: smallest, middle, largest)"
        )
    return codes


def _axes_text(codes):
    return "-".join(_CODES[c] for c in codes)


def axis_order(default, doc):
    """An axis order a-b-c: a(h/2) b(h/2) c(h) b(h/2) a(h/2), in body labels (1-2-3) or moment ranks (S-M-L)."""
    return Parameter(default, _parse_axes, _axes_text, doc)


def _number(convert, accept, what):
    """A parser: ``convert(text)`` (int or float), ValueError "'text' is not ``what``" unless ``accept``s it
    (NaN never does)."""

    def parse(text):
        try:
            value = convert(text)
        except ValueError:
            value = math.nan
        if not accept(value):
            raise ValueError(f"{text!r} is not {what}")
        return value

    return parse


def count(default, doc):
    """A whole number from 1 to 1000 (substeps, iterations)."""
    return Parameter(
        default, _number(int, lambda v: 1 <= v <= 1000, "a count: give a whole number from 1 to 1000"), str, doc
    )


def unit_interval(default, doc):
    """A number from 0 to 1 (a spectral radius); canonical text is Python's shortest repr (0.60 → 0.6)."""
    return Parameter(default, _number(float, lambda v: 0.0 <= v <= 1.0, "a number from 0 to 1"), repr, doc)


def nonnegative(default, doc):
    """A finite number ≥ 0 (a mass, an acceleration); canonical text as ``unit_interval``'s."""
    return Parameter(default, _number(float, lambda v: 0.0 <= v < math.inf, "a number >= 0"), repr, doc)


def choice(default, options, doc):
    """One of the words ``options`` (case-insensitive); the kernel value is its index, 0 for the first."""
    words = tuple(o.lower() for o in options)

    def parse(text):
        word = str(text).strip().lower()
        if word not in words:
            raise ValueError(f"{text!r} is not one of {', '.join(words)}")
        return words.index(word)

    return Parameter(default, parse, lambda index: words[index], doc)


ACCUMULATE = choice(
    "plain",
    ("plain", "compensated"),
    "how a splitting adds each flow to the state: plain (overwrite ω and q) or compensated (ω and q kept "
    "as hi + lo, each flow added error-free as an increment: kernels/compensated.py)",
)


_NAME = re.compile(r"([A-Za-z_]\w*)\((.*)\)")
_ITEM = re.compile(r"([A-Za-z_]\w*)=([^=,()]+)")


def split_names(text):
    """The comma-separated names of ``text``, a comma inside parentheses belonging to a name's parameters:
    ``"rk4,no_squish(axes=S-M-L,substeps=10)"`` → ``["rk4", "no_squish(axes=S-M-L,substeps=10)"]``; an
    unclosed parenthesis runs to the end (one malformed name, which its reader then refuses whole)."""
    return [m.strip() for m in re.findall(r"(?:[^,(]|\([^)]*(?:\)|$))+", str(text)) if m.strip()]


def split_name(name):
    """``(method, {parameter: text})`` of ``name``: ``"no_squish(substeps=10)"`` → ``("no_squish",
    {"substeps": "10"})``, a plain name → ``(name, {})``; ValueError (one line) when it is neither."""
    name = str(name).strip()
    if "(" not in name and ")" not in name:
        return name, {}
    match = _NAME.fullmatch(name.replace(" ", ""))
    items = match.group(2).split(",") if match else []
    pairs = [_ITEM.fullmatch(item) for item in items]
    if not match or not items or not all(pairs):
        raise ValueError(f"{name!r}: write a method with parameters as method(name=value,...): no_squish(substeps=10)")
    given = {}
    for pair in pairs:
        if pair.group(1) in given:
            raise ValueError(f"{name!r}: parameter {pair.group(1)} given twice")
        given[pair.group(1)] = pair.group(2)
    return match.group(1), given


def canonical(method, declared, given):
    """``(canonical name, values)`` of ``method`` with ``given`` ({parameter: text}) against ``declared``
    (its PARAMETERS): values is {parameter: kernel value} for every declared parameter in declared
    order (defaults filled in); ValueError (one line) for an unknown parameter or a bad value."""
    unknown = [k for k in given if k not in declared]
    if unknown:
        takes = f"takes {', '.join(declared)}" if declared else "takes no parameters"
        raise ValueError(f"{method}({unknown[0]}=...): unknown parameter; {method} {takes}")
    values, shown = {}, []
    for key, parameter in declared.items():
        try:
            value = parameter.parse(given.get(key, parameter.default))
        except ValueError as err:
            raise ValueError(f"{method}({key}=...): {err}") from None
        values[key] = value
        if value != parameter.parse(parameter.default):
            shown.append(f"{key}={parameter.text(value)}")
    return (f"{method}({','.join(shown)})" if shown else method), values
