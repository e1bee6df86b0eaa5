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
    first), then for each further semi-trailer ``k = 3, 4`` its articulation against the unit ahead and its
    yaw rate, ``gamma<k-1>, r<k>``. Input: ``steer_<axle>`` per steerable axle, ``drive_force``, ``mu_<axle>``
    per axle, then the in-plane gravity direction of each body ``slope_x_tractor, slope_y_tractor,
    slope_x_trailer, slope_y_trailer`` (global frame, fraction of g) and ``slope_x_trailer<k>, slope_y_trailer<k>``
    for the further ones.
    """

    states: tuple[str, ...]
    inputs: tuple[str, ...]
    axles: tuple[str, ...]
    steerable_axles: tuple[str, ...]
    n_units: int = 2

    @classmethod
    def for_vehicle(cls, params: VehicleParams) -> Layout:
        table = params.axle_table
        steerable = tuple(n for n, s in zip(table.names, table.steerable, strict=True) if s)
        trailing = tuple(name for k in range(3, params.n_units + 1) for name in (f"gamma{k - 1}", f"r{k}"))
        states = BODY_STATES + tuple(f"slip_{n}" for n in table.names) + trailing
        inputs = (
            *tuple(f"steer_{n}" for n in steerable),
            "drive_force",
            *tuple(f"mu_{n}" for n in table.names),
            "slope_x_tractor",
            "slope_y_tractor",
            "slope_x_trailer",
            "slope_y_trailer",
            *tuple(f"slope_{c}_trailer{k}" for k in range(2, params.n_units) for c in "xy"),
        )
        return cls(states=states, inputs=inputs, axles=table.names, steerable_axles=steerable, n_units=params.n_units)

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
        return slice(start, start + 2 * self.n_units)

    @property
    def slip_slice(self) -> slice:
        """The transient slip states, one per axle."""
        return slice(len(BODY_STATES), len(BODY_STATES) + len(self.axles))

    @property
    def trailing_slice(self) -> slice:
        """The further semi-trailers' states ``gamma<k-1>, r<k>`` (empty for a tractor–semi-trailer)."""
        start = len(BODY_STATES) + len(self.axles)
        return slice(start, start + 2 * (self.n_units - 2))
