"""Figures (matplotlib) and the live viewer."""
