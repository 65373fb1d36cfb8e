"""The realistic plant's state as the emulator reports it (no rclpy): its true platform pose where its encoders
read given lengths, the joint states its sensors report and their ground truth.

Joint states are (names, positions, velocities, efforts) for leg_1..6, vib_1..6: lengths and displacements in
m, rates in m/s, the axial strut forces in N (the same for a leg's strut and unit).
"""

from __future__ import annotations

import numpy as np

from ..kinematics import forward_kinematics
from ..robot import LEG_NAMES, VIB_NAMES
from .plant import Plant, Sensors
from .plant_drive import PlantDrive


def true_pose(plant: Plant, lengths: np.ndarray, guess) -> np.ndarray:
    """The plant's true pose (6,) where its struts read ``lengths`` (6,) m on their encoders (the controller's
    frame): FK of the robot as built at the true lengths (encoder + zero offset)."""
    result = forward_kinematics(plant.robot, lengths + plant.strut_zero_offsets, guess=guess)
    return np.asarray(result.pose, float).reshape(6)


def sensed_joint_state(drive: PlantDrive, sensors: Sensors, forces: np.ndarray):
    """The plant's joint states: encoders and unit sensors (their readings and rates over the last step)
    and the load cells (the strut ``forces`` with the plant's noise and offsets)."""
    (strut, unit), (strut_rate, unit_rate) = drive.readings(), drive.reading_rates()
    cells = forces + sensors.load_cell_offsets_n
    if sensors.load_cell_noise_n > 0:
        cells = cells + drive.rng.normal(0.0, sensors.load_cell_noise_n, 6)
    return (LEG_NAMES + VIB_NAMES, np.concatenate([strut, unit]), np.concatenate([strut_rate, unit_rate]),
            np.concatenate([cells, cells]))


def true_joint_state(drive: PlantDrive, forces: np.ndarray):
    """The ground truth of the plant's joint states: leg_* the struts' true lengths (the plant's frame, no
    encoder offset) and rates, vib_* the units' true displacements and rates, efforts the true axial strut
    ``forces``."""
    d = drive.data
    positions = np.concatenate([d.qpos[drive.slide_q], d.qpos[drive.vib_q]])
    velocities = np.concatenate([d.qvel[drive.slide_v], d.qvel[drive.vib_v]])
    return LEG_NAMES + VIB_NAMES, positions, velocities, np.concatenate([forces, forces])
