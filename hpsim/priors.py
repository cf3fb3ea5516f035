"""Prior distributions of parameters, written next to their values in parameter files.

Any value in a parameter file may say how uncertain it is:

    unsprung_mass: {value: "450 kg", prior: {uniform: ["350 kg", "550 kg"]}, source: "assumed: ..."}

Distributions (the arguments accept units like the value; bare numbers are SI):

    uniform:    [low, high]
    normal:     [mean, standard deviation]          (a temperature's deviation in K, a difference)
    lognormal:  [median, factor]                    factor = geometric standard deviation > 1
                                                    (68 % of draws within median/factor .. median*factor)
    triangular: [low, mode, high]

`shared: NAME` inside `prior` ties several values to one draw (e.g. the unsprung mass of every
axle: the same hardware); tied priors must be identical.

`per: axle` (or `per: station`) inside `prior` draws the value once per axle (station) where the
study knows a per-axle form of it (vehicle.studies.uq: a heat-environment key goes to
`axles[k].heat`, a road pass factor to each following axle's pass, ...). The draws are independent,
or with `correlation: r` (0 <= r < 1) equally rank-correlated between every pair of axles. That is a
Gaussian copula whose normal correlation 2 sin(pi r / 6) gives the Spearman rank correlation r (Pearson r
for uniform priors; Kruskal 1958). It is drawn through independent standard normals (one common, one
per axle: `correlated_quantile`), so a Saltelli design and Sobol' indices by group stay valid.

`collect_priors(data, source)` walks a loaded YAML mapping and returns every prior with its key
path (`axles.0.unsprung_mass`), in SI; errors name the file and the key path. The loaders of
parameter files ignore `prior` (hpsim.config), so a file with priors runs at its `value`s.
Sampling and the sensitivity analysis live in vehicle.studies.uq.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from .errors import UserInputError
from .units import parse_quantity, registry

# distribution name -> names of its arguments
TYPICAL_QUANTILE = 0.6        # `Prior.typical`: a quantile off the median


DISTRIBUTIONS = {
    "uniform": ("low", "high"),
    "normal": ("mean", "standard deviation"),
    "lognormal": ("median", "factor"),
    "triangular": ("low", "mode", "high"),
}
PRIOR_KEYS = set(DISTRIBUTIONS) | {"shared", "per", "correlation"}
PER = ("axle", "station")


@dataclass(frozen=True)
class Prior:
    """One uncertain value: where it is, its nominal value and its distribution, in SI."""

    path: str                     # key path in the file, e.g. "axles.0.unsprung_mass"
    kind: str                     # a key of DISTRIBUTIONS
    args: tuple[float, ...]       # the distribution's arguments in SI (lognormal: median [SI], factor [-])
    value: float                  # the nominal value in SI
    unit: str                     # the unit the file writes the value in ("" for a plain number)
    si_unit: str                  # SI unit of `value` and `args` ("" for a plain number)
    shared: str | None = None     # label tying several values to one draw
    source: str = ""              # the file, for messages
    note: str = ""                # the value's `source` text (the reasoning)
    per: str | None = None        # "axle" / "station": one draw per axle / station
    correlation: float = 0.0      # Spearman rank correlation between the per-axle draws

    @property
    def where(self) -> str:
        return f"{self.source}: {self.path}" if self.source else self.path

    def same_distribution(self, other: "Prior") -> bool:
        return self.kind == other.kind and self.si_unit == other.si_unit and \
            all(math.isclose(a, b, rel_tol=1e-12, abs_tol=0.0) for a, b in zip(self.args, other.args))

    def salib(self) -> tuple[str, list[float]]:
        """(dists entry, bounds entry) of a SALib problem (SALib.util.scale_samples conventions)."""
        if self.kind == "uniform":
            return "unif", [self.args[0], self.args[1]]
        if self.kind == "normal":
            return "norm", [self.args[0], self.args[1]]
        if self.kind == "lognormal":
            return "lognorm", [math.log(self.args[0]), math.log(self.args[1])]
        lo, mode, hi = self.args
        # SALib: [start, end, peak as a fraction of the width in [0, 1)]
        return "triang", [lo, hi, min((mode - lo) / (hi - lo), 1.0 - 1e-12)]

    def ppf(self, q):
        """Quantile function (inverse CDF) in SI: the band of the prior itself, for tables."""
        from scipy import stats

        if self.kind == "uniform":
            return stats.uniform.ppf(q, loc=self.args[0], scale=self.args[1] - self.args[0])
        if self.kind == "normal":
            return stats.norm.ppf(q, loc=self.args[0], scale=self.args[1])
        if self.kind == "lognormal":
            return self.args[0] * self.args[1] ** stats.norm.ppf(q)
        lo, mode, hi = self.args
        return stats.triang.ppf(q, (mode - lo) / (hi - lo), loc=lo, scale=hi - lo)

    def typical(self) -> float:
        """A value in SI typical of the draws: the TYPICAL_QUANTILE quantile, off the median, which is exactly
        zero for a prior symmetric about zero (no draw is). A file's zero shapes a compiled model, a draw's
        value does not (hpsim.parameters), so a typical value stands for the draws' model."""
        return float(self.ppf(TYPICAL_QUANTILE))

    def cdf(self, x):
        """Cumulative distribution function at x [SI] (the inverse of `ppf`)."""
        from scipy import stats

        if self.kind == "uniform":
            return stats.uniform.cdf(x, loc=self.args[0], scale=self.args[1] - self.args[0])
        if self.kind == "normal":
            return stats.norm.cdf(x, loc=self.args[0], scale=self.args[1])
        if self.kind == "lognormal":
            return stats.norm.cdf(math.log(x / self.args[0]) / math.log(self.args[1]))
        lo, mode, hi = self.args
        return stats.triang.cdf(x, (mode - lo) / (hi - lo), loc=lo, scale=hi - lo)

    def to_unit(self, x_si: float) -> float:
        """A value in SI expressed in the file's unit (e.g. kg*m^2 -> kg*m^2, K -> degC)."""
        if not self.unit:
            return float(x_si)
        Q = registry().Quantity
        return float(Q(x_si, self.si_unit).to(self.unit).magnitude)

    def override(self, x_si: float) -> Any:
        """The value to write into a parameter file for a draw: a quantity string in the file's unit."""
        if not self.unit:
            return float(x_si)
        return f"{self.to_unit(x_si):.12g} {self.unit}"

    def describe(self) -> str:
        """The distribution in the file's unit, e.g. 'uniform 350 .. 550 kg'."""
        u = f" {self.unit}" if self.unit else ""
        if self.kind == "uniform":
            return f"uniform {self.to_unit(self.args[0]):.4g} .. {self.to_unit(self.args[1]):.4g}{u}" + self._per()
        if self.kind == "triangular":
            lo, mode, hi = (self.to_unit(a) for a in self.args)
            return f"triangular {lo:.4g} .. {hi:.4g}{u}, mode {mode:.4g}" + self._per()
        if self.kind == "normal":
            mean, sd = self.args
            sd_unit = self.to_unit(mean + sd) - self.to_unit(mean)     # a difference (degC -> K scale)
            return f"normal mean {self.to_unit(mean):.4g}{u}, sd {sd_unit:.4g}{u}" + self._per()
        return f"lognormal median {self.to_unit(self.args[0]):.4g}{u}, factor {self.args[1]:.4g}" + self._per()

    def _per(self) -> str:
        if not self.per:
            return ""
        return f", per {self.per}" + (f", rank correlation {self.correlation:g}" if self.correlation else "")


def _unit_of(value: Any, where: str) -> tuple[str, str] | None:
    """(unit as written, SI unit) of a quantity string, or None for a bare number."""
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise UserInputError(f"{where}: expected a number or a quantity such as '450 kg', got {value!r}")
    if isinstance(value, (int, float)):
        return None
    ureg = registry()
    try:
        q = ureg.Quantity(value.strip())
    except Exception as exc:
        raise UserInputError(f"{where}: cannot read {value!r} as a quantity ({exc.__class__.__name__})") from None
    if isinstance(q, (int, float)) or q.dimensionless:
        return None                 # a plain number (also "70 %")
    base = q.to_base_units()
    # short symbols that parse back ("kJ/K", "degC"), for tables and the values written into cases
    return format(q.units, "~C").replace("°C", "degC").replace("**", "^"), str(base.units)


def parse_prior(node: dict, path: str, source: str = "") -> Prior:
    """A {value:, prior:, source:} mapping -> Prior (in SI). Errors name the file and key path."""
    here = f"{source}: {path}" if source else path
    prior = node.get("prior")
    value = node.get("value")
    if isinstance(value, (list, tuple, dict)):
        raise UserInputError(f"{here}: a prior needs a single value, got {type(value).__name__} {value!r}")
    if not isinstance(prior, dict):
        raise UserInputError(f"{here}.prior: expected a mapping such as {{uniform: [low, high]}}, got {prior!r}")
    unknown = sorted(set(prior) - PRIOR_KEYS)
    if unknown:
        raise UserInputError(f"{here}.prior: unknown key {unknown[0]!r}; allowed: one of "
                             f"{', '.join(DISTRIBUTIONS)} and optionally shared")
    kinds = [k for k in prior if k in DISTRIBUTIONS]
    if len(kinds) != 1:
        raise UserInputError(f"{here}.prior: give exactly one distribution ({', '.join(DISTRIBUTIONS)}), "
                             f"got {kinds or 'none'}")
    kind = kinds[0]
    names = DISTRIBUTIONS[kind]
    raw = prior[kind]
    if not isinstance(raw, (list, tuple)) or len(raw) != len(names):
        raise UserInputError(f"{here}.prior.{kind}: expected a list [{', '.join(names)}], got {raw!r}")
    shared = prior.get("shared")
    if shared is not None and (not isinstance(shared, str) or not shared.strip() or "," in shared):
        raise UserInputError(f"{here}.prior.shared: expected a name without commas, got {shared!r}")
    # the unit: the value's, else the first argument with units (a bare value is SI)
    dimensioned = [(v, f"{here}.value") for v in [value]] + \
        [(a, f"{here}.prior.{kind}[{i}]") for i, a in enumerate(raw) if not (kind == "lognormal" and i == 1)]
    units = None
    for v, w in dimensioned:
        units = _unit_of(v, w)
        if units is not None:
            break
    unit, si_unit = units if units is not None else ("", "")
    target = si_unit or "dimensionless"

    def q(v, w):
        if si_unit and isinstance(v, (int, float)) and not isinstance(v, bool):
            return float(v)         # bare numbers are SI
        return parse_quantity(v, target, where=w)

    x0 = q(value, f"{here}.value")
    args = []
    for i, (a, name) in enumerate(zip(raw, names)):
        w = f"{here}.prior.{kind}[{i}] ({name})"
        if kind == "lognormal" and i == 1:
            args.append(parse_quantity(a, "dimensionless", where=w))
        elif kind == "normal" and i == 1 and si_unit == "kelvin":
            if isinstance(a, str) and ("deg" in a or "°" in a):
                raise UserInputError(f"{w}: a temperature's standard deviation is a difference: give it in K, got {a!r}")
            args.append(parse_quantity(a, "kelvin", where=w))
        else:
            args.append(q(a, w))
    _check(kind, args, x0, unit, si_unit, here)
    per, rho = _per_axle(prior, here, shared)
    note = node.get("source", "")
    return Prior(path=path, kind=kind, args=tuple(args), value=x0, unit=unit, si_unit=si_unit,
                 shared=shared.strip() if shared else None, source=source, note=str(note) if note else "",
                 per=per, correlation=rho)


def _per_axle(prior: dict, here: str, shared) -> tuple[str | None, float]:
    """(per, correlation) of a prior mapping, checked."""
    per = prior.get("per")
    if per is not None and per not in PER:
        raise UserInputError(f"{here}.prior.per: {per!r}; allowed: {', '.join(PER)}")
    if per is not None and shared is not None:
        raise UserInputError(f"{here}.prior: give shared (one draw for several values) or per (one draw per "
                             "axle or station), not both")
    rho = prior.get("correlation", 0.0)
    if "correlation" in prior and per is None:
        raise UserInputError(f"{here}.prior.correlation: needs per: axle or per: station (a correlation between "
                             "the per-axle draws)")
    if isinstance(rho, bool) or not isinstance(rho, (int, float)) or not 0.0 <= rho < 1.0:
        raise UserInputError(f"{here}.prior.correlation: expected a number in [0, 1) (a rank correlation; 1 is "
                             f"one shared draw), got {rho!r}")
    return per, float(rho)


def correlated_quantile(z_common, z_own, rank_correlation: float):
    """The quantile (0..1) of one per-axle draw from independent standard normals: the common one, shared by
    every axle, and the axle's own. The normal correlation 2 sin(pi r / 6) gives the rank correlation r
    between any two axles' draws (Gaussian copula; Kruskal 1958)."""
    from scipy import stats

    rho = 2.0 * math.sin(math.pi * rank_correlation / 6.0)
    return stats.norm.cdf(math.sqrt(rho) * z_common + math.sqrt(1.0 - rho) * z_own)


def _check(kind: str, args: list[float], x0: float, unit: str, si_unit: str, here: str) -> None:
    def show(x):
        if not unit:
            return f"{x:.6g}"
        Q = registry().Quantity
        return f"{Q(x, si_unit).to(unit).magnitude:.6g} {unit}"

    w = f"{here}.prior.{kind}"
    if kind in ("uniform", "triangular"):
        lo, hi = args[0], args[-1]
        if not lo < hi:
            raise UserInputError(f"{w}: low ({show(lo)}) must be below high ({show(hi)})")
        if kind == "triangular" and not lo <= args[1] <= hi:
            raise UserInputError(f"{w}: mode ({show(args[1])}) must be in [{show(lo)}, {show(hi)}]")
        if not lo <= x0 <= hi:
            raise UserInputError(f"{w}: the value {show(x0)} lies outside the prior's range "
                                 f"[{show(lo)}, {show(hi)}]")
    elif kind == "normal":
        if not args[1] > 0:
            raise UserInputError(f"{w}: the standard deviation must be > 0, got {args[1]:.6g} {si_unit or ''}".rstrip())
    elif kind == "lognormal":
        if not args[0] > 0:
            raise UserInputError(f"{w}: the median must be > 0, got {show(args[0])}")
        if not args[1] > 1:
            raise UserInputError(f"{w}: the factor (geometric standard deviation) must be > 1, got {args[1]:.6g}")
        if not x0 > 0:
            raise UserInputError(f"{w}: a lognormal prior needs a value > 0, got {show(x0)}")


def is_prior_node(node: Any) -> bool:
    return isinstance(node, dict) and "prior" in node and "value" in node


def collect_priors(data: Any, source: str = "", *, skip: tuple[str, ...] = ()) -> list[Prior]:
    """Every value with a prior in a loaded YAML mapping, with its key path, in file order.

    `skip`: key paths (and everything below them) to leave out. A `prior` without `value`
    is an error naming the file and key path.
    """
    out: list[Prior] = []

    def walk(node, path):
        if path in skip:
            return
        if isinstance(node, dict):
            if "prior" in node:
                if "value" not in node:
                    raise UserInputError(f"{source + ': ' if source else ''}{path or '(top level)'}: "
                                         "a prior needs the value next to it: {value: ..., prior: {...}}")
                out.append(parse_prior(node, path, source))
                return
            for k, v in node.items():
                walk(v, f"{path}.{k}" if path else str(k))
        elif isinstance(node, list):
            for i, v in enumerate(node):
                walk(v, f"{path}.{i}" if path else str(i))

    walk(data, "")
    return out


def tie_shared(priors: list[Prior]) -> list[tuple[str, list[Prior]]]:
    """Group priors into independent draws: (name, priors). A shared label makes one draw for
    every prior carrying it (named by the label); the others are named by their key path."""
    groups: dict[str, list[Prior]] = {}
    for p in priors:
        key = p.shared if p.shared else p.path
        if p.shared and p.shared in groups and not groups[p.shared][0].same_distribution(p):
            first = groups[p.shared][0]
            raise UserInputError(f"{p.where}.prior: shared {p.shared!r} with {first.path} but the distributions "
                                 f"differ ({p.describe()} vs {first.describe()}); tied values need one distribution")
        if not p.shared and key in groups:
            raise UserInputError(f"{p.where}: the key path is also used as a shared name")
        groups.setdefault(key, []).append(p)
    return list(groups.items())


def values_only(data: Any, skip: tuple[str, ...] = ()) -> Any:
    """A copy of a loaded YAML mapping with every {value:, prior:, ...} node replaced by its value (a scenario
    with priors runs at its values); the top-level keys in `skip` are kept as they are."""
    if is_prior_node(data):
        return data["value"]
    if isinstance(data, dict):
        return {k: (v if k in skip else values_only(v)) for k, v in data.items()}
    if isinstance(data, list):
        return [values_only(v) for v in data]
    return data
