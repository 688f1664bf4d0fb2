r"""Read a test-rig recording and compute its flux linkage by paper eq. 4 (``sf.read_recording``).

Psi(t) = integral of (U - R i) dt, with the coil resistance from the header (or estimated) and the
integration constant from the rests. Writes the recording back and reads it again: the format
round trip is exact. Run::

    python examples/ex_read_recording.py RECORDING.csv
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

import solenoid_fmu as sf


def run(path) -> dict:
    """Kind, samples, sample rate [Hz], flux linkage (``FluxResult``) and the round-trip check."""
    rec = sf.read_recording(path)
    flux = sf.flux_linkage(rec)
    with tempfile.TemporaryDirectory() as tmp:
        again = sf.read_recording(sf.write_recording(Path(tmp) / Path(path).name, rec))
    return {"kind": rec.kind, "n": len(rec.time_s), "time_s": rec.time_s, "current_A": rec.current_A,
            "flux": flux, "round_trip_equal": bool(np.array_equal(again.current_A, rec.current_A)
                                                     and np.array_equal(again.time_s, rec.time_s))}


if __name__ == "__main__":
    r = run(sys.argv[1])
    print(f"{r['kind']}: {r['n']} samples, R = {r['flux'].R_ohm:.4g} ohm "
          f"({r['flux'].resistance_source}), Psi max = {np.max(r['flux'].psi_Wb) * 1e3:.4f} mWb")
