"""Ctrl-C stops a render that would take minutes: the render looks at Python's
signals between chunks, with the GIL released in between."""

import signal
import subprocess
import sys
import time

# 600 s of 200 modes through the reference interpreter: minutes of work.
LONG_RENDER = """
import sys, timbre
try:
    print("rendering", flush=True)
    timbre.render("(combine (sine (* t (rvector 200 100 1000))))", duration=600,
                  engine="interp", threads=1)
except KeyboardInterrupt:
    print("interrupted", flush=True)
    sys.exit(3)
print("finished", flush=True)
"""


def test_ctrl_c_interrupts_a_long_render():
    child = subprocess.Popen(
        [sys.executable, "-c", LONG_RENDER], stdout=subprocess.PIPE, text=True
    )
    try:
        assert child.stdout.readline() == "rendering\n"
        time.sleep(1)  # into the render, which lasts minutes
        child.send_signal(signal.SIGINT)
        out, _ = child.communicate(timeout=120)
    finally:
        child.kill()
    assert out == "interrupted\n"
    assert child.returncode == 3


def test_ctrl_c_interrupts_a_render_with_a_progress_callback():
    child = subprocess.Popen(
        [sys.executable, "-c", LONG_RENDER.replace("threads=1)", "threads=1, progress=float)")],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert child.stdout.readline() == "rendering\n"
        time.sleep(1)
        child.send_signal(signal.SIGINT)
        out, _ = child.communicate(timeout=120)
    finally:
        child.kill()
    assert out == "interrupted\n"
    assert child.returncode == 3
