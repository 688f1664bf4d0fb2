"""The package's version, in a leaf module that imports nothing: every module that stamps it into what it
writes (maps provenance, FMU descriptions, reports, ``--version``) imports it from here, and the package root
re-exports it, so that no module imports from the package root."""

__version__ = "0.1.0"
