"""A bench row says how many cores other processes kept busy beside its run
(app/studies/benchrun.py): the machine's busy CPU time over the run less the run's own."""
import os
import subprocess
import sys
import time

import pytest

from vpcontact.studies.benchrun import BUSY_CORES, busy_cpu_seconds, busy_text, others_cores

BUSY_LOOP = "import time\nt = time.perf_counter()\nwhile time.perf_counter() - t < 1.0:\n    pass\n"


def test_others_are_the_busy_time_less_the_runs_own_over_its_wall():
    assert others_cores(100.0, 104.0, 2.0, 2.0) == 1.0
    assert others_cores(100.0, 101.0, 1.5, 1.0) == 0.0       # never below 0 (tick rounding)
    assert others_cores(None, 104.0, 2.0, 2.0) is None
    assert others_cores(100.0, 104.0, 2.0, 0.0) is None


def test_the_machines_busy_time_counts_a_busy_process():
    """A busy loop's CPU time (its own account, wait4) is inside the machine's busy time
    over the same interval."""
    if busy_cpu_seconds() is None:
        pytest.skip("no /proc/stat")
    before = busy_cpu_seconds()
    proc = subprocess.Popen([sys.executable, "-c", BUSY_LOOP])
    _, _, usage = os.wait4(proc.pid, 0)
    time.sleep(0.05)
    after = busy_cpu_seconds()
    own = usage.ru_utime + usage.ru_stime
    assert own > 0.3
    assert after - before >= own - 0.05          # clock ticks: 10 ms each


def test_busy_text_names_the_others_from_the_threshold():
    assert busy_text({"others_cores": None}) == ""
    assert busy_text({"others_cores": BUSY_CORES / 2}) == ""
    assert busy_text({"others_cores": 0.85}) == ", other processes busy on 0.85 cores meanwhile"
