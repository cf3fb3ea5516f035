"""Write examples/track_class_C.crg: 300 m of an ISO 8608 class C road (seed 11) as an OpenCRG surface, written
by the OpenCRG library's own writer (pycrg.write; extra crg). Long sections at v = -1.6, -1.25, 0, 1.25, 1.6 m:
the right and left tracks of a 2.5 m track at -1.25 / +1.25 m, their mean at the centre, the borders 2 mm
above the tracks.

    python docs/scripts/make_sample_crg.py
"""
from pathlib import Path

import numpy as np
import pycrg

from terrain import iso8608

SPACING_M, N = 0.05, 6001
left, right = iso8608.generate_tracks(iso8608.ISO_CLASS_GD_N0_M3["C"], 2.0, SPACING_M, N, seed=11)
z = np.column_stack([right + 0.002, right, 0.5 * (left + right), left, left + 0.002])
out = Path(__file__).resolve().parents[2] / "examples" / "track_class_C.crg"
pycrg.write(out, z, SPACING_M, [-1.6, -1.25, 0.0, 1.25, 1.6],
            comment=["hpsim sample: ISO 8608 class C, seed 11, 300 m", "made by docs/scripts/make_sample_crg.py"])
print(f"wrote {out}")
