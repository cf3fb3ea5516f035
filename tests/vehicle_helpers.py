"""Shared fixtures for the vehicle tests: small drives built from the shipped parameter files."""
from __future__ import annotations

import numpy as np

from terrain import RoadSpec, build_road
from vehicle.runs.drive import Drive, DriveSettings, SpeedProfile
from vehicle.physics.model import VehicleModel
from vehicle.physics.params import load_vehicle


class Recorder:
    """A drive sink that keeps everything in memory."""

    def __init__(self):
        self.blocks, self.rows, self.checkpoints = [], [], []

    def samples(self, block):
        self.blocks.append(block)

    def stats(self, rows):
        self.rows.extend(rows)

    def checkpoint(self, state):
        self.checkpoints.append(state)

    def series(self, name):
        return np.concatenate([b[name] for b in self.blocks], axis=-1)


def make_drive(distance_m=200.0, road=None, vehicle="apc_8x8", overrides=None, speed_kmh=20.0, **settings):
    model = VehicleModel(load_vehicle(vehicle, overrides))
    if road is None:
        road = build_road(RoadSpec(iso_class="D", length=distance_m + 20.0, seed=3))
    s = DriveSettings(distance_m=distance_m, speed=SpeedProfile.constant(speed_kmh / 3.6), **settings)
    return Drive(model, road, s)
