"""The hardware emulator node with the tissue file checks lifted (the stiffening length's lower bound and the
worst-case wrench), so that a test can give it a tissue no file may describe (a wall: e-fold every 1 um) and
watch its physics guard catch the divergence over DDS. Run as ``python -m wall_tissue_emulator`` with test/ on
PYTHONPATH."""

from stewart_vibration.dynamics import tissue_config
from stewart_vibration.nodes import hardware_emulator_node

if __name__ == "__main__":
    tissue_config._PLAUSIBLE["length_m"] = tissue_config.Plausible(0.0, 1.0, "m")
    tissue_config.check_tissue_wrench = lambda *args, **kwargs: None
    hardware_emulator_node.main()
