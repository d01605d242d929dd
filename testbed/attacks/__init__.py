"""Attacks on localization (FusionRipper, trace injection, stealthy) and on lane detection (DRP)."""
