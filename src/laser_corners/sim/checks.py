"""Validation of the simulator's numeric arguments (one-line errors naming the parameter)."""

from __future__ import annotations

import math

from laser_corners.errors import InvalidParamsError

__all__ = ["check_number"]


def check_number(name: str, value: object, *, positive: bool = False) -> float:
    """``value`` as a finite float that is ``>= 0`` (``> 0`` with ``positive``).

    Raises
    ------
    InvalidParamsError
        Naming ``name``, for a value that is not a number, not finite or out of range.

    Examples
    --------
    >>> check_number("speed", 0.5, positive=True)
    0.5
    >>> check_number("noise_sigma", -1.0)
    Traceback (most recent call last):
    ...
    laser_corners.errors.InvalidParamsError: noise_sigma must be a finite number >= 0, got -1.0
    """
    bound = "> 0" if positive else ">= 0"
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise InvalidParamsError(f"{name} must be a finite number {bound}, got {value!r}") from None
    if not math.isfinite(number) or number < 0.0 or (positive and number == 0.0):
        raise InvalidParamsError(f"{name} must be a finite number {bound}, got {number}")
    return number
