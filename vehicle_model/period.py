"""One control period of the vehicle model in one compiled call: the RK4 steps and the state checks.

The simulator's hot path. Casadi's Python ``Function`` call costs a few microseconds — as much as a
handful of RK4 steps — so the C below, appended to the generated model (:mod:`.codegen`), loops over
the compiled ``rk4_step`` itself, checks the inputs and the new state (finite, inside the limits)
and commits the state only when it is good. Python calls it through :mod:`ctypes` with a single
pointer: everything it reads and writes lives in one preallocated array, the *context*, laid out as

========================  ================================================================
entries                   content
========================  ================================================================
``0``                     number of RK4 steps ``n``
``1``                     step length ``h`` [s]
``2``                     number of state limits ``L``
``3``                     number of leading inputs checked for finiteness (steer, drive force)
``x``  (``n_states``)     state at the start of the period; the end state once it passed
``u``  (``n_inputs``)     inputs held over the period
``x_end`` (``n_states``)  state at the end of the period, good or not
``limits`` (``2·L``)      pairs (state index, largest magnitude)
``trajectory``            state after every RK4 step, ``n × n_states`` (step-major)
========================  ================================================================

Each step is the same compiled ``rk4_step`` that casadi's ``mapaccum`` integrator calls, with the
same arguments, so the states are bit-for-bit those of :meth:`VehicleModel.integrator`.
"""

from __future__ import annotations

import ctypes
import functools
from collections.abc import Callable
from pathlib import Path

import casadi as ca
import numpy as np

HEADER = 4
"""Context entries before the state (see the module docstring)."""

SYMBOL = "offtrack_period"
"""Name of the exported C function."""

OK, BAD_INPUT, DIVERGED, STEP_FAILED = 0, 1, 2, 3
"""Return codes of the C function: committed; a checked input is not finite (nothing integrated);
the end state is not finite or exceeds a limit (``x`` kept, ``x_end`` holds it); ``rk4_step`` failed."""

_TEMPLATE = """
/* offtrack: one control period (vehicle_model/period.py; context layout in its docstring). */
#include <math.h>
#define OT_NX {nx}
#define OT_NU {nu}
#define OT_HEADER {header}
CASADI_SYMBOL_EXPORT int {symbol}(casadi_real* ctx) {{
  const casadi_int n = (casadi_int) ctx[0];
  const casadi_real h = ctx[1];
  const casadi_int n_limits = (casadi_int) ctx[2];
  const casadi_int n_checked = (casadi_int) ctx[3];
  casadi_real* x = ctx + OT_HEADER;
  const casadi_real* u = x + OT_NX;
  casadi_real* x_end = x + OT_NX + OT_NU;
  const casadi_real* limits = x_end + OT_NX;
  casadi_real* traj = x_end + OT_NX + 2 * n_limits;
  const casadi_real* arg[{sz_arg}];
  casadi_real* res[{sz_res}];
  casadi_int iw[{sz_iw}];
  casadi_real w[{sz_w}];
  const casadi_real* prev = x;
  casadi_int i, k;
  for (i = 0; i < n_checked; ++i) {{
    if (!isfinite(u[i])) return {bad_input};
  }}
  for (k = 0; k < n; ++k) {{
    casadi_real* next = traj + k * OT_NX;
    arg[0] = prev;
    arg[1] = u;
    arg[2] = &h;
    res[0] = next;
    if ({step}(arg, res, iw, w, 0)) return {step_failed};
    prev = next;
  }}
  for (i = 0; i < OT_NX; ++i) x_end[i] = prev[i];
  for (i = 0; i < OT_NX; ++i) {{
    if (!isfinite(x_end[i])) return {diverged};
  }}
  for (i = 0; i < n_limits; ++i) {{
    if (fabs(x_end[(casadi_int) limits[2 * i]]) > limits[2 * i + 1]) return {diverged};
  }}
  for (i = 0; i < OT_NX; ++i) x[i] = x_end[i];
  return {ok};
}}
"""


def period_source(step: ca.Function, n_states: int, n_inputs: int) -> str:
    """C source of the control-period function around the generated ``step`` ``(x, u, h) → x⁺``.

    Appended to the file casadi generates for ``step`` (:func:`vehicle_model.codegen.compile_library`).
    """
    return _TEMPLATE.format(
        nx=n_states,
        nu=n_inputs,
        header=HEADER,
        symbol=SYMBOL,
        step=step.name(),
        sz_arg=max(step.sz_arg(), 3),
        sz_res=max(step.sz_res(), 1),
        sz_iw=max(step.sz_iw(), 1),
        sz_w=max(step.sz_w(), 1),
        ok=OK,
        bad_input=BAD_INPUT,
        diverged=DIVERGED,
        step_failed=STEP_FAILED,
    )


def context_size(n_states: int, n_inputs: int, n_limits: int, substeps: int) -> int:
    """Length of a context array (module docstring)."""
    return HEADER + 2 * n_states + n_inputs + 2 * n_limits + substeps * n_states


@functools.lru_cache(maxsize=32)
def load_period(lib: Path) -> Callable[[int], int]:
    """The control-period function of the compiled library ``lib``: ``(address of a context) → return code``.

    Loaded once per library and process (every simulator of a vehicle shares it: it keeps no state).
    """
    fn = ctypes.CDLL(str(lib))[SYMBOL]
    fn.argtypes = [ctypes.c_void_p]
    fn.restype = ctypes.c_int
    return fn


def new_context(
    n_states: int, n_inputs: int, substeps: int, h: float, limits: list[tuple[int, float]], n_checked: int
) -> np.ndarray:
    """A zeroed context with its header and limits filled (module docstring)."""
    ctx = np.zeros(context_size(n_states, n_inputs, len(limits), substeps))
    ctx[:HEADER] = (substeps, h, len(limits), n_checked)
    start = HEADER + 2 * n_states + n_inputs
    ctx[start : start + 2 * len(limits)] = np.asarray(limits, dtype=float).ravel()
    return ctx


def context_views(ctx: np.ndarray, n_states: int, n_inputs: int, substeps: int) -> tuple[np.ndarray, ...]:
    """Views ``(x, u, x_end, trajectory)`` into a context; ``trajectory`` is flat, step-major."""
    n_limits = int(ctx[2])
    x0 = HEADER
    u0 = x0 + n_states
    e0 = u0 + n_inputs
    t0 = e0 + n_states + 2 * n_limits
    return ctx[x0:u0], ctx[u0:e0], ctx[e0 : e0 + n_states], ctx[t0 : t0 + substeps * n_states]
