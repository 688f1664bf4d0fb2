"""lot: a production lot, every unit its own model (``solenoid-fmu batch``).

Modules: :mod:`.units` (campaign folders in, unit folders out, whole or not at all, restartable),
:mod:`.worker` (one unit on a worker: files in as bytes, the pipeline, outputs out as bytes),
:mod:`.execute` (the lot on a local process pool or a Dask cluster, progress, Ctrl-C),
:mod:`.features` (what is compared between units), :mod:`.outliers` (robust z by median/MAD),
:mod:`.summary` (``lot.csv``, ``lot.html``), :mod:`.cli`.
"""

from .execute import connect, run_batch
from .features import FEATURES, unit_features
from .outliers import RULE, Z_THRESHOLD, robust_z, stand_out
from .summary import LOT_COLUMNS, write_lot_summary
from .units import UNIT_JSON, LotError, campaign_files, input_sha256, unit_complete
from .worker import run_unit

__all__ = [
    "FEATURES",
    "LOT_COLUMNS",
    "RULE",
    "UNIT_JSON",
    "Z_THRESHOLD",
    "LotError",
    "campaign_files",
    "connect",
    "input_sha256",
    "robust_z",
    "run_batch",
    "run_unit",
    "stand_out",
    "unit_complete",
    "unit_features",
    "write_lot_summary",
]
