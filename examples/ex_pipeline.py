r"""The main job on a campaign folder (``sf.run_pipeline``): recordings in, validated FMUs out.

Identify B(H), build the maps, fit the eddy-current parameter, export the FMUs (pythonfmu and
native), validate, diagnose and improve; writes ``report.html`` and ``summary.json``. Run::

    python examples/ex_pipeline.py CAMPAIGN_DIR OUT_DIR [quick|full]
"""

from __future__ import annotations

import sys

import solenoid_fmu as sf


def run(campaign="fitting/ps45-demo", out_dir="build/ex_pipeline", preset: str = "quick", workers: int = 2) -> dict:
    """The summary dict (also in ``OUT_DIR/summary.json``): effects added, errors before/after, files."""
    return sf.run_pipeline(campaign, out_dir, preset=preset, workers=workers, progress=None)


if __name__ == "__main__":
    s = run(*sys.argv[1:4])
    print(f"effects added: {', '.join(s['effects_added']) or 'none'}; report: {s['report']}")
