"""Running a study of the registry (:data:`scenarios.studies.registry.STUDIES`) into a table and figures.

:func:`study_cases` gives a study's cases (a small subset that finishes in minutes unless ``full``), checked against
the ``vehicle`` and run ``settings`` given; :func:`run_study` runs them with
:func:`scenarios.studies.sweep.run_sweep`: serially, on local worker processes (``workers``) or on a Dask cluster
(``scheduler``); every finished case is recorded in ``OUT/cases/`` as it completes, so running the study again into
the same directory only runs what is missing or failed. The studies that take another combination (``vehicle``,
:func:`check_study_vehicle`) are those whose record says so; the camera studies keep their own vehicle. Likewise a
study whose record says so runs its cells at the seeds given (``seeds``, :func:`check_study_seeds`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import pandas as pd

from vehicle_model.errors import InputError
from vehicle_model.parameters import VehicleParams

from ..config import load_scenario
from ..loop.ends import RunStatus
from ..registry import feedback_sources, unit_feedback_sources
from ..unit_feedback import one_semi_trailer, uses_camera
from .progress import ProgressCallback, SweepProgress
from .records import CaseSpec
from .registry import STUDIES, vehicle_studies
from .seeds import parse_seeds
from .sweep import run_sweep
from .unit_steering import study_vehicle, vehicle_problem

__all__ = ["STUDIES", "check_study_seeds", "check_study_vehicle", "run_study", "study_cases", "study_vehicle_params"]


def check_study_vehicle(name: str, vehicle: str | None) -> list[str]:
    """Refuse, before any work, a ``vehicle`` the study ``name`` cannot drive; return what it will leave out.

    Parameters
    ----------
    name
        A key of :data:`STUDIES`.
    vehicle
        ``None`` (the study's own vehicle), a preset's name or a combination file.

    Returns
    -------
    list of str
        Notes to tell once: the camera feedbacks that ``estimators-under-slip`` drops for a longer combination.

    Raises
    ------
    InputError
        One line naming ``--vehicle``: a camera study given any vehicle (a longer combination has no camera;
        a tractor with one semi-trailer is not the vehicle the study reproduces), or a vehicle that is not a
        combination the study can steer (:func:`~scenarios.studies.unit_steering.study_vehicle`).
    """
    if vehicle is None:
        return []
    takes = " and ".join(vehicle_studies())
    if not STUDIES[name].takes_vehicle:
        resolved = study_vehicle_params(vehicle)
        why = (
            "it sees the first towed unit with a stereo camera, which needs a tractor or rigid truck with one "
            "semi-trailer"
            if not one_semi_trailer(resolved)
            else "it reproduces its cases on its own vehicle"
        )
        raise InputError(f"--vehicle {vehicle}: {name} takes no --vehicle ({why}); {takes} take one")
    resolved_vehicle = study_vehicle(vehicle, name)
    if name == "estimators-under-slip" and not one_semi_trailer(resolved_vehicle.params):
        dropped = [f for f in feedback_sources() if f not in unit_feedback_sources() or uses_camera(f)]
        return [
            f"{name} --vehicle {resolved_vehicle.name}: the camera feedbacks ({', '.join(dropped)}) are left out; "
            "the study is model-only on a longer combination (field-loop --vehicle runs one on its cameras)"
        ]
    return []


def study_vehicle_params(vehicle: str) -> VehicleParams:
    """The model's parameters of a preset's name or combination file given as ``--vehicle`` (one line naming it
    when it is neither)."""
    try:
        return load_scenario("roundabout-3", {"vehicle": vehicle}).vehicle_params()
    except (InputError, ValueError) as exc:
        raise InputError(f"--vehicle {vehicle}: {vehicle_problem(exc)}") from None


def check_study_seeds(name: str, seeds: str | Sequence[int] | None) -> tuple[int, ...] | None:
    """The seeds of ``--seeds`` for study ``name`` (:func:`~scenarios.studies.seeds.parse_seeds` when given as
    text), checked before any work; ``None`` (the study's own seed) when not given.

    Raises
    ------
    InputError
        One line naming ``--seeds``: a study that does not take seeds
        (:attr:`~scenarios.studies.registry.Study.takes_seeds`), or seeds outside
        :data:`~scenarios.studies.seeds.ALLOWED`.
    """
    if seeds is None:
        return None
    text = seeds if isinstance(seeds, str) else ",".join(str(seed) for seed in seeds)
    if not STUDIES[name].takes_seeds:
        takes = ", ".join(n for n, study in STUDIES.items() if study.takes_seeds)
        raise InputError(f"--seeds {text}: {name} takes no --seeds (it runs at its own seeds); {takes} takes one")
    return parse_seeds(text)


def study_cases(
    name: str,
    full: bool = False,
    vehicle: str | None = None,
    settings: Mapping[str, Any] | None = None,
    camera: bool = False,
    seeds: str | Sequence[int] | None = None,
) -> list[CaseSpec]:
    """The cases of study ``name`` (a subset unless ``full``), for ``vehicle`` where it takes one
    (:func:`check_study_vehicle`), with ``settings`` (dotted run settings, e.g. the fused filter's) appended to
    every case's own overrides, with ``camera`` its fused camera cases
    (:attr:`~scenarios.studies.registry.Study.takes_camera`), and at ``seeds`` (:func:`check_study_seeds`) every
    cell once per seed.

    Raises
    ------
    InputError
        An unknown study, a ``vehicle`` it does not take, ``camera`` for a study without camera cases, ``seeds``
        it does not take or outside their range, or ``settings`` that make some case's configuration invalid (one
        line naming the field, from the configuration's own validation; before any case runs).
    """
    if name not in STUDIES:
        raise InputError(f"unknown study {name!r}; choose one of {', '.join(sorted(STUDIES))}")
    check_study_vehicle(name, vehicle)
    if camera and not STUDIES[name].takes_camera:
        takes = ", ".join(n for n, study in STUDIES.items() if study.takes_camera)
        raise InputError(f"--camera: {name} has no camera cases; {takes} has")
    cases = STUDIES[name].case_specs(full, vehicle, camera, check_study_seeds(name, seeds))
    if not settings:
        return cases
    extra = tuple(settings.items())
    cases = [dataclasses.replace(spec, overrides=spec.overrides + extra) for spec in cases]
    for spec in cases:  # every case's configuration validated with them, before any runs
        load_scenario(spec.scenario, dict(spec.overrides))
    return cases


def run_study(
    name: str,
    out_dir: Path,
    full: bool = False,
    progress: Callable[[int, int, CaseSpec], None] | None = None,
    *,
    workers: int = 1,
    scheduler: str | Any | None = None,
    resume: bool = True,
    on_progress: ProgressCallback | None = None,
    vehicle: str | None = None,
    settings: Mapping[str, Any] | None = None,
    camera: bool = False,
    seeds: str | Sequence[int] | None = None,
) -> pd.DataFrame:
    """Run every case of a study; write ``table.parquet``, ``table.csv``, ``table.md`` and the figures.

    Parameters
    ----------
    name
        A key of :data:`STUDIES`.
    out_dir
        The study directory: a run directory and a ``cases/<name>.json`` record per case, the table and
        the figures.
    full
        Run the whole study instead of its default subset.
    progress
        ``progress(ended, total, spec)``, called at the start and whenever a case ends (finished or
        failed) with the number of ended cases and that case's spec.
    workers
        Local worker processes (1: one case after another in this process).
    scheduler
        Address of a Dask scheduler (or a ``distributed.Client``) to run the cases on instead.
    resume
        Skip cases already finished in ``out_dir`` (failed ones run again).
    on_progress
        Called with a :class:`~scenarios.studies.progress.SweepProgress` (finished, failed, remaining, ETA).
    vehicle
        Another combination (a preset's name or a combination file) for a study that takes one
        (:attr:`~scenarios.studies.registry.Study.takes_vehicle`); refused for the others
        (:func:`check_study_vehicle`, before any case runs).
    settings
        Dotted run settings appended to every case's overrides (:func:`study_cases`); a finished case whose spec
        they change is run again on resume.
    camera
        Add the study's fused camera cases (:attr:`~scenarios.studies.registry.Study.takes_camera`; refused for the
        others, before any case runs).
    seeds
        Run every cell at each of these seeds (``"0-7"``, ``"0,1,5"`` or a sequence of integers) for a study that
        takes seeds (:func:`check_study_seeds`, refused for the others before any case runs); default the study's
        own.

    Returns
    -------
    pandas.DataFrame
        One row per case in the study's order; a failed case has ``status`` ``failed`` and its ``error``.
        The figures are drawn from the cases that did not fail (a study that counts failed cases in its own tables
        is given them too, :attr:`~scenarios.studies.registry.Study.figures_take_failed`).

    Raises
    ------
    InputError
        An unknown study, a ``vehicle``, ``camera`` or ``seeds`` it does not take or outside their range, or
        ``settings`` a case's configuration refuses (one line, before any case runs).
    KeyboardInterrupt
        Ctrl-C, or :class:`~scenarios.run.stopping.Terminated` on SIGTERM, anywhere in the study (also in a
        case or a worker): the study stops at once, the finished cases stay recorded, no table or figure
        is written, and running it again into ``out_dir`` runs the rest
        (:func:`~scenarios.studies.sweep.run_sweep`).
    """
    cases = study_cases(name, full, vehicle, settings, camera, seeds)
    by_name = {spec.name: spec for spec in cases}

    def report(p: SweepProgress) -> None:
        if progress is not None and cases:
            progress(p.ended, p.total, by_name[p.last.name] if p.last is not None else cases[0])
        if on_progress is not None:
            on_progress(p)

    study = STUDIES[name]
    result = run_sweep(
        cases, out_dir, study.run_case, workers=workers, scheduler=scheduler, resume=resume, progress=report
    )
    table = result.table
    ok = table[table["status"] != RunStatus.FAILED] if "status" in table.columns else table
    if not ok.empty:
        study.figures((table if study.figures_take_failed else ok).reset_index(drop=True), out_dir)
    return table
