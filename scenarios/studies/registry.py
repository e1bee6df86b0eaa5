"""The studies offtrack ships, each one :class:`Study` record in one registry, :data:`STUDIES`.

A study is its cases (a function of ``full``, and of ``vehicle`` for a study that takes another combination, of
``seeds`` for one that takes seeds), the function that runs one case into a table row, and the function that draws
its figures from the table. Everything that lists, runs or describes the studies (the ``study`` command,
:func:`scenarios.studies.definitions.run_study`, the behaviour fingerprint) reads this registry.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd

from .cases import run_case
from .controller_limits import controller_limits_cases, controller_limits_figures, run_controller_limits_case
from .estimators_under_slip import estimators_under_slip_cases, run_estimators_under_slip_case
from .field_bias import field_bias_cases, run_field_bias_case
from .field_loop import FIELD_LOOP_COLUMNS, field_loop_cases, field_loop_terminal_rows, run_field_loop_case
from .figures import grid_figures, paper_figures
from .figures_field_bias import field_bias_figures
from .figures_field_loop import field_loop_figures
from .figures_off_highway import off_highway_figures, roughness_figures
from .figures_section4 import section4_figures
from .figures_unit_steering import unit_steering_figures
from .off_highway import OFF_HIGHWAY_COLUMNS, off_highway_cases, run_off_highway_case
from .off_highway_roughness import ROUGHNESS_COLUMNS, roughness_cases, run_roughness_case
from .off_highway_seeds import terminal_rows_over_seeds
from .records import CaseSpec
from .section3 import SECTION3_COLUMNS, paper_section3_cases
from .section4 import paper_section4_cases, run_section4_case
from .unit_steering import run_unit_steering_case, unit_steering_cases
from .workers import RunFunction


@dataclass(frozen=True)
class Study:
    """One study: what it runs, how it runs one case, and how it draws its table.

    Attributes
    ----------
    name : str
        The name on the command line (``offtrack study NAME``).
    summary : str
        One line saying what the study compares.
    cases : callable
        ``cases(full)`` (or ``cases(full, vehicle)`` when :attr:`takes_vehicle`; ``camera=`` and ``seeds=`` when
        :attr:`takes_camera` / :attr:`takes_seeds`): the case specs, the default subset unless ``full``.
    figures : callable
        ``figures(table, out_dir)``: draws the study's figures from the rows of the cases that did not fail (every
        row, failed ones included, when :attr:`figures_take_failed`).
    run_case : callable
        ``run_case(spec, out_dir) -> row``, a module-level function (it is pickled for the workers); default
        :func:`scenarios.studies.cases.run_case`, a study's own adds its columns.
    takes_vehicle : bool
        The study runs on another combination given as ``vehicle``; the others keep their own vehicle.
    columns : tuple of str
        The columns of its terminal table after the labels that vary, in order: the ones that answer the study's
        question (empty: :data:`scenarios.studies.summary.PRIORITY`, which already leads with the off-tracking and
        each unit's columns of the model-only studies). The full table is in ``table.md``.
    takes_camera : bool
        The study has fused camera cases its default leaves out (rendered, minutes each), added with ``camera``
        (``cases(full, camera=True)``).
    terminal_rows : callable or None
        ``terminal_rows(table) -> (rows, note)``: the rows the terminal shows instead of the cases (field-loop: one
        per cell with its acceptance, as its ``table.md``) and a note for the title (e.g. how many cells pass);
        None: the cases.
    takes_seeds : bool
        The study runs its cells at the seeds given (``cases(full, seeds=…)``, ``--seeds``,
        :func:`~scenarios.studies.seeds.parse_seeds`), each seed a cell of its own; without them, at its own seed.
    figures_take_failed : bool
        :attr:`figures` is given every case's row, failed ones included, and leaves them out of what it draws
        itself: a table it writes counts a failed case as failed (the off-highway study's cells pooled over
        seeds), not as one that never ran.
    """

    name: str
    summary: str
    cases: Callable[..., list[CaseSpec]]
    figures: Callable[[pd.DataFrame, Path], None]
    run_case: RunFunction = run_case
    takes_vehicle: bool = False
    columns: tuple[str, ...] = ()
    terminal_rows: Callable[[pd.DataFrame], tuple[pd.DataFrame, str]] | None = None
    takes_camera: bool = False
    takes_seeds: bool = False
    figures_take_failed: bool = False

    def case_specs(
        self,
        full: bool = False,
        vehicle: str | None = None,
        camera: bool = False,
        seeds: Sequence[int] | None = None,
    ) -> list[CaseSpec]:
        """The cases (a subset unless ``full``), on ``vehicle`` when given (only for :attr:`takes_vehicle`), with the
        camera cases when ``camera`` (only for :attr:`takes_camera`), at ``seeds`` when given (only for
        :attr:`takes_seeds`)."""
        if camera and not self.takes_camera:
            raise ValueError(f"{self.name} takes no camera option")
        if vehicle is not None and not self.takes_vehicle:
            raise ValueError(f"{self.name} takes no vehicle")
        if seeds is not None and not self.takes_seeds:
            raise ValueError(f"{self.name} takes no seeds")
        options: dict[str, Any] = {}
        if camera:
            options["camera"] = True
        if seeds is not None:
            options["seeds"] = tuple(seeds)
        return self.cases(full, **options) if vehicle is None else self.cases(full, vehicle, **options)


def _studies(*studies: Study) -> dict[str, Study]:
    return {study.name: study for study in studies}


STUDIES: dict[str, Study] = _studies(
    Study(
        "paper-section3",
        "de Saxe & Cebon 2018 §3: VISO-OT on the constant-slip straight over stereo baseline, slip and scenery "
        "density (Figs 6–8)",
        paper_section3_cases,
        paper_figures,
        columns=SECTION3_COLUMNS,
    ),
    Study(
        "estimators-under-slip",
        "every feedback source over μ, camber and manoeuvre, the fused VISO-OT beside the raw one",
        estimators_under_slip_cases,
        grid_figures,
        run_estimators_under_slip_case,
        takes_vehicle=True,
    ),
    Study(
        "paper-section4",
        "de Saxe & Cebon 2018 §4: rear and side cameras, baselines and the field manoeuvres with the right camera "
        "aligned, misaligned and corrected (Figs 14–16)",
        paper_section4_cases,
        section4_figures,
        run_section4_case,
        columns=(
            "status",
            "viso_ot_rms_error_m",
            "viso_ot_max_abs_error_m",
            "viso_ot_mean_error_m",
            "neg_mean_error_m",
            "pos_mean_error_m",
            "mean_matches",
            "inlier_percent",
            "failed_frames",
        ),
    ),
    Study(
        "field-loop",
        "the fused VISO-OT loop under field conditions beside the zero-slip-fed and truth-fed loops, with an "
        "acceptance per cell",
        field_loop_cases,
        field_loop_figures,
        run_field_loop_case,
        columns=FIELD_LOOP_COLUMNS,
        terminal_rows=field_loop_terminal_rows,
        takes_vehicle=True,
    ),
    Study(
        "field-bias",
        "each part of the field conditions alone and in pairs, under pixel-refined odometry and a fused filter "
        "without bias states (before) against the defaults (after): the odometry's error and VISO-OT's bias",
        field_bias_cases,
        field_bias_figures,
        run_field_bias_case,
        columns=(
            "status",
            "vo_yaw_error_mrad_per_m",
            "vo_lateral_error_mm_per_m",
            "vo_scale_error_percent",
            "viso_ot_mean_error_m",
            "viso_ot_rms_error_m",
            "fused_mean_error_m",
            "fused_rms_error_m",
            "fused_within_2sigma",
        ),
    ),
    Study(
        "unit-steering",
        "a combination with several steerable towed units, each on its own feedback, against unsteered (model only)",
        unit_steering_cases,
        unit_steering_figures,
        run_unit_steering_case,
        takes_vehicle=True,
    ),
    Study(
        "controller-limits",
        "the path-following controller where its axles run out of reach: unsteered, truth-fed and zero-slip-fed, "
        "with the share of the path beyond the steering's reach (--camera: and the fused camera under field "
        "conditions)",
        controller_limits_cases,
        controller_limits_figures,
        run_controller_limits_case,
        takes_vehicle=True,
        takes_camera=True,
    ),
    Study(
        "off-highway",
        "the loop on terrain that is not a plane, on unsealed surfaces: fused VISO-OT (field and ideal camera) "
        "beside the zero-slip-fed, truth-fed and unsteered loops, with a verdict per cell",
        off_highway_cases,
        off_highway_figures,
        run_off_highway_case,
        columns=OFF_HIGHWAY_COLUMNS,
        terminal_rows=terminal_rows_over_seeds,
        takes_vehicle=True,
        takes_seeds=True,
        figures_take_failed=True,
    ),
    Study(
        "off-highway-roughness",
        "VISO-OT's error against the road's undulation and potholes, ideal camera, in the level frame and with the "
        "planar eqs (model only)",
        roughness_cases,
        roughness_figures,
        run_roughness_case,
        columns=ROUGHNESS_COLUMNS,
    ),
)
"""Every study by name, in the order they are listed."""


def vehicle_studies() -> tuple[str, ...]:
    """The names of the studies that take another combination (``vehicle``)."""
    return tuple(name for name, study in STUDIES.items() if study.takes_vehicle)
