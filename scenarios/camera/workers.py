"""Render workers: spawned processes that render the stereo pairs while the co-simulation runs the odometry.

A pipelined camera run renders frame ``n + 1`` in one worker while the co-simulation process runs the
visual odometry and VISO-OT on frame ``n``, so both cores work (:mod:`.delivery` says when each estimate may
reach the controller). Workers take the frames in turn (frame ``n`` goes to worker ``n mod workers``); with
the default latency of one frame period up to two frames are in flight. The default is one worker
(:data:`DEFAULT_WORKERS`); with two, the second renders the next frame while the first one's pair waits for
the odometry.

Each worker is a ``spawn``-ed process (never a fork: OpenGL contexts do not survive one) that rebuilds the scenario
from its configuration and owns one :class:`sensor.stereo_camera.StereoCamera` (:func:`.build.stereo_camera`), hence
one renderer, as the rendering rules of :mod:`sensor.renderer` demand. The co-simulation sends the frame number, the
:class:`~vehicle_model.geometry.CombinationPose` and the frame's mount flex down a pipe; the worker renders the pair
and, unless the development must see the frames in order (auto-exposure,
:attr:`sensor.stereo_camera.StereoCamera.develops_in_order`), develops it too, and answers with the render time and
CPU time, then the left and right images as raw bytes (their cost: ``benchmarks/README.md``). Workers can run at a
lower priority than the co-simulation (:data:`RENDER_NICENESS`, off by default), whose odometry is the critical
path, and with two or more of them llvmpipe rasterises in each worker's own thread (:data:`RENDER_THREADS`). A
worker ignores Ctrl-C (the co-simulation process stops it, keeping the data) and exits when its pipe closes; a
thread of its own, the first thing it starts, ends it within :data:`PARENT_CHECK_S` of its parent's death, so it
never outlives the run, even after a SIGKILL of the run that lands while it builds its world or renders.
A worker that raises sends the traceback back; one that dies or stops answering is a
:class:`CameraWorkerError` naming the worker, the frame and the exit code, never a hang.
"""

from __future__ import annotations

import ctypes
import math
import multiprocessing
import os
import signal
import sys
import threading
import time
import traceback
from multiprocessing.connection import Connection, wait
from typing import Any

import numpy as np

from sensor.camera import Misalignment
from vehicle_model.errors import OfftrackError
from vehicle_model.geometry import ChainPose, CombinationPose, chain_pose

DEFAULT_WORKERS = 1
"""Render workers of a pipelined run. One: its llvmpipe threads use the core the odometry leaves free, where two
workers would keep two OpenGL contexts and texture caches (``offtrack bench loop`` compares them; figures in
``benchmarks/README.md``)."""
ANSWER_TIMEOUT_S = 300.0
"""Longest wait for one worker's answer [s]; the first includes building the world and the OpenGL context."""
MIN_PIPELINED_FRAMES = 150
"""Shortest run (camera frames) pipelined by default: below it the workers' start-up costs more than they save."""
STOP_TIMEOUT_S = 2.0
"""How long a worker gets to exit on request before it is terminated [s]."""
RENDER_THREADS = "0"
"""llvmpipe rasteriser threads of each of two or more workers (``LP_NUM_THREADS`` unless set; "0": in the worker's
own thread). Such workers already render two frames at once beside the odometry, so threads inside each would
only add their synchronisation cost (figures in ``benchmarks/README.md``); a single worker, and a serial run, keep
llvmpipe's default (one thread per core)."""
RENDER_NICENESS = 0
"""How much lower a worker's scheduling priority is than the co-simulation's (``nice`` increment). The
co-simulation process is the critical path (each estimate waits for its odometry); a positive increment
lets it keep its core while the renders take what is left. Off by default (``offtrack bench loop`` at both
increments; figures in ``benchmarks/README.md``)."""


PARENT_CHECK_S = 0.2
"""How often a worker checks that the process that started it is still there [s]; it exits when it is not."""


class CameraWorkerError(OfftrackError, RuntimeError):
    """A render worker died, raised, or stopped answering: the run cannot go on."""


def _exit_with_parent(parent: int) -> None:
    """End this worker at once when ``parent`` (the co-simulation process) is no longer its parent: it died."""
    while True:
        if os.getppid() != parent:
            os._exit(1)
        time.sleep(PARENT_CHECK_S)


def _die_with_parent(parent: int) -> None:
    """Have the kernel SIGKILL this process when the thread that started it ends (Linux's ``PR_SET_PDEATHSIG``,
    ``prctl(2)``), so that the worker ends with its co-simulation process even while its own Python threads cannot
    run (a long C call holding the interpreter's lock, e.g. while its world or OpenGL context is built); exits at
    once if ``parent`` is already gone. Elsewhere, or where ``prctl`` is not found, it does nothing: the thread of
    :func:`_exit_with_parent` remains."""
    if not sys.platform.startswith("linux"):
        return
    try:
        prctl = ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return
    pr_set_pdeathsig = 1  # <linux/prctl.h>
    if prctl(pr_set_pdeathsig, int(signal.SIGKILL), 0, 0, 0) != 0:
        return
    if os.getppid() != parent:  # it died before the request was made
        os._exit(1)


def _worker_main(
    config: Any,
    conn: Connection,
    threads: str | None = None,
    parent: int | None = None,
    rig_index: int = 0,
    terrain: Any = None,
    die_with_parent: bool = False,
) -> None:
    """Body of one render worker (runs in the spawned process); ``threads``: llvmpipe's, unless set; ``parent``: the
    process id of the co-simulation process, whose death ends the worker (:func:`_exit_with_parent`, and
    :func:`_die_with_parent` when ``die_with_parent``: the worker was started by that process's main thread)."""
    if parent is not None:  # first of all: a world being built, or a frame being rendered, is no one's any more
        if die_with_parent:
            _die_with_parent(parent)
        threading.Thread(target=_exit_with_parent, args=(parent,), daemon=True, name="offtrack-parent-watch").start()
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the co-simulation process handles Ctrl-C and stops us
    if hasattr(signal, "pthread_sigmask"):
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})  # started blocked (RenderWorkers)
    if threads is not None:
        os.environ.setdefault("LP_NUM_THREADS", threads)  # read when the OpenGL context is created
    if RENDER_NICENESS and hasattr(os, "nice"):
        try:
            os.nice(RENDER_NICENESS)  # before the renderer's threads start: they inherit it
        except OSError:
            pass
    try:
        from ..portable_arithmetic import apply as apply_portable_arithmetic
        from ..setup.build import build_scenario
        from .build import stereo_camera

        apply_portable_arithmetic()  # OFFTRACK_PORTABLE_ARITHMETIC=1 (inherited): as the co-simulation process

        camera = stereo_camera(build_scenario(config), rig_index=rig_index, terrain=terrain)
    except BaseException:
        _send_error(conn, traceback.format_exc())
        return
    while True:
        try:
            job = conn.recv()
        except (EOFError, OSError):
            return  # the co-simulation is gone
        if job is None:
            return
        frame, pose, flex = job
        try:
            t0, cpu0 = time.perf_counter(), time.process_time()
            rotation = None if flex is None else Misalignment(*flex)
            raw = camera.render(pose, frame, right_rotation=rotation)
            left, right = (raw.left, raw.right) if camera.develops_in_order else camera.develop(raw, frame)
            answer = (frame, time.perf_counter() - t0, time.process_time() - cpu0, (left.shape, left.dtype.str))
            conn.send(answer)
            conn.send_bytes(np.ascontiguousarray(left).reshape(-1))
            conn.send_bytes(np.ascontiguousarray(right).reshape(-1))
        except (BrokenPipeError, EOFError, OSError):
            return
        except BaseException:
            _send_error(conn, traceback.format_exc())
            return


def _receive_image(conn: Connection, layout: tuple[tuple[int, int], str]) -> np.ndarray:
    """One image sent as raw bytes (grey levels, or radiance before the in-order exposure), in its own array."""
    shape, dtype = layout
    image = np.empty(shape, dtype=np.dtype(dtype))
    conn.recv_bytes_into(memoryview(image.reshape(-1)))
    return image


def _send_error(conn: Connection, text: str) -> None:
    try:
        conn.send(("error", text))
    except (BrokenPipeError, EOFError, OSError):
        pass


class RenderWorkers:
    """A few spawned render workers, frames dealt round-robin, answers read in frame order.

    Parameters
    ----------
    config
        The scenario configuration (:class:`~scenarios.config.ScenarioConfig`); each worker rebuilds the
        scenario from it.
    workers
        Number of worker processes.
    rig_index
        Which rig of the configuration the workers render (:class:`.delivery.CameraFeed`).
    terrain
        The ground the workers' worlds are draped on (:func:`.build.stereo_camera`); pickled to each worker.
        ``None``: the level road.

    Attributes
    ----------
    cpu_s : float
        CPU time the workers spent rendering the frames answered so far (all their threads) [s].
    wait_s : float
        Wall time the co-simulation spent waiting for the workers' answers [s].
    """

    def __init__(self, config: Any, workers: int = DEFAULT_WORKERS, rig_index: int = 0, terrain: Any = None) -> None:
        if workers < 1:
            raise ValueError(f"workers = {workers} must be at least 1")
        ctx = multiprocessing.get_context("spawn")
        self._procs: list[Any] = []
        self._conns: list[Connection] = []
        self.cpu_s = 0.0
        self.wait_s = 0.0
        self._outstanding: dict[int, int] = {}  # frame → worker
        # Start the workers with Ctrl-C blocked (the mask is inherited through exec, and the worker ignores
        # SIGINT before it unblocks it), so that a Ctrl-C at the terminal cannot kill a worker that is still
        # importing. A Ctrl-C meant for this process is held meanwhile and arrives when the block ends —
        # never lost (ignoring it here instead would let a run go on after Ctrl-C).
        on_main_thread = threading.current_thread() is threading.main_thread()
        block = on_main_thread and hasattr(signal, "pthread_sigmask")
        previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT}) if block else None
        try:
            try:
                for i in range(workers):
                    here, there = ctx.Pipe(duplex=True)
                    threads = RENDER_THREADS if workers >= 2 else None
                    proc = ctx.Process(
                        target=_worker_main,
                        # the kernel's death signal follows the starting thread: only the main thread's lasts the run
                        args=(config, there, threads, os.getpid(), rig_index, terrain, on_main_thread),
                        name=f"offtrack-render-{i}",
                        daemon=True,
                    )
                    proc.start()
                    there.close()  # so that the worker's death reads as end-of-file here
                    self._procs.append(proc)
                    self._conns.append(here)
            finally:
                if previous is not None:
                    signal.pthread_sigmask(signal.SIG_SETMASK, previous)  # a held Ctrl-C is raised now
        except BaseException:
            self.close()
            raise

    def __len__(self) -> int:
        return len(self._procs)

    def submit(self, frame: int, pose: CombinationPose | ChainPose, right_rotation: Misalignment | None = None) -> None:
        """Have worker ``frame mod workers`` render frame ``frame`` at the combination pose ``pose`` (every unit's
        articulation: the other units are drawn).

        ``right_rotation``: the frame's mount flex (or ``None``).
        """
        i = frame % len(self._conns)
        flex = None if right_rotation is None else (right_rotation.roll, right_rotation.pitch, right_rotation.yaw)
        try:
            full = chain_pose(pose)
            angles = tuple(float(a) for a in full.angles)
            self._conns[i].send((frame, ChainPose(float(full.x), float(full.y), float(full.psi1), angles), flex))
        except (BrokenPipeError, EOFError, OSError):
            raise self._failure(i, frame, "") from None
        self._outstanding[frame] = i

    def ready(self, frame: int) -> bool:
        """Whether frame ``frame``'s answer can be read without waiting."""
        i = self._outstanding.get(frame)
        return i is not None and self._conns[i].poll()

    def result(self, frame: int) -> tuple[np.ndarray, np.ndarray, float, float]:
        """Left and right images, render wall time and CPU time [s] of ``frame`` (waits for them).

        Frames of one worker must be read in the order they were submitted.

        Raises
        ------
        CameraWorkerError
            The worker died, raised, or gave no answer within :data:`ANSWER_TIMEOUT_S`.
        """
        i = self._outstanding.pop(frame)
        conn, proc = self._conns[i], self._procs[i]
        t0 = time.perf_counter()
        while not conn.poll():
            ready = wait([conn, proc.sentinel], timeout=max(ANSWER_TIMEOUT_S - (time.perf_counter() - t0), 0.0))
            if not ready:
                raise CameraWorkerError(
                    f"camera render worker {i} (pid {proc.pid}) gave no answer for frame {frame} "
                    f"within {ANSWER_TIMEOUT_S:g} s"
                )
            if conn not in ready and proc.sentinel in ready:
                proc.join(0.1)
                raise self._failure(i, frame, "")
        try:
            answer = conn.recv()
            if answer[0] == "error":
                raise self._failure(i, frame, answer[1])
            got, render_s, cpu_s, shape = answer
            left, right = _receive_image(conn, shape), _receive_image(conn, shape)
        except (EOFError, OSError):
            proc.join(0.5)
            raise self._failure(i, frame, "") from None
        self.wait_s += time.perf_counter() - t0
        if got != frame:  # cannot happen while frames are read in order
            raise CameraWorkerError(f"camera render worker {i} answered frame {got} for frame {frame}")
        self.cpu_s += cpu_s
        return left, right, render_s, cpu_s

    def _failure(self, i: int, frame: int, worker_traceback: str) -> CameraWorkerError:
        proc = self._procs[i]
        if worker_traceback:
            last = worker_traceback.strip().splitlines()[-1]
            return CameraWorkerError(
                f"camera render worker {i} (pid {proc.pid}) failed at frame {frame}: {last}\n{worker_traceback}"
            )
        code = proc.exitcode
        how = "is gone" if code is None else f"died with exit code {code}"
        if code is not None and code < 0:
            how += f" ({signal.Signals(-code).name})"
        return CameraWorkerError(f"camera render worker {i} (pid {proc.pid}) {how} at frame {frame}")

    def close(self) -> None:
        """Stop every worker: close the pipes (a worker exits on end-of-file or a broken pipe), wait
        :data:`STOP_TIMEOUT_S`, then terminate and kill. Safe to call twice."""
        for conn in self._conns:
            conn.close()
        deadline = time.monotonic() + STOP_TIMEOUT_S
        for proc in self._procs:
            proc.join(max(deadline - time.monotonic(), 0.0))
            if proc.is_alive():
                proc.terminate()
                proc.join(1.0)
            if proc.is_alive():
                proc.kill()
                proc.join(1.0)
        self._procs, self._conns, self._outstanding = [], [], {}


def default_workers(frames: float = math.inf) -> int:
    """Render workers a run of about ``frames`` camera frames uses when not told.

    ``OFFTRACK_CAMERA_WORKERS`` if set (0: serial); else :data:`DEFAULT_WORKERS` on a machine with two or
    more cores, in the main process (a study's worker process shares the cores with its siblings and
    renders in-process) and for runs of :data:`MIN_PIPELINED_FRAMES` frames or more (the workers take a
    few seconds to start); else 0.
    """
    value = os.environ.get("OFFTRACK_CAMERA_WORKERS", "").strip()
    if value:
        try:
            return max(0, int(value))
        except ValueError:
            raise ValueError(f"OFFTRACK_CAMERA_WORKERS = {value!r} must be a whole number (0: serial)") from None
    if frames <= 0:
        return 0
    if (os.cpu_count() or 1) >= 2 and multiprocessing.parent_process() is None and frames >= MIN_PIPELINED_FRAMES:
        return DEFAULT_WORKERS
    return 0
