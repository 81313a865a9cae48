"""The verdict's cells in words: order, drift class, preserved quantities, stability threshold.

One wording for every table and figure that shows a verdict record (docs/verdict.md, the terminal table,
the README's table, the engine cards, the verdict figure's threshold bars), read from the record's own
fields (verdict.py's RECORD_KEYS); no number is recomputed here.
"""

import math

import numpy as np

from .classify import MIN_LADDER, collapse_words, is_rounding_drift


def fmt_number(x, digits=3):
    """``x`` to ``digits`` significant digits; "—" for a value that is missing (None) or not finite."""
    return "—" if x is None or (isinstance(x, float) and not math.isfinite(x)) else f"{x:.{digits}g}"


def fmt_order(rec, short=False):
    """The measured order [CI] in words; without a fit, why (``short``: the reason's first clause)."""
    if rec.get("order") is None or not math.isfinite(rec["order"]):
        excl = rec.get("ladder_excluded") or []
        reason = rec.get("order_reason") or ""
        if "reference" in reason and not any(k in reason for k in ("flat", "pre_asymptotic")):
            ref_errs = [e for e, x in zip(rec.get("ladder_err") or [], excl) if x == "reference" and e is not None]
            top = f" (err ≤ {max(ref_errs):.0e})" if ref_errs else ""
            return f"— (≤ reference{top}: below the reference's own error)"
        if "floor" in reason and not any(k in reason for k in ("diverged", "reference", "flat", "pre_asymptotic")):
            return "exact (err at rounding floor)"
        if "diverged" in reason:
            return "— (err ≥ 1 at most dt)"
        errs = np.array([e for e in rec.get("ladder_err") or [] if e is not None and math.isfinite(e) and e > 0])
        if errs.size >= MIN_LADDER and errs.max() < 1e-8 and "exact flow" in (rec.get("reference") or ""):
            # against the exact solution, at every dt: what is left is rounding, amplified by the
            # instability of the motion itself (the tennis racket near its separatrix)
            return f"exact to rounding (err ≤ {errs.max():.0e} at every dt)"
        if errs.size >= MIN_LADDER and errs.max() < 10 * errs.min():
            return f"— (flat: err ≈ {np.median(errs):.0e} at every dt)"
        if reason and short and "slopes disagree" in reason:  # no asymptotic range (classify.fit_order)
            return "— (local slopes disagree)"
        if reason:
            return f"— ({reason.split(' after ')[0] if short else reason})"  # the record's own reason
        return "— (err does not fall with dt)" if excl else "—"
    lo, hi = rec["order_ci"]
    ci = f" [{lo:.2f}, {hi:.2f}]" if lo is not None and math.isfinite(lo) else ""
    return f"{rec['order']:.2f}{ci}"


UNIT_TEXT = {"1/s": "/s", "1/sqrt(s)": "/√s", "1/s e-folding": "/s (e-fold)", "power": "(t^p)"}


def _fmt_rate(c, rate, unit):
    if unit == "power":
        return f"growing ∝ t^{fmt_number(rate)}"
    return f"{c} {fmt_number(rate)} {UNIT_TEXT.get(unit, unit)}"


def fmt_drift(rec, short=False):
    """The drift class in words, from the record's own numbers (classify.Drift's fields); ``short``:
    the terminal table's compact form."""
    c = rec.get("drift_class")
    if c is None:
        return "—"
    if c == "bounded":
        amp, late = rec.get("amplitude"), rec.get("late_mean")
        if amp == 0:  # the invariant's bits never moved: "bounded (≤ 0)" would undersell it
            return "exact (e = 0)" if short else "exact (e = 0 at every sample)"
        settles = (
            f", settles at {late:.2g}" if late is not None and amp and amp > 1e-6 and abs(late) > 0.5 * amp else ""
        )
        period = rec.get("period")
        per = f", period {period:.3g} s" if period is not None and math.isfinite(period) else ""
        return f"bounded (≤ {fmt_number(amp, 2)}{settles}{per})"
    if c == "diverged":
        return f"diverged (t = {fmt_number(rec.get('t_diverged'))} s)"
    if c == "undetermined":
        return "undetermined (too few samples)"
    if c == "collapse":
        size, when = rec.get("collapse_size"), rec.get("collapse_time")
        then = rec.get("then_class") or "—"
        if then == "slow_oscillation":
            rate, period = fmt_number(rec.get("then_rate")), fmt_number(rec.get("period"), 2)
            then = f"a trend {rate} /s (oscillation ~ {period} s > record)"
        elif then == "slowing":
            then = "a trend that slows"
        elif then in ("linear", "wander", "growing") and rec.get("then_rate") is not None:
            then = _fmt_rate(then, rec["then_rate"], rec.get("then_rate_unit") or "")
        return f"{collapse_words(size or 0.0)} within {fmt_number(when, 2)} s, then {then}"
    if c == "slow_oscillation" and short:
        rate, period = fmt_number(rec.get("drift_rate")), fmt_number(rec.get("period"), 2)
        return f"trend {rate} /s; oscillation ~ {period} s > record"
    if c == "slowing" and short:
        return f"trend slowing (stops ~ {fmt_number(rec.get('t_turn'), 2)} s)"
    if c == "slow_oscillation":
        return (
            f"trend {fmt_number(rec.get('drift_rate'))} /s over a record shorter than its oscillation "
            f"(period ~ {fmt_number(rec.get('period'), 2)} s); "
            f"run > {fmt_number(rec.get('run_longer'), 2)} s to decide"
        )
    if c == "slowing":
        turn, longer = fmt_number(rec.get("t_turn"), 2), fmt_number(rec.get("run_longer"), 2)
        return f"trend slowing (would stop at t ~ {turn} s); run > {longer} s"
    return _fmt_rate(c, rec.get("drift_rate"), rec.get("drift_rate_unit") or "")


def fmt_threshold(rec):
    """'2.57', '< 0.001' (not bounded at the smallest step), '> 10' (bounded at the largest); with
    '; fails at ≤ x' when steps below the bounded range failed too (a solver that stalls at small steps)."""
    small = rec.get("omega_dt_small_fail")
    tail = f"; fails at ≤ {small:.3g}" if small is not None and math.isfinite(small) else ""
    crit = rec.get("omega_dt_crit")
    if crit is not None and math.isfinite(crit):
        return f"{crit:.3g}{tail}"
    lo, hi = rec.get("omega_dt_bracket") or (None, None)
    if hi is not None and math.isfinite(hi) and (lo is None or not math.isfinite(lo)):
        return f"< {hi:.3g}"
    if lo is not None and math.isfinite(lo) and (hi is None or not math.isfinite(hi)):
        return f"> {lo:.3g}{tail}"
    return "—"


def fmt_preserved(recs):
    """'L, Lz' preserved to rounding; '!' marks a mismatch with the method's PRESERVES."""
    parts = []
    for r in recs:
        if r.get("preserved") is None:
            continue
        if r["preserved"]:
            parts.append(r["quantity"] + ("" if r.get("declared_preserved") in (True, None) else " (undeclared)"))
        elif r.get("rounding_drift") or is_rounding_drift(
            r.get("drift_class"), r.get("amplitude"), r.get("n_steps") or 0, r.get("preserved"),
            r.get("drift_rate_unit") or "",
        ):  # fmt: skip
            parts.append(f"{r['quantity']} (rounding drift)")
        elif r.get("declared_preserved"):
            parts.append(f"!{r['quantity']} declared, not kept")
    return ", ".join(parts) or "none"
