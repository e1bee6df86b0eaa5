"""Named layouts of the model's state, input and output vectors."""

from __future__ import annotations

from dataclasses import dataclass

from .parameters import VehicleParams

BODY_STATES: tuple[str, ...] = ("X", "Y", "psi1", "u", "v1", "r1", "gamma", "r2")
"""Tractor CG position (global), tractor heading, tractor CG forward and lateral speed, tractor yaw
rate, articulation angle Γ = ψ1 − ψ2, trailer yaw rate."""


@dataclass(frozen=True)
class Layout:
    """Index maps of one vehicle's vectors.

    State: ``BODY_STATES`` then one transient-slip state ``slip_<axle>`` per axle (tractor axles
    first). Input: ``steer_<axle>`` per steerable axle, ``drive_force``, ``mu_<axle>`` per axle,
    then the in-plane gravity direction of each body ``slope_x_tractor, slope_y_tractor,
    slope_x_trailer, slope_y_trailer`` (global frame, fraction of g).
    """

    states: tuple[str, ...]
    inputs: tuple[str, ...]
    axles: tuple[str, ...]
    steerable_axles: tuple[str, ...]

    @classmethod
    def for_vehicle(cls, params: VehicleParams) -> Layout:
        table = params.axle_table
        steerable = tuple(n for n, s in zip(table.names, table.steerable, strict=True) if s)
        states = BODY_STATES + tuple(f"slip_{n}" for n in table.names)
        inputs = (
            *tuple(f"steer_{n}" for n in steerable),
            "drive_force",
            *tuple(f"mu_{n}" for n in table.names),
            "slope_x_tractor",
            "slope_y_tractor",
            "slope_x_trailer",
            "slope_y_trailer",
        )
        return cls(states=states, inputs=inputs, axles=table.names, steerable_axles=steerable)

    @property
    def n_states(self) -> int:
        return len(self.states)

    @property
    def n_inputs(self) -> int:
        return len(self.inputs)

    def state_index(self, name: str) -> int:
        """Index of a named state."""
        try:
            return self.states.index(name)
        except ValueError:
            raise ValueError(f"unknown state {name!r}; states are {list(self.states)}") from None

    def input_index(self, name: str) -> int:
        """Index of a named input."""
        try:
            return self.inputs.index(name)
        except ValueError:
            raise ValueError(f"unknown input {name!r}; inputs are {list(self.inputs)}") from None

    @property
    def steer_slice(self) -> slice:
        return slice(0, len(self.steerable_axles))

    @property
    def drive_index(self) -> int:
        return len(self.steerable_axles)

    @property
    def mu_slice(self) -> slice:
        start = len(self.steerable_axles) + 1
        return slice(start, start + len(self.axles))

    @property
    def slope_slice(self) -> slice:
        start = len(self.steerable_axles) + 1 + len(self.axles)
        return slice(start, start + 4)
