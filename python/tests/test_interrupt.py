"""Ctrl-C during Scene.render: the render stops at its next iteration and KeyboardInterrupt comes
within about a second, carrying the image of the samples finished (as `spectrack render` writes
them on SIGINT); the GIL is released meanwhile (another Python thread runs)."""
import os
import signal
import threading
import time

import pytest

import spectrack
from test_api import SLAB


def test_keyboard_interrupt_stops_within_a_second():
    scene = spectrack.load_dict({**SLAB, "film": {"width": 64, "height": 64, "spp": 1}})
    scene.render(spp=1)  # kernels built and cached: the render below is in its stage loop at once
    progressed = threading.Event()
    ticks = []
    sent = []

    def ticker():  # runs only if the render releases the GIL
        while not sent:
            ticks.append(1)
            time.sleep(0.01)

    def interrupt():
        progressed.wait(60)
        time.sleep(1.0)
        sent.append(time.monotonic())
        os.kill(os.getpid(), signal.SIGINT)

    threading.Thread(target=ticker).start()
    threading.Thread(target=interrupt).start()
    with pytest.raises(KeyboardInterrupt) as info:
        scene.render(spp=1 << 20, progress=lambda f: f > 0 and progressed.set())
    waited = time.monotonic() - sent[0]
    assert waited < 1.0, f"the render took {waited:.2f} s to stop"
    img = info.value.image
    assert img.interrupted and 0 < img.spp < (1 << 20)
    assert img.stats["interrupted"] and img.stats["spp"] == img.spp and img.stats["stop_reason"] == "signal"
    assert len(ticks) > 20, "another thread did not run while rendering (the GIL was held)"


def test_time_limit_keeps_the_samples_done():
    scene = spectrack.load_dict({**SLAB, "film": {"width": 64, "height": 64, "spp": 1}})
    scene.render(spp=1)
    t0 = time.monotonic()
    img = scene.render(spp=1 << 20, time_limit=2.0)
    assert time.monotonic() - t0 < 4.0
    assert img.interrupted and img.spp > 0 and img.stats["stop_reason"] == "time-limit"
    with pytest.raises(TimeoutError, match="time limit"):
        scene.render(spp=1 << 20, time_limit=1e-3)
    for bad in (0.0, -1.0, 1e-6, float("nan"), float("inf"), 1e10):  # refused before rendering, not a TimeoutError
        with pytest.raises(ValueError, match="time_limit"):
            scene.render(spp=1, time_limit=bad)
