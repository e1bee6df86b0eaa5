"""The mount's twist as a term of the online self-calibration: an offset plus a gain times the unit's lateral
acceleration per axis (``camera.self_calibration.twist_regressor: lateral_acceleration``; docs/camera.md, "The
mount's twist in the model").

A mount that twists linearly with the unit's lateral acceleration ``a`` (the flex model of :mod:`sensor.mount_flex`)
turns the right camera by ``ω(a) = ω₀ + g·a`` per axis (roll, pitch, yaw); :class:`~sensor.vo.self_calibration.
StereoSelfCalibration` alone follows it with its memory's lag ((SC3) of :mod:`sensor.vo.self_calibration`). Here
the parameters are six, a level and a gain per axis, the level being the angles at the regressor's recent mean
``ā``, not at ``a = 0``:

    ω(a) = ω_c + g·(a − ā_k),   ā_k = λ·ā_{k−1} + (1 − λ)·a_k   (ā_1 = a_1),                      (SC4)

``λ`` the offsets' forgetting, so ``ā`` is the regressor's mean over the offsets' own memory. The regressor
enters centred (the centred straight-line fit, Draper & Smith 1998, ch. 1: a centred predictor makes the
intercept's and the slope's estimates uncorrelated): where ``a`` holds still, whatever its value, the rows say
nothing of the gains and the level is estimated as by (SC3) alone, with its memory; only the regressor's change
within that memory carries the gains. A frame taken at the measured regressor ``a_k`` (the rig's own unit's gyro
yaw rate times its wheel speed, never the truth) gives the rows

    z + A·ω_used = [A, (a_k − ā_k)·A]·x,   x = (ω_c, g),                                        (SC5)

``A``, ``z`` the frame's rows (SC1)–(SC2), ``ω_used`` the angles its right image was corrected with (those of the
frames before at ``a_k``, which is known when the frame is taken). Before a frame's rows, ``ā`` takes the frame's
regressor and the parameters are carried to it, ``x ← T·x``, ``Λ ← T⁻ᵀ·Λ·T⁻¹``, ``η ← T⁻ᵀ·η``,
``T = [[I₃, Δ·I₃], [0, I₃]]``, ``Δ = ā_k − ā_{k−1}`` (the same ``ω(a)`` and the same information in the new
coordinates: exact), and forgotten, each block at its own rate, the levels at ``λ`` (``forgetting``), the gains at
``λ_g`` (``twist_forgetting``), the gains' information kept from falling below their prior's (stabilised
forgetting, Kulhavý & Zarrop 1993), so that a drive where ``a`` holds still does not wind their covariance up, and
the estimate is kept through the forgetting:

    Λ⁻_k = D·Λ_{k−1}·D + (I − D²)·Λ_g0,   η⁻_k = Λ⁻_k·x̃_{k−1},   D = diag(√λ·I₃, √λ_g·I₃),        (SC6)

``Λ_g0`` the gains' prior information (zero on the levels; ``T`` leaves it as it is), ``x̃ = Λ⁻¹·η`` the unclipped
estimate; then the update of (SC3) with the rows (SC5), Huber weights and all. The angles reported, and used for
the next frame's correction, are those at the frame's regressor, with their standard deviations:

    ω̂(a_k) = ω̂_c + ĝ·(a_k − ā),   σ(a_k) = sqrt(diag J·Λ⁻¹·Jᵀ),   J = [I₃, (a_k − ā)·I₃].        (SC7)

It fits a twist linear in the regressor exactly, a real mount's only as far as it is linear. The regressor
``u·r`` is the steady-state lateral acceleration at the unit's axles: the lever of the rig's station times the
yaw acceleration and the rate of the side-slip are left to the levels' memory.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .self_calibration import MAX_TWIST_DEG_PER_MPS2, SelfCalibrationStep, StereoSelfCalibration

__all__ = ["TwistSelfCalibration"]


@dataclass
class TwistSelfCalibration(StereoSelfCalibration):
    """The self-calibration with a twist term per axis, (SC4)–(SC7) (module docstring).

    Parameters are :class:`~sensor.vo.self_calibration.StereoSelfCalibration`'s; ``settings.twist_forgetting`` and
    ``settings.twist_prior_std_deg_per_mps2`` set the gains' forgetting and prior. :meth:`update`,
    :meth:`correction_homography` and :meth:`angles_at` take the frame's regressor ``a_k`` [m/s²] (None: 0).
    """

    def reset(self) -> None:
        """Back to the zero start: the levels' and the gains' prior information, no regressor mean yet."""
        s = self.settings
        offset = 1.0 / math.radians(s.prior_std_deg) ** 2
        gain = 1.0 / math.radians(s.twist_prior_std_deg_per_mps2) ** 2
        self._gain_prior = np.diag([0.0, 0.0, 0.0, gain, gain, gain])
        self._info = np.diag([offset, offset, offset, gain, gain, gain])
        self._eta = np.zeros(6)
        self._omega = np.zeros(6)
        self._regressor = 0.0
        self._mean: float | None = None

    @property
    def angles(self) -> tuple[float, float, float]:
        """The estimate (roll, pitch, yaw) [rad] at the last frame's regressor (SC7)."""
        return self.angles_at(self._regressor)

    @property
    def sigma(self) -> tuple[float, float, float]:
        """Standard deviations of :attr:`angles` [rad] (SC7)."""
        return self.sigma_at(self._regressor)

    @property
    def regressor_mean(self) -> float:
        """``ā`` of (SC4) [m/s²]: the regressor's mean over the offsets' memory (0 before the first frame)."""
        return 0.0 if self._mean is None else self._mean

    @property
    def offsets(self) -> tuple[float, float, float]:
        """``ω̂(0)``: the angles at no lateral acceleration (roll, pitch, yaw) [rad]."""
        return self.angles_at(0.0)

    @property
    def gains(self) -> tuple[float, float, float]:
        """``ĝ``: the twist per axis (roll, pitch, yaw) [rad/(m/s²)]."""
        return (float(self._omega[3]), float(self._omega[4]), float(self._omega[5]))

    def _centred(self, regressor: float | None) -> float:
        """``a − ā`` of (SC4) [m/s²] for the regressor ``a`` (None: 0)."""
        return (0.0 if regressor is None else float(regressor)) - self.regressor_mean

    def angles_at(self, regressor: float | None = None) -> tuple[float, float, float]:
        """``ω̂_c + ĝ·(a − ā)`` (SC7) [rad] at the regressor ``a`` [m/s²] (None: 0)."""
        a = self._centred(regressor)
        w = self._omega[:3] + a * self._omega[3:]
        return (float(w[0]), float(w[1]), float(w[2]))

    def sigma_at(self, regressor: float | None = None) -> tuple[float, float, float]:
        """``sqrt(diag J·Λ⁻¹·Jᵀ)``, ``J = [I₃, (a − ā)·I₃]`` (SC7) [rad]."""
        a = self._centred(regressor)
        jacobian = np.hstack([np.eye(3), a * np.eye(3)])
        d = np.sqrt(np.diag(jacobian @ np.linalg.solve(self._info, jacobian.T)))
        return (float(d[0]), float(d[1]), float(d[2]))

    def update(
        self,
        matches: np.ndarray,
        used: tuple[float, float, float] | None = None,
        inliers: np.ndarray | None = None,
        regressor: float | None = None,
    ) -> SelfCalibrationStep:
        """:meth:`StereoSelfCalibration.update` with the rows (SC5) at ``regressor`` [m/s²] (None: 0)."""
        a = 0.0 if regressor is None else float(regressor)
        if not math.isfinite(a):
            raise ValueError(f"twist regressor must be finite [m/s²], got {regressor!r}")
        self._regressor = a
        self._centre(a)
        return super().update(matches, used, inliers, a)

    def _centre(self, a: float) -> None:
        """The frame's regressor mean ``ā_k`` (SC4) and the parameters carried to it, ``x ← T·x``, ``Λ ← T⁻ᵀ·Λ·T⁻¹``,
        ``η ← T⁻ᵀ·η``, ``T = [[I, Δ·I], [0, I]]``: the same angles at every regressor, in the new coordinates."""
        previous = self._mean
        lam = self.settings.forgetting
        self._mean = a if previous is None else lam * previous + (1.0 - lam) * a
        shift = 0.0 if previous is None else self._mean - previous
        if shift:
            inverse = np.eye(6)
            inverse[:3, 3:] = -shift * np.eye(3)
            self._info = inverse.T @ self._info @ inverse
            self._eta = inverse.T @ self._eta
            self._omega = np.concatenate([self._omega[:3] + shift * self._omega[3:], self._omega[3:]])

    def _design(self, a: np.ndarray, regressor: float | None) -> np.ndarray:
        """``[A, (a_k − ā_k)·A]`` (SC5)."""
        return np.hstack([a, self._centred(regressor) * a])

    def _forget(self) -> tuple[np.ndarray, np.ndarray]:
        """(SC6): each block at its own rate, the gains' information kept at least their prior's."""
        s = self.settings
        d = np.sqrt(np.array([s.forgetting] * 3 + [s.twist_forgetting] * 3))
        kept = np.linalg.solve(self._info, self._eta)
        info = d[:, None] * self._info * d[None, :] + (1.0 - d**2)[:, None] * self._gain_prior
        return info, info @ kept

    def _clip(self, x: np.ndarray) -> np.ndarray:
        """The levels to ``max_angle_deg``, the gains to :data:`~sensor.vo.self_calibration.MAX_TWIST_DEG_PER_MPS2`."""
        angle, gain = math.radians(self.settings.max_angle_deg), math.radians(MAX_TWIST_DEG_PER_MPS2)
        return np.concatenate([np.clip(x[:3], -angle, angle), np.clip(x[3:], -gain, gain)])
