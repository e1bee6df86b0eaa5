"""The following unit's measurement widened by the follower's own off-tracking variance in the share its own filter
gives its tyres: (C4).

A following unit's camera motion carried forward through the couplings ((C1)–(C2) of :mod:`sensor.fusion_coupling`)
has no tyre in it, but it has the follower's camera's own errors, less the part the follower's filter holds to be its
odometry's yaw error ((C0)). While the follower's tyres scrub (its axles at or near their lock) its filter cannot tell
that error from the scrub: (K5)–(K6) of :mod:`sensor.fusion_slip` take its frame's motion with the coupled translation
at ``1 − D`` and the yaw error at ``1 − r·D`` of their estimates, ``D`` in ``[0, 1]`` its scrub demand at the frame,
so the share ``D`` of what the camera's motion says is left to the scrub, and (C0) removes from the reference only
what the filter keeps. The rest of the follower's camera error reaches the lead's kingpin unremoved; it persists as
long as the scrub does (docs/field_bias.md §7.37), while (C2) takes each frame's error as white. What the follower
knows of that error is its own off-tracking variance ``σ_f²`` (its fused filter's std squared): its position across
its path is known no better, whatever its camera's per-frame covariance says. With ``follower_share``
(``fusion.side_rig.coupling_follower_share``; on by default, ``false`` turns it off) the reference's lateral
variance takes ``σ_f²`` in the same share ``D`` the follower's filter gives the scrub::

    R_c ← R_c + D·σ_f²·e_y·e_yᵀ                                                                            (C4)

``D = 0`` leaves (C2) as it is, so on a road where the follower's tyres roll the reference is unchanged; at ``D = 1``
it is (C3)'s ``inflate`` (:func:`~sensor.fusion_coupling.follower_limited`) without its threshold. A frame whose ``D``
or ``σ_f`` is not known (no follower filter, or one without an estimate yet) is taken as (C2) gives it. The increment
is not changed.
"""

from __future__ import annotations

import math

import numpy as np

from vehicle_model.errors import InputError

__all__ = ["follower_shared"]


def follower_shared(covariance: np.ndarray, demand: float, follower_std: float) -> np.ndarray:
    """(C4) of the module notes: the reference's 3×3 covariance ``R_c`` widened on the lead's lateral axis by the
    follower's off-tracking variance in the share ``demand`` of its scrub.

    Parameters
    ----------
    covariance
        ``R_c`` of (C2) [m², m², rad² and their products], ``(dx, dy, dψ)`` in the lead's axes.
    demand
        The follower's scrub demand ``D`` at the frame, in [0, 1] (NaN: not known).
    follower_std
        The follower's off-tracking std [m] (its fused filter's; NaN: not known).

    Returns
    -------
    numpy.ndarray
        ``R_c + D·σ_f²·e_y·e_yᵀ``; a copy of ``covariance`` where ``D`` or ``σ_f`` is not known.

    Raises
    ------
    InputError
        ``demand`` outside [0, 1] or ``follower_std`` negative.
    """
    widened = np.array(covariance, dtype=float)
    if math.isnan(demand) or math.isnan(follower_std):
        return widened
    if not 0.0 <= demand <= 1.0:
        raise InputError(f"demand = {demand!r}: allowed 0–1 (the follower's scrub demand D of (K5))")
    if not 0.0 <= follower_std < math.inf:
        raise InputError(f"follower_std = {follower_std!r}: allowed a finite std of at least 0 m")
    widened[1, 1] += demand * follower_std * follower_std
    return widened
