"""Loss of control: when a run stops being the manoeuvre it was meant to be.

A model that stays finite can still be meaningless: a combination spiralling off a ring on ice, or a trailer
folded past the tractor, integrates happily. The co-simulation checks every tick against two physical limits
and ends the run with status ``lost_control``, the time and the reason in words:

* **off the road** — the driver's control point more than :data:`MAX_PATH_ERROR` from its path. A 3.5 m
  lane (the usual width of a trunk-road lane, UK DMRB CD 127 / EU practice) with the 2.55 m-wide
  combination centred in it: once the control point is 3.0 m off the centre line (half the lane plus half
  the vehicle) no part of the tractor's front is in its lane any more.
* **jackknife** — the articulation angle beyond :data:`MAX_ARTICULATION_DEG`: at 90° the trailer's front
  corner reaches the tractor's rear for every preset's geometry (kingpin ahead of the drive axle, trailer
  front overhang ~1.6 m), so the real combination would have collided with itself.
"""

from __future__ import annotations

import math

MAX_PATH_ERROR = 3.0
"""Largest distance [m] of the driver's control point from its path before the run counts as off the road."""
MAX_ARTICULATION_DEG = 90.0
"""Largest articulation angle [deg] before the run counts as a jackknife."""


def loss_of_control(articulation: float, path_error: float) -> str:
    """Why the combination is out of control, in words, or ``""``.

    Parameters
    ----------
    articulation
        Articulation angle Γ [rad].
    path_error
        The driver's control point's lateral distance from its path [m].
    """
    if not math.isfinite(articulation) or abs(articulation) > math.radians(MAX_ARTICULATION_DEG):
        return (
            f"jackknife: articulation {math.degrees(articulation):+.1f}° beyond ±{MAX_ARTICULATION_DEG:g}° "
            "(the trailer would hit the tractor)"
        )
    if not math.isfinite(path_error) or abs(path_error) > MAX_PATH_ERROR:
        return (
            f"left the road: the driver's control point is {path_error:+.2f} m from its path "
            f"(limit ±{MAX_PATH_ERROR:g} m, a 3.5 m lane)"
        )
    return ""
