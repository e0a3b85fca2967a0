"""The set-up of a lot's Dask worker process: what a worker may print on the terminal."""

import subprocess
import sys


def test_a_worker_prints_no_error_of_dask_s_own_about_a_scheduler_gone():
    """A Ctrl-C closes the scheduler while workers still send their heartbeats: the
    worker's error about the closed stream is Dask's, and not printed (the lot's own
    outcome is one line); a critical message still is."""
    code = (
        "import logging, sys\n"
        "from pmdc_bayes._lot_worker import dask_setup\n"
        "logging.basicConfig(stream=sys.stderr)\n"
        "dask_setup(None)\n"
        "logging.getLogger('distributed.worker').error('Failed to communicate with "
        "scheduler during heartbeat.')\n"
        "logging.getLogger('tornado.application').error('Exception in callback')\n"
        "logging.getLogger('distributed.nanny').critical('worker lost')\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120, check=True)
    assert done.stderr.strip().splitlines() == ["CRITICAL:distributed.nanny:worker lost"]
