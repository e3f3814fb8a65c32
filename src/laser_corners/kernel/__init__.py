"""The detector's numba kernel, one module per phase (imported by :mod:`laser_corners.detector`).

- :mod:`~laser_corners.kernel.candidates`: points -> per-point candidate keypoints, and the one
  conversion of :class:`~laser_corners.DetectorParams` into kernel arguments;
- :mod:`~laser_corners.kernel.neighbourhood` (with its LLVM IR primitive
  :mod:`~laser_corners.kernel.simd`): the neighbourhood bounds of a point at every scale;
- :mod:`~laser_corners.kernel.linefit`: the closed-form line fits and intersection (eqs. 2-13);
- :mod:`~laser_corners.kernel.scale_tests`: the per-scale screen, exact test and best run;
- :mod:`~laser_corners.kernel.merge`: candidates -> keypoints (merging, refinement, batches);
- :mod:`~laser_corners.kernel.covariance` and :mod:`~laser_corners.kernel.fit_covariance`:
  keypoint covariances, computed on demand.

Nothing is imported here: importing a kernel module loads numba, and the package stays lazy.
"""
