"""Reporting a plan: renderings of its result for people and for other tools."""
