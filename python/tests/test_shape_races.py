"""A Shape changed by one thread while another writes, deforms or takes the field of it: the
call works on the shape as it was when called (a copy taken with the GIL held), never on records
the other thread frees. Each run is in a subprocess, so that a crash fails the test."""

import os
import subprocess
import sys
import textwrap

import pytest

SCRIPT = textwrap.dedent("""
    import sys, threading
    import numpy as np
    import hgdeform
    from conftest import tube, tube_scenario

    what, out = sys.argv[1], sys.argv[2]
    p, _ = tube(20000)
    sh = hgdeform.Shape(p)
    s = tube_scenario()
    ref = hgdeform.deform(p, s)[0]
    stop = False

    def mutate():
        k = 0
        while not stop:
            if what == "write":
                sh.points = p + (k % 2)  # rewritten in place
            sh.set_field("f%d" % k, np.zeros(len(p)))  # the records reallocated
            k += 1

    t = threading.Thread(target=mutate)
    t.start()
    try:
        for i in range(8):
            if what == "write":
                hgdeform.write(out, sh)
                q = hgdeform.read(out).points
                assert np.array_equal(q, p) or np.array_equal(q, p + 1), "a torn point set"
            elif what == "deform":
                q = hgdeform.deform(sh, s)[0].points
                assert np.array_equal(q, ref)
            else:
                phi = hgdeform.field(sh, s)
                assert phi.shape == (len(p),) and np.isfinite(phi).all()
    finally:
        stop = True
        t.join()
    print("ok")
""")


@pytest.mark.parametrize("what", ["write", "deform", "field"])
def test_a_shape_changed_by_another_thread_while_a_call_uses_it(tmp_path, what):
    here = os.path.dirname(os.path.abspath(__file__))
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([here, env.get("PYTHONPATH", "")])
    r = subprocess.run([sys.executable, "-c", SCRIPT, what, str(tmp_path / "out.ply")],
                       capture_output=True, text=True, env=env, timeout=300)
    assert r.returncode == 0 and r.stdout.strip() == "ok", (r.returncode, r.stderr[-2000:])
