"""Run a lot: every unit through the pipeline on an existing engine, restartable, with progress.

``scheduler="local"``: a :class:`concurrent.futures.ProcessPoolExecutor` on this machine (``workers``
processes; :func:`solenoid_fmu.maps.process_pool`, whose workers exit when the batch dies). Any other value is
a Dask scheduler address: ``distributed.Client(address)`` submits one task per unit; the cluster decides how
many run at once. Nothing here schedules or transports by itself: the unit's campaign goes to the worker as
bytes in the task's arguments and its outputs come back as the task's result (no shared filesystem needed).

A unit whose output folder is complete for its present inputs (:func:`solenoid_fmu.lot.units.unit_complete`)
is skipped. Each unit's result is written into ``OUT/<unit>/`` whole as soon as it arrives
(:func:`solenoid_fmu.lot.units.publish_unit`). Ctrl-C cancels what is not finished, keeps what is, writes
the lot summary and raises :class:`KeyboardInterrupt` (the command exits 130).
"""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
import sys
import time
from pathlib import Path

from tqdm import tqdm

from ..fileio import dir_lock, require_directory
from ..maps import process_pool
from ..pipeline import PRESETS
from .summary import write_lot_summary
from .units import (
    LotError,
    campaign_files,
    input_sha256,
    publish_unit,
    read_unit_json,
    remove_leftovers,
    unit_complete,
    unit_names,
)
from .worker import one_line, run_unit

__all__ = ["connect", "run_batch"]

#: Seconds to wait for a Dask scheduler to answer.
CONNECT_TIMEOUT_S = 10


def connect(address: str):
    """A ``distributed.Client`` on the scheduler at ``address``; :class:`LotError` naming it when unreachable."""
    try:
        from distributed import Client
        from distributed.comm import parse_address, parse_host_port
    except ImportError as exc:  # pragma: no cover - a dependency of the package
        raise LotError(f"--scheduler {address}: dask.distributed is not installed ({exc})") from None
    try:  # a malformed address is refused before a Client exists (a half-made one hangs on its way out)
        scheme, location = parse_address(address)
        if scheme in ("tcp", "tls"):
            parse_host_port(location)
    except (ValueError, TypeError) as exc:
        raise LotError(f"not a Dask scheduler address: {address!r} ({' '.join(str(exc).split())}); "
                       "use 'local' or tcp://HOST:PORT") from None
    try:
        return Client(address, timeout=CONNECT_TIMEOUT_S, set_as_default=False)
    except (OSError, TimeoutError, ValueError, TypeError) as exc:
        raise LotError(f"cannot reach the Dask scheduler at {address!r}: {' '.join(str(exc).split())}") from None


def _check_workers(client) -> None:
    """Say what the cluster offers: no worker yet (the units wait for one), or workers running several units at
    once in one process (threads: the figures' matplotlib is not thread-safe; start them with ``--nthreads 1``)."""
    workers = client.scheduler_info().get("workers", {})
    if not workers:
        _say(f"lot: the scheduler {client.scheduler.address} has no worker yet; the units wait for one")
    threaded = sorted(w.get("name", a) for a, w in workers.items() if w.get("nthreads", 1) > 1)
    if threaded:
        _say(f"lot: note: {len(threaded)} worker(s) have more than one thread and run several units in one process; "
             "start workers with --nthreads 1 (one unit per process)")


def _say(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def run_batch(campaign_dirs, out_dir, *, scheduler: str = "local", workers: int | None = None,
              preset: str = "quick", geometry=None, start_material=None, progress: bool = True) -> dict:
    """Run the pipeline on every unit of a lot (module docstring) and write the lot summary.

    Parameters
    ----------
    campaign_dirs : list of path-like
        One campaign folder per unit; the folder's name is the unit's.
    out_dir : path-like
        ``OUT``: ``OUT/<unit>/`` per unit (the pipeline's outputs and ``unit.json``), ``lot.csv``, ``lot.html``.
    scheduler : str
        ``"local"`` (a process pool here) or a Dask scheduler address (``tcp://host:8786``).
    workers : int, optional
        Processes of the local pool (default: all cores); ignored for a Dask scheduler.
    preset : str
        The pipeline preset of every unit (:data:`solenoid_fmu.pipeline.PRESETS`).
    geometry : path-like, optional
        The solenoid's geometry TOML (default: the packaged PS45); sent to the workers as text.
    start_material : path-like, optional
        B(H) CSV the identification of every unit starts from (the lot's nominal steel; default the literature
        curve); sent to the workers as text.
    progress : bool
        Units done / failed / skipped and the time left on stderr.

    Returns
    -------
    dict
        ``rows`` (one per unit, as in ``lot.csv``), ``ran`` (units run now), ``skipped`` (complete before),
        ``failed``, ``lot_csv``, ``lot_html``, ``wall_s``.
    """
    t0 = time.perf_counter()
    if preset not in PRESETS:
        raise LotError(f"unknown preset {preset!r}; use one of {', '.join(PRESETS)}")
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise LotError(f"workers must be a whole number >= 1, got {workers!r}")
    units = unit_names(campaign_dirs)
    geometry_text, start_text = _read_text(geometry, "geometry"), _read_text(start_material, "start material")
    out = require_directory(out_dir, "-o")
    for _name, folder in units:
        if out.resolve().is_relative_to(folder.resolve()):
            raise LotError(f"-o {out_dir} is inside the campaign folder {folder}")
    client = None if scheduler == "local" else connect(scheduler)  # before any work: a bad address fails at once
    if client is not None and progress:
        _check_workers(client)
    out.mkdir(parents=True, exist_ok=True)
    try:
        with dir_lock(out):
            remove_leftovers(out)
            return _run(units, out, client, workers, preset, (geometry_text, start_text), progress, t0)
    finally:
        if client is not None:
            client.close()


def _read_text(path, what: str) -> str | None:
    if path is None:
        return None
    try:
        return Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        raise LotError(f"{path}: cannot read the {what}: {exc.strerror}") from None


def _run(units, out: Path, client, workers, preset, texts, progress, t0) -> dict:
    geometry_text, start_text = texts
    todo, inputs = [], {}
    for name, folder in units:
        files = campaign_files(folder)
        sha = input_sha256(files, preset, geometry_text, start_text)
        inputs[name] = (folder, files, sha)
        if not unit_complete(out / name, sha):
            todo.append(name)
    skipped = [n for n, _ in units if n not in todo]
    if progress:
        _say(f"lot: {len(units)} units, {len(skipped)} complete already, {len(todo)} to run "
             f"({'local' if client is None else client.scheduler.address}, preset {preset})")
    ran, failed = [], []
    bar = tqdm(total=len(todo), desc="lot", unit="unit", file=sys.stderr, disable=not progress)
    executor, futures = None, {}
    try:
        def task(n):
            return {"preset": preset, "geometry_text": geometry_text, "start_material_text": start_text,
                    "campaign_label": str(inputs[n][0]), "input_sha256": inputs[n][2]}

        if client is None:
            executor = process_pool(workers)
            futures = {executor.submit(run_unit, n, inputs[n][1], **task(n)): n for n in todo}
            done_iter = cf.as_completed(futures)
        else:
            from distributed import as_completed

            futures = {client.submit(run_unit, n, inputs[n][1], **task(n), pure=False,
                                     key=f"solenoid-unit-{n}-{inputs[n][2][:12]}"): n for n in todo}
            done_iter = as_completed(list(futures), loop=client.loop)
        for fut in done_iter:
            name = futures[fut]
            try:
                res = fut.result()
            except Exception as exc:  # the task itself died (worker lost, result not transferable)
                res = {"unit": {"unit": name, "status": "failed", "error": f"task lost: {one_line(exc)}",
                                "features": {}, "run_id": None, "input_sha256": inputs[name][2], "preset": preset,
                                "campaign": str(inputs[name][0]), "wall_s": None}, "files": {}}
            publish_unit(out, name, res["files"], res["unit"])
            ran.append(name)
            if res["unit"]["status"] != "ok":
                failed.append(name)
                bar.write(f"lot: {name} failed: {res['unit']['error']}", file=sys.stderr)
            bar.update(1)
            bar.set_postfix_str(f"done {len(ran) - len(failed)}, failed {len(failed)}")
    except KeyboardInterrupt:
        bar.close()
        _stop(executor, client, futures)
        executor = None
        summary = write_lot_summary(out, [n for n, _ in units], _records(out, units))
        _say(f"lot: interrupted; {len(ran)} unit(s) finished in this run are complete in {out}; "
             f"{len(todo) - len(ran)} left for the next run ({summary['lot_csv']})")
        raise
    finally:
        bar.close()
        if executor is not None:
            executor.shutdown(wait=True, cancel_futures=True)
    summary = write_lot_summary(out, [n for n, _ in units], _records(out, units))
    wall = time.perf_counter() - t0
    if progress:
        _say(f"lot: {len(ran) - len(failed)} done, {len(failed)} failed, {len(skipped)} skipped in {wall:.0f} s; "
             f"{summary['n_flagged']} stand out; {summary['lot_csv']}, {summary['lot_html']}")
    return {**summary, "ran": ran, "skipped": skipped, "failed": failed, "wall_s": wall}


def _records(out: Path, units) -> list[dict]:
    return [read_unit_json(out / n) or {"unit": n, "status": "not run", "error": None, "features": {}}
            for n, _ in units]


def _stop(executor, client, futures) -> None:
    """Ctrl-C: cancel the units not finished; end the local pool's processes now (their units are lost)."""
    if executor is not None:
        # the pool's own processes only (not other children of a program that called run_batch); the executor
        # has no public handle on them, and shutdown() would wait for their units to finish
        procs = list(getattr(executor, "_processes", None) or {})
        executor.shutdown(wait=False, cancel_futures=True)
        for p in multiprocessing.active_children():
            if p.pid in procs:
                p.terminate()
    if client is not None:
        client.cancel(list(futures))
