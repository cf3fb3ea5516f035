"""The same ground under successive passes: a factor and a smoothing per pass (multi-pass effect).

On loose ground the first wheels to roll over a stretch compact and level it, so the k-th wheel
over the same ground (pass k = 0, 1, 2, ...) may meet a smoother surface than the first
(terramechanics multi-pass effect; REFERENCE §10: roughness under following wheels 0.7-1.0 of the
first, 1.0 on hard roads). The terrain knows nothing of vehicles: it speaks of passes; the vehicle
decides which of its wheels is which pass.

Pass k's surface (`pass_profile`):

    z_k = level + factor_k * M_{L_k}(z - level)

z is the road profile and `level` its persistent changes of level (step and ramp events: a change of
grade is not roughness and is not compacted away). M_L is the moving average over smoothing_length L,
the same exact discrete kernel as the tyre envelope (`terrain.envelope`). Its transfer function is
H(n) = sin(pi n L)/(pi n L): the PSD is multiplied by factor^2 H(n)^2, lowered above n ~ 1/L.
A list of passes gives pass 0, 1, ...; passes beyond the list repeat its last entry. The default
(no list, or factor 1 and no smoothing) leaves every pass on the same surface.
"""
from __future__ import annotations

import numpy as np
from pydantic import model_validator

from hpsim.config import Model, Plain, Quantity

from .envelope import envelope_profile, envelope_transfer

FACTOR_RANGE = (0.0, 2.0)
MAX_SMOOTHING_LENGTH_M = 100.0


class PassSpec(Model):
    """One pass: factor on the roughness [-], moving-average smoothing length [m] (0: none)."""

    factor: Plain() = 1.0
    smoothing_length: Quantity("m") = 0.0

    @model_validator(mode="after")
    def _check(self):
        if not FACTOR_RANGE[0] <= self.factor <= FACTOR_RANGE[1]:
            raise ValueError(f"factor must be in [{FACTOR_RANGE[0]:g}, {FACTOR_RANGE[1]:g}] "
                             f"(1: the same surface as the first pass), got {self.factor:g}")
        if not 0.0 <= self.smoothing_length <= MAX_SMOOTHING_LENGTH_M:
            raise ValueError(f"smoothing_length must be in [0, {MAX_SMOOTHING_LENGTH_M:g}] m, "
                             f"got {self.smoothing_length:g} m")
        return self

    @property
    def identity(self) -> bool:
        return self.factor == 1.0 and self.smoothing_length == 0.0


IDENTITY = PassSpec()


def pass_spec(passes, pass_index: int) -> PassSpec:
    """The transform of pass `pass_index` (>= 0): the list's entry, its last entry beyond it, identity if empty."""
    if isinstance(pass_index, bool) or int(pass_index) != pass_index or pass_index < 0:
        raise ValueError(f"pass_index must be an integer >= 0 (0: the first wheel over the ground), got {pass_index!r}")
    if not passes:
        return IDENTITY
    return passes[min(int(pass_index), len(passes) - 1)]


def pass_profile(height_m: np.ndarray, spacing_m: float, spec: PassSpec, level_m: np.ndarray | None = None):
    """Pass surface level + factor * moving_average(height - level) on a uniform grid [m]."""
    z = np.asarray(height_m, float)
    if spec.identity:
        return z
    rough = z if level_m is None else z - level_m
    if spec.smoothing_length > 0:
        rough = envelope_profile(rough, spec.smoothing_length, spacing_m)
    out = spec.factor * rough
    return out if level_m is None else out + level_m


def pass_transfer(n_cycle_per_m, spec: PassSpec, spacing_m: float | None = None):
    """Amplitude transfer function of a pass on the roughness: factor * H_L(n) (PSD ratio: its square)."""
    n = np.asarray(n_cycle_per_m, float)
    if spec.smoothing_length <= 0:
        return np.full_like(n, spec.factor)
    return spec.factor * envelope_transfer(n, spec.smoothing_length, spacing_m)
