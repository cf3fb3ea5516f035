"""Where each quantity a drive reads sits in the vehicle model's state vector: the quadratures (energies, ride
integrals), the nodes of each strut's heat network, the gas node, and the rows of the output table's time
series that are states (vehicle.physics.outputs). Built once per model and drive."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vehicle.physics import thermal
from vehicle.physics.model import DISSIPATION_TERMS, ENERGY_TERMS, HULL_ACCELERATIONS, VehicleModel
from vehicle.physics.outputs import VARIABLES, From


@dataclass(frozen=True)
class StateIndex:
    """quad_index     the quadratures a statistics interval differences: energies per station, int v^2 per station,
                      the hull's squared accelerations, then the ride integrals (VehicleModel.ride_index)
    ride_slots        ride integral name -> its positions in quad_index
    pump_index        the oil volume the levelling pump moved, per station (V_pump[i]; vehicle.physics.compensation)
    pump_slots        those states' positions in quad_index
                      (after the ride integrals)
    node_index        heat node (vehicle.physics.thermal.NODES) -> its state per station
    heat_nodes_index  every heat node's states, node by node in NODES' order (node k // n of station k % n)
    T_index, T_wall_index, T_oil_index   the surface (what a pyrometer reads: "strut temperature" in results),
                      wall and oil nodes per station
    T_gas_index       the gas node per station: the strut's T_gas state (energy-equation gas), else its oil
    heat_index        the dissipation energies per term (DISSIPATION_TERMS) per station
    series            the output table's time series (drive key -> From)
    series_rows       the state rows of those series that are states"""

    quad_index: np.ndarray
    ride_slots: dict
    pump_index: np.ndarray
    pump_slots: np.ndarray
    node_index: dict
    heat_nodes_index: np.ndarray
    T_index: np.ndarray
    T_wall_index: np.ndarray
    T_oil_index: np.ndarray
    T_gas_index: np.ndarray
    heat_index: list
    series: dict
    series_rows: dict

    @classmethod
    def of(cls, model: VehicleModel) -> "StateIndex":
        n = model.n
        quad = np.array([model.idx(f"E_{e}[{i}]") for e in ENERGY_TERMS for i in range(n)]
                        + [model.idx(f"I_v2[{i}]") for i in range(n)]
                        + [model.idx(f"I_{a}2") for a in HULL_ACCELERATIONS])
        ride_slots, k = {}, len(quad)
        for q, idx in model.ride_index.items():
            ride_slots[q] = k + np.arange(idx.size).reshape(idx.shape)
            k += idx.size
        if model.ride_index:
            quad = np.concatenate([quad] + [idx.ravel() for idx in model.ride_index.values()])
        pump = np.array([model.idx(f"V_pump[{i}]") for i in range(n)])
        pump_slots = len(quad) + np.arange(n)
        quad = np.concatenate([quad, pump])
        nodes = {node: np.array([model.idx(f"T_{node}[{i}]") for i in range(n)]) for node in thermal.NODES}
        T_gas = np.array([model.idx(f"T_gas[{i}]") if "T_gas" in model.struts[i].state_names
                          else model.idx(f"T_oil[{i}]") for i in range(n)])
        series = {key: v.series for key, v in VARIABLES.items() if v.series is not None}
        rows = {key: r for key, f in series.items() if (r := series_rows(model, nodes, f)) is not None}
        return cls(quad_index=quad, ride_slots=ride_slots, pump_index=pump, pump_slots=pump_slots, node_index=nodes,
                   heat_nodes_index=np.concatenate([nodes[node] for node in thermal.NODES]), T_index=nodes["surface"],
                   T_wall_index=nodes["wall"], T_oil_index=nodes["oil"], T_gas_index=T_gas,
                   heat_index=[model.energy_index[e] for e in DISSIPATION_TERMS], series=series, series_rows=rows)


def series_rows(model: VehicleModel, nodes: dict, f: From):
    """The state rows of a time series that is a slice of the states (vehicle.physics.outputs.From), or None."""
    if f.kind == "heat_node":
        return nodes[f.name]
    if f.kind == "state":
        return model.idx(f.name)
    if f.kind == "station_state":
        return np.array([model.idx(f"{f.name}[{i}]") for i in range(model.n)])
    if f.kind == "energy":
        return model.energy_index[f.name]
    return None
