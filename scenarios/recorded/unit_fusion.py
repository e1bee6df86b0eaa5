"""Fused VISO-OT of a towed unit behind the first, on a recording's signals (``offtrack estimate --rigs``).

The first towed unit's offline estimators are the registry's (:mod:`scenarios.loop.offline`). A rig on unit ``k``
behind it gets :class:`sensor.fusion.FusedVisoOt` of that unit: its own gyro and wheel speed propagate the filter
(the signals' ``trailer_yaw_rate`` and ``trailer_speed``, the unit's own beside its rig), and the zero-slip
measurement (K1) takes the tractor's signals carried down the chain through every coupling's articulation
(:class:`sensor.unit_kinematics.ChainSignals`: ``articulation``, ``articulation2``, … ``articulation<k>``); each
frame's motion is measured on its own row, with a following unit's measurement of the same frame where the
settings take it, as the first unit's adapter does.
"""

from __future__ import annotations

from typing import Any

from ..loop.offline import OfflineContext, OfflineFusedVisoOt

__all__ = ["UnitFusedVisoOt", "chain_signal_keys"]


def chain_signal_keys(unit: int) -> tuple[str, ...]:
    """The signals' keys of the articulations ``Γ_1 … Γ_unit`` (``unit``: the towed unit, 1 the first)."""
    return ("articulation", *(f"articulation{k}" for k in range(2, unit + 1)))


class UnitFusedVisoOt(OfflineFusedVisoOt):
    """Fused VISO-OT of the rig's unit (module notes) over the rows, within the signals' span: the first unit's
    adapter (:class:`scenarios.loop.offline.OfflineFusedVisoOt`) with the unit's filter and the chain's signals."""

    def __init__(self, context: OfflineContext) -> None:
        self.keys = chain_signal_keys(context.inputs.rig.unit)
        super().__init__(context)

    def build_filter(self, context: OfflineContext) -> Any:
        """The filter of the rig's unit (:class:`sensor.fusion.FusedVisoOt` with ``unit``)."""
        from sensor.fusion import FusedVisoOt

        inputs = context.inputs
        return FusedVisoOt(inputs.rig.params, inputs.camera_in_trailer, context.fusion_settings(), unit=inputs.rig.unit)

    def kinematics(self, row: int) -> Any:
        """The tractor's signals and every coupling's articulation down to the unit
        (:class:`sensor.unit_kinematics.ChainSignals`)."""
        from sensor.fusion import ChainSignals

        return ChainSignals(
            self.value(row, "speed"),
            self.value(row, "yaw_rate"),
            tuple(self.value(row, key) for key in self.keys),
            self.value(row, "lateral_acceleration"),
        )
