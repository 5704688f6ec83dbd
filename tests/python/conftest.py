"""Fixtures for the Python client's tests: real invr-server and invr-worker processes on loopback
(ctest sets PYTHONPATH to build/python and INVR_BIN to build/bin)."""

import os
import socket
import subprocess
import time
from pathlib import Path

import pytest

import invr


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Service:
    """An invr-server on a fixed free port (so it can be restarted there) and one worker."""

    def __init__(self, tmp):
        self.tmp = Path(tmp)
        self.port = free_port()
        self.address = f"127.0.0.1:{self.port}"
        self.server = None
        self.worker = None

    def start_server(self):
        log = open(self.tmp / "server.log", "a")
        # The final renders are fetched, never judged, here: 4 samples a pixel, not 64.
        self.server = subprocess.Popen([invr.binary("invr-server"), "--store", str(self.tmp / "store"), "--address", self.address,
                                        "--final-spp", "4"], stdout=log, stderr=log)

    def stop_server(self):
        self.server.terminate()
        self.server.wait(timeout=30)

    def start_worker(self):
        log = open(self.tmp / "worker.log", "a")
        self.worker = subprocess.Popen([invr.binary("invr-worker"), "--server", self.address, "--threads", "1"], stdout=log, stderr=log)

    def stop(self):
        for p in (self.worker, self.server):
            if p is not None and p.poll() is None:
                p.terminate()
                try:
                    p.wait(timeout=30)
                except subprocess.TimeoutExpired:
                    p.kill()


def _started(tmp):
    s = Service(tmp)
    s.start_server()
    s.start_worker()
    s.client = invr.Client(s.address)
    s.client.wait_for_workers(1, timeout=60)
    return s


@pytest.fixture(scope="module")
def service(tmp_path_factory):
    """One server and worker for the tests that only submit to them (each job is its own)."""
    s = _started(tmp_path_factory.mktemp("service"))
    yield s
    s.client.close()
    s.stop()


@pytest.fixture
def fresh_service(tmp_path):
    """A server and worker of the test's own, for a test that stops or restarts them."""
    s = _started(tmp_path)
    yield s
    s.client.close()
    s.stop()
