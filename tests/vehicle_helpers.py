"""Shared fixtures for the vehicle tests: small drives built from the shipped parameter files."""
from __future__ import annotations

from terrain import RoadSpec, build_road
from vehicle.engines.full import Drive
from vehicle.scenario.settings import DriveSettings
from vehicle.scenario.speed import SpeedProfile
from vehicle.physics.model import VehicleModel
from vehicle.physics.params import load_vehicle


def make_drive(distance_m=200.0, road=None, vehicle="apc_8x8", overrides=None, speed_kmh=20.0, **settings):
    model = VehicleModel(load_vehicle(vehicle, overrides))
    if road is None:
        road = build_road(RoadSpec(iso_class="D", length=distance_m + 20.0, seed=3))
    s = DriveSettings(distance_m=distance_m, speed=SpeedProfile.constant(speed_kmh / 3.6), **settings)
    return Drive(model, road, s)
