"""rig: see the README's package map."""

from .core import CampaignConfig, Effects, run_campaign

__all__ = ["CampaignConfig", "Effects", "run_campaign"]
