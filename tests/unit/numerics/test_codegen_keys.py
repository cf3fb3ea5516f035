"""The compile cache finds a drive's libraries by what determines their code (issue 26): no graph is built and no C
generated for a library in the cache; a change of the key (the model's structure) or of hpsim's source misses."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from terrain import RoadSpec, build_road
from vehicle.physics.model import VehicleModel
from vehicle.physics.params import load_vehicle
from vehicle.numerics import codegen, solvers
from vehicle.engines.full import Drive
from vehicle.scenario.settings import DriveSettings
from vehicle.scenario.speed import SpeedProfile

pytestmark = pytest.mark.skipif(codegen._compiler() is None, reason="no C compiler")


def _toy(name: str, builds: list, scale: float = 2.0):
    def build():
        builds.append(name)
        x = ca.SX.sym("x", 3)
        return ca.Function(name, [x], [ca.sin(x) * scale + x[0]])
    return build


def test_a_library_is_found_by_its_key_without_building_its_graph(tmp_path, monkeypatch):
    monkeypatch.setenv(codegen.CACHE_ENV, str(tmp_path / "cache"))
    generated = []
    real_generate = codegen._generate_c
    monkeypatch.setattr(codegen, "_generate_c",
                        lambda fn, *a, **kw: generated.append(fn.name()) or real_generate(fn, *a, **kw))
    builds: list = []
    name = "hpsim_keytest_f"
    first = codegen.compile_function(codegen.Library(name, ("structure-a", 4), _toy(name, builds)))
    assert builds == [name] and generated == [name]
    arg = np.array([0.1, 0.2, 0.3])
    expected = np.asarray(_toy(name, [])()(arg))
    np.testing.assert_array_equal(np.asarray(first(arg)), expected)
    # another process-like lookup: the same name and key find the library; no graph, no C
    again = codegen.compile_function(codegen.Library(name, ("structure-a", 4), _toy(name, builds)))
    assert builds == [name] and generated == [name]
    assert isinstance(again, ca.Function) and again.name() == name
    np.testing.assert_array_equal(np.asarray(again(arg)), expected)
    assert codegen.precompile([codegen.Library(name, ("structure-a", 4), _toy(name, builds))]) == 0
    assert builds == [name]
    # a changed key (another model structure) misses: built and compiled anew, with its own values
    other = codegen.compile_function(codegen.Library(name, ("structure-b", 4), _toy(name, builds, scale=3.0)))
    assert builds == [name, name] and len(generated) == 2
    np.testing.assert_array_equal(np.asarray(other(arg)), np.asarray(_toy(name, [], scale=3.0)()(arg)))
    # a changed source of hpsim misses too (the code that builds the graph or writes its C may have changed)
    monkeypatch.setattr(codegen, "source_version", lambda: "an edited hpsim")
    assert codegen.precompile([codegen.Library(name, ("structure-a", 4), _toy(name, builds))]) == 1
    assert builds == [name] * 3


def test_a_library_whose_signature_differs_from_its_record_is_not_loaded(tmp_path, monkeypatch):
    """The record keeps the graph's signature: a library (rightly hashed) with another signature is rebuilt."""
    monkeypatch.setenv(codegen.CACHE_ENV, str(tmp_path / "cache"))
    builds: list = []
    name = "hpsim_keytest_g"
    codegen.compile_function(codegen.Library(name, ("k",), _toy(name, builds)))
    record = next((tmp_path / "cache").glob(f"{name}_*.json"))
    good = record.read_text()
    record.write_text(good.replace('"signature": "', '"signature": "0'))
    fn = codegen.compile_function(codegen.Library(name, ("k",), _toy(name, builds)))
    assert builds == [name, name]                          # rebuilt from its graph, not loaded
    assert '"signature": "0' not in record.read_text()
    np.testing.assert_array_equal(np.asarray(fn([1.0, 2.0, 3.0])), np.asarray(_toy(name, [])()([1.0, 2.0, 3.0])))


def test_the_source_version_follows_the_installed_source():
    v = codegen.source_version()
    assert len(v) == 64 and v == codegen.source_version()
    codegen.source_version.cache_clear()
    assert codegen.source_version() == v


def test_a_drive_with_its_libraries_in_the_cache_builds_no_graph(monkeypatch):
    """A second process (here: the in-process memo cleared) builds the drive from the cache: no block function and
    no block outputs graph, no C; the drive's result is the same to the bit. A model of another structure misses."""
    road = build_road(RoadSpec(iso_class="D", length=80.0, seed=3))
    settings = dict(distance_m=40.0, speed=SpeedProfile.constant(20 / 3.6))
    m = VehicleModel(load_vehicle("apc_8x8"))
    solvers._BLOCK_FUNCTIONS.clear()
    first = Drive(m, road, DriveSettings(**settings)).run().state.x            # compiles when the cache is cold
    graphs = []
    real_graph, real_outputs = solvers.Ros2.block_function, solvers._outputs_function
    monkeypatch.setattr(solvers.Ros2, "block_function",
                        lambda self, model, K, M: graphs.append("block") or real_graph(self, model, K, M))
    monkeypatch.setattr(solvers, "_outputs_function",
                        lambda model, n: graphs.append("outputs") or real_outputs(model, n))
    monkeypatch.setattr(codegen, "_generate_c", lambda fn, *a, **kw: pytest.fail("C generated for a cached library"))
    real_step = solvers.Ros2.step_functions          # the batched block stepper's C is written from these
    monkeypatch.setattr(solvers.Ros2, "step_functions", lambda self, model: graphs.append("step") or real_step(self, model))
    real_split = solvers.Ros2.split_step_functions
    monkeypatch.setattr(solvers.Ros2, "split_step_functions",
                        lambda self, model: graphs.append("split") or real_split(self, model))
    solvers._BLOCK_FUNCTIONS.clear()
    again = Drive(m, road, DriveSettings(**settings)).run().state.x
    assert graphs == []
    np.testing.assert_array_equal(first, again)
    # the block function's key holds the structure: a structural change looks for (and builds) another library
    structure = m.structure
    solvers._BLOCK_FUNCTIONS.clear()
    lib = solvers.Ros2(0.004, batch_calls=False).block_graph(m, 50, 20)       # CasADi's C: a codegen.Library
    assert lib is not None and structure in lib.name and lib.key[0] == structure
    spec = solvers.Ros2(0.004).block_graph(m, 50, 20)           # the batched stepper: a codegen.CLibrary
    assert isinstance(spec, codegen.CLibrary) and structure in spec.name and spec.key[0] == structure
    monkeypatch.setattr(type(m), "structure", property(lambda self: structure + "_changed"))
    changed = solvers.Ros2(0.004, batch_calls=False).block_graph(m, 50, 20)
    assert changed.name != lib.name and codegen.lookup_key(changed, "cc") != codegen.lookup_key(lib, "cc")
    changed_spec = solvers.Ros2(0.004).block_graph(m, 50, 20)
    assert changed_spec.name != spec.name
    assert codegen._library_stem(changed_spec, "cc", "-O2")[2] != codegen._library_stem(spec, "cc", "-O2")[2]
    solvers._BLOCK_FUNCTIONS.clear()
