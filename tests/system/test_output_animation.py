"""`plot --animate` streams its frames: the memory of the pictures'
process does not grow with the number of frames (it held every frame and every time's
grid: 1.9 GB for 1501 frames).  Measured as the peak resident memory of the process (not
a time), for 20 and 120 frames."""
import json
import os
import subprocess
import sys

import pytest

from conftest import PAPER_CASE, ROOT, run_cli

pytestmark = pytest.mark.slow    # two runs and two animations (each pair side by side): 9 s
FRAME_BYTES = 800 * 560          # one quantized frame (pictures.FRAME)


def _animate(out) -> tuple[int, int]:
    """(frames, peak resident bytes) of `python -m vpcontact.post.pictures OUT --animate`."""
    proc = subprocess.Popen([sys.executable, "-P", "-m", "vpcontact.post.pictures", str(out),
                             "--animate", "--dim", "2"], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": str(ROOT)})
    stdout, stderr = proc.stdout.read(), proc.stderr.read()
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    assert proc.returncode == 0, stderr
    return json.loads(stdout.strip().splitlines()[-1])["frames"], usage.ru_maxrss * 1024


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Runs of 20 and 120 steps, side by side."""
    from concurrent.futures import ThreadPoolExecutor
    outs = {n: tmp_path_factory.mktemp("anim") / f"n{n}" for n in (20, 120)}
    with ThreadPoolExecutor(2) as pool:
        procs = pool.map(lambda n: run_cli(["run", PAPER_CASE, "--out", outs[n], "--set",
                                            "mesh.n=4", "--set", f"time.N={n}", "--quiet"]),
                         outs)
    for proc in procs:
        assert proc.returncode == 0, proc.stderr
    return outs


def test_animation_memory_does_not_grow_with_the_frames(runs):
    from concurrent.futures import ThreadPoolExecutor
    with ThreadPoolExecutor(2) as pool:    # two processes side by side, each its own peak
        (f20, rss20), (f120, rss120) = pool.map(_animate, (runs[20], runs[120]))
    assert (f20, f120) == (21, 121)
    # holding the frames would take 100 more frames of FRAME_BYTES (and Pillow's copies)
    assert rss120 - rss20 < 20 * FRAME_BYTES, (rss20, rss120)


def test_streamed_gif_has_every_frame_and_time(runs):
    """Every output time is a frame of the set duration, looping; the last differs from
    the first (the body deforms)."""
    import numpy as np
    from PIL import Image, ImageSequence
    gif = Image.open(runs[20] / "animation.gif")
    assert gif.info["loop"] == 0 and gif.size == (800, 560)
    frames = [(np.asarray(f.convert("RGB"), dtype=float), f.info["duration"])
              for f in ImageSequence.Iterator(gif)]
    assert len(frames) == 21 and {d for _, d in frames} == {150}
    assert np.abs(frames[0][0] - frames[-1][0]).mean() > 0.5
