"""The resume state in a results file: the content of its checkpoint group (`layout.CHECKPOINT`), written by the
HDF5 sink after every block's data, read by the reader and by `--resume`."""
from __future__ import annotations

import json

import h5py
import numpy as np

from vehicle.results.netcdf import attach, dimension_only


class Checkpoint:
    """Double-buffered resume state in the checkpoint group: slots (2, L) float64 and pointer [slot, seq].

    A slot packs the DriveState dict plus n_samples, n_stats and wall_s; attrs["fields"] (JSON)
    gives each field's [offset, length] and shape. pointer = [-1, 0] until the first checkpoint.
    """

    META = ("n_samples", "n_stats", "wall_s")

    def __init__(self, group: h5py.Group):
        self.g = group
        self.fields = json.loads(group.attrs["fields"])

    @classmethod
    def create(cls, g: h5py.Group, state: dict) -> "Checkpoint":
        """The slots of `state`'s fields (and META) in the new, empty group g, no checkpoint written yet."""
        fields, off = {}, 0
        for k, v in list(state.items()) + [(m, 0.0) for m in cls.META]:
            a = np.asarray(v, float)
            fields[k] = [off, int(a.size), list(a.shape)]
            off += int(a.size)
        scales = {"slot": dimension_only(g, "slot", 2), "element": dimension_only(g, "element", off),
                  "entry": dimension_only(g, "entry", 2)}
        slots = g.create_dataset("slots", shape=(2, off), dtype="f8")
        attach(slots, ("slot", "element"), scales)
        pointer = g.create_dataset("pointer", data=np.array([-1, 0], dtype="i8"))
        attach(pointer, ("entry",), scales)
        g.attrs["fields"] = json.dumps(fields)
        g.attrs["description"] = ("resume state of the drive: pointer = [active slot, sequence number] (slot -1: "
                                  "none yet); slots[slot] packs the fields listed in attrs['fields'] as "
                                  "name: [offset, length, shape]")
        return cls(g)

    @staticmethod
    def complete(g: h5py.Group) -> bool:
        """Whether g holds what `read` needs (slots, pointer, fields)."""
        return "slots" in g and "pointer" in g and "fields" in g.attrs

    def write(self, state: dict, meta: dict) -> None:
        """The state into the inactive slot, the file flushed (with whatever else was written into it), then the
        pointer to that slot, flushed: a reader or a resume sees the previous checkpoint until the new one is whole."""
        slot, seq = (int(v) for v in self.g["pointer"][()])
        new = 1 - slot if slot in (0, 1) else 0
        vec = np.zeros(self.g["slots"].shape[1])
        values = {**state, **meta}
        for k, (off, size, _shape) in self.fields.items():
            vec[off:off + size] = np.asarray(values[k], float).ravel()
        self.g["slots"][new] = vec
        self.g.file.flush()
        self.g["pointer"][...] = np.array([new, seq + 1], dtype="i8")
        self.g.file.flush()

    def read(self) -> tuple[dict, dict] | None:
        slot, seq = (int(v) for v in self.g["pointer"][()])
        if slot not in (0, 1):
            return None
        vec = np.asarray(self.g["slots"][slot], float)
        out = {}
        for k, (off, size, shape) in self.fields.items():
            v = vec[off:off + size]
            out[k] = v.reshape(shape) if shape else float(v[0])
        meta = {m: out.pop(m) for m in self.META}
        meta["n_samples"], meta["n_stats"] = int(meta["n_samples"]), int(meta["n_stats"])
        return out, meta
