"""Fused VISO-OT of a towed unit behind the first, on a recording's signals (``offtrack estimate --rigs``).

The first towed unit's offline estimators are the registry's (:mod:`scenarios.loop.offline`). A rig on unit ``k``
behind it gets :class:`sensor.fusion.FusedVisoOt` of that unit: its own gyro and wheel speed propagate the filter
(the signals' ``trailer_yaw_rate`` and ``trailer_speed``, the unit's own beside its rig), and the zero-slip
measurement (K1) takes the tractor's signals carried down the chain through every coupling's articulation
(:class:`sensor.unit_kinematics.ChainSignals`: ``articulation``, ``articulation2``, … ``articulation<k>``); each
frame's motion is measured on its own row, as the first unit's adapter does.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from ..config import FusionConfig
from ..loop.estimators import FusedVisoOtEstimator, fusion_std_record
from ..loop.offline import OfflineContext

__all__ = ["UnitFusedVisoOt", "chain_signal_keys"]


def chain_signal_keys(unit: int) -> tuple[str, ...]:
    """The signals' keys of the articulations ``Γ_1 … Γ_unit`` (``unit``: the towed unit, 1 the first)."""
    return ("articulation", *(f"articulation{k}" for k in range(2, unit + 1)))


class UnitFusedVisoOt:
    """Fused VISO-OT of the rig's unit (module notes) over the rows, within the signals' span."""

    name = "viso_ot_fused"
    columns = FusedVisoOtEstimator.columns

    def __init__(self, context: OfflineContext) -> None:
        from sensor.fusion import FusedVisoOt

        assert context.signals is not None
        inputs = context.inputs
        self.signals, self.times = context.signals, context.times
        self.keys = chain_signal_keys(inputs.rig.unit)
        fusion = FusionConfig(kinematic_rear_point=inputs.rear_point)
        self.fused = FusedVisoOt(inputs.rig.params, inputs.camera_in_trailer, fusion, unit=inputs.rig.unit)
        self.previous: int | None = None
        self.active = False

    def update(self, row: int, frame: Any, reference: Mapping[str, float]) -> None:
        """Propagate to ``row`` with the chain's signals; then the frame's motion (or none, if refused)."""
        from sensor.fusion import ChainSignals

        s = self.signals
        self.active = bool(np.isfinite(s["speed"][row]))
        if not self.active:
            return
        dt = float(self.times[row] - self.times[self.previous]) if self.previous is not None else 0.0
        self.previous = row
        chain = ChainSignals(
            float(s["speed"][row]),
            float(s["yaw_rate"][row]),
            tuple(float(s[key][row]) for key in self.keys),
            float(s["lateral_acceleration"][row]),
        )
        self.fused.propagate(row, dt, float(s["trailer_yaw_rate"][row]), float(s["trailer_speed"][row]), None, chain)
        if frame is not None:
            usable = frame.valid
            self.fused.measure(row, frame.vo.camera_motion if usable else None, frame.vo.covariance if usable else None)

    def record(self) -> Mapping[str, float]:
        """The estimate, its standard deviation and its terms, within the signals' span."""
        if not self.active:
            return {}
        fused = self.fused
        return {
            "offtracking_viso_ot_fused": math.nan if fused.estimate is None else float(fused.estimate),
            "offtracking_viso_ot_fused_std": float(fused.std),
            "fusion_kinematic_std": float(fused.kinematic_std),
            **fusion_std_record(fused),
        }
