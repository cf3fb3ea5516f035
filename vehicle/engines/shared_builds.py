"""What the cases of one study share in a worker process: the built vehicle model, its vehicle check and the road.

A study's cases often drive one vehicle (a sweep over road seeds, speeds or temperatures, the load cases of one
optimisation trial). `SharedBuilds` builds such a vehicle's model once per process and hands the same object to
every case that asks for it: with it go everything the model keeps for its own reuse (the equilibrium and
weighing solvers, the compiled functions bound to it) and the quiet vehicle check, whose outcome depends on the
vehicle alone. A road is shared when its specification and base folder are equal. Each is keyed by everything it
is built from, so a case gets what it would have built alone and its results are the same bit for bit
(tests/unit/studies/test_shared_builds.py).

`OwnBuilds` builds everything afresh for each drive (`hpsim run`); `build_engine` takes either.
"""
from __future__ import annotations

import json
import logging
import threading
from collections import OrderedDict
from pathlib import Path

from hpsim.errors import UserInputError
from struts.params import strut_file

from vehicle.physics.model import VehicleModel
from vehicle.physics.vehicle_check import pre_drive_check
from vehicle.scenario.schema import resolve_path, road_length_needed

LOG = logging.getLogger("hpsim")

# A built 8x8 model holds its symbolic graphs (a few MB); a 106 km road a few tens of MB with its splines. A study
# drives few vehicles and roads at a time, and a design study a new vehicle per trial: a handful of each is kept.
MAX_MODELS = 4
MAX_ROADS = 2


class OwnBuilds:
    """Every part built for this drive alone (what `hpsim run` does)."""

    def model(self, prepared) -> VehicleModel:
        return prepared.model()

    def check_vehicle(self, prepared, model: VehicleModel) -> None:
        prepared.check_vehicle(model)

    def road(self, prepared):
        return prepared.road()


def _file_stamp(path: Path) -> tuple:
    """(path, size, modification time) of a file a vehicle reads: a strut file changed during a study is read again."""
    try:
        st = path.stat()
    except OSError:
        return (str(path), None, None)
    return (str(path.resolve()), st.st_size, st.st_mtime_ns)


def vehicle_key(prepared) -> str:
    """Everything a `VehicleModel` is built from: the validated vehicle parameters (with the scenario's overrides,
    struts and compensation) and the strut files they name, by path, size and modification time."""
    vehicle = prepared.vehicle
    struts = []
    for axle in vehicle.axles:
        try:
            struts.append(_file_stamp(strut_file(axle.strut)))
        except UserInputError:
            struts.append((str(axle.strut), None, None))      # the model's own build reports it
    return json.dumps([vehicle.model_dump(mode="json"), struts], sort_keys=True, default=str)


def road_key(prepared) -> str:
    """Everything a road is built from: its validated specification, the folder its files are relative to, and the
    length the drive needs (which `Prepared.road` checks a profile file against)."""
    spec = prepared.road_spec
    dumped = spec.model_dump(mode="json") if hasattr(spec, "model_dump") else repr(spec)
    files = [_file_stamp(Path(resolve_path(str(getattr(spec, key)), Path(prepared.source.base_dir))))
             for key in ("csv", "crg") if getattr(spec, key, None)]
    needed = road_length_needed(prepared.scenario, prepared.vehicle)
    return json.dumps([dumped, str(prepared.source.base_dir), files, needed], sort_keys=True, default=str)


class _Recent:
    """The last `size` values by key (least recently used dropped first), safe for a worker's threads."""

    def __init__(self, size: int):
        self.size = size
        self.items: OrderedDict = OrderedDict()
        self.lock = threading.Lock()

    def get(self, key):
        with self.lock:
            if key in self.items:
                self.items.move_to_end(key)
                return self.items[key]
            return None

    def put(self, key, value) -> None:
        with self.lock:
            self.items[key] = value
            self.items.move_to_end(key)
            while len(self.items) > self.size:
                self.items.popitem(last=False)


class SharedBuilds:
    """The parts a worker process's drives share (see the module docstring); `hits` counts what was reused, by
    part ("model", "check", "road")."""

    def __init__(self, max_models: int = MAX_MODELS, max_roads: int = MAX_ROADS):
        self.models = _Recent(max_models)       # vehicle key -> (model, the vehicle check's outcome or None)
        self.roads = _Recent(max_roads)
        self.hits = {"model": 0, "check": 0, "road": 0}

    def model(self, prepared) -> VehicleModel:
        key = vehicle_key(prepared)
        entry = self.models.get(key)
        if entry is not None:
            self.hits["model"] += 1
            return entry["model"]
        model = prepared.model()
        self.models.put(key, {"model": model, "check": None})
        return model

    def check_vehicle(self, prepared, model: VehicleModel) -> None:
        """The quiet vehicle check (`Prepared.check_vehicle`), run once per vehicle: its warnings logged again and
        its refusal raised again, with this case's name, for every later drive of the same vehicle."""
        entry = self.models.get(vehicle_key(prepared))
        if entry is None or entry["model"] is not model:
            prepared.check_vehicle(model)
            return
        if entry["check"] is None:
            warnings: list[str] = []
            try:
                pre_drive_check(prepared.vehicle, model, log=warnings.append)
            except UserInputError as exc:
                entry["check"] = {"error": str(exc), "warnings": []}
            else:
                entry["check"] = {"error": None, "warnings": warnings}
        else:
            self.hits["check"] += 1
        for line in entry["check"]["warnings"]:
            LOG.warning(line)
        if entry["check"]["error"] is not None:
            raise UserInputError(f"{prepared.source.name}: {entry['check']['error']}")

    def road(self, prepared):
        key = road_key(prepared)
        road = self.roads.get(key)
        if road is not None:
            self.hits["road"] += 1
            return road
        road = prepared.road()
        self.roads.put(key, road)
        return road


_PROCESS_BUILDS: SharedBuilds | None = None
_PROCESS_LOCK = threading.Lock()


def process_builds() -> SharedBuilds:
    """This process's `SharedBuilds`: what a study's worker process shares between the cases it runs."""
    global _PROCESS_BUILDS
    with _PROCESS_LOCK:
        if _PROCESS_BUILDS is None:
            _PROCESS_BUILDS = SharedBuilds()
        return _PROCESS_BUILDS
