"""The co-simulation's dense kingpin path (``scenarios.loop.estimators.DensePath``): a ring of one buffer.

Its contract, checked against a direct implementation (a list of chunks, stacked on demand): the kept path is
the newest whole chunks, as few as still span ``keep_length`` (at least two), oldest first.
"""

from __future__ import annotations

import numpy as np
import pytest

from scenarios.loop.estimators import DensePath


def _chunk_lengths(chunks: list[np.ndarray]) -> list[float]:
    out = []
    for k, c in enumerate(chunks):
        joined = np.vstack([chunks[k - 1][-1:], c]) if k else c
        out.append(float(np.hypot(*np.diff(joined, axis=0).T).sum()) if len(joined) > 1 else 0.0)
    return out


@pytest.mark.parametrize("capacity", [8, 64, 4096])
def test_the_kept_path_is_the_newest_whole_chunks_spanning_the_keep_length(capacity: int) -> None:
    rng = np.random.default_rng(1)
    keep = 12.0
    path = DensePath(keep, capacity=capacity)
    chunks: list[np.ndarray] = []
    lengths: list[float] = []
    first = 0  # index of the oldest kept chunk, by the direct definition
    p = np.zeros(2)
    for k in range(1500):
        m = 1 if k % 5 == 0 else 11  # single points (start, model-only ticks) and whole trajectories
        pts = p + np.cumsum(rng.normal(0.05, 0.02, (m, 2)), axis=0)
        p = pts[-1]
        chunks.append(pts)
        lengths.append(_chunk_lengths(chunks[-2:])[-1])
        path.extend(pts)
        total = sum(lengths[first:])
        while len(chunks) - first > 2 and total - lengths[first] > keep:
            total -= lengths[first]
            first += 1
        expected = np.vstack(chunks[first:])
        got = path.array()
        assert np.array_equal(got, expected), k
    assert sum(lengths[first + 1 :]) <= keep < sum(lengths[first:])  # as few chunks as still span keep_length
    assert not path.array().flags.writeable  # a view of the buffer: callers cannot corrupt it
