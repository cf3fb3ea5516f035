"""A compiled function called through CasADi's generated C interface (`vehicle.numerics.direct_call`, issue 26: a
drive's block outputs without CasADi's NumPy-to-DM conversion) gives the values of the same library loaded by
`casadi.external`, bit for bit: dense and sparse outputs, vectors given as 1-D arrays, non-contiguous arguments; a
wrong shape is refused."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from vehicle.numerics import codegen
from vehicle.numerics.direct_call import DirectFunction


def _toy() -> ca.Function:
    X = ca.SX.sym("X", 3, 4)
    v = ca.SX.sym("v", 3)
    s = ca.SX.sym("s")
    dense = ca.exp(X) * v + ca.sin(s) * X ** 2          # (3, 4), columns broadcast v
    sparse = ca.diag(ca.tanh(v) * s)                    # (3, 3), three nonzeros
    total = ca.sum2(ca.sum1(X * X)) / s                 # (1, 1)
    return ca.Function("hpsim_directtest_f", [X, v, s], [dense, sparse, total])


def test_the_direct_call_gives_the_external_functions_values_bit_for_bit(tmp_path, monkeypatch):
    monkeypatch.setenv(codegen.CACHE_ENV, str(tmp_path / "cache"))
    fn = _toy()
    external = codegen.compile_function(fn)
    if external.class_name() != "External":
        pytest.skip("no C compiler: nothing compiled to call directly")
    direct = codegen.compile_function(fn, direct=True)
    assert isinstance(direct, DirectFunction)
    rng = np.random.default_rng(4)
    big = rng.normal(size=(3, 8))
    X = big[:, ::2]                                      # not contiguous: the call makes its own column-major copy
    v, s = rng.normal(size=3), 0.7
    want = [np.asarray(r) for r in external(X, v, s)]
    got = direct(X, v, s)
    assert [g.shape for g in got] == [(3, 4), (3, 3), (1, 1)]
    for g, w in zip(got, want):
        np.testing.assert_array_equal(g, w)
    assert np.count_nonzero(got[1] - np.diag(np.diag(got[1]))) == 0      # the sparse output scattered to its diagonal
    np.testing.assert_array_equal(direct(X, v[:, None], np.array([s]))[0], want[0])
    with pytest.raises(ValueError, match="shape"):
        direct(X.T, v, s)
    with pytest.raises(TypeError, match="arguments"):
        direct(X, v)


def test_a_drives_block_outputs_are_called_directly_with_the_externals_values():
    """A drive's compiled block outputs (`solvers.compiled_outputs`) on its first block of states equal CasADi's call
    of the same library."""
    from terrain import RoadSpec, build_road
    from vehicle.engines.full import Drive
    from vehicle.numerics.solvers import Ros2
    from vehicle.physics.model import VehicleModel
    from vehicle.physics.params import load_vehicle
    from vehicle.scenario.settings import DriveSettings
    from vehicle.scenario.speed import SpeedProfile

    model = VehicleModel(load_vehicle("apc_8x8"))
    road = build_road(RoadSpec(iso_class="D", length=60.0, seed=2))
    d = Drive(model, road, DriveSettings(distance_m=20.0, speed=SpeedProfile.constant(20 / 3.6),
                                         output_interval_s=0.2, samples_per_block=2, error_check_every=0),
              solver=Ros2(0.004))
    if not isinstance(d.compiled_outputs, DirectFunction):
        pytest.skip("no C compiler: the outputs run in CasADi's virtual machine")
    st = d.initial_state()
    U = d.inputs(st.t_s + 0.004 * np.arange(d.K * d.M + 1))
    X = d.solver.advance(st.x, U, d.p)
    args = (X, d.solver.memory_samples, U[:, d.K * np.arange(1, d.M + 1)], d.p)
    want = [np.asarray(r) for r in d.compiled_outputs.fn(*args)]
    got = d.compiled_outputs(*args)
    assert len(got) == len(want) == 3
    for g, w in zip(got, want):
        assert np.all(np.isfinite(g))
        np.testing.assert_array_equal(g, w)
