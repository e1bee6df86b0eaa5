"""The path-following controller's rules where its axles run out of reach (:mod:`controller.path_following`).

* The slip-angle window holds the feed-forward's own steer (:func:`window_holding`): the window ``β_j ± α_max`` comes
  from zero-slip kinematics of the tractor's signals, wrong when the tractor slides; the feed-forward depends on the
  kingpin's path only and no estimate moves it, so the limit bounds what the feedback adds (docs/controller_design.md
  §3.5, *Where the truth-fed maximum came from*).
* An outswing is not integrated where the feed-forward is beyond reach (:func:`is_outswing`): the lock's transient
  can leave the follow point outside the turn, and the integral would carry that as a bias into the cut-in after it.
* The outswing bound (:func:`outswing_scale`): the outward part of the command scaled down as the estimate's outswing
  nears the bound.

Sign convention: a left turn has ``κ5 > 0``; the trailer cuts in with ``e_tr < 0`` there, so an outswing is
``e_tr·κ5 > 0`` (docs/design.md §6).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["is_outswing", "outswing_scale", "window_holding"]


def window_holding(window: tuple[np.ndarray, np.ndarray], own: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The per-axle window ``(low, high)`` [rad] widened to hold the commands ``own`` [rad]."""
    return np.minimum(window[0], own), np.maximum(window[1], own)


def is_outswing(error: float | None, curvature: float) -> bool:
    """Whether the off-tracking ``error`` [m] lies outside the turn of curvature ``curvature`` [1/m]."""
    return error is not None and error * curvature > 0.0


def outswing_scale(virtual: float, error: float | None, curvature: float, bound: float | None) -> float:
    """The virtual-axle angle ``virtual`` [rad] with its outward part scaled by ``clip((b − o)/b, 0, 1)``.

    Parameters
    ----------
    virtual
        ``δ_v`` [rad]; outward is against the turn (negative in a left turn).
    error
        The estimate's off-tracking ``e_tr`` [m] (``None``: no estimate, nothing scaled).
    curvature
        ``κ5`` [1/m] (zero: no turn, nothing scaled).
    bound
        ``b`` [m] (``None``: no bound).
    """
    if bound is None or error is None or curvature == 0.0:
        return virtual
    turn = math.copysign(1.0, curvature)
    if virtual * turn >= 0.0:
        return virtual
    return virtual * min(max((bound - error * turn) / bound, 0.0), 1.0)
