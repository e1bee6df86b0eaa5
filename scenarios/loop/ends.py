"""How a run ends: its status, and the limits that end it early because it stopped being its manoeuvre.

A model that stays finite can still be meaningless: a combination spiralling off a ring on ice, or a trailer
folded past the tractor, integrates happily. The loop checks every tick against :class:`Limits` and ends the
run with the :class:`StopReason` and a sentence saying what happened:

* **jackknife** — the articulation angle of any coupling beyond ``max_articulation_deg``. At 90° (the default of a
  run) the trailer's front corner reaches the tractor's rear for every preset's geometry (kingpin ahead of the drive
  axle, trailer front overhang ~1.6 m), so the real combination would have collided with itself. The same 90° holds
  each coupling behind: a B-double's rear trailer hangs on a fifth wheel under the lead trailer's body, so at 90° its
  front overhang swings into that body; a dolly's or a centre-axle trailer's drawbar is hitched under the rear
  overhang of the unit ahead, so at 90° it lies across that unit's rear. Beyond it a yaw-plane model integrates
  states no combination can reach (one unit through another).
* **left the road** — the driver's control point more than ``max_lateral_error`` from its path. A 3.5 m lane (the
  usual width of a trunk-road lane, UK DMRB CD 127 / EU practice) with the 2.55 m-wide combination centred in
  it: once the control point is 3.0 m (the default of a run) off the centre line, no part of the tractor's
  front is in its lane any more.
* **the trailer left the road** — the true off-tracking beyond ``max_offtracking`` (not checked in a run by
  default; the environments check 3.5 m).

With ``every_unit`` (a run's and the environments') each unit behind the first towed one is held to the
articulation and off-tracking limits as well (:meth:`Limits.check_units`); a run checks no off-tracking, so it holds
every coupling to the articulation limit.

The Gymnasium environments pass stricter limits (:data:`ENVIRONMENT_LIMITS`): an episode that an agent steers
should end well before the physical limits.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from enum import StrEnum

from vehicle_model.errors import InputError

__all__ = ["ENVIRONMENT_LIMITS", "RUN_LIMITS", "LimitBreach", "Limits", "RunStatus", "StopReason"]


class RunStatus(StrEnum):
    """How a run went (``status`` in ``metrics.json``; compares equal to its string)."""

    COMPLETED = "completed"
    """The driver reached the end of the path, or the run's time was up."""
    DIVERGED = "diverged"
    """The model left its valid region (non-finite, or beyond its physical state limits)."""
    LOST_CONTROL = "lost_control"
    """A :class:`Limits` check ended the run."""
    FAILED = "failed"
    """Something the run needs failed: a render worker, a file that could not be written."""
    INTERRUPTED = "interrupted"
    """Ctrl-C or SIGTERM."""
    RUNNING = "running"
    """Started, metrics not yet written (what a killed run's ``metrics.json`` says)."""
    INCOMPLETE = "incomplete"
    """Rebuilt from the time series of a run that stopped without writing its metrics."""


class StopReason(StrEnum):
    """Why a run ended before its end (an environment's ``termination_reason``)."""

    JACKKNIFE = "jackknife"
    LEFT_ROAD = "left_road"
    TRAILER_LEFT_ROAD = "trailer_left_road"
    DIVERGED = "diverged"


@dataclass(frozen=True)
class LimitBreach:
    """A limit the current tick is beyond: which, and in words."""

    reason: StopReason
    message: str


@dataclass(frozen=True)
class Limits:
    """When a run stops being its manoeuvre (module docstring).

    Parameters
    ----------
    max_articulation_deg : float
        Jackknife: ``|Γ|`` above this [deg], in (0, 180].
    max_lateral_error : float
        Off the road: the driver's control point more than this [m] from its path.
    max_offtracking : float or None
        The trailer off the road: true off-tracking ``|e_tr|`` above this [m] (``None``: not checked).
    every_unit : bool
        Also hold every towed unit behind the first to the articulation and off-tracking limits (its articulation
        against the unit ahead, its off-tracking against its own coupling's path: :meth:`check_units`), as a run
        and the environments do; ``False``: the first towed unit's only.
    """

    max_articulation_deg: float = 90.0
    max_lateral_error: float = 3.0
    max_offtracking: float | None = None
    every_unit: bool = True

    def __post_init__(self) -> None:
        if not (0.0 < self.max_articulation_deg <= 180.0):
            raise InputError(f"max_articulation_deg = {self.max_articulation_deg!r} must be in (0, 180]")
        if not (self.max_lateral_error > 0.0 and math.isfinite(self.max_lateral_error)):
            raise InputError(f"max_lateral_error = {self.max_lateral_error!r} must be a finite number > 0 [m]")
        if self.max_offtracking is not None and not (
            self.max_offtracking > 0.0 and math.isfinite(self.max_offtracking)
        ):
            raise InputError(f"max_offtracking = {self.max_offtracking!r} must be a finite number > 0 [m] or None")

    def check(self, articulation: float, path_error: float, offtracking: float) -> LimitBreach | None:
        """The first limit broken, or ``None``.

        Parameters
        ----------
        articulation
            Articulation angle Γ [rad].
        path_error
            The driver's control point's lateral distance from its path [m].
        offtracking
            The true off-tracking [m] (NaN while there is none).
        """
        if (breach := self._jackknife(articulation, "articulation", "the trailer would hit the tractor")) is not None:
            return breach
        if not math.isfinite(path_error) or abs(path_error) > self.max_lateral_error:
            return LimitBreach(
                StopReason.LEFT_ROAD,
                f"left the road: the driver's control point is {path_error:+.2f} m from its path "
                f"(limit ±{self.max_lateral_error:g} m, a 3.5 m lane)",
            )
        return self._off_road(offtracking, "the trailer left the road")

    def _jackknife(self, articulation: float, what: str, why: str) -> LimitBreach | None:
        if not math.isfinite(articulation) or abs(articulation) > math.radians(self.max_articulation_deg):
            return LimitBreach(
                StopReason.JACKKNIFE,
                f"jackknife: {what} {math.degrees(articulation):+.1f}° beyond ±{self.max_articulation_deg:g}° ({why})",
            )
        return None

    def _off_road(self, offtracking: float, who: str) -> LimitBreach | None:
        if self.max_offtracking is not None and abs(offtracking) > self.max_offtracking:
            return LimitBreach(
                StopReason.TRAILER_LEFT_ROAD,
                f"{who}: true off-tracking {offtracking:+.2f} m beyond ±{self.max_offtracking:g} m",
            )
        return None

    def check_units(
        self, articulations: Sequence[float], path_error: float, offtrackings: Sequence[float]
    ) -> LimitBreach | None:
        """The first limit broken by any towed unit, or ``None``: :meth:`check` for the first towed unit, then the
        articulation and off-tracking limits of each unit behind it, front to rear.

        Parameters
        ----------
        articulations
            Each towed unit's articulation against the unit ahead, front to rear ``[Γ, Γ2, …]`` [rad].
        path_error
            The driver's control point's lateral distance from its path [m].
        offtrackings
            Each towed unit's true off-tracking against its own coupling's path, front to rear [m] (NaN while
            there is none).
        """
        breach = self.check(articulations[0], path_error, offtrackings[0])
        if breach is not None:
            return breach
        for unit, (articulation, offtracking) in enumerate(
            zip(articulations[1:], offtrackings[1:], strict=True), start=3
        ):
            breach = self._jackknife(articulation, f"unit {unit}'s articulation", "it would hit the unit ahead")
            if breach is None:
                breach = self._off_road(offtracking, f"unit {unit} left the road")
            if breach is not None:
                return breach
        return None


RUN_LIMITS = Limits()
"""The limits of a run (``offtrack run``, the studies): the physical ones of the module docstring, every coupling
held to the articulation limit."""

ENVIRONMENT_LIMITS = Limits(max_articulation_deg=80.0, max_lateral_error=2.0, max_offtracking=3.5, every_unit=True)
"""The Gymnasium environments' default limits: stricter, so an episode ends before the physical ones, and on every
towed unit."""
