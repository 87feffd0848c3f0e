"""Summaries and reports built from what the engine recorded."""
