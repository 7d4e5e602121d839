"""One writer per results folder: a live holder refuses a second run, a killed run's lock is taken over."""

import subprocess
import sys

import pytest

from remaster import results
from remaster.results import LOCK_FILE, ResultsLocked


def test_a_second_writer_is_refused_naming_the_holder(tmp_path):
    lock = results.take_lock(tmp_path / "results")
    assert lock == tmp_path / "results" / LOCK_FILE and lock.is_file()
    assert results.take_lock(tmp_path / "results") == lock  # the holder may take it again
    other = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
    try:
        with pytest.raises(ResultsLocked, match=rf"{LOCK_FILE}: another run is writing this results folder") as info:
            results.take_lock(tmp_path / "results", pid=other.pid)
        assert "host" in str(info.value) and "wait for it to end, or give another results_dir" in str(info.value)
        results.release_lock(tmp_path / "results", pid=other.pid)  # not the holder: nothing happens
        assert lock.is_file()
    finally:
        other.kill()
        other.wait()
    results.release_lock(tmp_path / "results")
    assert not lock.exists()


def test_the_lock_of_a_killed_run_is_taken_over(tmp_path, caplog):
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()
    results.take_lock(tmp_path, pid=gone.pid)
    lock = results.take_lock(tmp_path)
    assert f"taken over from process {gone.pid}" in caplog.text
    assert results._lock_holder(lock)["pid"] != gone.pid
