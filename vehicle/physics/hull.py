"""Rigid hull with bounce, pitch and roll on wheel stations (the hull equations).

Coordinates (all small motions about the charged pose):
  z      hull heave at the CG [m], + up
  theta  pitch [rad], + nose up (front axles rise)
  phi    roll [rad], + left side up
A station at longitudinal position a (behind axle 1) and lateral position y (+ left) moves
  z_station = z - theta (a - a_cg) + phi (y - y_cg).
Virtual work gives the generalised forces of vertical station forces F_i:
  Q_z = sum F_i,  Q_theta = -sum F_i (a_i - a_cg),  Q_phi = sum F_i (y_i - y_cg).
"""
from __future__ import annotations


def station_displacement(z, theta, phi, a_m, y_m, a_cg_m, y_cg_m):
    """Vertical displacement [m] of the hull point above a station."""
    return z - theta * (a_m - a_cg_m) + phi * (y_m - y_cg_m)


def generalised_forces(forces_N, a_m, y_m, a_cg_m, y_cg_m):
    """(Q_z [N], Q_theta [N m], Q_phi [N m]) of vertical station forces (virtual work)."""
    Qz = 0.0
    Qt = 0.0
    Qp = 0.0
    for F, a, y in zip(forces_N, a_m, y_m):
        Qz = Qz + F
        Qt = Qt - F * (a - a_cg_m)
        Qp = Qp + F * (y - y_cg_m)
    return Qz, Qt, Qp


def hull_accelerations(Q_z, Q_theta, Q_phi, mass_kg, pitch_inertia, roll_inertia, gravity):
    """Newton-Euler for small angles about the CG: (z'', theta'', phi'')."""
    return Q_z / mass_kg - gravity, Q_theta / pitch_inertia, Q_phi / roll_inertia


def strut_deflection(x_charged_m, motion_ratio, w_m, z_station_m):
    """Strut deflection [m]: wheel rising relative to the hull compresses the strut by r per metre."""
    return x_charged_m + motion_ratio * (w_m - z_station_m)


def axle_height_change(z, theta, a_m, a_cg_m):
    """Hull height change [m] at an axle (mean of left and right: roll cancels)."""
    return z - theta * (a_m - a_cg_m)
