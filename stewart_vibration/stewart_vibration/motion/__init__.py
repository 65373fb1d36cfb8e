"""Point-to-point motion of the platform (the reduction): minimum-jerk profiles (``profiles``), checked
SE(3) paths with the strut forces they need (``paths``) and the force guard that stops a move against
an excessive load (``force_guard``)."""
