"""Chain kinematics, backward-motion controller and the co-simulation master."""
