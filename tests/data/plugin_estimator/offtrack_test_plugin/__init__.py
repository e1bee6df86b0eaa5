"""An estimator plug-in of offtrack's tests: the ground truth of the same tick shifted by a constant.

Its distribution (``offtrack_test_plugin-0.1.dist-info`` beside this package) declares :data:`ENTRY` under the
entry-point group ``offtrack.estimators``; putting this folder on ``PYTHONPATH`` installs it for
:mod:`importlib.metadata`. Only :mod:`scenarios.registry` and pydantic are imported here: the loop's modules are
imported by the builder, when a run builds it.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from scenarios.registry import EstimatorEntry

NAME = "shifted_truth"
COLOUR = "#8c2d04"
"""Its colour in figures: one no built-in estimator and no colour cycle uses."""


class ShiftSettings(BaseModel):
    """``estimators.shifted_truth: {shift_m: …}``."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    shift_m: float = Field(0.05, ge=-1.0, le=1.0, description="[m] added to the truth")


class ShiftedTruth:
    """The truth participant's estimate of the same tick plus ``shift`` [m]."""

    name = NAME

    def __init__(self, truth: Any, shift: float) -> None:
        from scenarios.loop.participant import Column
        from vehicle_model.offtracking import OfftrackingEstimate

        self.columns = (
            Column.estimate(NAME, "the truth shifted by a constant"),
            Column("shifted_truth_shift", "m", "the constant", role="diagnostic"),
        )
        self.truth, self.shift = truth, shift
        self._estimate_of = OfftrackingEstimate
        self.estimate = OfftrackingEstimate.of(None)

    def update(self, tick: Any) -> Any:
        truth = self.truth.estimate  # updated earlier on this tick (it is required, so built before)
        self.estimate = self._estimate_of(truth.value + self.shift) if truth.available else truth
        return self.estimate

    def record(self) -> Mapping[str, float]:
        return {f"offtracking_{NAME}": self.estimate.value, "shifted_truth_shift": self.shift}


class OfflineShiftedTruth:
    """Its offline adapter: the recording's reference off-tracking (where it has one) plus the default shift."""

    name = NAME

    def __init__(self, shift: float) -> None:
        from scenarios.loop.participant import Column

        self.columns = (
            Column.estimate(NAME, "the reference's off-tracking shifted by a constant"),
            Column("shifted_truth_shift", "m", "the constant", role="diagnostic"),
        )
        self.shift = shift
        self.value = float("nan")

    def update(self, row: int, frame: Any, reference: Mapping[str, float]) -> None:
        self.value = reference.get("offtracking_truth", float("nan")) + self.shift

    def record(self) -> Mapping[str, float]:
        return {f"offtracking_{NAME}": self.value, "shifted_truth_shift": self.shift}


def offline(context: Any) -> OfflineShiftedTruth:
    return OfflineShiftedTruth(ShiftSettings().shift_m)


def build(context: Any) -> ShiftedTruth:
    from scenarios.estimator_settings import estimator_settings

    settings = estimator_settings(context.setup.config, NAME)
    return ShiftedTruth(context.estimators["truth"], settings.shift_m)  # type: ignore[attr-defined]


ENTRY = EstimatorEntry(
    NAME,
    "the ground truth shifted by a constant (a test plug-in)",
    build,
    requires=("truth",),
    colour=COLOUR,
    label="shifted truth",
    settings=ShiftSettings,
    offline=offline,
)
