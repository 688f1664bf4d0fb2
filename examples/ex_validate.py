r"""Validate an FMU against recordings (``sf.validate``): errors per recording and signal.

The FMU is driven by each recording's measured input (current, or voltage for voltage steps);
the simulated current, flux linkage (paper eq. 4) and force are compared with the measured ones:
RMS error in the signal's unit and NRMSE over the full scale of the campaign. Run::

    python examples/ex_validate.py FMU RECORDING.csv ...
"""

from __future__ import annotations

import sys

import solenoid_fmu as sf


def run(fmu, recordings, report_dir=None) -> dict:
    """The validation dict (``recordings``: per file and signal; ``summary``: per signal)."""
    return sf.validate(fmu, recordings, report_dir=report_dir)


if __name__ == "__main__":
    res = run(sys.argv[1], sys.argv[2:])
    for signal, s in res["summary"].items():
        print(f"{signal}: NRMSE (full scale) mean {s['nrmse_fs_mean']:.2%}, max {s['nrmse_fs_max']:.2%}")
