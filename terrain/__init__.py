"""Road profiles: ISO 8608 random roads, discrete events, measured profiles (no vehicle knowledge).

    from terrain import RoadSpec, build_road, road_statistics
    road = build_road(RoadSpec(iso_class="D", length="20 km", seed=7))
    h, dh = road.evaluate(s, "left")            # NumPy, C1 spline
    h, dh = road.evaluate(s, "left", pass_index=1)   # the surface the 2nd wheel over it meets
    f = road.casadi_functions()["left"]         # CasADi: s -> (height, slope)
    road_statistics(road)["gd_n0_m3"]

Modules: iso8608 (class table, PSD, generation), coherence, envelope (tyre contact
filter), events (and random populations of them), passes (surface per pass), profile_io
(CSV), road (Road), stats (PSD fit, IRI), spec (RoadSpec, build_road), plots, cli.
"""
import importlib

# names -> defining module, imported on first use (PEP 562): `import terrain` stays cheap for a
# command that only needs one of them (scipy.signal and scipy.ndimage take ~1 s to import)
_EXPORTS = {
    "EVENT_TYPES": "events", "EventPopulation": "events", "EventSpec": "events",
    "ISO_CLASS_GD_N0_M3": "iso8608", "class_of_gd": "iso8608", "displacement_psd": "iso8608",
    "PassSpec": "passes", "Road": "road",
    "RoadSpec": "spec", "build_road": "spec", "load_road_spec": "spec",
    "road_statistics": "stats",
}
__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    if name in _EXPORTS:
        value = getattr(importlib.import_module(f".{_EXPORTS[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_EXPORTS))
