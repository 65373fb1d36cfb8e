"""The emulated robot's commands and its safety layer's state, as the node and the tests use them (no rclpy):
each is the ``SafetyController``'s (the robot's own safety layer: strut trajectory follower, vibration command
buffer, every command check and stop) at the robot's own time (simulation time, s). Lengths in m, poses
[x, y, z, roll, pitch, yaw] in m and rad in the base frame.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

from .physics_guard import PhysicsFault
from .safety_controller import SafetyController
from .strut_trajectory import JointTrajectory, TrajectoryFollower
from .vibration_buffer import VibrationBuffer
from .vibration_status import VibrationReport, VibrationStatusTracker


class EmulatorCommands(ABC):
    """The commands of a robot whose safety layer is ``safety``, at the robot's ``time``; the robot
    (``HardwareEmulator``) adds the physics and the pose of its platform (``platform_pose``)."""

    safety: SafetyController

    @property
    @abstractmethod
    def time(self) -> float:
        """Simulation time now (s)."""

    @abstractmethod
    def platform_pose(self) -> np.ndarray:
        """The platform's pose now (6,) [x, y, z, roll, pitch, yaw] (m, rad) in the base frame."""

    # the safety controller's state, as the node and the tests read it
    @property
    def struts(self) -> TrajectoryFollower:
        """The strut trajectory follower (the commanded strut lengths)."""
        return self.safety.struts

    @property
    def vibration(self) -> VibrationBuffer:
        """The vibration command buffer (the commanded unit displacements)."""
        return self.safety.vibration

    @property
    def status(self) -> VibrationStatusTracker:
        """The vibration status tracker."""
        return self.safety.status

    @property
    def estopped(self) -> bool:
        """True while the e-stop (or a physics fault) is latched."""
        return self.safety.estopped

    @property
    def fault(self) -> PhysicsFault | None:
        """The latched physics fault, or None."""
        return self.safety.fault

    @property
    def home_lengths(self) -> np.ndarray:
        """The strut lengths at the home pose (6,) (m)."""
        return self.safety.home_lengths

    # -- commands (``SafetyController``, at the emulator's time) -----------------------------------
    def command_struts(self, names, start, times, positions, velocities=None, accelerations=None,
                       lock=None) -> JointTrajectory:
        """Validate and run a leg_* trajectory (``SafetyController.command_struts``); returns it as it runs.

        joint_trajectory_controller rules with the limits enforced on what will actually be followed:
        start 0 = now; points already in the past are dropped and the motion departs from the state
        commanded now toward the first future point; a trajectory with positions only gets
        finite-difference velocities (zero at its first and last point) and cubic segments instead of
        linear ones (a linear one steps the velocity at every point). The spline from the departure
        state through every point must stay within the stroke, strut_velocity_max and
        strut_acceleration_max and end at rest (the last point is held), keep the six struts together inside
        the workspace and leave room for a controlled stop (``strut_acceptance``); a start more than
        ``max_start_delay_s`` ahead, or one in the future while another still waits for its start, is refused.
        Until a future start the running command goes on. At most MAX_TRAJECTORY_POINTS points.

        ``lock``: the lock the caller shares with the physics thread (``advance``); the checks then run outside
        it and only the commit takes it. Raises the typed reason (InvalidInputError, StrokeLimitError,
        ActuatorLimitError, UnreachablePoseError, JointLimitError, SingularPoseError, PhysicsFaultError);
        nothing moves then.
        """
        return self.safety.command_struts(self.time, names, start, times, positions, velocities, accelerations,
                                          pose=self.platform_pose, clock=lambda: self.time, lock=lock)

    def command_vibration(self, names, start, times, positions, velocities=None, accelerations=None) -> float:
        """Validate and splice a vib_* window (``SafetyController.command_vibration``); returns the splice time."""
        return self.safety.command_vibration(self.time, names, start, times, positions, velocities, accelerations)

    def emergency_stop(self) -> None:
        """Ramp the vibration to zero and bring the struts to rest along their commanded path within
        strut_acceleration_max (``TrajectoryFollower.brake``), then hold; latched until reset()."""
        self.safety.emergency_stop(self.time)

    def halt(self, reason: str) -> None:
        """A safety stop that does not latch (lifecycle deactivate, shutdown; ``SafetyController.halt``)."""
        self.safety.halt(self.time, reason)

    def at_rest(self) -> bool:
        """True when the commanded struts and vibration units are at rest from now on."""
        return self.safety.at_rest(self.time)

    def reset(self) -> float:
        """Clear a latched e-stop and move home from where its stop comes to rest (``SafetyController.reset``);
        returns the time until home (s)."""
        return self.safety.reset(self.time, self.platform_pose())

    def vibration_report(self) -> tuple[VibrationReport, bool]:
        """(report, state changed) of what the vibration units do now (see vibration_status)."""
        return self.safety.vibration_report(self.time)

    @property
    def _version(self) -> int:
        return self.safety.version

    def _changed(self) -> None:
        self.safety.changed()
