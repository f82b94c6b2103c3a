"""Row-parallel passes: the chunks cover the batch, errors surface, a split gives the same numbers."""

import os
import threading
import time

import numpy as np
import pytest

from filters.core import threads
from filters.core.normal import box_muller
from filters.core.pcg64 import raw_words
from filters.core.threads import chunks, get_num_threads, matmul, num_threads, over_rows, set_num_threads


@pytest.mark.parametrize(("rows", "parts"), [(1, 1), (5, 2), (7, 3), (256, 2), (3, 8), (10, 10)])
def test_chunks_cover_the_rows_in_order(rows, parts):
    cs = chunks(rows, parts)
    assert len(cs) == min(rows, parts)
    assert cs[0][0] == 0 and cs[-1][1] == rows
    assert all(a[1] == b[0] for a, b in zip(cs, cs[1:], strict=False))
    sizes = [stop - start for start, stop in cs]
    assert max(sizes) - min(sizes) <= 1 and min(sizes) >= 1


def test_over_rows_splits_over_threads_and_covers_every_row():
    seen = np.zeros(100, dtype=int)
    names = set()

    def fn(start, stop):
        seen[start:stop] += 1
        names.add(threading.current_thread().name)
        time.sleep(0.01)  # without the GIL: a pool thread takes the next chunk meanwhile

    with num_threads(3, min_work=0):
        over_rows(100, 1, fn)
    assert (seen == 1).all()  # each row once: every chunk taken by one thread only
    assert len(names) >= 2 and threading.current_thread().name in names


def test_small_work_or_one_thread_stays_on_the_caller():
    calls = []
    with num_threads(4):  # the default threshold: 10 rows of 10 is far below it
        over_rows(10, 10, lambda a, b: calls.append((a, b, threading.current_thread().name)))
    with num_threads(1, min_work=0):
        over_rows(10, 10, lambda a, b: calls.append((a, b, threading.current_thread().name)))
    me = threading.current_thread().name
    assert calls == [(0, 10, me), (0, 10, me)]


def test_an_error_in_any_chunk_is_raised_after_all_chunks_ran():
    done = []

    def fn(start, stop):
        done.append(start)
        if start > 0:
            raise RuntimeError(f"chunk {start}")

    with num_threads(2, min_work=0), pytest.raises(RuntimeError, match="chunk [1-9]"):
        over_rows(100, 1, fn)
    assert sorted(done) == [start for start, _ in chunks(100, 2 * threads.CHUNKS_PER_THREAD)]


def test_thread_counts_are_validated_and_restored():
    before = get_num_threads()
    for bad in (0, -1, 1.5, True, "2"):
        with pytest.raises(ValueError, match="n must be a positive integer"):
            set_num_threads(bad)
    with pytest.raises(ValueError, match="min_work"), num_threads(before + 3, min_work=-1):
        pass
    assert get_num_threads() == before  # refused before anything changed
    with num_threads(5):
        assert get_num_threads() == 5
    assert get_num_threads() == before


def test_the_environment_variable_is_read_and_checked(monkeypatch):
    monkeypatch.setenv(threads.ENV_VAR, "3")
    assert threads._from_environment() == 3
    monkeypatch.setenv(threads.ENV_VAR, "")
    assert threads._from_environment() == threads.available_cores()
    for bad in ("0", "two"):
        monkeypatch.setenv(threads.ENV_VAR, bad)
        with pytest.raises(ValueError, match=threads.ENV_VAR):
            threads._from_environment()


@pytest.mark.skipif(not hasattr(os, "fork"), reason="needs fork")
def test_a_forked_child_makes_its_own_pool():
    with num_threads(2, min_work=0):
        over_rows(4, 1, lambda a, b: None)  # the parent's pool exists
        r, w = os.pipe()
        pid = os.fork()
        if pid == 0:  # pragma: no cover - child
            try:
                seen = np.zeros(4, dtype=int)

                def fn(a, b):
                    seen[a:b] += 1

                over_rows(4, 1, fn)
                os.write(w, b"ok" if (seen == 1).all() else b"no")
            finally:
                os._exit(0)
        os.close(w)
        answer = os.read(r, 2)
        os.waitpid(pid, 0)
    assert answer == b"ok"


def test_box_muller_is_the_same_on_any_split():
    words = np.random.default_rng(4).integers(0, 2**63, size=(37, 50), dtype=np.uint64)
    with num_threads(1):
        serial = box_muller(words, np.float32)
    with num_threads(3, min_work=0):
        split = box_muller(words, np.float32)
    np.testing.assert_array_equal(split, serial)


def test_raw_words_are_the_same_on_any_split():
    def gens():
        return [np.random.default_rng(s) for s in range(29)]

    a, b = gens(), gens()
    with num_threads(1):
        serial = raw_words(a, 40)
    with num_threads(4, min_work=0):
        split = raw_words(b, 40)
    np.testing.assert_array_equal(split, serial)
    assert [g.bit_generator.state for g in a] == [g.bit_generator.state for g in b]


@pytest.mark.parametrize(
    ("a_shape", "b_shape", "dtype"),
    [
        ((9, 9), (7, 9, 300), np.float32),
        ((7, 9, 9), (7, 9, 300), np.float64),
        ((7, 1, 300), (7, 300, 9), np.float32),
    ],
)
def test_matmul_split_equals_numpy(a_shape, b_shape, dtype):
    rng = np.random.default_rng(0)
    a, b = rng.standard_normal(a_shape).astype(dtype), rng.standard_normal(b_shape).astype(dtype)
    b_view = b.transpose(0, 2, 1).copy().transpose(0, 2, 1)  # a strided view, as a particle cloud
    with num_threads(3, min_work=0):
        for rhs in (b, b_view):
            np.testing.assert_array_equal(matmul(a, rhs), np.matmul(a, rhs))


def test_matmul_leaves_other_shapes_to_numpy():
    a, b = np.ones((3, 4)), np.ones((4, 2))
    np.testing.assert_array_equal(matmul(a, b), a @ b)
    with pytest.raises(ValueError):
        matmul(np.ones((2, 3, 4)), np.ones((5, 4, 2)))  # NumPy's broadcasting error


def test_a_pass_inside_a_chunk_stays_on_its_thread():
    inner = []

    def outer(start, stop):
        me = threading.current_thread().name
        over_rows(10, 1, lambda a, b: inner.append((a, b, threading.current_thread().name == me)))

    with num_threads(2, min_work=0):
        over_rows(2, 1, outer)
    assert sorted(inner) == [(0, 10, True), (0, 10, True)]


def test_the_fork_hook_drops_the_parents_pool():
    with num_threads(2, min_work=0):
        over_rows(4, 1, lambda a, b: None)
    assert threads._pool is not None
    saved = threads._pool, threads._pool_key, threads._pool_lock
    try:
        threads._after_fork_in_child()
        assert threads._pool is None and threads._pool_key is None
    finally:
        threads._pool, threads._pool_key, threads._pool_lock = saved
