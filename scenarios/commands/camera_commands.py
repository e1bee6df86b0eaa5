"""The commands of the camera and recorded data: ``render``, ``estimate``, ``vo-eval``, ``calibrate`` and
``animate``."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer
from rich.markup import escape

from scenarios.scenario_shortcuts import shortcut_pairs

from .options import (
    ForceOfftrackFilesOption,
    ForceRunOption,
    JsonOption,
    OdometrySeedOption,
    PlotsOption,
    RefinementOption,
    RunDirArgument,
    ScenarioArgument,
)
from .scenario_input import load_config, scenario_overrides
from .terminal import console, exit_for_status, handled, print_summary


@handled
def render(
    scenario: ScenarioArgument,
    out: Annotated[Path, typer.Option(help="Dataset directory (KITTI odometry layout).")],
    frames: Annotated[int | None, typer.Option(help="Render at most this many camera frames.", min=1)] = None,
    density: Annotated[float | None, typer.Option(help="Scenery density in [0, 1].", min=0.0, max=1.0)] = None,
    seed: Annotated[int | None, typer.Option(help="Seed of the world and the run.", min=0)] = None,
    duration: Annotated[float | None, typer.Option(help="Simulated seconds.")] = None,
    set_: Annotated[
        list[str] | None, typer.Option("--set", help="Any config field, e.g. --set camera.baseline=1.5.")
    ] = None,
    video: Annotated[bool, typer.Option(help="Also write a side-by-side stereo video.")] = False,
    antialias: Annotated[
        bool | None, typer.Option(help="4× multisampling (slower); default: the configuration's camera.antialias.")
    ] = None,
    force: Annotated[bool, typer.Option(help="Replace an earlier dataset in --out (offtrack's files only).")] = False,
    as_json: JsonOption = False,
) -> None:
    """Export the scenario's rendered stereo sequence as a KITTI-odometry-style dataset."""
    from rich.progress import Progress

    from scenarios.export.kitti import export_kitti, render_summary
    from scenarios.run.claim import claim_directory
    from scenarios.run.json_output import strict_json
    from scenarios.run.results import check_output_dir

    pairs = (*shortcut_pairs(seed=seed, duration_s=duration), ("camera.scenery_density", density))
    config = load_config(scenario, scenario_overrides(pairs, None, None, set_))
    check_output_dir(out)
    out.mkdir(parents=True, exist_ok=True)
    claim_directory(out)  # one process writes a dataset: another into it is refused before any work
    with Progress(console=console, transient=True, disable=as_json) as bar:
        task = bar.add_task(escape(f"rendering {config.name}"), total=None)
        summary = export_kitti(
            config,
            out,
            max_frames=frames,
            scenery_density=density,
            video=video,
            overwrite=force,
            antialias=antialias,
            progress=lambda done, total: bar.update(task, completed=done, total=total),
        )
    if as_json:
        print(strict_json(summary, indent=None))
        return
    console.print(render_summary(summary), markup=False, highlight=False, soft_wrap=True)


@handled
def estimate(
    recording: Annotated[
        Path | None,
        typer.Argument(help="KITTI-odometry folder, ROS 1/2 bag, or the left video (with --right-video)."),
    ] = None,
    rig: Annotated[
        Path | None, typer.Option(help="Rig YAML: vehicle, psi_c2v_deg, lever_arm_m [, follow_point_offset_m].")
    ] = None,
    rigs: Annotated[
        Path | None,
        typer.Option(help="Rigs YAML: vehicle and one rig per towed unit, each with its recording (no RECORDING)."),
    ] = None,
    out: Annotated[Path | None, typer.Option(help="Run directory (default runs/recording-NAME/TIMESTAMP).")] = None,
    force: ForceRunOption = False,
    calibration: Annotated[
        Path | None, typer.Option(help="OpenCV YAML of offtrack calibrate: raw images, rectified on the fly.")
    ] = None,
    calib: Annotated[
        Path | None, typer.Option(help="KITTI calib.txt of rectified images (default: the folder's).")
    ] = None,
    right_video: Annotated[Path | None, typer.Option(help="The right camera's video (RECORDING the left one).")] = None,
    times: Annotated[Path | None, typer.Option(help="One time per video frame [s].")] = None,
    left_topic: Annotated[str | None, typer.Option(help="Bag: the left camera's image topic.")] = None,
    right_topic: Annotated[str | None, typer.Option(help="Bag: the right camera's image topic.")] = None,
    pair_tolerance: Annotated[
        float | None, typer.Option(help="Bag: largest left-right stamp difference [s] (default: interval/4).")
    ] = None,
    signals: Annotated[
        Path | None, typer.Option(help="CSV time_s, speed_m_s, yaw_rate_deg_s, articulation_deg: fused + zero-slip.")
    ] = None,
    reference: Annotated[Path | None, typer.Option(help="Reference camera poses (KITTI or TUM).")] = None,
    reference_format: Annotated[str | None, typer.Option(help="kitti or tum (default: from the file).")] = None,
    reference_offtracking: Annotated[
        Path | None, typer.Option(help="Reference off-tracking CSV: time_s, offtracking_m.")
    ] = None,
    folder_poses: Annotated[bool, typer.Option(help="Use a KITTI folder's poses.txt as the reference.")] = True,
    refinement: RefinementOption = 2,
    seed: OdometrySeedOption = 0,
    rear_point: Annotated[
        str,
        typer.Option(
            help="The tractor's rear point of the zero-slip and fused estimates: axle_mean, equivalent, "
            "speed_compensated or lateral_acceleration (needs lateral_acceleration_m_s2 in --signals)."
        ),
    ] = "axle_mean",
    zero_slip_grade: Annotated[
        str,
        typer.Option(
            help="The zero-slip estimate's grade: none (the wheel speed taken as horizontal) or accelerometer "
            "(needs longitudinal_acceleration_m_s2 in --signals)."
        ),
    ] = "none",
    plots: PlotsOption = True,
) -> None:
    """VISO-OT (and with --signals the fused and zero-slip estimates) on a recorded stereo sequence: a run directory
    like a simulated run's (offtrack report and offtrack animate take it). With --rigs, one rig per towed unit:
    each unit's run in unitK/ of the directory."""
    from rich.progress import Progress

    from scenarios.recorded.estimate import estimate_recording
    from scenarios.recorded.inputs import resolve_inputs
    from scenarios.recorded.report import recording_lines
    from scenarios.run.results import check_output_dir, new_run_dir
    from vehicle_model.errors import InputError

    if out is not None:
        check_output_dir(out)
    if rigs is not None:
        given = [name for name, value in (("RECORDING", recording), ("--rig", rig), ("--signals", signals)) if value]
        if given:
            raise InputError(f"--rigs names each rig's recording and signals; {', '.join(given)}: not with --rigs")
        _estimate_rigs(rigs, out, force, refinement, seed, rear_point, zero_slip_grade, folder_poses, plots)
        return
    if recording is None or rig is None:
        raise InputError("offtrack estimate needs RECORDING and --rig RIG.yaml, or --rigs RIGS.yaml")
    inputs = resolve_inputs(
        recording,
        rig=rig,
        calibration=calibration,
        calib=calib,
        right_video=right_video,
        times=times,
        left_topic=left_topic,
        right_topic=right_topic,
        pair_tolerance=pair_tolerance,
        signals=signals,
        reference=reference,
        reference_format=reference_format,
        reference_offtracking=reference_offtracking,
        use_folder_poses=folder_poses,
        refinement=refinement,
        seed=seed,
        rear_point=rear_point,
        zero_slip_grade=zero_slip_grade,
    )
    run_dir = new_run_dir(out, f"recording-{recording.resolve().name}", force=force)
    with Progress(console=console, transient=True) as bar:
        task = bar.add_task(escape(f"estimating on {recording.name}"), total=len(inputs.recording.slots))
        metrics = estimate_recording(
            inputs, run_dir, plots=plots, progress=lambda done, _: bar.update(task, completed=done)
        )
    print_summary(metrics, run_dir)
    for line in recording_lines(metrics):
        console.print(escape(line))
    exit_for_status(metrics)


def _estimate_rigs(
    rigs: Path,
    out: Path | None,
    force: bool,
    refinement: int,
    seed: int,
    rear_point: str,
    zero_slip_grade: str,
    folder_poses: bool,
    plots: bool,
) -> None:
    """``offtrack estimate --rigs``: every rig's unit estimated (:mod:`scenarios.recorded.rigs`)."""
    from rich.progress import Progress

    from scenarios.recorded.rigs import estimate_rigs, load_rigs, rigs_lines
    from scenarios.run.results import new_run_dir

    inputs = load_rigs(
        rigs,
        refinement=refinement,
        seed=seed,
        rear_point=rear_point,
        zero_slip_grade=zero_slip_grade,
        use_folder_poses=folder_poses,
    )
    run_dir = new_run_dir(out, f"recording-{rigs.resolve().stem}", force=force)
    with Progress(console=console, transient=True) as bar:
        task = bar.add_task(escape(f"estimating on {rigs.name}"), total=None)
        summary = estimate_rigs(
            inputs, run_dir, plots=plots, progress=lambda done, total: bar.update(task, completed=done, total=total)
        )
    console.print(escape(f"{run_dir}: {summary['status']} — {summary['message']}"))
    for line in rigs_lines(summary):
        console.print(escape(line))
    exit_for_status(summary)


@handled
def vo_eval(
    sequence: Annotated[Path, typer.Argument(help="KITTI-odometry folder (image_0/, image_1/, times.txt).")],
    poses: Annotated[
        Path | None, typer.Option(help="The left camera's poses, KITTI format (default poses.txt).")
    ] = None,
    calibration: Annotated[Path | None, typer.Option(help="OpenCV YAML of offtrack calibrate (raw images).")] = None,
    calib: Annotated[Path | None, typer.Option(help="KITTI calib.txt (default: the folder's).")] = None,
    refinement: RefinementOption = 2,
    seed: OdometrySeedOption = 0,
    out: Annotated[Path | None, typer.Option(help="Write vo_eval.json and drift.png here.")] = None,
    force: ForceOfftrackFilesOption = False,
    as_json: JsonOption = False,
) -> None:
    """The visual odometry on a KITTI-format sequence with poses: KITTI metric, per-frame error, drift plot."""
    from rich.progress import Progress

    from scenarios.recorded.vo_eval import evaluate_vo, plot_drift, result_lines
    from scenarios.run.json_output import strict_json, write_json
    from scenarios.run.results import check_output_dir, new_run_dir

    if out is not None:
        check_output_dir(out)
    with Progress(console=console, transient=True, disable=as_json) as bar:
        task = bar.add_task(escape(f"odometry on {sequence.name}"), total=None)
        result, arrays = evaluate_vo(
            sequence,
            poses=poses,
            calibration=calibration,
            calib=calib,
            refinement=refinement,
            seed=seed,
            progress=lambda done, total: bar.update(task, completed=done, total=total),
        )
    if out is not None:
        run_dir = new_run_dir(out, "vo-eval", force=force)
        write_json(run_dir / "vo_eval.json", result)
        plot_drift(run_dir / "drift.png", result, arrays)
    if as_json:
        print(strict_json(result, indent=None))
        return
    for line in result_lines(result):
        console.print(escape(line))


@handled
def calibrate(
    scenario: Annotated[
        str | None, typer.Argument(help="Catalogue name or YAML file: its rendered camera is calibrated.")
    ] = None,
    out: Annotated[Path | None, typer.Option(help="Directory for calibration.yaml and residuals.json.")] = None,
    set_: Annotated[
        list[str] | None, typer.Option("--set", help="Any config field, e.g. --set camera.calibration.views=30.")
    ] = None,
    seed: Annotated[int | None, typer.Option(help="Seed of the target poses and the noise.", min=0)] = None,
    force: ForceOfftrackFilesOption = False,
    images: Annotated[
        Path | None, typer.Option(help="Folder of photos of a board: left*/right* files, or left/ and right/ folders.")
    ] = None,
    left: Annotated[str | None, typer.Option(help="Glob of the left photos (with --right).")] = None,
    right: Annotated[str | None, typer.Option(help="Glob of the right photos (with --left).")] = None,
    pattern: Annotated[str, typer.Option(help="Board: chessboard or charuco.")] = "chessboard",
    corners: Annotated[
        str, typer.Option(help="Inner corners COLSxROWS (a ChArUco board has one more square).")
    ] = "9x6",
    square: Annotated[float, typer.Option(help="Side of a square [m].")] = 0.025,
    marker: Annotated[float | None, typer.Option(help="ChArUco marker side [m] (default 0.75 × square).")] = None,
    dictionary: Annotated[str, typer.Option(help="ChArUco ArUco dictionary (OpenCV name).")] = "DICT_4X4_50",
    min_views: Annotated[int, typer.Option(help="Fewest views with the board in both photos.")] = 5,
    alpha: Annotated[float, typer.Option(help="stereoRectify's free scaling: 0 valid pixels only, 1 all.")] = 0.0,
    corner_window: Annotated[
        int | None,
        typer.Option(help="cornerSubPix half-window [px] for all corners (default: one per corner, 2–11 px)."),
    ] = None,
    reject_outliers: Annotated[
        bool, typer.Option("--reject-outliers/--keep-outliers", help="Reject views whose RMS is far above the median.")
    ] = True,
) -> None:
    """Calibrate a stereo camera (OpenCV): from photos of a board (--images or --left/--right), or the scenario's
    rendered camera on a rendered checkerboard. Writes calibration.yaml and residuals.json (and calibration.png).

    A run uses the file with --set camera.calibration.mode=file --set camera.calibration.file=OUT/calibration.yaml;
    offtrack estimate with --calibration OUT/calibration.yaml.
    """
    from vehicle_model.errors import InputError

    if out is None:
        raise InputError("--out DIR is required: the directory for calibration.yaml and residuals.json")
    if images is not None or left is not None or right is not None:
        if scenario is not None or set_ or seed is not None:
            raise InputError("photos (--images, --left/--right) take no SCENARIO, --set or --seed")
        _calibrate_photos(
            out,
            force,
            corners,
            images=images,
            left=left,
            right=right,
            pattern=pattern,
            square=square,
            marker=marker,
            dictionary=dictionary,
            min_views=min_views,
            alpha=alpha,
            corner_window=corner_window,
            reject_outliers=reject_outliers,
        )
        return
    if scenario is None:
        raise InputError("give a SCENARIO (its rendered camera), or photos with --images DIR or --left/--right GLOB")
    from scenarios.camera.build import calibration_target_rig, lenses, rig_from_config, run_calibration
    from scenarios.run.json_output import write_json
    from scenarios.run.results import new_run_dir
    from sensor.calibration_report import calibration_line, calibration_summary

    config = load_config(scenario, scenario_overrides(shortcut_pairs(seed=seed), None, None, set_))
    run_dir = new_run_dir(out, "calibration", force=force)
    rig = rig_from_config(config)
    with console.status("calibrating: imaging the target and solving"):
        result = run_calibration(rig, config)
    path = result.write(run_dir / "calibration.yaml")
    summary = calibration_summary(result, calibration_target_rig(rig, config), *lenses(config))
    write_json(run_dir / "residuals.json", summary)
    console.print(escape(f"calibration → {path}; residuals → {run_dir / 'residuals.json'}"))
    console.print(calibration_line(summary))


def _calibrate_photos(out: Path, force: bool, corners: str, **options: Any) -> None:
    """``offtrack calibrate`` on photos (:mod:`scenarios.recorded.calibrate`): files, then a table of the views."""
    from scenarios.recorded.calibrate import board_pattern, calibrate_from_photos, check_photos, report_lines
    from scenarios.run.results import check_output_dir, new_run_dir
    from sensor.board_calibration import check_options
    from vehicle_model.errors import InputError

    board = board_pattern(corners, **{k: options.pop(k) for k in ("pattern", "square", "marker", "dictionary")})
    check_options(**{k: options[k] for k in ("min_views", "alpha", "corner_window")})  # before any photo is read
    check_output_dir(out)
    check_photos(options["images"], options["left"], options["right"], board)  # before the directory is made
    made = not out.exists()
    run_dir = new_run_dir(out, "calibration", force=force)
    try:
        with console.status("calibrating: finding the board and solving"):
            calibration, report = calibrate_from_photos(run_dir, board, **options)
    except InputError:  # too few views with the board: no empty directory left behind
        if made and not any(run_dir.iterdir()):
            run_dir.rmdir()
        raise
    for line in report_lines(calibration, report, run_dir):
        console.print(line)


@handled
def animate(
    run_dir: RunDirArgument,
    out: Annotated[Path | None, typer.Option(help="Video file (.mp4 or .gif; default RUN_DIR/animation.mp4).")] = None,
    fps: Annotated[float, typer.Option(help="Video frames per second.", min=1.0, max=60.0)] = 10.0,
    speed: Annotated[float, typer.Option(help="Simulated seconds per video second.", min=0.1, max=100.0)] = 4.0,
    max_frames: Annotated[
        int | None, typer.Option(help="At most this many frames, spread over the run.", min=2)
    ] = None,
    camera: Annotated[
        bool | None, typer.Option(help="Show the left camera with its matched features (default: if it ran).")
    ] = None,
) -> None:
    """Animate a run from its directory: plan view, off-tracking traces and, for camera runs, the camera image."""
    from rich.progress import Progress

    from scenarios.export.animation import animate_run
    from scenarios.recorded.report import is_recorded_run

    recorded = is_recorded_run(run_dir)  # offtrack estimate's run
    if not recorded and not (run_dir / "config.yaml").is_file():
        from vehicle_model.errors import InputError

        raise InputError(f"RUN_DIR {run_dir} holds no config.yaml: give the directory of an offtrack run")
    if recorded:
        from scenarios.recorded.animation import animate_recorded_run as animate_run  # type: ignore[no-redef]
    with Progress(console=console, transient=True) as bar:
        task = bar.add_task("animating", total=None)
        path = animate_run(
            run_dir,
            out,
            fps=fps,
            max_frames=max_frames,
            speed=speed,
            camera=camera,
            progress=lambda done, total: bar.update(task, completed=done, total=total),
        )
    console.print(escape(f"animation → {path}"))
