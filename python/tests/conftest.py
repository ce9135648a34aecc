# SPDX-License-Identifier: Apache-2.0
"""Fixtures: real farms (harness.py) shared by a module's tests, and farms of a test's own."""

from __future__ import annotations

import os
import tempfile
from typing import Callable, Iterator

import pytest

# The CLI and the package read these; a developer's environment must not steer the tests' farms.
for _var in ("TESSERA_COORDINATOR", "TESSERA_CLIENT_TOKEN", "TESSERA_TLS_CA", "TESSERA_WORKER_TOKEN",
             "TESSERA_THREADS", "TESSERA_EXIT_WHEN_IDLE"):
    os.environ.pop(_var, None)

import harness  # noqa: E402  (after the environment is cleaned: it reads TESSERA_* paths)


@pytest.fixture(scope="session")
def tmp_root() -> Iterator[str]:
    root = tempfile.mkdtemp(prefix="tessera-python-tests-")
    yield root
    harness.remove_tree(root)


@pytest.fixture(scope="session")
def worker_farm(tmp_root: str) -> Iterator[harness.LocalFarm]:
    """A coordinator with two one-thread workers, w1 and w2."""
    farm = harness.LocalFarm(tmp_root, "farm")
    try:
        farm.add_worker("w1")
        farm.add_worker("w2")
        farm.wait_for_workers(["w1", "w2"])
        yield farm
    finally:
        farm.stop()


@pytest.fixture(scope="session")
def bare_farm(tmp_root: str) -> Iterator[harness.LocalFarm]:
    """A coordinator without workers: its jobs stay queued (nothing renders, nothing changes)."""
    farm = harness.LocalFarm(tmp_root, "bare")
    try:
        yield farm
    finally:
        farm.stop()


@pytest.fixture
def make_farm(tmp_root: str, request: pytest.FixtureRequest) -> Iterator[Callable[..., harness.LocalFarm]]:
    """Starts farms of this test's own (e.g. with a token, or workers to kill); stopped after it."""
    farms: list[harness.LocalFarm] = []

    def make(*server_args: str) -> harness.LocalFarm:
        farm = harness.LocalFarm(tmp_root, f"{request.node.name}-{len(farms)}", server_args)
        farms.append(farm)
        return farm

    yield make
    for farm in farms:
        farm.stop()


@pytest.fixture
def scratch(tmp_path: pytest.TempPathFactory) -> str:
    return str(tmp_path)
