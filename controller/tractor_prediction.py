"""The tractor's steer over a receding horizon, predicted by running the driver's own law on the model.

The receding-horizon MPC (:mod:`controller.receding_horizon`) needs the tractor's inputs over its horizon. Held at
their present values they say the tractor keeps its present steer; the driver, though, steers along its known path,
into and out of each turn. This predicts that steer: from the present state, one control tick at a time, a copy of
the driver (:class:`controller.driver.PathFollowingDriver`, its integrator, rate limit and progress as they are now)
steers the model, which one RK4 step of the tick (:func:`controller.steer_shooting.interval_integrator`) carries
forward with the trailer's steer on the plan's guess and every other input held. Only the steer is predicted: the
drive force and the surface stay held.
"""

from __future__ import annotations

import copy
from collections.abc import Callable

import numpy as np

from vehicle_model.layout import Layout
from vehicle_model.parameters import VehicleParams
from vehicle_model.simulator import VehicleState

from .driver import PathFollowingDriver
from .steer_shooting import interval_integrator

__all__ = ["DriverPrediction"]


class DriverPrediction:
    """The driver's steer over a horizon, the driver's law run on the model's prediction (module docstring).

    Parameters
    ----------
    params
        The combination.
    steered
        Indices into the layout's steerable axles of the trailer axles the plan steers.
    tick
        The driver's control period [s], also the prediction's RK4 step.
    """

    def __init__(self, params: VehicleParams, steered: list[int], tick: float) -> None:
        self.layout = Layout.for_vehicle(params)
        self.steered = list(steered)
        self.tick = float(tick)
        self._step = interval_integrator(params, self.steered, 1, self.tick)
        self._front = 0  # the driver's steer is the first input (the tractor's first steerable axle)

    def steer(
        self,
        driver: PathFollowingDriver,
        command: float,
        present: float,
        x0: np.ndarray,
        held: np.ndarray,
        ticks: int,
        trailer_steer: Callable[[float], np.ndarray],
    ) -> np.ndarray:
        """The driver's steer [rad] over ``ticks`` control ticks from ``x0``.

        Parameters
        ----------
        driver
            The driver as it is after this tick's call; a copy steers from the second tick on (the driver itself is
            left as it is).
        command
            The driver's command of this tick [rad], the first tick's steer.
        present
            The present time [s].
        x0
            The present state vector.
        held
            The model's input vector, held over the horizon except the tractor's steer (predicted) and the trailer's
            (``trailer_steer``).
        ticks
            Ticks to predict.
        trailer_steer
            The plan's trailer steer [rad] at a time [s].

        Returns
        -------
        numpy.ndarray
            ``(ticks,)``, the steer applied over each tick, the first the driver's present command.
        """
        shadow = copy.copy(driver)  # the law's state is floats: a shallow copy steers without touching ``driver``
        inputs = np.asarray(held, dtype=float).copy()
        x = np.asarray(x0, dtype=float)
        n_axles = len(self.layout.axles)
        steer = np.empty(ticks)
        steer[0] = command
        for k in range(ticks):
            if k > 0:
                steer[k] = shadow.steer(VehicleState.from_vector(x, present + k * self.tick, n_axles), self.tick)
            if k == ticks - 1:
                break
            inputs[self._front] = steer[k]
            start, end = present + k * self.tick, present + (k + 1) * self.tick
            x = np.asarray(self._step(x, trailer_steer(start), trailer_steer(end), inputs[:, None])).ravel()
        return steer
