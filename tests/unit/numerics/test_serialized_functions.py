"""CasADi functions kept in the compile cache as their serialization (`codegen.serialized_function`, issue 26: the
multiscale proxy's linearisation Jacobians are read, not built from the model's equations, in every run): found by
their key without building the graph, the same values, and loaded only under the cache's trust model."""
from __future__ import annotations

import casadi as ca
import numpy as np

from vehicle.numerics import codegen


def _toy(name: str, builds: list, scale: float = 2.0):
    def build():
        builds.append(name)
        x = ca.SX.sym("x", 3)
        return ca.Function(name, [x], [ca.sin(x) * scale + x[0], ca.jacobian(ca.exp(x) * x[1], x)])
    return build


def _values(fn, arg):
    return [np.asarray(v) for v in fn(arg)]


def test_a_serialized_function_is_read_back_without_its_graph(tmp_path, monkeypatch):
    monkeypatch.setenv(codegen.CACHE_ENV, str(tmp_path / "cache"))
    builds: list = []
    name = "hpsim_serialtest_f"
    arg = np.array([0.1, -0.2, 0.3])
    expected = _values(_toy(name, [])(), arg)
    first = codegen.serialized_function(codegen.Library(name, ("structure-a",), _toy(name, builds)))
    assert builds == [name]
    assert len(list((tmp_path / "cache").glob(f"{name}_*.casadi"))) == 1
    again = codegen.serialized_function(codegen.Library(name, ("structure-a",), _toy(name, builds)))
    assert builds == [name]                                   # read back: no graph built
    for fn in (first, again):
        for got, want in zip(_values(fn, arg), expected):
            np.testing.assert_array_equal(got, want)
    # another key (model structure) or another hpsim source misses
    codegen.serialized_function(codegen.Library(name, ("structure-b",), _toy(name, builds, scale=3.0)))
    assert builds == [name, name]
    monkeypatch.setattr(codegen, "source_version", lambda: "an edited hpsim")
    codegen.serialized_function(codegen.Library(name, ("structure-a",), _toy(name, builds)))
    assert builds == [name] * 3


def test_a_changed_serialized_file_is_built_again_not_read(tmp_path, monkeypatch):
    """The record holds the file's SHA-256: a file changed after it was written (here: another function's
    serialization in its place) is not deserialized; the function is built again and the file rewritten."""
    monkeypatch.setenv(codegen.CACHE_ENV, str(tmp_path / "cache"))
    builds: list = []
    name = "hpsim_serialtest_g"
    codegen.serialized_function(codegen.Library(name, ("k",), _toy(name, builds)))
    data = next((tmp_path / "cache").glob(f"{name}_*.casadi"))
    data.write_text(_toy(name, [], scale=-5.0)().serialize())
    fn = codegen.serialized_function(codegen.Library(name, ("k",), _toy(name, builds)))
    assert builds == [name, name]
    arg = np.array([1.0, 2.0, 3.0])
    for got, want in zip(_values(fn, arg), _values(_toy(name, [])(), arg)):
        np.testing.assert_array_equal(got, want)
    again = codegen.serialized_function(codegen.Library(name, ("k",), _toy(name, builds)))
    assert builds == [name, name]                             # the rewritten file is read
    np.testing.assert_array_equal(_values(again, arg)[0], _values(fn, arg)[0])


def test_an_unwritable_cache_still_gives_the_function(tmp_path, monkeypatch):
    """A cache folder that cannot be written: the function is built and used (nothing kept)."""
    cache = tmp_path / "cache"
    monkeypatch.setenv(codegen.CACHE_ENV, str(cache))
    codegen.cache_dir()                                      # created (0700)
    monkeypatch.setattr(codegen.tempfile, "mkdtemp", lambda **kw: (_ for _ in ()).throw(OSError("read-only")))
    builds: list = []
    fn = codegen.serialized_function(codegen.Library("hpsim_serialtest_h", ("k",), _toy("hpsim_serialtest_h",
                                                                                          builds)))
    assert builds == ["hpsim_serialtest_h"] and fn.name() == "hpsim_serialtest_h"
    assert not list(cache.glob("*.casadi"))
