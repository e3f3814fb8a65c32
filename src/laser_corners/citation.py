"""The reference of the method, in one place: docstrings point here, outputs record it."""

from __future__ import annotations

__all__ = ["CITATION", "DOI"]

DOI = "10.1109/ICARA60736.2024.10553006"
"""DOI of the paper."""

CITATION = (
    'R. B. Sousa, H. M. Sobreira, M. F. Silva, A. P. Moreira, "Line Fitting-Based Corner-Like '
    'Detector for 2D Laser Scanners Data", 2024 10th International Conference on Automation, '
    "Robotics and Applications (ICARA), Athens, Greece, pp. 210-216, "
    f"doi:{DOI}"
)
"""The paper (the authors' own bibliography entry), recorded in every output's metadata."""
