"""loop: see the README's package map."""

from .improvement import heating_corrected, improve, jsonable, tables_from_fmu

__all__ = ["heating_corrected", "improve", "jsonable", "tables_from_fmu"]
