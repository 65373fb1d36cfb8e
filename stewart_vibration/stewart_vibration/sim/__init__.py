"""MuJoCo model of the robot: MJCF generation from config/robot.yaml (``mjcf``) and the simulation
wrapper with strut drives and state read-back (``mujoco_sim``)."""
