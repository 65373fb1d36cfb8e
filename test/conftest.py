"""Shared fixtures: the robot, and isolated ROS domains for node tests."""

from __future__ import annotations

import os

import pytest

from stewart_vibration import load_robot
from stewart_vibration.runtime.processes import claim_ros_domain


@pytest.fixture(scope="session")
def robot():
    return load_robot()


@pytest.fixture
def ros_domain(monkeypatch):
    """A ROS_DOMAIN_ID in 1..101 (localhost discovery) held by this test alone, for it and its children.

    claim_ros_domain locks the ID, so concurrent pytest runs and benchmarks never share a domain.
    """
    domain, lock = claim_ros_domain()
    monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    yield domain
    lock.close()


@pytest.fixture
def second_ros_domain(ros_domain):
    """Another held domain (1..101) for a test that needs two isolated graphs."""
    domain, lock = claim_ros_domain(avoid=(ros_domain,))
    yield domain
    lock.close()


# Hypothesis draws the same examples on every run (CI must not go red by chance; a new find is kept as an
# explicit test case). Set HYPOTHESIS_RANDOM=1 to explore with fresh random examples.
if not os.environ.get("HYPOTHESIS_RANDOM"):
    from hypothesis import settings as _hypothesis_settings

    _hypothesis_settings.register_profile("derandomized", derandomize=True)
    _hypothesis_settings.load_profile("derandomized")
