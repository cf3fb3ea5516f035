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

from hpsim import symbolic as sym


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


# --- longitudinal acceleration --------------------------------------------------------------------
# The drive/brake forces X_i at the tyres accelerate the whole vehicle: sum X_i = m_total a_x (flat road,
# rolling resistance and drag left out: they are part of the same tyre forces and small beside braking).
# Each wheel passes X_i - m_u a_x to the hull through its linkage. In the reference linkage (no anti
# effects: the instant centres at ground level, Gillespie, Fundamentals of Vehicle Dynamics, 1992, §7
# "anti-dive/anti-squat") these horizontal forces act on the hull at ground level, h_s below its CG,
# and each wheel hands the hull the moment of its own inertial force (at its centre, h_w above the
# ground) through the linkage, so the hull gets the pitch moment about its CG
#     M_theta = (M h_s + sum_i m_u,i h_w,i) a_x = m_total h_total a_x      (+ nose up when accelerating)
# which its struts react: the classic load transfer dN_front = -dN_rear = m a h / L of a two-axle
# vehicle (Gillespie 1992 §2, eq. 2-9 to 2-11; Milliken & Milliken, Race Car Vehicle Dynamics, 1995,
# ch. 17). An anti-pitch linkage turns part of each tyre force into a vertical force at its station
# (the line of action through the instant centre, Gillespie §7: dF = X tan(theta)), which loads the
# wheel directly and lifts or pulls the hull at the station, bypassing the strut (`linkage_forces`).


def longitudinal_pitch_moment(acceleration_m_s2, sprung_mass_kg, cg_height_m, unsprung_masses_kg,
                              wheel_centre_heights_m):
    """Pitch moment [N m] on the hull (+ nose up) from a longitudinal acceleration a_x [m/s^2] (+ forward):
    (M h_s + sum m_u h_w) a_x; braking (a_x < 0) pitches the nose down."""
    moment = sprung_mass_kg * cg_height_m
    for m_u, h_w in zip(unsprung_masses_kg, wheel_centre_heights_m):
        moment = moment + m_u * h_w
    return moment * acceleration_m_s2


def linkage_coefficients(shares, positions_m, anti_fraction):
    """Per station c_i [1/m] of the anti-pitch linkage: V_i = c_i * (m_total h_total a_x) is the vertical force
    [N] on the hull at station i (the wheel gets -V_i) for tyre forces X_i = share_i m_total a_x.

    Each linkage force is proportional to its own tyre force, V_i = X_i tan(theta_i) (Gillespie 1992 §7),
    with tan(theta_i) = f h_total (a_i - a_bar) / S, a_bar = sum share_i a_i, S = sum share_i (a_i - a_bar)^2.
    The forces then add to no net lift and to the pitch moment -f M_theta about any point. f is the fraction
    of the pitch moment taken by the linkage instead of the struts (for f = 0 every c_i is the number 0).
    """
    if isinstance(anti_fraction, (int, float)) and anti_fraction == 0:
        return [0.0] * len(shares)
    a_bar = 0.0
    for s, a in zip(shares, positions_m):
        a_bar = a_bar + s * a
    S = 0.0
    for s, a in zip(shares, positions_m):
        S = S + s * (a - a_bar) ** 2
    return [anti_fraction * s * (a - a_bar) / S for s, a in zip(shares, positions_m)]


def linkage_forces(acceleration_m_s2, moment_per_acceleration, drive_coefficients, brake_coefficients):
    """Vertical linkage forces V_i [N] on the hull at each station (+ up; the wheel gets -V_i): the drive
    coefficients while accelerating, the brake ones while braking. moment_per_acceleration: m_total h_total
    [kg m] (= M_theta / a_x)."""
    a_pos = sym.fmax(acceleration_m_s2, 0.0)
    a_neg = sym.fmin(acceleration_m_s2, 0.0)
    out = []
    for cd, cb in zip(drive_coefficients, brake_coefficients):
        v = 0.0
        if not (isinstance(cd, (int, float)) and cd == 0):
            v = v + cd * a_pos
        if not (isinstance(cb, (int, float)) and cb == 0):
            v = v + cb * a_neg
        out.append(v if isinstance(v, float) and v == 0.0 else moment_per_acceleration * v)
    return out
