"""Per-axle priors of `hpsim uq` (hpsim.priors `per: axle|station`, `correlation: r`; docs/uq.md): where each
axle's draw goes, the parameters of a per-axle prior (independent draws, or the latents of a rank-correlated
one) and setting a drawn value at a scenario key path."""
from __future__ import annotations

import copy
import math
import re

from hpsim.errors import UserInputError
from hpsim.priors import Prior

from vehicle.physics.thermal import ENVIRONMENT_KEYS


def latent_nominal(prior: Prior) -> float:
    """The own latent of a rank-correlated per-axle draw that gives the prior's value with the common latent at 0."""
    from scipy import stats

    rho = 2.0 * math.sin(math.pi * prior.correlation / 6.0)
    q = min(max(float(prior.cdf(prior.value)), 1e-12), 1 - 1e-12)
    return float(stats.norm.ppf(q)) / math.sqrt(1.0 - rho)


def per_axle_targets(p: Prior, target: str, n_axles: int, per_axle: int = 2) -> list[tuple[str, str]]:
    """(label, key path) of each draw of a `per: axle|station` prior: a heat-environment key or a tyre key of
    the vehicle -> `axles.<k>.heat|tyre.<key>`; a scenario's `road.passes.<j>.factor` -> the pass of every
    axle from j + 1 on (`road.passes.<k>.factor`, pass k = axle k + 1); `initial_temperatures` -> one value per
    axle or station. Anything else has no per-axle form: an error naming the file and key."""
    head, _, key = p.path.partition(".")
    if p.per == "axle" and target == "vehicle" and ((head == "heat" and key in ENVIRONMENT_KEYS) or
                                                    (head == "tyre" and key and "." not in key)):
        return [(f"axle{k + 1}", f"axles.{k}.{head}.{key}") for k in range(n_axles)]
    m = re.fullmatch(r"road\.passes\.(\d+)\.factor", p.path)
    if p.per == "axle" and target == "scenario" and m:
        return [(f"axle{k + 1}", f"road.passes.{k}.factor") for k in range(max(int(m.group(1)), 1), n_axles)]
    if target == "scenario" and p.path == "initial_temperatures":
        if p.per == "axle":
            return [(f"axle{k + 1}", f"initial_temperatures.{k}") for k in range(n_axles)]
        return [(f"axle{i // per_axle + 1}{'LR'[i % per_axle] if per_axle == 2 else i % per_axle}",
                 f"initial_temperatures.{i}") for i in range(n_axles * per_axle)]
    raise UserInputError(f"{p.where}.prior.per: {p.per!r} is allowed on the vehicle's heat.<{'|'.join(ENVIRONMENT_KEYS)}> "
                         "(per axle) and tyre.<key> (per axle), and on the scenario's road.passes.<k>.factor (per "
                         "axle) and initial_temperatures (per axle or station)")


def expand_per_axle(p: Prior, prefix: str, target: str, n_axles: int, Parameter) -> list:
    """The parameters of one per-axle prior: independent draws, or latents of a rank-correlated one; all in one
    section (`--groups section`: the prior's Sobol' index by group)."""
    base = f"{prefix}.{p.path}" if prefix else p.path
    section = f"{base} (per {p.per})"
    members = per_axle_targets(p, target, n_axles)
    if not p.correlation:
        return [Parameter(name=f"{base}[{lab}]", prior=p, paths=(path,), target=target, section=section)
                for lab, path in members]
    common = f"{base}[common]"
    return [Parameter(name=common, prior=p, paths=(), target=target, section=section, latent="common")] + \
        [Parameter(name=f"{base}[{lab}]", prior=p, paths=(path,), target=target, section=section, latent="member",
                   common=common) for lab, path in members]


def set_path(data: dict, path: str, value) -> None:
    """Set a dotted key path of a scenario mapping in place; a list index beyond the list extends it with copies
    of its last entry (road passes beyond the list repeat the last one) or empty mappings."""
    keys = path.split(".")
    node = data
    for i, k in enumerate(keys):
        last = i == len(keys) - 1
        if isinstance(node, list):
            j = int(k)
            while len(node) <= j:
                node.append(copy.deepcopy(node[-1]) if node else {})
            if last:
                node[j] = value
            else:
                node[j] = node[j] if isinstance(node[j], (dict, list)) else {}
                node = node[j]
        else:
            if last:
                node[k] = value
            else:
                nxt = node.get(k)
                if not isinstance(nxt, (dict, list)):
                    nxt = [] if keys[i + 1].isdigit() else {}
                    if node.get(k) is not None:
                        nxt = [node[k]]            # one value for all (initial_temperatures): the list's first
                node[k] = nxt
                node = nxt
