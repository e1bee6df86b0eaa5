"""The one registry of the closed loop's off-tracking estimators, and so of its feedback sources.

Every off-tracking source a run can record and feed back to the trailer steering is an entry here: the
ground truth, Cheng's zero-slip estimator, VISO-OT and its fused form, any estimator a user registers
(:func:`register_estimator`) and any estimator an installed distribution declares under the entry-point group
:data:`PLUGIN_GROUP` (``docs/estimators.md``). The configuration schema (``feedback``, ``rear_feedback``, the
``estimators`` switches), the command line's help, ``offtrack compare``, the studies, the figures' colours and the
Gymnasium environments all read their choices from this registry; the closed loop
(:mod:`scenarios.loop.cosimulation`) builds one participant per enabled entry, in registration order.

An entry is the estimator's whole declaration (:class:`EstimatorEntry`): its builder, what it requires, whether it
needs the camera or estimates every towed unit along the chain, its switch's default, its settings model, its label
and colour. The built-in entries are declared with the loop, in :data:`BUILTIN_MODULE`, whose builders import the
loop's estimators lazily, inside their bodies, so reading the names never imports OpenGL or the odometry. The
built-ins and then the plug-ins are loaded once, when the registry is first read (or first added to), so the
command line, spawned study workers and Dask workers all see them.

This module imports only the standard library: the configuration schema sits above it, the loop above that.
"""

from __future__ import annotations

import importlib
import logging
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from importlib.metadata import entry_points
from typing import Any

__all__ = [
    "BUILTIN_MODULE",
    "NO_FEEDBACK",
    "PLUGIN_GROUP",
    "TRUTH",
    "EstimatorEntry",
    "check_estimator_name",
    "estimator_entries",
    "estimator_entry",
    "feedback_sources",
    "load_plugins",
    "register_estimator",
    "source_colour",
    "unit_feedback_sources",
    "unregister_estimator",
]

NO_FEEDBACK = "none"
"""The feedback choice of an unsteered trailer (no estimate is fed back)."""

PLUGIN_GROUP = "offtrack.estimators"
"""The entry-point group under which an installed distribution declares estimators: each entry point names an
:class:`EstimatorEntry`, an iterable of them, or a function of no arguments returning either."""

BUILTIN_MODULE = "scenarios.loop.builtin_estimators"
"""The module declaring the built-in estimators (``BUILTIN_ESTIMATORS``, in registration order), loaded with the
registry's first use: it sits with the loop, above the configuration schema that reads this registry."""

TRUTH = "truth"
"""The ground truth's name: every other ``offtracking_truth…`` column is one of its own."""

_log = logging.getLogger(__name__)


def check_estimator_name(name: str) -> None:
    """Refuse a name the recorded columns could not carry (``offtracking_<name>``, ``offtracking_<name><k>`` for
    towed unit ``k``, ``offtracking_<name>_std``) or that a choice already means.

    Raises
    ------
    ValueError
        One line naming the rule ``name`` breaks.
    """
    rules = (
        (name.isidentifier() and name.isascii(), "be a Python identifier (letters, digits, underscores)"),
        (name == name.lower(), "be lowercase"),
        (not name.startswith("_"), "not start with an underscore"),
        (name != NO_FEEDBACK, f"not be {NO_FEEDBACK!r} (no feedback)"),
        (name == TRUTH or not name.startswith(TRUTH), f"not start with {TRUTH!r} (the truth's own columns)"),
        (not name.endswith("_std"), "not end in '_std' (a standard deviation's column)"),
        (not name[-1:].isdigit(), "not end in a digit (the unit of a towed unit's estimate, e.g. zero_slip3)"),
    )
    for holds, rule in rules:
        if not holds:
            raise ValueError(f"estimator name {name!r} must {rule}")


@dataclass(frozen=True)
class EstimatorEntry:
    """One off-tracking estimator of the closed loop: its whole declaration.

    Parameters
    ----------
    name : str
        The estimate's name: its column ``offtracking_<name>``, its ``metrics.json`` entry, its feedback choice
        and its switch in the configuration's ``estimators`` section (:func:`check_estimator_name`).
    summary : str
        One line for help texts and listings.
    build : callable
        ``build(context) -> EstimatorParticipant``, given the loop's
        :class:`~scenarios.loop.participant.LoopContext` (import heavy modules inside it).
    requires : tuple of str
        Entries it reads (registered before it); enabling it enables them.
    always : bool
        Runs in every run (the ground truth); it has no switch.
    enabled : bool
        Its switch's default: it runs unless the configuration turns it off.
    needs_camera : bool
        Renders the trailer's stereo camera (headless OpenGL; about ten times slower than a model-only run).
    colour : str or None
        Its colour in figures (a matplotlib colour; ``None``: the next of the cycle).
    label : str or None
        Its name in legends (``None``: ``name``).
    settings : type or None
        A pydantic model of its settings, given in the configuration as ``estimators.<name>: {field: value, …}``
        (which also turns it on); the builder reads them with
        :func:`scenarios.estimator_settings.estimator_settings`. ``None``: it takes none that way.
    per_unit : bool
        It estimates every towed unit along the chain (recorded as ``offtracking_<name><k>`` for unit ``k`` of the
        combination) and may steer the units behind the first (``rear_feedback``).
    build_unit : callable or None
        With ``per_unit``: ``build_unit(context, unit) -> UnitEstimator or None`` for towed unit ``unit`` ≥ 2 (2: the
        unit behind the first), an object whose ``update(tick)`` returns that unit's
        :class:`~vehicle_model.offtracking.OfftrackingEstimate` (``None``: it cannot estimate that unit, e.g. no
        camera rig is on it). A unit estimator may declare its own ``columns`` and ``record()`` (and ``finish``,
        ``report``, ``close``), as a participant; without them its estimate is recorded as
        ``offtracking_<name><k>``. Only the ground truth, whose units' truths are the loop's own
        (:mod:`scenarios.loop.further_units`), is per unit without one.
    offline : callable or None
        Its adapter to recorded rows, ``offline(context) -> OfflineEstimator or None``
        (:mod:`scenarios.loop.offline`): ``offtrack estimate`` runs it over a recording beside the recording's own
        odometry. ``None``: it does not run on recordings.
    """

    name: str
    summary: str
    build: Callable[..., Any]
    requires: tuple[str, ...] = ()
    always: bool = False
    enabled: bool = False
    needs_camera: bool = False
    colour: str | None = None
    label: str | None = None
    settings: type | None = None
    per_unit: bool = False
    build_unit: Callable[..., Any] | None = None
    offline: Callable[..., Any] | None = None

    def __post_init__(self) -> None:
        check_estimator_name(self.name)
        if not callable(self.build):
            raise ValueError(f"estimator {self.name!r}: build must be a callable, build(context) -> participant")
        if self.per_unit and not self.always and not callable(self.build_unit):
            raise ValueError(f"estimator {self.name!r}: per_unit needs build_unit(context, unit) -> unit estimator")
        if self.offline is not None and not callable(self.offline):
            raise ValueError(f"estimator {self.name!r}: offline must be a callable, offline(context) -> adapter")

    @property
    def switch(self) -> str | None:
        """Its on/off switch in the configuration's ``estimators`` section (its name; ``None`` if it always runs)."""
        return None if self.always else self.name

    @property
    def legend(self) -> str:
        """Its name in legends."""
        return self.label or self.name


_ENTRIES: dict[str, EstimatorEntry] = {}
_plugins_loaded = False


def register_estimator(entry: EstimatorEntry, replace: bool = False) -> None:
    """Add ``entry`` to the registry (after the entries it requires).

    Raises
    ------
    ValueError
        The name is taken (unless ``replace``) or a required entry is not registered.
    """
    load_plugins()
    if entry.name in _ENTRIES and not replace:
        raise ValueError(f"an estimator named {entry.name!r} is registered already")
    missing = [name for name in entry.requires if name not in _ENTRIES]
    if missing:
        raise ValueError(f"estimator {entry.name!r} requires {missing}, which are not registered (register them first)")
    _ENTRIES[entry.name] = entry


def unregister_estimator(name: str) -> None:
    """Remove the entry ``name`` (and nothing that requires it may stay)."""
    load_plugins()
    dependants = [e.name for e in _ENTRIES.values() if name in e.requires]
    if dependants:
        raise ValueError(f"estimators {dependants} require {name!r}")
    _ENTRIES.pop(name, None)


def _declared(loaded: Any) -> tuple[EstimatorEntry, ...]:
    """The entries an entry point's object declares (an entry, an iterable of them, or a function returning
    either)."""
    if callable(loaded) and not isinstance(loaded, EstimatorEntry):
        loaded = loaded()
    entries = (loaded,) if isinstance(loaded, EstimatorEntry) else tuple(loaded) if isinstance(loaded, Iterable) else ()
    if not entries or not all(isinstance(e, EstimatorEntry) for e in entries):
        raise TypeError(f"it declares {type(loaded).__name__}, not scenarios.registry.EstimatorEntry objects")
    return entries


def load_plugins() -> None:
    """Register the built-in estimators (:data:`BUILTIN_MODULE`), then those of every installed distribution's
    :data:`PLUGIN_GROUP` entry points in the entry points' name order; once. A plug-in that fails to load or to
    register is left out with one logged line naming it."""
    global _plugins_loaded
    if _plugins_loaded:
        return
    _plugins_loaded = True
    builtin = importlib.import_module(BUILTIN_MODULE).BUILTIN_ESTIMATORS
    for entry in builtin:
        register_estimator(entry)
    for point in sorted(entry_points(group=PLUGIN_GROUP), key=lambda p: p.name):
        try:
            for entry in _declared(point.load()):
                register_estimator(entry)
        except Exception as exc:  # a broken plug-in must not stop the project: one line naming it
            _log.warning(
                "estimator plug-in %r (%s = %s) is not loaded: %s: %s",
                point.name,
                PLUGIN_GROUP,
                point.value,
                type(exc).__name__,
                exc,
            )


def estimator_entries() -> tuple[EstimatorEntry, ...]:
    """Every registered estimator, in registration order (every entry after those it requires)."""
    load_plugins()
    return tuple(_ENTRIES.values())


def estimator_entry(name: str) -> EstimatorEntry:
    """The entry ``name``.

    Raises
    ------
    KeyError
        No such estimator.
    """
    load_plugins()
    return _ENTRIES[name]


def feedback_sources() -> tuple[str, ...]:
    """The feedback choices: :data:`NO_FEEDBACK` and every registered estimator, in registration order."""
    return (NO_FEEDBACK, *(e.name for e in estimator_entries()))


def unit_feedback_sources() -> tuple[str, ...]:
    """The estimates a towed unit behind the first can be steered on: :data:`NO_FEEDBACK`, the truth, then every
    other estimator that estimates each unit along the chain (:attr:`EstimatorEntry.per_unit`), in registration
    order."""
    others = (e.name for e in estimator_entries() if e.per_unit and e.name != TRUTH)
    return (NO_FEEDBACK, TRUTH, *others)


def source_colour(name: str) -> str | None:
    """The colour of a feedback source in figures (:data:`NO_FEEDBACK`: red; unknown or unset: ``None``)."""
    if name == NO_FEEDBACK:
        return "tab:red"
    load_plugins()
    entry = _ENTRIES.get(name)
    return None if entry is None else entry.colour
