"""``offtrack bench rigs``: its figures from the repetitions, its refusal of a bad repetition count, and (slow) one
short run of the two rigs by one render process."""

from __future__ import annotations

import pytest

from scenarios.bench.rigs import bench_rigs, rigs_figures
from vehicle_model.errors import InputError


def _run(ceiling_s: float, wall_s: float) -> dict[str, float]:
    # render CPU 0.8 s, this process 0.4 s of which its main thread 0.1 s (OpenCV's threads the rest)
    return {
        "ceiling_s": ceiling_s,
        "ceiling_render_cpu_s": 0.72,
        "wall_s": wall_s,
        "render_cpu_s": 0.8,
        "main_cpu_s": 0.4,
        "main_thread_cpu_s": 0.1,
        "vo_s": 0.3,
        "mask_s": 0.05,
    }


def test_the_ratios_are_medians_of_each_repetitions_own_ratio_and_count_every_thread() -> None:
    # 9 frames in the ceiling, 10 in the loop: loop/ceiling fps per run 5/9, 10/4.5, 10/9
    runs = [_run(1.0, 2.0), _run(2.0, 1.0), _run(1.0, 1.0)]
    figures = rigs_figures(runs, frames=9, cores=2)
    assert figures["loop_to_ceiling_runs"] == pytest.approx([5 / 9, 20 / 9, 10 / 9], rel=1e-12)
    assert figures["loop_to_ceiling"] == pytest.approx(10 / 9, rel=1e-12)  # not median loop / median ceiling (1.11)
    assert figures["ceiling_fps"] == pytest.approx(9.0) and figures["loop_fps"] == pytest.approx(10.0)
    # render CPU over render + this process's CPU, every thread: 0.8 / 1.2, not 0.8 / 0.9 with the main thread's
    assert figures["cpu_bound_loop_to_ceiling"] == pytest.approx(2 / 3, rel=1e-12)
    assert figures["main_cpu_ms_per_frame"] == pytest.approx(40.0) and figures[
        "main_thread_cpu_ms_per_frame"
    ] == pytest.approx(10.0)
    assert figures["ceiling_render_cpu_ms_per_frame"] == pytest.approx(80.0)
    assert figures["cpu_bound_fps"] == pytest.approx(2 * 10 / 1.2)


def test_a_repetition_count_below_one_is_refused_before_any_work() -> None:
    with pytest.raises(InputError, match=r"^repeats = 0: .*1 or more$"):
        bench_rigs(frames=5, repeats=0)


@pytest.mark.slow
def test_two_rigs_render_and_run_pipelined() -> None:
    result = bench_rigs(frames=5, repeats=2)
    assert result["repeats"] == 2 and len(result["loop_to_ceiling_runs"]) == 2
    assert result["rigs"] == ["towed unit 1, psi_c2v 270 deg", "towed unit 2, psi_c2v 180 deg"]
    assert 0.0 < result["cpu_bound_loop_to_ceiling"] < 1.0 and result["loop_fps"] > 0.0
    assert result["main_cpu_ms_per_frame"] >= result["main_thread_cpu_ms_per_frame"] > 0.0
