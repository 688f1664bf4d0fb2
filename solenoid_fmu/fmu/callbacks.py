"""fmpy's FMI 2.0 callbacks with one process-wide logger (used by :mod:`solenoid_fmu.fmu.simulate` and the tests).

fmpy's native logger proxy keeps ONE logger for the whole process; :func:`fmi2_callbacks` points it
at one callback that lives as long as the process and hands each message to the sink registered
for the instance's componentEnvironment.
"""

from __future__ import annotations

__all__ = ["fmi2_callbacks", "release_fmi2_callbacks"]

#: Log sinks of :func:`fmi2_callbacks` by componentEnvironment key; the one ctypes logger of the process.
_LOG_SINKS: dict = {}
_LOG_STATE = {"next_key": 1, "logger": None}


def _dispatch_fmi2_log(env, instance, status, category, message) -> None:
    """The process-wide FMI logger: hands a message to the sink registered for ``env`` (fmpy's
    printLogMessage for callbacks that are not ours, e.g. fmpy's defaults)."""
    sink = _LOG_SINKS.get(env)
    if sink is None:
        from fmpy.fmi1 import printLogMessage

        printLogMessage(env, instance, status, category, message)
        return
    sink(int(status), (category or b"").decode("utf-8", "replace"), (message or b"").decode("utf-8", "replace"))


def fmi2_callbacks(log):
    """fmpy ``fmi2CallbackFunctions`` whose logger calls ``log(status, category, message)`` (int, str, str).

    fmpy's native logger proxy (``fmpy.logging.addLoggerProxy``, which formats the FMU's printf-style
    messages) keeps ONE logger for the whole process, the last one registered. A ctypes callback made
    per FMU instance is freed with the instance and leaves that slot dangling: the next message of any
    FMU instantiated with fmpy's default callbacks then crashes the process (SIGSEGV). So the proxy
    always points to one callback that lives as long as the process, which passes each message to the
    ``log`` registered under the callbacks' componentEnvironment. Call :func:`release_fmi2_callbacks`
    when the instance is freed (an unreleased sink only keeps ``log`` alive).
    """
    from ctypes import byref

    import fmpy
    from fmpy.fmi2 import (
        fmi2CallbackAllocateMemoryTYPE,
        fmi2CallbackFreeMemoryTYPE,
        fmi2CallbackFunctions,
        fmi2CallbackLoggerTYPE,
    )
    from fmpy.logging import addLoggerProxy

    if _LOG_STATE["logger"] is None:
        _LOG_STATE["logger"] = fmi2CallbackLoggerTYPE(_dispatch_fmi2_log)
    key = _LOG_STATE["next_key"]
    _LOG_STATE["next_key"] = key + 1
    _LOG_SINKS[key] = log
    callbacks = fmi2CallbackFunctions()
    callbacks.logger = _LOG_STATE["logger"]
    callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(fmpy.calloc)
    callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(fmpy.free)
    callbacks.componentEnvironment = key
    addLoggerProxy(byref(callbacks))
    return callbacks


def release_fmi2_callbacks(callbacks) -> None:
    """Forget the log sink of callbacks made by :func:`fmi2_callbacks` (after fmi2FreeInstance)."""
    _LOG_SINKS.pop(callbacks.componentEnvironment, None)

