"""``offtrack bench render``: stereo rendering speed on a scenario's default world."""

from __future__ import annotations

import os
import platform
import time
from typing import Any

import numpy as np

from sensor.camera import StereoRig
from vehicle_model.geometry import CombinationPose

from ..camera.build import stereo_camera, world_for_scenario
from ..config import load_scenario
from ..setup.build import build_scenario


def bench_render(
    duration_frames: int = 50,
    scenario: str = "roundabout-3",
    antialias: bool = False,
    scenery_density: float = 1.0,
    field: bool = True,
    supersample: int = 1,
) -> dict[str, Any]:
    """Rendering speed of stereo pairs on a scenario's default world, at the default 1344 × 391.

    The cameras ride the reference path at the scenario's cornering speed and camera rate, from
    the start of the manoeuvre (the tractor's CG on the path, the trailer in line): the same
    world and viewpoints a run would render, without paying for the simulation.

    Returns
    -------
    dict
        ``pairs_per_s``, ``ms_per_pair`` (mean) and ``ms_per_pair_median``, ``width``, ``height``,
        ``triangles`` (in the world; instanced objects outside the view are skipped), the per-pair
        breakdown ``ms_cull`` (instance culling and scene upkeep), ``ms_submit`` (Python/pyrender
        and llvmpipe's vertex work while issuing draw calls), ``ms_draw`` (waiting for llvmpipe's
        rasteriser to finish), ``ms_readback`` (resolve and ``glReadPixels``), ``ms_grey`` (RGBA →
        grey and row flip), plus ``world_build_s``, ``first_pair_s`` (context creation and
        texture upload), ``cpu_ms_per_pair`` (CPU time of all threads: llvmpipe rasterises on
        every core, so on a busy machine the wall time grows while this stays) and the OpenGL
        renderer string. With ``field``, the same poses are rendered again under field conditions
        (a low sun with baked shadows, sky, glare and the lagging auto-exposure,
        :meth:`sensor.lighting.Lighting.field`) between two blocks of ideal pairs (the process has
        one GL context; switching scenes re-uploads them, so pairs are not interleaved):
        ``field_ms_per_pair`` (mean), ``field_ms_per_pair_median``, ``ideal_ms_per_pair_both_blocks``
        (median over both ideal blocks) and ``field_ratio`` (field over ideal, medians). With ``supersample`` > 1,
        the ideal pairs again, one sample a pixel and ``supersample`` × ``supersample`` samples a pixel
        (:attr:`sensor.camera.StereoRig.supersample`) in alternating blocks of the same poses:
        ``supersample_ms_per_pair_median`` and ``supersample_cpu_ms_per_pair`` against ``plain_ms_per_pair_median``
        and ``plain_cpu_ms_per_pair`` (CPU of all threads), and ``supersample_ratio`` / ``supersample_cpu_ratio``.
    """
    config = load_scenario(scenario)
    setup = build_scenario(config)
    t0 = time.perf_counter()
    world = world_for_scenario(setup, scenery_density)
    build_s = time.perf_counter() - t0
    rig = StereoRig()
    renderer = stereo_camera(setup, ideal=True, rig=rig, world=world, antialias=antialias).renderer
    path = setup.path
    step = config.speed.cornering_kmh / 3.6 / config.rates.camera_hz
    s = path.turn_span[0] + step * np.arange(duration_frames + 1)
    x, y = np.interp(s, path.s, path.x), np.interp(s, path.s, path.y)
    h = np.interp(s, path.s, path.heading)
    t1 = time.perf_counter()
    renderer.render(CombinationPose(x[0], y[0], h[0], 0.0), frame=0)
    first_s = time.perf_counter() - t1
    renderer.reset_timings()
    times = []
    cpu0 = time.process_time()
    for k in range(1, duration_frames + 1):
        t = time.perf_counter()
        renderer.render(CombinationPose(x[k], y[k], h[k], 0.0), frame=k)
        times.append(time.perf_counter() - t)
    cpu_s = time.process_time() - cpu0
    times_a = np.array(times)
    tm = dict(renderer.timings)
    field_figures = _bench_field(renderer, setup, world, rig, (x, y, h), times) if field else {}
    if supersample > 1:
        field_figures |= _bench_supersample(renderer, setup, world, rig, (x, y, h), supersample)
    n = max(len(times), 1)
    info = renderer.gl_info
    return {
        "benchmark": "render",
        "scenario": scenario,
        "pairs": len(times),
        "pairs_per_s": float(len(times) / times_a.sum()),
        "ms_per_pair": float(1000.0 * times_a.mean()),
        "ms_per_pair_median": float(1000.0 * np.median(times_a)),
        "ms_per_pair_p90": float(1000.0 * np.percentile(times_a, 90)),
        "cpu_ms_per_pair": 1000.0 * cpu_s / max(len(times), 1),
        "width": rig.width,
        "height": rig.height,
        "triangles": world.triangle_count,
        "scenery_density": scenery_density,
        "antialias": antialias,
        "ms_cull": 1000.0 * tm.get("cull_s", 0.0) / n,
        "ms_submit": 1000.0 * tm.get("submit_s", 0.0) / n,
        "ms_draw": 1000.0 * tm.get("draw_s", 0.0) / n,
        "ms_readback": 1000.0 * tm.get("readback_s", 0.0) / n,
        "ms_grey": 1000.0 * tm.get("grey_s", 0.0) / n,
        "ms_effects": 1000.0 * tm.get("effects_s", 0.0) / n,
        "world_build_s": build_s,
        "first_pair_s": first_s,
        "gl_renderer": info["renderer"],
        "gl_version": info["version"],
        "pyopengl_platform": os.environ.get("PYOPENGL_PLATFORM", ""),
        "python": platform.python_version(),
        "cpu_count": os.cpu_count(),
        **field_figures,
    }


def _bench_field(
    renderer: Any, setup: Any, world: Any, rig: StereoRig, xyh: tuple, ideal_before: list[float]
) -> dict[str, Any]:
    """Field-conditions pairs against ideal ones on the same poses, interleaved (see :func:`bench_render`)."""
    from sensor.lighting import Lighting

    x, y, h = xyh
    lighting = Lighting.field()
    camera = stereo_camera(setup, ideal=True, rig=rig, lighting=lighting, world=world, antialias=renderer.antialias)
    field = camera.renderer
    t0 = time.perf_counter()
    field.render(CombinationPose(x[0], y[0], h[0], 0.0), frame=0)  # bakes the light, uploads the lit scene
    first_s = time.perf_counter() - t0
    # One scene per renderer in the context: switching scenes re-uploads them, so time blocks, not
    # alternate pairs: field, then ideal again (its median with the first ideal block's, before).
    field_t = []
    for k in range(1, len(x)):
        t = time.perf_counter()
        field.render(CombinationPose(x[k], y[k], h[k], 0.0), frame=k)
        field_t.append(time.perf_counter() - t)
    renderer.render(CombinationPose(x[0], y[0], h[0], 0.0), frame=0)  # switch back (re-upload), untimed
    ideal_t = list(ideal_before)
    for k in range(1, len(x)):
        t = time.perf_counter()
        renderer.render(CombinationPose(x[k], y[k], h[k], 0.0), frame=k)
        ideal_t.append(time.perf_counter() - t)
    ideal_m, field_m = float(np.median(ideal_t)), float(np.median(field_t))
    return {
        "field_lighting": {
            "sun_azimuth_deg": lighting.sun_azimuth_deg,
            "sun_elevation_deg": lighting.sun_elevation_deg,
        },
        "field_first_pair_s": first_s,
        "field_ms_per_pair": float(1000.0 * np.mean(field_t)),
        "field_ms_per_pair_median": 1000.0 * field_m,
        "ideal_ms_per_pair_both_blocks": 1000.0 * ideal_m,
        "field_ratio": field_m / ideal_m,
    }


def _bench_supersample(
    renderer: Any, setup: Any, world: Any, rig: StereoRig, xyh: tuple, samples: int
) -> dict[str, Any]:
    """Supersampled ideal pairs against one-sample ones on the same poses, in alternating blocks (each block's first
    pair, which resizes the framebuffer, untimed; see :func:`bench_render`)."""
    x, y, h = xyh
    fine = stereo_camera(
        setup, ideal=True, rig=rig.replace(supersample=samples), world=world, antialias=renderer.antialias
    ).renderer
    wall: dict[str, list[float]] = {"plain": [], "fine": []}
    cpu = {"plain": 0.0, "fine": 0.0}
    for name, r in (("plain", renderer), ("fine", fine), ("plain", renderer), ("fine", fine)):
        r.render(CombinationPose(x[0], y[0], h[0], 0.0), frame=0)
        c0 = time.process_time()
        for k in range(1, len(x)):
            t = time.perf_counter()
            r.render(CombinationPose(x[k], y[k], h[k], 0.0), frame=k)
            wall[name].append(time.perf_counter() - t)
        cpu[name] += time.process_time() - c0
    plain_m, fine_m = float(np.median(wall["plain"])), float(np.median(wall["fine"]))
    plain_cpu, fine_cpu = (1000.0 * cpu[name] / len(wall[name]) for name in ("plain", "fine"))
    return {
        "supersample": samples,
        "plain_ms_per_pair_median": 1000.0 * plain_m,
        "supersample_ms_per_pair_median": 1000.0 * fine_m,
        "plain_cpu_ms_per_pair": plain_cpu,
        "supersample_cpu_ms_per_pair": fine_cpu,
        "supersample_ratio": fine_m / plain_m,
        "supersample_cpu_ratio": fine_cpu / plain_cpu,
    }
