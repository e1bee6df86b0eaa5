"""The one registry of the closed loop's off-tracking estimators, and so of its feedback sources.

Every off-tracking source a run can record and feed back to the trailer steering is an entry here: the
ground truth, Cheng's zero-slip estimator, VISO-OT and its fused form, and any estimator a user registers
(:func:`register_estimator`). The configuration schema (``feedback``), the command line's help, ``offtrack
compare``, the studies and the Gymnasium environments all read their choices from this registry; the closed
loop (:mod:`scenarios.loop.cosimulation`) builds one participant per enabled entry, in registration order.

An entry names its builder either as a callable or as ``"module:function"``, imported only when a run needs it
(so that reading the names never imports OpenGL or the odometry). A builder is called with the loop's
:class:`~scenarios.loop.participant.LoopContext` and returns an
:class:`~scenarios.loop.participant.EstimatorParticipant`.

This module imports only the standard library: the configuration schema sits above it.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

__all__ = [
    "NO_FEEDBACK",
    "EstimatorEntry",
    "estimator_entries",
    "estimator_entry",
    "feedback_sources",
    "register_estimator",
    "source_colour",
    "unregister_estimator",
]

NO_FEEDBACK = "none"
"""The feedback choice of an unsteered trailer (no estimate is fed back)."""


@dataclass(frozen=True)
class EstimatorEntry:
    """One off-tracking estimator of the closed loop.

    Parameters
    ----------
    name : str
        The estimate's name: its column ``offtracking_<name>``, its ``metrics.json`` entry, its feedback choice.
    summary : str
        One line for help texts and listings.
    build : str or callable
        ``"module:function"`` or a callable, ``build(context) -> EstimatorParticipant``.
    switch : str or None
        The boolean field of the configuration's ``estimators`` section that turns it on (``None``: it runs
        when it is the feedback, when another enabled entry requires it, or always with ``always``).
    requires : tuple of str
        Entries it reads (registered before it); enabling it enables them.
    always : bool
        Runs in every run (the ground truth).
    needs_camera : bool
        Renders the trailer's stereo camera (headless OpenGL; about ten times slower than a model-only run).
    colour : str or None
        Its colour in figures (a matplotlib colour; ``None``: the next of the cycle).
    """

    name: str
    summary: str
    build: str | Callable[..., Any]
    switch: str | None = None
    requires: tuple[str, ...] = ()
    always: bool = False
    needs_camera: bool = False
    colour: str | None = None

    def __post_init__(self) -> None:
        if not self.name.isidentifier() or self.name == NO_FEEDBACK or self.name.startswith("truth_"):
            raise ValueError(
                f"estimator name {self.name!r} must be an identifier other than {NO_FEEDBACK!r} and not start with "
                "'truth_' (the truth's own columns)"
            )

    def builder(self) -> Callable[..., Any]:
        """The builder, imported if named by a string."""
        if callable(self.build):
            return self.build
        module, _, function = self.build.partition(":")
        return getattr(importlib.import_module(module), function)  # type: ignore[no-any-return]


_ENTRIES: dict[str, EstimatorEntry] = {}


def register_estimator(entry: EstimatorEntry, replace: bool = False) -> None:
    """Add ``entry`` to the registry (after the entries it requires).

    Raises
    ------
    ValueError
        The name is taken (unless ``replace``) or a required entry is not registered.
    """
    if entry.name in _ENTRIES and not replace:
        raise ValueError(f"an estimator named {entry.name!r} is registered already")
    missing = [name for name in entry.requires if name not in _ENTRIES]
    if missing:
        raise ValueError(f"estimator {entry.name!r} requires {missing}, which are not registered (register them first)")
    _ENTRIES[entry.name] = entry


def unregister_estimator(name: str) -> None:
    """Remove the entry ``name`` (and nothing that requires it may stay)."""
    dependants = [e.name for e in _ENTRIES.values() if name in e.requires]
    if dependants:
        raise ValueError(f"estimators {dependants} require {name!r}")
    _ENTRIES.pop(name, None)


def estimator_entries() -> tuple[EstimatorEntry, ...]:
    """Every registered estimator, in registration order (every entry after those it requires)."""
    return tuple(_ENTRIES.values())


def estimator_entry(name: str) -> EstimatorEntry:
    """The entry ``name``.

    Raises
    ------
    KeyError
        No such estimator.
    """
    return _ENTRIES[name]


def feedback_sources() -> tuple[str, ...]:
    """The feedback choices: :data:`NO_FEEDBACK` and every registered estimator, in registration order."""
    return (NO_FEEDBACK, *_ENTRIES)


def source_colour(name: str) -> str | None:
    """The colour of a feedback source in figures (:data:`NO_FEEDBACK`: red; unknown or unset: ``None``)."""
    if name == NO_FEEDBACK:
        return "tab:red"
    entry = _ENTRIES.get(name)
    return None if entry is None else entry.colour


for _entry in (
    EstimatorEntry(
        "zero_slip",
        "Cheng's zero-slip estimate from the tractor's signals (blind to tyre slip)",
        "scenarios.loop.estimators:zero_slip",
        switch="zero_slip",
        colour="tab:orange",
    ),
    EstimatorEntry(
        "viso_ot",
        "VISO-OT: the trailer's stereo camera, visual odometry and the kingpin path (renders; slow)",
        "scenarios.loop.camera_estimator:viso_ot",
        switch="viso_ot",
        needs_camera=True,
        colour="tab:green",
    ),
    EstimatorEntry(
        "viso_ot_fused",
        "fused VISO-OT: a Kalman filter of the trailer's gyro, wheel speed and steer with the camera (renders)",
        "scenarios.loop.estimators:fused_viso_ot",
        switch="viso_ot_fused",
        requires=("viso_ot",),
        needs_camera=True,
        colour="tab:purple",
    ),
    EstimatorEntry(
        "truth",
        "ground truth: the exact kingpin path of the simulation (de Saxe & Cebon 2018, eqs (3)–(7))",
        "scenarios.loop.estimators:ground_truth",
        always=True,
        colour="tab:blue",
    ),
):
    register_estimator(_entry)
