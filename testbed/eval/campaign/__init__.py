"""Campaigns: many runs in one folder, resumable, on a registered backend (local, Ray)."""
