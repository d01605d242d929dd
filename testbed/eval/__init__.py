"""Scenarios, campaigns, metrics, plots and reports."""
