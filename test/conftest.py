"""Shared fixtures: the robot, and isolated ROS domains for node tests."""

from __future__ import annotations

import itertools
import os

import pytest

from stewart_vibration import load_robot

# Each test that starts nodes takes its own ROS_DOMAIN_ID (pytest-xdist is not
# used; the pid spreads concurrent pytest runs over different ranges).
_DOMAIN_IDS = itertools.count(10 + (os.getpid() % 8) * 12)


@pytest.fixture(scope="session")
def robot():
    return load_robot()


@pytest.fixture
def ros_domain(monkeypatch):
    """A fresh ROS_DOMAIN_ID (localhost discovery) for this test and its child processes."""
    domain = next(_DOMAIN_IDS) % 101 + 100  # 100..200, away from the default 0
    monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    return domain
