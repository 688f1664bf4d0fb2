"""identification: see the README's package map."""

from .identify import identify_from_recordings

__all__ = ["identify_from_recordings"]
