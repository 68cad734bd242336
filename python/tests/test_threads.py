"""The GIL is released while the library works: two threads deforming two clouds are inside
their deform() calls at the same time, and the interpreter runs other Python code meanwhile."""

import threading
import time

import numpy as np

import hgdeform

from conftest import tube, tube_scenario


def test_two_threads_deform_at_the_same_time():
    clouds = [tube(n=60000, seed=11)[0], tube(n=60000, seed=12)[0]]
    scenario = tube_scenario()
    expected = [hgdeform.deform(c, scenario)[0] for c in clouds]  # (and warms up)
    intervals = [None, None]
    results = [None, None]
    barrier = threading.Barrier(3)

    def work(k):
        barrier.wait()
        start = time.perf_counter()
        results[k] = hgdeform.deform(clouds[k], scenario)[0]
        intervals[k] = (start, time.perf_counter())

    threads = [threading.Thread(target=work, args=(k,)) for k in range(2)]
    for t in threads:
        t.start()
    # Meanwhile this thread samples the clock from Python code, which can only run while
    # neither call holds the GIL.
    barrier.wait()
    ticks = []
    while any(t.is_alive() for t in threads):
        ticks.append(time.perf_counter())
        time.sleep(0.0005)
    for t in threads:
        t.join()

    (a0, a1), (b0, b1) = intervals
    overlap_start, overlap_end = max(a0, b0), min(a1, b1)
    assert overlap_end > overlap_start, intervals  # both calls were running at once
    shorter = min(a1 - a0, b1 - b0)
    assert overlap_end - overlap_start > 0.5 * shorter, intervals
    # ... and not one waiting on the other's GIL: Python ran all through the overlap.
    inside = [t for t in ticks if overlap_start < t < overlap_end]
    assert len(inside) >= 10, (len(inside), intervals)
    gaps = np.diff([overlap_start, *inside, overlap_end])
    assert gaps.max() < 0.5 * (overlap_end - overlap_start), gaps.max()
    for k in range(2):  # and each got its own answer, the same as alone
        assert np.array_equal(results[k], expected[k])


def _ticks_while(work):
    """Runs work() in a thread while this one ticks every 0.5 ms; (start, end, ticks inside)."""
    interval = []

    def run():
        start = time.perf_counter()
        work()
        interval.extend([start, time.perf_counter()])

    t = threading.Thread(target=run)
    t.start()
    ticks = []
    while t.is_alive():
        ticks.append(time.perf_counter())
        time.sleep(0.0005)
    t.join()
    start, end = interval
    return start, end, [x for x in ticks if start < x < end]


def test_a_handle_deformation_frame_releases_the_gil():
    points = tube(n=60000, seed=13)[0]
    h = hgdeform.HandleDeformation(points)
    h.set_fixed([np.flatnonzero(points[:, 0] < 1.0)])
    h.set_manipulated(np.flatnonzero(points[:, 0] > 9.0))
    # the build, then a frame: a whole drag (many drag() calls), while Python keeps running
    start, end, inside = _ticks_while(h.build)
    assert len(inside) >= 5, (len(inside), end - start)

    def drag():
        for k in range(1, 16):
            h.drag([10.0, 1.0 + 0.2 * (k - 1), 0.0], [10.0, 1.0 + 0.2 * k, 0.0])

    start, end, inside = _ticks_while(drag)
    assert len(inside) >= 5, (len(inside), end - start)
    gaps = np.diff([start, *inside, end])
    assert gaps.max() < 0.5 * (end - start), (gaps.max(), end - start)


def test_too_many_threads_under_an_address_space_limit_is_a_memory_error():
    # libgomp ended the interpreter (status 1, no exception, no `finally`) when it could not
    # create its threads' stacks under `ulimit -v`: the module checks first, as the tools do.
    import os
    import subprocess
    import sys

    code = (
        "import numpy as np, hgdeform\n"
        "from conftest import tube, tube_scenario\n"
        "p, n = tube(n=600)\n"
        "try:\n"
        "    hgdeform.deform(p, tube_scenario())\n"
        "    print('ran')\n"
        "except MemoryError as e:\n"
        "    print('MemoryError', 'OMP_NUM_THREADS' in str(e))\n"
        "finally:\n"
        "    print('finally')\n")
    env = dict(os.environ, OMP_NUM_THREADS="1000", OPENBLAS_NUM_THREADS="1")
    here = os.path.dirname(os.path.abspath(__file__))
    r = subprocess.run(["bash", "-c", 'ulimit -v 4000000; exec "$0" -c "$1"', sys.executable, code],
                       capture_output=True, text=True, env=env, cwd=here, timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split("\n")[:2] == ["MemoryError True", "finally"], r.stdout + r.stderr
