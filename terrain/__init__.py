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
from .events import EVENT_TYPES, EventPopulation, EventSpec
from .iso8608 import ISO_CLASS_GD_N0_M3, class_of_gd, displacement_psd
from .passes import PassSpec
from .road import Road
from .spec import RoadSpec, build_road, load_road_spec
from .stats import road_statistics

__all__ = ["EVENT_TYPES", "EventPopulation", "EventSpec", "ISO_CLASS_GD_N0_M3", "PassSpec", "Road", "RoadSpec",
           "build_road", "class_of_gd", "displacement_psd", "load_road_spec", "road_statistics"]
