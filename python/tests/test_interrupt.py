"""Ctrl-C (SIGINT) stops a run after the current step: KeyboardInterrupt carries the partial
result. The signal comes from a timer thread, as a terminal's would, while the run holds no GIL."""

import os
import signal
import threading

import pytest

import ribbon
from conftest import robot

# Long enough that the signal, sent once the run is under way, lands well before its end.
LONG_DURATION_S = 120.0


def interrupt_when(started):
    def wait_and_signal():
        started.wait(timeout=60)
        os.kill(os.getpid(), signal.SIGINT)

    thread = threading.Thread(target=wait_and_signal, daemon=True)
    thread.start()
    return thread


def test_keyboard_interrupt_stops_a_study_with_its_partial_result():
    started = threading.Event()
    seen = []

    def progress(p):
        seen.append(p)
        started.set()

    thread = interrupt_when(started)
    with pytest.raises(KeyboardInterrupt) as caught:
        ribbon.analyze(robot("ur5"), duration=LONG_DURATION_S, progress=progress)
    thread.join()
    result = caught.value.result
    assert isinstance(result, ribbon.StudyResult)
    assert result.partial and not result.trusted
    assert seen and seen[0]["phase"] == "design" and seen[0]["records_total"] > 0
    # Stopped early: far fewer record times than the horizon has.
    assert 0 < len(result.times) and result.times[-1] < LONG_DURATION_S / 2


def test_keyboard_interrupt_stops_a_simulation_after_the_current_step():
    started = threading.Event()
    timer = threading.Timer(0.3, started.set)
    timer.start()
    thread = interrupt_when(started)
    with pytest.raises(KeyboardInterrupt) as caught:
        ribbon.simulate(robot("ur5"), duration=10_000.0)
    thread.join()
    sim = caught.value.result
    assert sim.partial
    assert 0 < sim.times[-1] < 10_000.0


def test_an_exception_in_the_progress_callback_stops_the_study():
    class Enough(Exception):
        pass

    def progress(p):
        raise Enough(p["phase"])

    with pytest.raises(Enough) as caught:
        ribbon.analyze(robot("ur5"), duration=LONG_DURATION_S, progress=progress)
    assert caught.value.result.partial


def test_the_gil_is_released_while_a_study_runs():
    ticks = []
    done = threading.Event()

    def count():
        while not done.is_set():
            ticks.append(1)
            done.wait(0.001)

    thread = threading.Thread(target=count)
    thread.start()
    try:
        study = ribbon.analyze(robot("ur5"), duration=6.0)
    finally:
        done.set()
        thread.join()
    assert study.runs > 100
    # A thread that needs the GIL every millisecond ran all along (held for the study, it would
    # get it only between the progress calls).
    assert len(ticks) > 200, len(ticks)
