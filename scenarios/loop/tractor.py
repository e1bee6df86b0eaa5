"""The tractor's participant: the driver steering its control point along the path and holding the speed profile.

In a kinematic scenario (the constant-slip straight of de Saxe & Cebon 2018, §3) nothing is steered or driven:
the combination is moved along the path, both units crabbing at the slip angle (:func:`constant_slip_step`), and
the driver only follows its progress. With an open-loop steer input (the configuration's ``driver`` section,
:mod:`controller.steer_input`) the steer angle follows the input — its sign set by the scenario's direction, so a
right run mirrors a left one — while the driver follows its progress along the path and the speed controller holds
the speed profile.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from controller.driver import PathFollowingDriver
from controller.speed import (
    SpeedController,
    combination_grade_feedforward,
    grade_feedforward,
    service_brake_limit,
    traction_limit,
)
from vehicle_model.simulator import Simulator, VehicleState

from ..setup.build import ScenarioSetup
from .participant import Column, TickInput

__all__ = ["DriverParticipant", "TractorCommand", "constant_slip_step"]


@dataclass(frozen=True)
class TractorCommand:
    """What the driver commands for the next control period."""

    front_steer: float
    """Steer-axle angle [rad]."""
    drive_force: float
    """Force demand [N]: the driven axles' drive force when positive, every axle's service brake when negative."""
    speed_target: float
    """The speed profile's target at the driver's progress [m/s]."""


class DriverParticipant:
    """The driver (:class:`controller.driver.PathFollowingDriver`) and its speed controller.

    Parameters
    ----------
    setup
        The built scenario (path, control point, feed-forward, speed profile).
    simulator
        The simulator, asked for the friction under the driven axles (the traction limit).
    """

    name = "driver"

    def __init__(self, setup: ScenarioSetup, simulator: Simulator) -> None:
        params = setup.params
        self.setup = setup
        self.simulator = simulator
        self.kinematic = setup.kinematic_slip is not None
        self.driver = PathFollowingDriver(params, setup.path, setup.control_point, feedforward=setup.feedforward)
        self.driver.reset(setup.initial_state)
        steer_input = setup.config.driver
        self.open_loop = steer_input.steer() if steer_input.open_loop else None
        self._sign = setup.direction_sign
        self.speed_control = SpeedController(params.tractor.mass + params.trailer.mass)
        # On a terrain the speed controller foresees the grade's load on the whole combination (docs/terrain.md).
        self._unit_masses = tuple(unit.mass for unit in params.units)
        self._grade_mass = sum(self._unit_masses) if setup.config.terrain.kind != "flat" else None
        self._grade_by_unit = setup.config.speed.grade_feedforward == "units"
        driven = np.flatnonzero(params.axle_table.driven)
        self._driven = driven
        self._driven_load = float(params.axle_table.static_load[driven].sum())
        self._axles = np.arange(len(params.axle_table.static_load))
        self._total_load = float(params.axle_table.static_load.sum())
        front = setup.model.layout.steerable_axles[0]
        self.columns: tuple[Column, ...] = (
            Column(f"steer_{front}", "rad", "the driver's steer-axle command", role="command", vehicle_unit=1),
            Column(
                "drive_force",
                "N",
                "the speed controller's force demand (drive +, brake −)",
                role="command",
                vehicle_unit=1,
            ),
            Column("speed_target", "m/s", "the speed profile's target", role="diagnostic", vehicle_unit=1),
            Column("path_progress", "m", "the control point's arc length along the path", role="state", vehicle_unit=1),
            Column(
                "lateral_error",
                "m",
                "the control point's distance from the path (left +)",
                role="state",
                vehicle_unit=1,
            ),
        )
        self._steer_column = self.columns[0].name
        self.command = TractorCommand(0.0, 0.0, 0.0)

    @property
    def progress(self) -> float:
        """The control point's arc length along the path [m]."""
        return self.driver.progress

    @property
    def lateral_error(self) -> float:
        """The control point's lateral distance from the path [m], left positive."""
        return self.driver.lateral_error

    @property
    def kept_error(self) -> float:
        """The distance from the path the run's road limit holds the driver to [m]: the lateral error when the
        path follower steers; 0 under an open-loop input, which does not try to keep to the path (the run's
        duration or the path's length ends it, the articulation limit still applies)."""
        return self.driver.lateral_error if self.open_loop is None else 0.0

    @property
    def finished(self) -> bool:
        """The control point reached the end of the path."""
        return self.driver.finished

    def update(self, tick: TickInput) -> TractorCommand:
        """The tractor's commands for the period from ``tick`` on."""
        setup, state, period = self.setup, tick.state, tick.period
        driver = self.driver
        if self.kinematic:
            driver.progress, driver.lateral_error = setup.path.project(
                driver.control_point_position(state), driver.progress
            )
            self.command = TractorCommand(0.0, 0.0, setup.speed_profile(driver.progress))
            return self.command
        if self.open_loop is None:
            front = driver.steer(state, period)
        else:  # the input, held over the period from this tick; the driver only follows its progress
            driver.progress, driver.lateral_error = setup.path.project(
                driver.control_point_position(state), driver.progress
            )
            front = self._sign * self.open_loop(tick.time)
        target = setup.speed_profile(driver.progress)
        mu_drive, mu_brake = self.simulator.min_frictions(self._driven, self._axles)
        limit = traction_limit(mu_drive, self._driven_load)
        brake = service_brake_limit(mu_brake, self._total_load)  # every axle brakes
        grade = 0.0
        if self._grade_mass is not None:
            if self._grade_by_unit:
                grade = self._grade_by_units(state)
            else:
                grade = grade_feedforward(self._grade_mass, self.simulator.tractor_gravity()[0])
        drive = self.speed_control(target, state.u, period, limit, grade, brake)
        self.command = TractorCommand(front, drive, target)
        return self.command

    def _grade_by_units(self, state: VehicleState) -> float:
        """The grade's feed-forward from each unit's own gravity along its heading
        (:func:`controller.speed.combination_grade_feedforward`)."""
        articulations = state.articulations
        heading = state.psi1
        gravity = [self.simulator.unit_gravity(0, heading)[0]]
        for k, angle in enumerate(articulations, start=1):
            heading -= angle
            gravity.append(self.simulator.unit_gravity(k, heading)[0])
        return combination_grade_feedforward(self._unit_masses, gravity, articulations)

    def record(self) -> Mapping[str, float]:
        """The commands and the driver's progress and error."""
        c = self.command
        return {
            self._steer_column: c.front_steer,
            "drive_force": c.drive_force,
            "speed_target": c.speed_target,
            "path_progress": self.driver.progress,
            "lateral_error": self.driver.lateral_error,
        }


def constant_slip_step(setup: ScenarioSetup, state: VehicleState, period: float) -> VehicleState:
    """Constant-slip straight (de Saxe & Cebon 2018, §3): both units crab at the slip angle along the path."""
    beta = setup.kinematic_slip or 0.0
    speed = setup.speed_profile(0.0)
    direction = state.psi1 + beta
    return VehicleState(
        state.time + period,
        state.X + speed * period * math.cos(direction),
        state.Y + speed * period * math.sin(direction),
        state.psi1,
        state.u,
        state.v1,
        0.0,
        0.0,
        0.0,
        slip=state.slip,
        trailing=state.trailing,
    )
