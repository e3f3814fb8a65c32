"""Evaluation: results and data only (figures and report folders: :mod:`laser_corners.viz`).

Ground truth from the simulator (``evaluate sim``): :mod:`~laser_corners.eval.accuracy`.
Paper section IV on real recordings (``evaluate real``): :mod:`~laser_corners.eval.real`
(result, :func:`~laser_corners.eval.real.load_scans`), :mod:`~laser_corners.eval.real_config`,
:mod:`~laser_corners.eval.real_phases` (the phases, composed of :mod:`~.no_return`,
:mod:`~.grid`, :mod:`~.visibility`, :mod:`~.observability`, :mod:`~.persistent`,
:mod:`~.association`, :mod:`~.pairs`, :mod:`~.poses`, :mod:`~.repeatability`) and
:mod:`~laser_corners.eval.real_summary` (the numbers as JSON and text).
Methods compared (one registry, :mod:`~laser_corners.eval.methods`): our detector's presets,
:mod:`~laser_corners.eval.baselines` (split-and-merge) and
:mod:`~laser_corners.eval.falko_like` (our reading of FALKO's score, not falkolib).
"""
