"""The commands of many runs: ``compare``, ``study``, ``assess`` and ``tune``."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.markup import escape

from scenarios.extras import require
from scenarios.loop.ends import RunStatus
from scenarios.registry import NO_FEEDBACK, feedback_sources
from scenarios.scenario_shortcuts import shortcut_pairs

from .options import (
    FEEDBACKS,
    CamberDirectionOption,
    ForceOption,
    JsonOption,
    MuOption,
    PlotFormatOption,
    ResumeOption,
    ScenarioArgument,
    SchedulerOption,
    SurfaceOption,
    WorkersOption,
)
from .scenario_input import load_config, scenario_overrides
from .terminal import EXIT_FAILED, console, errors, handled, print_study_summary, simulation_progress


@handled
def compare(
    scenario: ScenarioArgument,
    surface: SurfaceOption = None,
    mu: MuOption = None,
    camber: Annotated[float | None, typer.Option(help="Camber [%].")] = None,
    camber_direction: CamberDirectionOption = None,
    vehicle: Annotated[
        str, typer.Option(help="Vehicle preset with steerable trailer axles, or a combination file NAME.yaml.")
    ] = "lst",
    feedbacks: Annotated[
        str,
        typer.Option(
            help=f"Comma-separated feedback sources to compare (default: every registered one, {FEEDBACKS}; the "
            "viso_ot ones render the camera).",
            show_default=False,
        ),
    ] = ",".join(feedback_sources()),
    duration: Annotated[float | None, typer.Option(help="Stop every run after this many simulated seconds.")] = None,
    set_: Annotated[list[str] | None, typer.Option("--set", help="Any config field, e.g. --set path.turns=1.")] = None,
    out: Annotated[Path | None, typer.Option(help="Output directory (default runs/compare-SCENARIO/…).")] = None,
    force: ForceOption = False,
    plot_format: PlotFormatOption = "png",
    workers: WorkersOption = 1,
    scheduler: SchedulerOption = None,
) -> None:
    """Run each feedback source given (default: every one) on the same scenario; write a table and one overlay
    figure."""
    from scenarios.run.results import check_plot_format, new_run_dir
    from scenarios.run.summary import MISSING
    from scenarios.studies.compare import compare_feedback, display_table
    from scenarios.studies.summary import summary_table
    from vehicle_model.errors import InputError

    plot_format = check_plot_format(plot_format)
    chosen = tuple(f.strip() for f in feedbacks.split(",") if f.strip())
    unknown = [f for f in chosen if f not in feedback_sources()]
    if not chosen or unknown:
        raise InputError(f"--feedbacks {feedbacks!r}: give one or more of {FEEDBACKS}, separated by commas")
    if duration is not None and not duration > 0:  # also NaN
        raise InputError(f"--duration {duration:g}: give a positive number of simulated seconds")
    pairs = shortcut_pairs(
        vehicle=vehicle,
        surface=surface,
        mu=mu,
        camber_percent=camber,
        camber_direction=camber_direction,
        duration_s=duration,
    )
    overrides = scenario_overrides(pairs, surface, mu, set_)
    config = load_config(scenario, overrides)
    for feedback in chosen:  # every variant (a camera's included) must be able to run
        load_config(scenario, {**overrides, "feedback": feedback})
    if scheduler is not None:
        require("distributed", "cluster", "--scheduler")
    run_dir = new_run_dir(out, f"compare-{config.name}", force=force)
    with simulation_progress() as bar:
        task = bar.add_task(escape(f"{chosen[0]} (1/{len(chosen)})"), total=1.0, sim_t=0.0)

        def progress(feedback: str, t: float, done: float) -> None:
            label = f"{feedback} ({chosen.index(feedback) + 1}/{len(chosen)})"
            bar.update(task, completed=done, sim_t=t, description=escape(label))

        table = compare_feedback(
            config, run_dir, chosen, progress=progress, plot_format=plot_format, workers=workers, scheduler=scheduler
        )
        bar.update(task, completed=1.0)
    files = (str(run_dir / "comparison.md"), str(run_dir / "comparison.csv"))
    title = f"{config.name}: feedback comparison"
    console.print(
        summary_table(display_table(table), console.width, files=files, title=title, rows="runs", missing=MISSING)
    )
    exit_for_compare(table, run_dir)


def exit_for_compare(table: Any, run_dir: Path) -> None:
    """After ``compare``'s table: each steered run worse than the unsteered one and each run's notes, one line each;
    then, if a run did not complete (diverged, lost control, failed), one line for each and exit 3."""
    from scenarios.run.notes import COMPARE_NOTE
    from scenarios.run.results import read_metrics
    from scenarios.studies.compare import unsteered_comparison

    for note in unsteered_comparison(table)[1]:
        console.print(f"[yellow]worse than unsteered[/]: {escape(note)}")
    for feedback in table["feedback"]:
        for note in (read_metrics(run_dir / str(feedback)) or {}).get("notes") or ():
            if note.get("note") != COMPARE_NOTE:  # the comparison is this table
                console.print(f"[yellow]note[/] ({escape(str(feedback))}): {escape(str(note.get('text')))}")
    unfinished = table[table["status"] != RunStatus.COMPLETED] if "status" in table.columns else table.iloc[:0]
    for _, row in unfinished.iterrows():
        why = row.get("reason") if isinstance(row.get("reason"), str) else row.get("error")
        errors.print(f"run {row['feedback']} {row['status']}: {why}", markup=False)
    if len(unfinished):
        errors.print(f"{len(unfinished)} of {len(table)} runs did not complete (exit 3)", markup=False)
        raise typer.Exit(EXIT_FAILED)


@contextmanager
def scheduler_client(scheduler: str | None) -> Iterator[Any]:
    """The Dask client of ``--scheduler``, connected before any directory is made (an address that cannot be
    reached is refused in one line, :func:`scenarios.studies.executors.dask_client`) and closed after; None
    without one."""
    if scheduler is None:
        yield None
        return
    from scenarios.studies.executors import dask_client

    client, owned = dask_client(scheduler)
    try:
        yield client
    finally:
        if owned:
            client.close()


def exit_if_cases_failed(table: Any, run_dir: Path) -> None:
    """Say how many of a sweep's cases failed and where their errors are, and exit 3; nothing when none did."""
    from scenarios.studies.records import CASES_DIR

    failed = int((table["status"] == RunStatus.FAILED).sum()) if "status" in table.columns else 0
    if failed:
        errors.print(
            f"{failed} case(s) failed (error and traceback in {run_dir / CASES_DIR}/); "
            f"run the same command with --out {run_dir} to retry them",
            markup=False,
        )
        raise typer.Exit(EXIT_FAILED)


@handled
def study(
    name: Annotated[str, typer.Argument(help="The study (an unknown name lists them all).")],
    full: Annotated[bool, typer.Option(help="Run the whole study (default: a small subset).")] = False,
    out: Annotated[Path | None, typer.Option(help="Output directory (default runs/study-NAME/…).")] = None,
    force: ForceOption = False,
    workers: WorkersOption = 1,
    scheduler: SchedulerOption = None,
    resume: ResumeOption = True,
    vehicle: Annotated[
        str | None,
        typer.Option(
            help="Another combination (preset or NAME.yaml) for unit-steering, estimators-under-slip, "
            "field-loop (every steered unit on its own camera), controller-limits or off-highway; it needs a "
            "steerable towed unit."
        ),
    ] = None,
    set_: Annotated[
        list[str] | None,
        typer.Option("--set", help="A run setting for every case, e.g. --set fusion.kinematic_error_model=state."),
    ] = None,
    camera: Annotated[
        bool, typer.Option(help="controller-limits: add each cell's fused camera case under field conditions.")
    ] = False,
    seeds: Annotated[
        str | None,
        typer.Option(
            help="off-highway: run every cell at each of these seeds, e.g. 0-7, 0,1,5 or 3 (at most 64), and pool "
            "them per cell into seeds.md / seeds.csv (default: the study's own seed).",
            show_default=False,
        ),
    ] = None,
) -> None:
    """Run a study: every case into its own directory, then one table and the figures."""
    from scenarios.config import parse_assignment
    from scenarios.run.claim import claim_directory
    from scenarios.run.results import new_run_dir
    from scenarios.studies.definitions import STUDIES, check_study_seeds, check_study_vehicle, run_study, study_cases
    from scenarios.studies.progress import rich_progress
    from scenarios.studies.records import CASES_DIR
    from vehicle_model.errors import InputError

    if name not in STUDIES:
        raise InputError(f"unknown study {name!r}; choose one of {', '.join(sorted(STUDIES))}")
    for note in check_study_vehicle(name, vehicle):  # a vehicle it cannot drive: refused before any work
        errors.print(f"note: {note}", markup=False)
    chosen_seeds = check_study_seeds(name, seeds)  # one line naming --seeds, before any work
    if scheduler is not None:
        require("distributed", "cluster", "--scheduler")
    settings = dict(parse_assignment(item) for item in set_ or [])
    if settings or camera:
        study_cases(name, full, vehicle, settings, camera, chosen_seeds)  # a case refusing them: one line, no work
    with scheduler_client(scheduler) as client:
        if out is not None and resume and (out / CASES_DIR).is_dir():
            claim_directory(out)  # one process resumes it: a second is refused before any case runs
            run_dir = out  # an earlier run of the study: finish it
        else:
            run_dir = new_run_dir(out, f"study-{name}", force=force)
        with rich_progress(name, console=console) as progress:
            table = run_study(
                name,
                run_dir,
                full=full,
                workers=workers,
                scheduler=client,
                resume=resume,
                on_progress=progress,
                vehicle=vehicle,
                settings=settings,
                camera=camera,
                seeds=chosen_seeds,
            )
    print_study_summary(table, run_dir, name)
    exit_if_cases_failed(table, run_dir)


@handled
def assess(
    combination: Annotated[str, typer.Argument(help="The combination: a preset's name or a combination YAML file.")],
    feedback: Annotated[
        list[str] | None,
        typer.Option(
            help="Feedback steering every steerable towed unit (repeatable): none, truth, zero_slip, viso_ot_fused."
        ),
    ] = None,
    side_by_side: Annotated[
        bool, typer.Option(help="Compare unsteered, truth-, zero-slip- (and for one semi-trailer VISO-OT-) fed.")
    ] = False,
    surface: Annotated[
        list[str] | None, typer.Option(help="Surface preset, repeatable: dry, wet, snow, ice (default dry).")
    ] = None,
    out: Annotated[Path | None, typer.Option(help="Output directory (default runs/assess-NAME/…).")] = None,
    force: ForceOption = False,
    workers: WorkersOption = 1,
    scheduler: SchedulerOption = None,
    resume: ResumeOption = True,
    plot_format: PlotFormatOption = "png",
    levels: Annotated[
        Path | None,
        typer.Option(
            help="Your PBS thresholds per standard and level, each with its clause (docs/pbs_levels_template.yaml): "
            "the assessment grades with them. Without: not graded."
        ),
    ] = None,
) -> None:
    """Assess one combination: the PBS measures a yaw-plane model supports and the UK/EU turning circle, each on its
    manoeuvre, into assessment.md / .csv / .json with a figure per measure (docs/pbs.md)."""
    from scenarios.assess.user_levels import load_levels
    from scenarios.run.claim import claim_directory
    from scenarios.run.results import check_plot_format, new_run_dir
    from scenarios.studies.pbs_assessment import assessment_cases, run_assessment, side_by_side_feedbacks
    from scenarios.studies.progress import rich_progress
    from scenarios.studies.records import CASES_DIR
    from vehicle_model.errors import InputError

    plot_format = check_plot_format(plot_format)
    user_levels = None if levels is None else load_levels(levels)  # checked before any work
    if side_by_side and feedback:
        raise InputError(
            f"--feedback {' --feedback '.join(feedback)} with --side-by-side: the comparison chooses its own "
            "feedbacks; allowed: --side-by-side or --feedback F …, not both"
        )
    surfaces = tuple(surface or ("dry",))
    feedbacks = side_by_side_feedbacks(combination) if side_by_side else tuple(feedback or ("none",))
    assessment_cases(combination, feedbacks, surfaces)  # every option checked before any work
    if scheduler is not None:
        require("distributed", "cluster", "--scheduler")
    name = Path(combination).stem if combination.endswith((".yaml", ".yml")) else combination
    with scheduler_client(scheduler) as client:
        if out is not None and resume and (out / CASES_DIR).is_dir():
            claim_directory(out)  # one process resumes it: a second is refused before any case runs
            run_dir = out
        else:
            run_dir = new_run_dir(out, f"assess-{name}", force=force)
        with rich_progress(f"assess {name}", console=console) as progress:
            table = run_assessment(
                combination,
                run_dir,
                feedbacks,
                surfaces,
                workers=workers,
                scheduler=client,
                resume=resume,
                on_progress=progress,
                plot_format=plot_format,
                levels=user_levels,
            )
    console.print(f"assessment: {run_dir / 'assessment.md'} (and .csv, .json, measure-*.{plot_format})")
    exit_if_cases_failed(table, run_dir)


@handled
def tune(
    trials: Annotated[int, typer.Option(help="Optuna trials (the first is the designed gains).", min=1)] = 30,
    draws: Annotated[int, typer.Option(help="Training draws of the randomised roads per trial.", min=1)] = 3,
    seed: Annotated[int, typer.Option(help="Seed of the draws and of the sampler.", min=0)] = 0,
    feedback: Annotated[
        str, typer.Option(help=f"Feedback source, one of: {FEEDBACKS.removeprefix('none, ')}.")
    ] = "truth",
    scenario: Annotated[
        str, typer.Option(help="Scenario driven (catalogue name or YAML file), a quarter turn of it: path.turns=0.25.")
    ] = "roundabout-3",
    vehicle: Annotated[
        str,
        typer.Option(
            help="Vehicle preset or combination file NAME.yaml; each steered towed unit gets its own gains "
            "(a preset with an -unladen variant is trained laden and unladen, any other as given)."
        ),
    ] = "lst",
    out: Annotated[
        Path | None,
        typer.Option(help="Write trials.csv, comparison.csv/.md and tuned_gains.yaml (a scenario a run loads) here."),
    ] = None,
    force: ForceOption = False,
    as_json: JsonOption = False,
) -> None:
    """Tune the trailer PID gains, one set per steered unit, with Optuna (offtrack/GainTuning-v0); compare them
    with the designed gains on held-out roads and advise the tuned ones only where those support them."""
    from rich.progress import Progress

    from scenarios.envs.scenario import DEFAULT_OVERRIDES
    from scenarios.envs.tuning import TuningStopped, tune_gains
    from scenarios.envs.tuning_report import gains_table, held_out_table, set_options, write_trials, write_tuning
    from scenarios.run.json_output import strict_json
    from scenarios.run.results import check_output_dir, new_run_dir
    from vehicle_model.errors import InputError

    require("optuna", "tune", "tuning the gains")
    steering = [source for source in feedback_sources() if source != NO_FEEDBACK]
    if feedback not in steering:  # the tuned gains steer the trailer on an estimate
        raise InputError(f"--feedback {feedback!r}: allowed: {', '.join(steering)}")
    base = load_config(
        scenario, {"feedback": feedback, "vehicle": vehicle}
    )  # the gains' scenario, refused before tuning
    if out is not None:
        check_output_dir(out)
    made = out is not None and not out.exists()
    out_dir = None if out is None else new_run_dir(out, "tune", force=force)
    with Progress(console=console, transient=True, disable=as_json) as bar:
        task = bar.add_task("tuning", total=trials)

        def progress(done: int, total: int, best: float) -> None:
            bar.update(task, completed=done, description=f"tuning: best training cost {best:.5f}")

        env_kwargs = {"feedback": feedback, "scenario": scenario, "overrides": dict(DEFAULT_OVERRIDES)}
        try:
            result = tune_gains(
                n_trials=trials, train_draws=draws, seed=seed, env_kwargs=env_kwargs, progress=progress, vehicle=vehicle
            )
        except TuningStopped as stopped:  # the finished trials are the data computed so far
            finished = len(stopped.trial_rows)
            if out_dir is not None:
                path = write_trials(stopped.trial_rows, out_dir)
                errors.print(f"{finished} finished trial(s) → {path}", markup=False)
            else:
                errors.print(f"{finished} finished trial(s); without --out they are not kept", markup=False)
            raise
        except InputError:  # refused by the environment: no empty --out left behind
            if made and out_dir is not None and not any(out_dir.iterdir()):
                out_dir.rmdir()
            raise
    paths = None if out_dir is None else write_tuning(result, out_dir, base)
    if as_json:
        files = None if paths is None else {key: str(path) for key, path in paths.items()}
        print(strict_json({"benchmark": "tune_gains", **result.to_dict(), "files": files}, indent=None))
        return
    console.print(gains_table(result))
    console.print(held_out_table(result))
    console.print(f"{result.trials} trials, {result.evaluations} scenario runs, {result.wall_s:.0f} s wall time")
    for line in result.advice():
        console.print(line, markup=False, highlight=False)
    if result.tuned_differs():
        head = "apply the tuned gains" if result.apply_tuned() else "the tuned gains, not advised"
        console.print(f"{head}: {set_options(result.tuned)}", markup=False, highlight=False, soft_wrap=True)
    if paths is not None:
        console.print(
            f"trials, comparison and gains in {paths['gains'].parent}; offtrack run {paths['gains']} runs {scenario} "
            "with them",
            markup=False,
            highlight=False,
        )
