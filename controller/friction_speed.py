"""A target speed a driver who knows the surface would drive: the profile capped so the combination's acceleration
stays within a share of the road's friction.

Point-mass friction-circle speed planning (Kapania, Subosits & Gerdes 2016, "A sequential two-step algorithm for
fast generation of vehicle racing trajectories", J. Dyn. Sys., Meas., Control 138(9), 091005: its speed profile by
a forward and a backward integration over the path, subject to the tyres' friction). The vehicle is a point of mass
that may use at most ``a = share·μ·g`` of total acceleration, lateral and longitudinal together:

* lateral: ``v²·|κ| ≤ a``, so ``v ≤ sqrt(a/|κ|)`` at a station of curvature ``κ``;
* longitudinal: what the circle leaves, ``|a_x| ≤ sqrt(a² − (v²·κ)²)``, which is ``a`` on a straight;
* backward pass (braking in time for the tightest curvature ahead):
  ``v_i² ≤ v_{i+1}² + 2·Δs·sqrt(a² − (v_{i+1}²·κ_{i+1})²)``;
* forward pass (accelerating out): the same with ``i − 1`` in place of ``i + 1``.

Each pass takes the lateral acceleration at the station whose speed is already known (explicit in the station
spacing). The capped speed is never above the profile it wraps, so the profile's own ramps stay where they are gentler
than the friction allows. The point mass leaves out load transfer, the trailer's own path and grade; the share is
what keeps the margin for them (the traction and brake limits use the same kind of share, :mod:`controller.speed`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TypeVar

import numpy as np

from .driver import StationSpeedProfile

__all__ = ["friction_limited_profile", "friction_limited_speeds"]

Profile = TypeVar("Profile", bound=Callable[[float], float])


def friction_limited_speeds(
    stations: np.ndarray, curvature: np.ndarray, speeds: np.ndarray, acceleration: float
) -> np.ndarray:
    """The speeds ``speeds`` capped at each station by a friction circle of radius ``acceleration``.

    Parameters
    ----------
    stations : numpy.ndarray
        Increasing arc lengths of the path [m].
    curvature : numpy.ndarray
        Signed path curvature at each station [1/m].
    speeds : numpy.ndarray
        The target speed at each station before the cap [m/s], positive.
    acceleration : float
        The friction circle's radius ``share·μ·g`` [m/s²], positive.

    Returns
    -------
    numpy.ndarray
        The capped speeds [m/s]: ``≤ speeds`` and ``≤ sqrt(acceleration/|κ|)`` everywhere, with
        ``(v_i² − v_{i+1}²)/(2·Δs)`` and ``(v_{i+1}² − v_i²)/(2·Δs)`` within what the circle leaves (module docstring).
    """
    s = np.asarray(stations, dtype=float)
    kappa = np.abs(np.asarray(curvature, dtype=float))
    v = np.asarray(speeds, dtype=float).copy()
    if not (s.shape == kappa.shape == v.shape) or acceleration <= 0.0:
        raise ValueError("friction-limited speeds need one curvature and speed per station and an acceleration > 0")
    curved = kappa > 0.0
    v[curved] = np.minimum(v[curved], np.sqrt(acceleration / kappa[curved]))  # lateral: v²|κ| ≤ a
    a2 = acceleration * acceleration
    ds = np.diff(s)
    # Plain loops: one pass is sequential by nature (each station's cap depends on the one before it).
    vl, kl, dl = v.tolist(), kappa.tolist(), ds.tolist()
    for i in range(len(vl) - 2, -1, -1):  # backward: brake in time for what lies ahead
        known = vl[i + 1]
        lateral = known * known * kl[i + 1]
        reach = math.sqrt(known * known + 2.0 * dl[i] * math.sqrt(max(a2 - lateral * lateral, 0.0)))
        if reach < vl[i]:
            vl[i] = reach
    for i in range(1, len(vl)):  # forward: accelerate out no harder than the circle allows
        known = vl[i - 1]
        lateral = known * known * kl[i - 1]
        reach = math.sqrt(known * known + 2.0 * dl[i - 1] * math.sqrt(max(a2 - lateral * lateral, 0.0)))
        if reach < vl[i]:
            vl[i] = reach
    return np.array(vl)


def friction_limited_profile(
    base: Profile,
    stations: np.ndarray,
    curvature: np.ndarray,
    mu: float,
    share: float,
    gravity: float,
) -> Profile | StationSpeedProfile:
    """The speed profile ``base`` capped by the friction circle of radius ``share·μ·g`` along the path.

    Parameters
    ----------
    base
        The target speed [m/s] at an arc length [m] (:class:`~controller.driver.SpeedProfile` or
        :class:`~controller.driver.StationSpeedProfile`).
    stations, curvature : numpy.ndarray
        The path's arc lengths [m] and signed curvature [1/m] (its samples).
    mu
        The friction the driver plans for (the caller's choice, e.g. the least on the path).
    share
        The share of that friction the driver uses, in (0, 1].
    gravity
        [m/s²].

    Returns
    -------
    callable
        ``base`` itself where the cap changes no station's speed (the profile untouched); else a
        :class:`~controller.driver.StationSpeedProfile` of the capped speeds (:func:`friction_limited_speeds`) at
        ``stations``.
    """
    if not 0.0 < share <= 1.0 or mu <= 0.0:
        raise ValueError(f"a friction-limited profile needs 0 < share ≤ 1 and μ > 0, not {share} and {mu}")
    s = np.asarray(stations, dtype=float)
    speeds = np.array([base(float(x)) for x in s])
    capped = friction_limited_speeds(s, curvature, speeds, share * mu * gravity)
    if np.array_equal(capped, speeds):
        return base
    return StationSpeedProfile(s, capped)
