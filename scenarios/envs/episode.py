"""Episode ends shared by the environments, and a whole run steered by a trailer-steer source.

An episode *terminates* when the combination jackknifes (``|Γ|`` beyond a limit, or the model diverges:
:class:`~vehicle_model.errors.SimulationDivergedError`) or leaves the road (the driver's control point, or
the trailer's follow point, too far from its path); it is *truncated* at the scenario's end (the driver
reaches the end of the path, or the run's time is up).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from vehicle_model.errors import InputError, SimulationDivergedError

from ..run.cosim import TrailerSteerSource
from ..run.metrics import after_warmup, max_abs, rms
from ..setup.build import ScenarioSetup
from .stepper import CoSimulation, Tick

__all__ = ["TERMINATION_REASONS", "EpisodeLimits", "EpisodeRecord", "run_episode"]

TERMINATION_REASONS: tuple[str, ...] = ("jackknife", "diverged", "left_road", "trailer_left_road")
"""Values of ``info["termination_reason"]`` (empty string: not terminated)."""


@dataclass(frozen=True)
class EpisodeLimits:
    """When an episode terminates.

    Parameters
    ----------
    max_articulation_deg : float
        Jackknife: ``|Γ|`` above this [deg].
    max_lateral_error : float
        Leaving the road: the driver's control point more than this [m] from its path.
    max_offtracking : float or None
        The trailer leaving the road: true off-tracking ``|e_tr|`` above this [m] (``None``: not checked).
    """

    max_articulation_deg: float = 80.0
    max_lateral_error: float = 2.0
    max_offtracking: float | None = 3.5

    def __post_init__(self) -> None:
        if not (0.0 < self.max_articulation_deg <= 180.0):
            raise InputError(f"max_articulation_deg = {self.max_articulation_deg!r} must be in (0, 180]")
        if not (self.max_lateral_error > 0.0 and math.isfinite(self.max_lateral_error)):
            raise InputError(f"max_lateral_error = {self.max_lateral_error!r} must be a finite number > 0 [m]")
        if self.max_offtracking is not None and not (
            self.max_offtracking > 0.0 and math.isfinite(self.max_offtracking)
        ):
            raise InputError(f"max_offtracking = {self.max_offtracking!r} must be a finite number > 0 [m] or None")

    def check(self, cosim: CoSimulation) -> str:
        """Why the current tick ends the episode (one of :data:`TERMINATION_REASONS`), or ``""``."""
        tick = cosim.tick
        if abs(tick.state.gamma) > math.radians(self.max_articulation_deg):
            return "jackknife"
        if abs(cosim.driver.lateral_error) > self.max_lateral_error:
            return "left_road"
        truth = tick.estimates["truth"]
        if self.max_offtracking is not None and truth is not None and abs(truth) > self.max_offtracking:
            return "trailer_left_road"
        return ""


@dataclass
class EpisodeRecord:
    """A run steered to its end (or termination) by a trailer-steer source.

    Attributes
    ----------
    status : str
        ``completed`` or a :data:`TERMINATION_REASONS` entry.
    columns : dict
        Per tick: ``time``, ``kingpin_x``, ``kingpin_y``, ``psi2``, ``offtracking_truth`` (NaN: none yet),
        ``offtracking_feedback`` (the fed-back estimate), and the source's telemetry (e.g.
        ``trailer_feedback_steer``, ``saturated_<axle>``).
    """

    status: str = "completed"
    columns: dict[str, np.ndarray] = field(default_factory=dict)

    def summary(self, follow_point_offset: float) -> dict[str, float]:
        """RMS and largest true off-tracking after warm-up [m], RMS feedback steer [rad], saturated fraction.

        Warm-up (:func:`scenarios.run.metrics.after_warmup`): until one trailer length after the truth exists.
        Missing figures are 0.0 (no settled sample: the run ended during warm-up).
        """
        cols = self.columns
        settled = after_warmup(cols, follow_point_offset)
        sat_cols = [v for k, v in cols.items() if k.startswith("saturated_")]
        saturated = np.any(np.vstack(sat_cols) > 0.5, axis=0) if sat_cols else np.zeros_like(settled)
        feedback = cols.get("trailer_feedback_steer", np.zeros(settled.size))

        def finite(x: float) -> float:
            return x if math.isfinite(x) else 0.0

        return {
            "rms_offtracking": finite(rms(cols["offtracking_truth"][settled])),
            "max_offtracking": finite(max_abs(cols["offtracking_truth"][settled])),
            "rms_feedback_steer": finite(rms(feedback[settled])),
            "saturated_fraction": float(np.mean(saturated[settled])) if settled.any() else 0.0,
            "settled_samples": float(settled.sum()),
            "simulated_s": float(cols["time"][-1]) if cols["time"].size else 0.0,
        }


def tick_row(cosim: CoSimulation, tick: Tick, feedback: str) -> dict[str, float]:
    """The recorded quantities of one tick."""
    kp = cosim.kingpin
    truth = tick.estimates["truth"]
    estimate = tick.estimates.get(feedback)
    return {
        "time": tick.time,
        "kingpin_x": float(kp[0]),
        "kingpin_y": float(kp[1]),
        "psi2": tick.state.psi1 - tick.state.gamma,
        "offtracking_truth": math.nan if truth is None else truth,
        "offtracking_feedback": math.nan if estimate is None else estimate,
    }


def run_episode(
    setup: ScenarioSetup, source: TrailerSteerSource, limits: EpisodeLimits, feedback: str = "truth"
) -> tuple[EpisodeRecord, CoSimulation]:
    """Run ``setup`` to its end with ``source`` steering the trailer, stopping early at a :class:`EpisodeLimits`.

    The loop of :func:`scenarios.run.cosim.run_cosimulation` (source called once per tick, row recorded, end
    checked, then one control period integrated) on :class:`CoSimulation`, plus the termination checks.

    Returns
    -------
    record : EpisodeRecord
    cosim : CoSimulation
        At the last tick (for rendering).
    """
    cosim = CoSimulation(setup)
    if hasattr(source, "reset"):
        source.reset()  # type: ignore[attr-defined]
    telemetry = getattr(source, "telemetry", None)
    rows: list[dict[str, Any]] = []
    status = "completed"
    while True:
        tick = cosim.tick
        steer = np.asarray(source(tick.state, dict(tick.estimates)), dtype=float)
        row = tick_row(cosim, tick, feedback)
        if callable(telemetry):
            row.update(telemetry())
        rows.append(row)
        if cosim.finished:
            break
        try:
            cosim.advance(steer)
        except SimulationDivergedError:
            status = "diverged"
            break
        reason = limits.check(cosim)
        if reason:
            status = reason
            rows.append(tick_row(cosim, cosim.tick, feedback))
            break
    keys = list(rows[0])
    columns = {k: np.array([r.get(k, math.nan) for r in rows], dtype=float) for k in keys}
    return EpisodeRecord(status, columns), cosim
