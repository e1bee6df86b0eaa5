"""The road's grade along the tractor's heading from its longitudinal accelerometer and its wheel speed.

An accelerometer along the tractor's x axis reads the specific force ``f_x = u̇ − v·r + g·sin θ`` (the
``tractor_longitudinal_acceleration`` signal, :mod:`sensor.signals`): the acceleration along the road plus the
grade's share of gravity. The wheel speed ``V`` gives the acceleration along the road as its derivative, so
``g·sin θ ≈ f_x − V̇``: the accelerometer-and-wheel-speed grade estimate of the road-grade literature (e.g. Bae, Ryu &
Gerdes 2001, "Road grade and vehicle parameter estimation for longitudinal control using GPS", which sets it beside
a GPS-based one; Sahlholm & Johansson 2010 estimate a road's grade on heavy trucks). Differencing a wheel speed
amplifies its noise (the data sheet's 0.02 m/s at 50 Hz is 1.4 m/s² per difference), so the derivative is not taken:
a two-state Kalman filter integrates the accelerometer less the grade into the speed and corrects both with the
wheel speed::

    V_k = V_(k-1) + dt·(f̄_x − g·s_(k-1))       s_k = s_(k-1) + w_s       measured: V_wheel = V + n     (G1)

with ``s = sin θ`` (a random walk: the road's grade changes as it goes), ``f̄_x`` the mean of the period's two
samples of the specific force less its ``−v·r`` (the caller's: :class:`~controller.zero_slip.ZeroSlipEstimator`
takes the tractor's lateral velocity at its centre of gravity from its zero-slip kinematics), ``w_s`` of variance
``grade_rate_std²·dt`` and ``n`` of variance ``wheel_speed_std²``; the accelerometer's noise and what (G1) leaves out
(the slip's share of ``v·r``; the difference between the horizontal ``u̇`` and the wheel's ``V̇``,
``u̇·(1/cos θ − 1)``) enter as ``acceleration_std``. In steady state it is a
complementary filter: the grade from the accelerometer at high frequency, its drift held by the wheel speed.

What it cannot see: the accelerometer's offset. A constant offset ``b`` reads as a grade ``b/g`` whichever way
the road goes, and nothing among the tractor's signals tells the two apart on a road driven one way (the literature
brings in a second source: GPS altitude, or a map), so the filter has no offset state: the data sheet's ±0.1 m/s²
(:mod:`sensor.datasheet`) is a grade error of up to ±1 %. Made horizontal with it, a wheel speed on a grade
``θ`` is off by ``sin θ·δθ`` instead of ``1 − cos θ``.
"""

from __future__ import annotations

import math

import numpy as np

from vehicle_model.parameters import GRAVITY

__all__ = ["GradeEstimator"]


class GradeEstimator:
    """Kalman filter (G1) of the grade along the tractor's heading (module notes).

    Parameters
    ----------
    acceleration_std
        White noise of the accelerometer less the acceleration along the road, per sample [m/s²].
    grade_rate_std
        How fast the grade's sine may wander [1/√s] (a random walk).
    wheel_speed_std
        Noise of the wheel speed [m/s] (the data sheet's; also with ideal signals, so the gain stays finite).
    initial_grade_std
        Prior standard deviation of the grade's sine at the first sample (the prior mean is level).
    """

    def __init__(
        self,
        acceleration_std: float = 0.05,
        grade_rate_std: float = 0.005,
        wheel_speed_std: float = 0.02,
        initial_grade_std: float = 0.2,
    ) -> None:
        for name, value in (
            ("acceleration_std", acceleration_std),
            ("grade_rate_std", grade_rate_std),
            ("wheel_speed_std", wheel_speed_std),
            ("initial_grade_std", initial_grade_std),
        ):
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"grade estimate {name} = {value!r} must be finite and > 0")
        self.acceleration_std = acceleration_std
        self.grade_rate_std = grade_rate_std
        self.wheel_speed_std = wheel_speed_std
        self.initial_grade_std = initial_grade_std
        self.reset()

    def reset(self) -> None:
        """Forget the state: the next sample starts the filter on a level road."""
        self._x: np.ndarray | None = None  # (V [m/s], sin θ)
        self._p = np.zeros((2, 2))
        self._last_acceleration = 0.0

    @property
    def sine(self) -> float:
        """The grade's sine ``sin θ̂`` (0 before the first sample), up the road positive."""
        return 0.0 if self._x is None else float(self._x[1])

    @property
    def grade(self) -> float:
        """The grade ``θ̂`` [rad] (0 before the first sample), up the road positive."""
        return math.asin(max(-1.0, min(1.0, self.sine)))

    def update(self, specific_force: float, wheel_speed: float, dt: float) -> float:
        """Take one control period's ``specific_force`` [m/s²] (the accelerometer's reading plus ``v·r``, module
        notes) and wheel speed [m/s] after
        ``dt`` [s] (ignored on the first sample); return the grade's sine ``sin θ̂``."""
        if self._x is None:
            self._x = np.array([wheel_speed, 0.0])
            self._p = np.diag([self.wheel_speed_std**2, self.initial_grade_std**2])
            self._last_acceleration = specific_force
            return self.sine
        mean_force = 0.5 * (specific_force + self._last_acceleration)
        self._last_acceleration = specific_force
        f = np.array([[1.0, -GRAVITY * dt], [0.0, 1.0]])
        x = f @ self._x + np.array([dt * mean_force, 0.0])
        q = np.diag([(self.acceleration_std * dt) ** 2, self.grade_rate_std**2 * dt])
        p = f @ self._p @ f.T + q
        innovation = wheel_speed - x[0]
        gain = p[:, 0] / (p[0, 0] + self.wheel_speed_std**2)
        self._x = x + gain * innovation
        self._p = p - np.outer(gain, p[0, :])
        return self.sine
