"""Coherence between the left and right wheel tracks.

"Coherence" here is the normalised real cross-spectrum of the two tracks,
γ(n) = Re G_LR(n) / sqrt(G_LL(n)·G_RR(n)), the quantity the isotropic-surface
model predicts (the magnitude-squared coherence that `scipy.signal.coherence`
returns is γ²).

Isotropic surface (REFERENCE §5; Kropáč & Múčka 2009; Bogsjö 2007): if the 1-D
PSD along any line is Gd(n) ∝ n^-w, the 2-D spectrum is ∝ |k|^-(w+1) and the
cross-spectrum between parallel tracks a distance B apart gives

    γ(n) = 2^(1-ν)/Γ(ν) · ρ^ν · K_ν(ρ),   ν = w/2,   ρ = 2π·n·B

which for w = 2 is γ = ρ·K1(ρ). γ → 1 for n → 0 (long waves are common to both
tracks) and decays like exp(-ρ) for short waves.
"""
from __future__ import annotations

import numpy as np

COHERENCE_MODELS = ("isotropic", "independent", "identical")


def isotropic_coherence(n_cycle_per_m, track_width_m: float, waviness: float = 2.0):
    """γ(n) of an isotropic surface for tracks `track_width_m` apart (w = 2: ρ·K1(ρ))."""
    n = np.asarray(n_cycle_per_m, dtype=float)
    nu = 0.5 * waviness
    rho = 2.0 * np.pi * np.abs(n) * track_width_m
    out = np.ones_like(rho)
    pos = rho > 0
    r = rho[pos]
    with np.errstate(over="ignore", invalid="ignore", under="ignore"):
        from scipy.special import gamma as gamma_fn, kv   # here: scipy.special costs 0.2 s to import

        val = 2.0 ** (1.0 - nu) / gamma_fn(nu) * r ** nu * kv(nu, r)
    out[pos] = np.nan_to_num(val, nan=0.0, posinf=0.0)
    return np.clip(out, 0.0, 1.0)


def coherence_model(model: str, n_cycle_per_m, track_width_m: float, waviness: float = 2.0):
    """γ(n) for "isotropic", "independent" (0) or "identical" (1)."""
    n = np.asarray(n_cycle_per_m, dtype=float)
    if model == "isotropic":
        return isotropic_coherence(n, track_width_m, waviness)
    if model == "independent":
        return np.zeros_like(n)
    if model == "identical":
        return np.ones_like(n)
    raise ValueError(f"coherence model {model!r}: allowed {', '.join(COHERENCE_MODELS)}")
