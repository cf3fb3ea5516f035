"""How far a study's sensitivity ranking can be trusted: an interval for each index and "not
resolved" where it does not exclude zero.

The intervals hold for all d parameters at once at 95 % (Bonferroni: each at 1 - 0.05 / d): a ranking
picks its top entries out of d, and the largest of 50 correlations of pure noise is large (with 9
cases about 0.8), so a per-parameter 95 % interval would "resolve" noise.

- Sobol' total indices (SALib): ST +- ST_conf, SALib's bootstrap half-width at 95 % (1.96 standard
  deviations) widened to the Bonferroni quantile; resolved when its lower end is above 0.
- Rank correlations of a Latin hypercube (n cases, d parameters): an interval through Fisher's
  z = atanh(r). Its standard error is sqrt(1.06 / (n - 3)) for Spearman's rho (Fieller, Hartley &
  Pearson, Biometrika 44, 1957) and 1 / sqrt(n - 3 - (d - 1)) for a partial correlation that removes
  d - 1 other ranks (Fisher 1924). Resolved when the interval excludes 0. The line also gives the
  sample-to-parameter ratio n / d: with n not much above d a ranking is mostly noise.
"""
from __future__ import annotations

import math

Z95 = 1.959963984540054          # two-sided 95 % quantile of the standard normal


def family_quantile(d: int, level: float = 0.95) -> float:
    """The two-sided normal quantile that holds `level` for d intervals at once (Bonferroni)."""
    from scipy.stats import norm

    return float(norm.ppf(1 - (1 - level) / (2 * max(d, 1))))


def correlation_interval(r: float, n: int, controlled: int = 0, spearman: bool = False,
                         z: float = Z95) -> tuple[float, float]:
    """Interval (z: its normal quantile, default 95 %) of a (partial) rank correlation r from n cases with
    `controlled` variables removed; (-1, 1) where the cases are too few for any statement."""
    dof = n - 3 - controlled
    if not math.isfinite(r) or dof <= 0:
        return -1.0, 1.0
    se = math.sqrt((1.06 if spearman else 1.0) / dof)
    zr = math.atanh(max(min(r, 1 - 1e-12), -1 + 1e-12))
    return math.tanh(zr - z * se), math.tanh(zr + z * se)


def ranked(summary: dict, output: str) -> tuple[str, list[dict]]:
    """(the index used, [{parameter, value, lo, hi, resolved}] in the study's order of influence)."""
    names = (summary.get("most_influential") or {}).get(output, [])
    d = len(summary.get("parameters") or []) or len(names)
    n = int(summary.get("done") or 0)
    zf = family_quantile(d)
    if "sobol" in summary:
        by = {r["parameter"]: r for r in summary["sobol"][output]["rows"]}
        rows = []
        for name in names:
            st, conf = by[name]["ST"], by[name]["ST_conf"] * zf / Z95
            rows.append({"parameter": name, "value": st, "lo": st - conf, "hi": st + conf,
                         "resolved": bool(math.isfinite(st) and math.isfinite(conf) and st - conf > 0)})
        return "ST", rows
    by = {r["parameter"]: r for r in summary["ranking"][output]["rows"]}
    use_prcc = any(r["prcc"] is not None and math.isfinite(r["prcc"]) for r in by.values())
    key = "PRCC" if use_prcc else "Spearman"
    rows = []
    for name in names:
        r = by[name]["prcc" if use_prcc else "spearman"]
        r = float("nan") if r is None else float(r)
        lo, hi = correlation_interval(r, n, d - 1 if use_prcc else 0, spearman=not use_prcc, z=zf)
        rows.append({"parameter": name, "value": r, "lo": lo, "hi": hi, "resolved": bool(lo > 0 or hi < 0)})
    return key, rows


def influence_line(summary: dict, output: str) -> str:
    """`most influential on <output> (by <index>, 95 %): a (+0.76 [+0.2, +0.9]), b (... not resolved)`."""
    key, rows = ranked(summary, output)
    d = len(summary.get("parameters") or [])
    n = int(summary.get("done") or 0)
    fmt = "{:.2f}" if key == "ST" else "{:+.2f}"
    parts = []
    for r in rows:
        text = f"{r['parameter']} ({fmt.format(r['value'])} [{fmt.format(r['lo'])}, {fmt.format(r['hi'])}]"
        parts.append(text + ("" if r["resolved"] else ", not resolved") + ")")
    head = (f"most influential on {output} (by {key}, intervals 95 % for all {d} parameters at once; {n} cases, "
            f"{n / max(d, 1):.2g} per parameter)")
    if rows and not any(r["resolved"] for r in rows):
        head += ": NOT RESOLVED, the ranking is noise at this sample size"
    return head + ": " + ", ".join(parts)
