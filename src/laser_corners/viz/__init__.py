"""Figures (matplotlib), report folders (:mod:`~laser_corners.viz.report`) and the live viewer."""
