"""Files of an identified curve: CSV (``load_material``), FEMM-style ``.bh`` and ``.tab``."""

from __future__ import annotations

from pathlib import Path

from ..field import write_bh_csv
from ..fileio import atomic_write_text
from .result import IdentificationResult, h_range_text

__all__ = ["write_curve_files"]


def write_curve_files(result: IdentificationResult, out_csv, sources=()) -> list[Path]:
    """Write the identified curve: ``out_csv`` (H_A_per_m,B_T, loadable by ``load_material``) and,
    beside it, ``.bh`` (FEMM style, "B H" per line, T and A/m) and ``.tab`` ("H B"), atomically."""
    out_csv = Path(out_csv)
    out_csv.parent.mkdir(parents=True, exist_ok=True)
    H, B = result.curve.table(n=200)
    lo, hi = result.identified_H_range_A_per_m
    comment = (f"B(H) identified by solenoid-fmu identify ({result.method}) at x = {result.x_m * 1e3:g} mm\n"
               f"identified H range {h_range_text((lo, hi))} (outside: shape of the start curve)\n"
               f"flux RMS error {result.rms_before * 100:.3g} % -> {result.rms_after * 100:.3g} % of peak\n"
               + (f"recordings: {', '.join(Path(str(s)).name for s in sources)}" if sources else ""))
    paths = [write_bh_csv(out_csv, H, B, comment=comment)]
    bh = "\n".join(f"{b:.9g}\t{h:.9g}" for h, b in zip(H, B, strict=True)) + "\n"
    tab = "\n".join(f"{h:.9g}\t{b:.9g}" for h, b in zip(H, B, strict=True)) + "\n"
    paths.append(atomic_write_text(out_csv.with_suffix(".bh"), bh))
    paths.append(atomic_write_text(out_csv.with_suffix(".tab"), tab))
    return paths

