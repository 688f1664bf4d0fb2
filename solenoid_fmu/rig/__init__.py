"""rig: see the README's package map."""
