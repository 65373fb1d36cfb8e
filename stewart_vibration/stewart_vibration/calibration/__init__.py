"""Kinematic calibration (pure numpy/scipy): the robot's hinges and strut zero offsets identified from strut
readings and an external tracker's platform poses, with their uncertainty."""
