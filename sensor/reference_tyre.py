"""The axles' lateral force curve the vehicle's declared tyres give, for the own slip reference's (T5) root
(``reference_tyre: stated`` of :class:`~sensor.fusion_noise.FusionNoise`).

(T5) of :mod:`sensor.unit_slip_reference` balances the coupling's moment with each axle's force at its own slip
angle. With ``reference_tyre: brush`` that force is the brush tyre of (T3), fixed by the axle's cornering stiffness,
its static load and the road's friction ``μ_r`` alone; it over-states the slip near the friction's peak
(docs/field_bias.md §7.39). With ``stated`` it is the lateral force of the tyre the vehicle declares
(:class:`~vehicle_model.parameters.TyreParams` on each axle: the Magic Formula's shape ``C`` (``pcy1``), curvature
``E`` (``pey1``, ``pey2``), peak (``pdy1``, ``pdy2``) and cornering stiffness (``pky1``, ``pky2``)), the one
definition of :func:`vehicle_model.tyre.pure_lateral_force`, at the axle's static load and ``μ_r``::

    F_j(α) = n_j·f_y(α, F_zj/n_j, μ_r)   on |α| ≤ α_pj,   F_j(±α_pj) beyond it                          (S1)

(``n_j`` the axle's tyres, ``f_y`` one tyre's force, docs/vehicle_dynamics.md §3.1). A peaked curve falls past its
peak slip ``α_pj`` (the first zero of ``∂F_j/∂α``; ``α_max`` where the curve has none below it), and a falling
branch would give (T5) more than one root; the reference takes the rising branch and holds the peak beyond it, as
the brush tyre holds its friction beyond its saturation slip. So the moment ``Σ_j L_j·F_j`` is monotone in the
slip and (T5)'s root is unique, bracketed by the slips at which every axle is at its peak.
"""

from __future__ import annotations

from collections.abc import Sequence

import casadi as ca
import numpy as np
from scipy.optimize import brentq

from vehicle_model.parameters import TyreParams
from vehicle_model.tyre import pure_lateral_force

__all__ = ["PEAK_SLIP_LIMIT", "StatedTyreCurve"]

PEAK_SLIP_LIMIT = 1.0
"""``α_max`` of (S1) [rad]: the peak slip taken for a curve that does not peak below it (shape ``C`` ≤ 1)."""


class StatedTyreCurve:
    """The axles' lateral forces of (S1) on their rising branch.

    Parameters
    ----------
    tyres
        Each axle's declared tyre.
    loads
        Each axle's static load ``F_zj`` [N].
    n_tyres
        Each axle's tyres ``n_j``.
    lengths
        Each axle's distance ``L_j`` behind the front coupling [m] (the moment's levers of (T1)).
    friction
        ``μ_r``, the road's friction.

    Attributes
    ----------
    peak_slip : numpy.ndarray
        ``α_pj`` of (S1) [rad], each axle's slip angle at its peak force.
    """

    def __init__(
        self,
        tyres: Sequence[TyreParams],
        loads: np.ndarray,
        n_tyres: np.ndarray,
        lengths: np.ndarray,
        friction: float,
    ) -> None:
        self._axles = [
            (tyre, float(load) / float(n), float(n), float(length))
            for tyre, load, n, length in zip(tyres, loads, n_tyres, lengths, strict=True)
        ]
        self.friction = float(friction)
        self.peak_slip = np.array([self._peak(tyre, load) for tyre, load, _, _ in self._axles])

    def _peak(self, tyre: TyreParams, load: float) -> float:
        """``α_pj`` of (S1): the first zero of one tyre's ``∂f_y/∂α`` on ``(0, α_max]`` (``α_max`` where it has
        none; the slope falls through zero once if at all) [rad]."""
        alpha = ca.SX.sym("alpha")
        force = pure_lateral_force(tyre, alpha, load, self.friction)
        slope = ca.Function("slope", [alpha], [ca.jacobian(force, alpha)])
        if float(slope(PEAK_SLIP_LIMIT)) >= 0.0:
            return PEAK_SLIP_LIMIT
        return float(brentq(lambda a: float(slope(a)), 0.0, PEAK_SLIP_LIMIT, xtol=1e-15))

    def forces(self, slip: np.ndarray) -> np.ndarray:
        """Each axle's force ``F_j`` of (S1) [N] at its slip angle ``slip`` [rad], the peak held beyond ``α_pj``."""
        clipped = np.clip(slip, -self.peak_slip, self.peak_slip)
        return np.array(
            [  # (S1): the declared tyre's one definition, evaluated on floats
                n * pure_lateral_force(tyre, float(a), load, self.friction)
                for a, (tyre, load, n, _) in zip(clipped, self._axles, strict=True)
            ]
        )

    def moment(self, slip: np.ndarray) -> float:
        """``Σ_j L_j·F_j`` of (T6) with (S1)'s forces [N·m] at the axles' slip angles ``slip`` [rad]."""
        return sum(length * force for (_, _, _, length), force in zip(self._axles, self.forces(slip), strict=True))
