"""Fixtures of the batch tests: a small fleet of recordings (built once per session)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from fleet import copy_recording, make_fleet


@pytest.fixture(scope="session")
def fleet_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Five recordings (mcap, db3 folder, mcap folder) of two robots, one broken; never modified."""
    root = tmp_path_factory.mktemp("fleet") / "fleet"
    make_fleet(root)
    return root


@pytest.fixture
def fleet(tmp_path: Path, fleet_dir: Path) -> Path:
    """A private copy of the fleet (tests may add, touch or truncate files)."""
    target = tmp_path / "fleet"
    shutil.copytree(fleet_dir, target)
    return target


@pytest.fixture(scope="session")
def long_recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The whole sample session logged four times in a row (56 maps): a task that takes a while."""
    return copy_recording(tmp_path_factory.mktemp("long") / "long.mcap", "mcap", repeat=4)


@pytest.fixture(scope="session")
def big_recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One 6000 x 6000 map: its FFTs need several hundred MB."""
    from fleet import big_map_recording

    return big_map_recording(tmp_path_factory.mktemp("big") / "big.mcap", side=6000)
